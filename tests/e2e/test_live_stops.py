"""A stop is a clean stop, after anything (issue 31): SIGINT, SIGTERM and SIGHUP end every live command with exit 0
and its end line, `record` in each mode after the port was lost and found again, once or twice."""

from __future__ import annotations

import json
import os
import signal
import shutil
import time

import pytest

from .helpers import Pty, cli, recorded_bytes, wait_opened

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")

WORDS = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM", signal.SIGHUP: "SIGHUP"}


def _finish(proc, sig, timeout: float = 30.0) -> tuple[int, str, str]:
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out.decode(), err.decode()


def _replug(link, old: Pty, proc) -> Pty:
    """The adapter unplugged (its node first, then the line) and plugged in again under the same link."""
    link.unlink()
    old.close()
    time.sleep(0.6)
    new = Pty()
    link.symlink_to(new.path)
    wait_opened(new.path, proc)  # found within the wait step, opened, and its input flushed before the first read
    return new


@pytest.mark.parametrize("mode,losses,sig", [
    ("one file", 1, signal.SIGINT),
    ("split", 2, signal.SIGTERM),
    ("trigger", 1, signal.SIGHUP),
    ("one file", 2, signal.SIGHUP),
])
def test_record_stops_cleanly_after_reconnects(tmp_path, mode, losses, sig):
    link = tmp_path / "ttyRIG"
    pty = Pty()
    link.symlink_to(pty.path)
    args = {"one file": ["-o", str(tmp_path / "rig.mcap")],
            "split": ["-o", str(tmp_path / "rig.mcap"), "--split-time", "1s"],
            "trigger": ["-o", str(tmp_path / "win") + "/", "--trigger", "kind:return", "--pre", "5s", "--post", "1s"]}
    proc = cli("record", str(link), *args[mode])
    ptys = [pty]
    try:
        wait_opened(pty.path, proc)
        sent = pty.write_sim("hexapod", duration=0.5)
        for k in range(losses):
            time.sleep(0.3)
            pty = _replug(link, pty, proc)
            ptys.append(pty)
            sent += pty.write_sim("hexapod", duration=0.5, seed=k + 1)
        time.sleep(0.5)
        rc, _, err = _finish(proc, sig)
    finally:
        for p in ptys:
            p.close()
        if proc.poll() is None:
            proc.kill()
    last = err.strip().splitlines()[-1]
    assert rc == 0, err
    assert last.startswith(f"rs30x-sniff: {WORDS[sig]}: ") and f"lost {losses} time" in last, last
    if mode == "trigger":
        assert list((tmp_path / "win").glob("*.mcap")), err
        return
    files = sorted(tmp_path.glob("rig*.mcap"))
    assert b"".join(recorded_bytes(f) for f in files) == sent  # every byte, in order, across the losses


@pytest.mark.parametrize("command", ["decode", "lint", "info"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_reading_commands_on_a_port_stop_cleanly(command, sig):
    pty = Pty()
    proc = cli(command, pty.path)
    try:
        wait_opened(pty.path, proc)
        pty.write_sim("hexapod", duration=0.5)
        time.sleep(0.5)
        rc, out, err = _finish(proc, sig)
    finally:
        pty.close()
        if proc.poll() is None:
            proc.kill()
    assert rc == 0, err
    assert out.strip(), "no report"
    assert any(WORDS[sig] in line and "bytes" in line for line in err.splitlines()), err


def test_serve_on_a_port_stops_cleanly():
    pty = Pty()
    proc = cli("serve", pty.path, "--foxglove", "127.0.0.1:0")
    try:
        wait_opened(pty.path, proc)
        pty.write_sim("hexapod", duration=0.5)
        time.sleep(0.5)
        rc, _, err = _finish(proc, signal.SIGTERM)
    finally:
        pty.close()
        if proc.poll() is None:
            proc.kill()
    assert rc == 0, err
    assert "bytes" in err.strip().splitlines()[-1], err


@pytest.mark.skipif(shutil.which("tmux") is None, reason="needs tmux (a terminal for the monitor)")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_monitor_on_a_port_stops_cleanly(tmp_path, sig):
    """The monitor on a port, in a real terminal (tmux), ended by a signal: exit 0 and the terminal back."""
    import subprocess
    import sys

    pty = Pty()
    session = f"rs30x-stop-{os.getpid()}-{int(sig)}"
    rc_file = tmp_path / "rc"
    cmd = f"{sys.executable} -m rs30x_sniff monitor {pty.path}; echo $? > {rc_file}"
    subprocess.run(["tmux", "new-session", "-d", "-s", session, "-x", "120", "-y", "40", cmd], check=True)
    try:
        time.sleep(3.0)
        pty.write_sim("hexapod", duration=0.5)
        time.sleep(0.5)
        # The monitor's own process, not the shell that waits for it to write its exit code.
        pids = [pid for pid in subprocess.run(["pgrep", "-f", f"rs30x_sniff monitor {pty.path}"], capture_output=True,
                                              text=True).stdout.split()
                if open(f"/proc/{pid}/cmdline", "rb").read().split(b"\0")[0] == sys.executable.encode()]
        # A reader process of its own (its port's) is the monitor's child: the signal goes to the monitor.
        pids = [pid for pid in pids if open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[1] not in pids]
        assert len(pids) == 1, "the monitor is not running"
        for pid in pids:
            os.kill(int(pid), sig)
        end = time.monotonic() + 20
        while not rc_file.exists() and time.monotonic() < end:
            time.sleep(0.1)
        assert rc_file.read_text().strip() == "0"
    finally:
        subprocess.run(["tmux", "kill-session", "-t", session], capture_output=True)
        pty.close()


@pytest.mark.skipif(shutil.which("tmux") is None, reason="needs tmux (a terminal for the monitor)")
def test_monitor_whose_terminal_is_gone_finishes_its_recording_and_ends(tmp_path):
    """An ssh session closed or a tmux killed under a monitor on a port: the terminal hangs up (SIGHUP, and no
    screen to restore); the monitor finishes its recording and ends instead of waiting for ever on the screen."""
    import subprocess
    import sys

    from .helpers import assert_finalized_mcap

    pty = Pty()
    session = f"rs30x-hup-{os.getpid()}"
    folder = tmp_path / "rec"
    folder.mkdir()
    cmd = f"{sys.executable} -m rs30x_sniff monitor {pty.path} --record-dir {folder}"
    subprocess.run(["tmux", "new-session", "-d", "-s", session, "-x", "120", "-y", "40", cmd], check=True)
    try:
        time.sleep(3.0)
        subprocess.run(["tmux", "send-keys", "-t", session, "r"], check=True)  # record what comes
        time.sleep(0.5)
        pty.write_sim("hexapod", duration=0.5)
        time.sleep(0.5)
        mine = f"rs30x_sniff monitor {pty.path}"
        assert subprocess.run(["pgrep", "-f", mine], capture_output=True).returncode == 0, "not running"
        subprocess.run(["tmux", "kill-session", "-t", session], check=True)
        end = time.monotonic() + 20
        while subprocess.run(["pgrep", "-f", mine], capture_output=True).returncode == 0:
            assert time.monotonic() < end, "the monitor goes on without its terminal"
            time.sleep(0.1)
    finally:
        subprocess.run(["tmux", "kill-session", "-t", session], capture_output=True)
        subprocess.run(["pkill", "-9", "-f", f"rs30x_sniff monitor {pty.path}"], capture_output=True)
        pty.close()
    (recording,) = folder.glob("*.mcap")
    assert_finalized_mcap(recording)
