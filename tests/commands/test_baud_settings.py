"""The baud rate a capture shows: from its timestamps, --baud auto, and a --baud its timestamps contradict."""

from __future__ import annotations

import json
import subprocess
import sys
import threading

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.sources.captures import write_capture
from rs30x_sniff.sim import run
from rs30x_sniff.protocol.wire import byte_time


def _info(capsys, *argv: str) -> tuple[dict, str]:
    assert main(["info", *argv, "--format", "json", "--isolated"]) == 0
    cap = capsys.readouterr()
    return json.loads(cap.out), cap.err


@pytest.mark.parametrize("baud", [9600, 57600, 230400])
def test_a_timed_capture_tells_its_rate(capsys, tmp_path, baud):
    path = tmp_path / "bus.thex"
    write_capture(path, run("hexapod", baud=baud, duration=1.0), "timestamped")
    info, err = _info(capsys, str(path))
    assert info["baud"] == baud and info["settings"]["origin"]["baud"].startswith("capture (its timestamps")
    if baud != 115200:
        assert f"{baud} bit/s, from its timestamps" in err  # and says so
    # The servos answer 100 us after a request: right only at the right rate.
    assert abs(info["latency_s"]["p50"] - 100e-6) < byte_time(baud)


def test_a_baud_the_timestamps_contradict_is_flagged(capsys, tmp_path):
    path = tmp_path / "bus.thex"
    write_capture(path, run("hexapod", baud=57600, duration=1.0), "timestamped")
    info, err = _info(capsys, str(path), "--baud", "115200")
    assert info["baud"] == 115200  # the command line wins ...
    assert "its timestamps show 57600 bit/s, not the 115200 given" in err  # ... but not silently


def test_an_arrival_stamped_capture_tells_its_rate_too(capsys, tmp_path):
    bt = byte_time(9600)
    path = tmp_path / "logger.thex"
    write_capture(path, [(d, t + len(d) * bt) for d, t in run("setup", baud=9600, duration=2.0)], "timestamped")
    info, _ = _info(capsys, str(path))
    assert info["baud"] == 9600 and info["settings"]["time_ref"] == "arrival"
    assert abs(info["latency_s"]["p50"] - 100e-6) < bt


def test_baud_auto_on_files(capsys, tmp_path):
    thex, raw = tmp_path / "bus.thex", tmp_path / "bus.bin"
    chunks = list(run("hexapod", baud=57600, duration=1.0))
    write_capture(thex, chunks, "timestamped")
    write_capture(raw, chunks, "bin")
    assert _info(capsys, str(thex), "--baud", "auto")[0]["baud"] == 57600
    info, _ = _info(capsys, str(raw), "--baud", "auto")
    assert info["baud"] == 115200 and "nothing to tell by" in info["settings"]["origin"]["baud"]
    assert main(["info", str(raw), "--baud", "fast"]) == 2  # argparse's own usage error, one line
    err = capsys.readouterr().err
    assert err.startswith("rs30x-sniff: error: ") and "not a baud rate (a number, or auto)" in err


def test_baud_auto_on_a_port_scans_and_says_what_it_chose(tmp_path):
    """A pty ignores the rate, so every rate reads the same bytes: the scan takes its first choice with
    valid frames, says so, and decodes at it (the rate logic itself is tested on a simulated wire)."""
    from tests.e2e.helpers import Pty

    pty = Pty()
    stop = threading.Event()

    def feed():
        while not stop.is_set():
            pty.write_sim("hexapod", duration=0.5)

    writer = threading.Thread(target=feed, daemon=True)
    try:
        writer.start()
        proc = subprocess.run([sys.executable, "-m", "rs30x_sniff", "decode", pty.path, "--baud", "auto", "--duration",
                               "1.5", "--no-lint", "--isolated"], capture_output=True, text=True, timeout=60)
    finally:
        stop.set()
        writer.join(10)
        pty.close()
    assert proc.returncode == 0, proc.stderr
    assert "--baud auto: 115200 bit/s" in proc.stderr.splitlines()[0]
    assert "LONG" in proc.stdout
