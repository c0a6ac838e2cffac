"""--time-format on a live port (a pty pair fed by the simulator): `decode PORT` and `record --print` show the
same forms as a file, and the recording keeps the wall-clock stamps."""

from __future__ import annotations

import os
import time
from datetime import datetime

import pytest

from rs30x_sniff.sources.mcap_reader import read_mcap_raw
from tests.e2e.helpers import Pty, cli, wait_for, wait_opened


@pytest.fixture
def pty():
    p = Pty()
    yield p
    p.close()


def times_of(out: str) -> list[str]:
    return [line[:line.index(" @")].strip() for line in out.splitlines() if " @" in line and " lint  " not in line]


def _decode(pty: Pty, *args: str) -> tuple[list[str], float, float]:
    """decode PORT's times for the setup scenario played once, and the wall clock around its run."""
    proc = cli("decode", pty.path, "--duration", "5", "--no-lint", *args,
               env=dict(os.environ, TZ="UTC"))
    wait_opened(pty.path, proc)  # the port is open (its input flushed) before the bus starts
    before = time.time()
    pty.write_sim("setup", duration=None)
    after = time.time()
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err.decode()
    return times_of(out.decode()), before, after


def test_decode_of_a_port_counts_from_its_first_byte(pty):
    got, before, after = _decode(pty)
    values = [float(x) for x in got]
    assert values[0] == 0.0 and len(values) > 20
    assert all(b >= a for a, b in zip(values, values[1:]))  # one origin, a clock that runs on
    assert values[-1] <= after - before + 1.0  # seconds of this run, not since 1970


def test_decode_of_a_port_in_the_time_of_day(pty):
    got, before, after = _decode(pty, "--time-format", "absolute")
    # The child runs with TZ=UTC: its local date and time of day is UTC's.
    stamp = datetime.strptime(got[0] + " +0000", "%Y-%m-%d %H:%M:%S.%f %z").timestamp()
    assert before - 1.0 <= stamp <= after + 1.0  # the bytes' own wall-clock time, within the run


def test_decode_of_a_port_in_deltas(pty):
    got, _, _ = _decode(pty, "--time-format", "delta")
    values = [None if x == "-" else float(x) for x in got]
    assert values[0] == 0.0 and all(v is not None and v >= 0 for v in values)


def test_record_print_shows_the_form_and_the_file_keeps_the_stamps(pty, tmp_path):
    out = tmp_path / "bus.mcap"
    proc = cli("record", pty.path, "-o", str(out), "--print", "--duration", "5", "--no-lint",
               "--time-format", "relative")
    wait_for(out, proc)
    wait_opened(pty.path, proc)
    before = time.time()
    pty.write_sim("setup", duration=None)
    after = time.time()
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 0, stderr.decode()
    values = [float(x) for x in times_of(stdout.decode())]
    assert values and values[0] == 0.0 and values[-1] <= after - before + 1.0
    stamps = [t for _, t in read_mcap_raw(str(out))]
    assert before - 1.0 <= stamps[0] <= after + 1.0  # the MCAP keeps seconds since 1970
