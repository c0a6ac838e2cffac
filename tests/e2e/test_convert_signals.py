"""`convert` stopped by a signal mid-input keeps a finished MCAP of what it read (a FIFO that stays open)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.e2e.helpers import assert_finalized_mcap, recorded_bytes

SESSION = Path(__file__).resolve().parents[2] / "captures" / "session-mixed.thex"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_stopped_convert_keeps_a_finished_log(tmp_path, sig):
    fifo = tmp_path / "bus.fifo"
    os.mkfifo(fifo)
    out = tmp_path / "bus.mcap"
    proc = subprocess.Popen([sys.executable, "-m", "rs30x_sniff", "convert", str(fifo), "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    writer = os.open(fifo, os.O_WRONLY)  # blocks until convert opens the FIFO
    try:
        os.write(writer, SESSION.read_bytes())  # and the writer never closes it: convert waits for more
        time.sleep(1.5)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=20)
    finally:
        os.close(writer)
    assert proc.returncode == 130, err
    assert b"stopped" in err and err.count(b"\n") == 1, err
    assert_finalized_mcap(out)
    assert len(recorded_bytes(out)) > 0
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".part")] == []
