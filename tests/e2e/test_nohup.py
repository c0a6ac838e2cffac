"""Under `nohup` (SIGHUP ignored from the start) a hang-up does not end a command: the run was asked to outlive its
terminal. SIGTERM still stops it cleanly, with exit 0 (a live capture) and its end line."""

from __future__ import annotations

import os
import signal
import time

import pytest

from .helpers import Pty, assert_finalized_mcap, cli, recorded_bytes, wait_opened

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGHUP") or not hasattr(os, "openpty"),
                                reason="needs SIGHUP and pseudo-terminals")

SESSION = os.path.join(os.path.dirname(__file__), "..", "..", "captures", "session-mixed.thex")


def _nohup() -> None:
    signal.signal(signal.SIGHUP, signal.SIG_IGN)  # as nohup(1) starts a command


def _hang_up_then_stop(proc, settle: float = 1.0) -> tuple[int, str]:
    proc.send_signal(signal.SIGHUP)
    time.sleep(settle)
    assert proc.poll() is None, f"a hang-up ended a run started under nohup: {proc.stderr.read().decode()}"
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    return proc.returncode, err.decode()


@pytest.mark.parametrize("mode", ["record", "record-trigger", "decode"])
def test_a_live_run_under_nohup_outlives_a_hang_up(tmp_path, mode):
    pty = Pty()
    link = tmp_path / "ttyRIG"  # a link: record looks for the port again after a loss, and holds its stops
    link.symlink_to(pty.path)
    args = {"record": ["record", str(link), "-o", str(tmp_path / "rig.mcap")],
            "record-trigger": ["record", str(link), "-o", str(tmp_path / "win") + "/", "--trigger", "kind:return",
                               "--pre", "5s"],
            "decode": ["decode", str(link)]}
    proc = cli(*args[mode], preexec_fn=_nohup)
    try:
        wait_opened(pty.path, proc)
        sent = pty.write_sim("hexapod", duration=0.5)
        time.sleep(0.3)
        rc, err = _hang_up_then_stop(proc)
    finally:
        pty.close()
        if proc.poll() is None:
            proc.kill()
    assert rc == 0, err
    assert err.strip().splitlines()[-1].startswith("rs30x-sniff: SIGTERM: "), err
    if mode == "record":
        assert recorded_bytes(tmp_path / "rig.mcap") == sent


def test_convert_under_nohup_outlives_a_hang_up(tmp_path):
    fifo = tmp_path / "bus.fifo"
    os.mkfifo(fifo)
    out = tmp_path / "bus.mcap"
    proc = cli("convert", str(fifo), "-o", str(out), preexec_fn=_nohup)
    writer = os.open(fifo, os.O_WRONLY)  # blocks until convert opens the FIFO
    try:
        with open(SESSION, "rb") as f:
            os.write(writer, f.read())  # and the writer never closes it: convert waits for more
        time.sleep(1.0)
        rc, err = _hang_up_then_stop(proc)
    finally:
        os.close(writer)
        if proc.poll() is None:
            proc.kill()
    assert rc == 130, err
    assert "stopped" in err and err.count("\n") == 1, err
    assert_finalized_mcap(out)


def test_the_stop_signals_leave_an_ignored_hang_up_alone():
    """One list for every live reader, the saved windows and the monitor: SIGHUP is in it unless ignored."""
    from rs30x_sniff.sources.serial_tap import stop_signals

    before = signal.getsignal(signal.SIGHUP)
    try:
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
        assert stop_signals() == (signal.SIGINT, signal.SIGTERM)
        signal.signal(signal.SIGHUP, signal.SIG_DFL)
        assert stop_signals() == (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    finally:
        signal.signal(signal.SIGHUP, before)
