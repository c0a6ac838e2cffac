"""--baud auto end to end: the scan over a simulated wire at four rates, and over a real pty."""

from __future__ import annotations

import os
import threading
import time

import pytest

from rs30x_sniff.decode.autobaud import scan
from rs30x_sniff.decode.autobaud import scan
from rs30x_sniff.sources.serial_tap import port_reader
from rs30x_sniff.sim import run
from rs30x_sniff.sim.port import play
from rs30x_sniff.sim.wire import SimWire
from tests.e2e.helpers import Pty


@pytest.mark.parametrize("line", [9600, 57600, 115200, 230400])
def test_scan_finds_each_rate_within_3_s_of_listening(line):
    wire = SimWire(run("hexapod", baud=line, duration=30.0), line, start=2.0)
    t0 = time.monotonic()
    result = scan(wire.read_for)
    wall = time.monotonic() - t0
    assert result.baud == line, result.describe()
    assert wire.t - 2.0 < 3.0, f"{wire.t - 2.0:.1f} s of simulated listening"
    assert wall < 3.0, f"{wall:.2f} s of wall time"


def test_scan_port_on_a_pty_picks_a_rate_with_valid_frames_and_never_writes():
    pty = Pty()
    try:
        chunks = list(run("hexapod", baud=115200, duration=4.0))
        stop = threading.Event()

        def writer():
            # A pty ignores the rate: every rate reads the same bytes, so only check the scan runs.
            play([c for c in chunks if c[1] > 1.5], lambda b: None if stop.is_set() else os.write(pty.master, b))

        th = threading.Thread(target=writer, daemon=True)
        th.start()
        time.sleep(0.1)
        result = scan(port_reader(pty.path), dwell=0.3)
        stop.set()
        th.join(5)
        assert result.baud is not None, result.describe()
        assert result.table[-1].frames >= 2
        assert pty.master_silent()
    finally:
        pty.close()
