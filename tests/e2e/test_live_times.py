"""A live port's times are wall-clock seconds since the epoch, as docs/live-capture.md says."""

from __future__ import annotations

import os
import time
from pathlib import Path

from rs30x_sniff.sources.serial_tap import LiveSource
from tests.e2e.helpers import Pty

DOC = Path(__file__).resolve().parents[2] / "docs" / "live-capture.md"


def test_live_times_are_the_wall_clock_as_documented():
    p = Pty()
    before = time.time()
    src = LiveSource(p.path, 115200, announce=False).start()
    try:
        time.sleep(0.3)  # times since the port opened would now be about 0.3
        os.write(p.master, bytes.fromhex("FA AF 01 09 00 00 01 09"))
        got: list[tuple[bytes, float]] = []
        deadline = time.monotonic() + 5
        while sum(len(d) for d, _ in got) < 8 and time.monotonic() < deadline:
            got += src.poll(0.1)
        after = time.time()
        meta = src.metadata
    finally:
        src.close()
        p.close()
    assert got
    opened = int(meta["wall_start_ns"]) / 1e9
    assert before <= opened <= after
    for _, t in got:
        # Seconds since the epoch, after the sleep since the port opened (less the chunk's byte times).
        assert before + 0.25 <= t <= after and t - opened >= 0.25, (before, t, after)
    text = " ".join(DOC.read_text().split())
    assert "seconds since the Unix epoch" in text and "seconds since the port was opened" not in text
