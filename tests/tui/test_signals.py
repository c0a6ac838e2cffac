"""SIGTERM and SIGHUP end the monitor as `q` does: terminal restored, an `r` recording finalized (a real pty)."""

from __future__ import annotations

import fcntl
import os
import select
import signal
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

ALT_SCREEN_OFF = b"\x1b[?1049l"
MOUSE_OFF = b"\x1b[?1000l"


def _run_monitor(args: list[str], cwd: Path):
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    env = dict(os.environ, TERM="xterm-256color", COLUMNS="120", LINES="40")
    proc = subprocess.Popen([sys.executable, "-m", "rs30x_sniff", "monitor", *args], stdin=slave, stdout=slave,
                            stderr=slave, env=env, cwd=cwd, start_new_session=True)
    os.close(slave)
    return master, proc


def _read_until(master: int, proc, pred, timeout: float) -> bytes:
    buf = b""
    end = time.monotonic() + timeout
    while time.monotonic() < end and not pred(buf):
        r, _, _ = select.select([master], [], [], 0.1)
        if r:
            try:
                data = os.read(master, 65536)
            except OSError:
                break
            if not data:
                break
            buf += data
        elif proc.poll() is not None:
            break
    return buf


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_a_stop_signal_restores_the_terminal_and_finishes_the_recording(tmp_path, sig):
    master, proc = _run_monitor(["--simulate", "hexapod", "--record-dir", str(tmp_path)], tmp_path)
    try:
        screen = _read_until(master, proc, lambda b: b"timeline" in b and b"live" in b, 30)
        assert b"timeline" in screen, screen[-500:]
        os.write(master, b"r")
        _read_until(master, proc, lambda b: b"recording to" in b, 10)
        time.sleep(1.0)
        proc.send_signal(sig)
        rest = _read_until(master, proc, lambda b: ALT_SCREEN_OFF in b and proc.poll() is not None, 20)
        assert proc.wait(10) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
    assert ALT_SCREEN_OFF in rest and MOUSE_OFF in rest  # the terminal is back to normal
    [log] = list(tmp_path.glob("*.mcap"))
    with open(log, "rb") as f:
        summary = make_reader(f).get_summary()  # a finished file: summary and footer written
    assert summary is not None and summary.statistics.message_count > 0
