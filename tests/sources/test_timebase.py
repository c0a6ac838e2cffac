"""Time references (first byte or arrival), a clock kept monotonic, F005/F006, and wall-clock live times."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.decode.framing import TIME_BACKWARDS, TIME_TOO_CLOSE, FrameDecoder
from rs30x_sniff.sources.captures import write_capture
from rs30x_sniff.sim import run
from rs30x_sniff.sources.timebase import ARRIVAL, FIRST, judge, to_first_byte
from rs30x_sniff.protocol.wire import byte_time, encode_read, encode_return

BT = byte_time(115200)
RETURN_DELAY = 100e-6  # the simulator's servos: return_delay 0 = 100 us (table 4.6 No. 7)


def _arrival(chunks, baud=115200):
    """What a logger that stamps each read when it returns writes: the end of the chunk's last byte."""
    bt = byte_time(baud)
    return [(d, t + len(d) * bt) for d, t in chunks]


def _info(capsys, path: Path, *opts: str) -> dict:
    assert main(["info", str(path), "--format", "json", "--isolated", *opts]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def setup_chunks():
    return list(run("setup", duration=2.0, seed=3))


def test_judge_tells_arrival_from_first_byte(setup_chunks):
    assert judge(setup_chunks, 115200).ref == FIRST
    verdict = judge(_arrival(setup_chunks), 115200)
    assert verdict.ref == ARRIVAL and "arrival" in verdict.reason
    back = list(to_first_byte(_arrival(setup_chunks), 115200))
    assert [d for d, _ in back] == [d for d, _ in setup_chunks]
    assert all(abs(t - t0) < 1e-9 for (_, t), (_, t0) in zip(back, setup_chunks))


def test_an_arrival_stamped_capture_gives_true_latencies(capsys, tmp_path, setup_chunks):
    """The issue's case: read as first-byte times, every reply began before its request ended."""
    path = tmp_path / "logger.thex"
    write_capture(path, _arrival(setup_chunks), "timestamped")
    info = _info(capsys, path)
    assert info["settings"]["time_ref"] == ARRIVAL and "told by the content" in info["settings"]["origin"]["time_ref"]
    lat = info["latency_s"]
    assert lat["count"] > 10
    # The simulator's return delay, to within one byte time.
    assert abs(lat["p50"] - RETURN_DELAY) <= BT and abs(lat["p95"] - RETURN_DELAY) <= BT
    # Forced the wrong way, nothing goes negative and the linter says why.
    forced = _info(capsys, path, "--time-ref", "first")
    assert forced["latency_s"]["p50"] >= 0 and forced["bus_load"] <= 1.0
    assert "F006 time-too-close" in forced["findings_by_rule"]


def test_the_frame_decoder_keeps_its_clock_monotonic():
    req, ret = encode_read(1, 0x2A, 2), encode_return(1, 0x2A, b"\x84\x03")
    dec = FrameDecoder(115200)
    # 5 ms back: a clock fault (F005), held; 10 ms or more back would be a restarted clock (a seam).
    events = dec.feed(req, 0.2) + dec.feed(ret, 0.195) + dec.feed(req, 0.2000001) + dec.close()
    starts = [e.t_start for e in events]
    assert starts == sorted(starts)
    assert events[1].t_start == pytest.approx(0.2)  # held at the request's time, not before it
    assert dec.time_faults[TIME_BACKWARDS].count == 1 and dec.time_faults[TIME_BACKWARDS].offset == len(req)
    assert dec.time_faults[TIME_TOO_CLOSE].count == 1


def test_backwards_timestamps_are_a_finding_not_a_negative_figure(capsys, tmp_path):
    """`0.2`, `0.195`, `0.1951`: once a duration of 0.000868 s and a bus load of 100 %."""
    req, ret = encode_read(1, 0x2A, 2), encode_return(1, 0x2A, b"\x84\x03")
    path = tmp_path / "back.thex"
    write_capture(path, [(req, 0.2), (ret, 0.195), (req, 0.1951)], "timestamped")
    info = _info(capsys, path, "--time-ref", "first")
    assert "F005 time-went-backwards" in info["findings_by_rule"]
    # The reply was held at its request's time: it has no latency, not a held clock's 0.000 ms.
    assert info["latency_s"]["p50"] is None and info["latency_s"]["count"] == 0
    assert info["bus_load"] is None or info["bus_load"] <= 1.0
    assert main(["lint", str(path), "--isolated", "--time-ref", "first", "--select", "F005", "--fail-on",
                 "warning"]) == 1
    out = capsys.readouterr().out
    assert "clock goes backwards once" in out and f"{path}:2:" in out  # the first place, by line


def test_time_ref_from_a_config_file_and_its_check(capsys, tmp_path, monkeypatch, setup_chunks):
    path = tmp_path / "logger.thex"
    write_capture(path, _arrival(setup_chunks), "timestamped")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "rs30x-sniff.toml").write_text('time-ref = "first"\n')
    assert main(["info", str(path), "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["settings"]["time_ref"] == FIRST
    (tmp_path / "rs30x-sniff.toml").write_text('time-ref = "late"\n')
    assert main(["info", str(path)]) == 2
    assert "time-ref = 'late': must be one of first, arrival" in capsys.readouterr().err


def test_a_pipe_is_not_read_ahead(capsys, setup_chunks, tmp_path):
    import subprocess
    import sys

    path = tmp_path / "logger.thex"
    write_capture(path, _arrival(setup_chunks), "timestamped")
    proc = subprocess.run([sys.executable, "-m", "rs30x_sniff", "info", "-", "--format", "json", "--isolated",
                           "--time-ref", "arrival"], stdin=open(path, "rb"), capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    info = json.loads(proc.stdout)
    assert info["settings"]["time_ref"] == ARRIVAL
    assert abs(info["latency_s"]["p50"] - RETURN_DELAY) <= BT


def test_start_time_anchors_a_log_to_the_wall_clock(capsys, tmp_path):
    from datetime import datetime, timezone

    from mcap.reader import make_reader

    src = Path(__file__).resolve().parents[2] / "captures" / "manual-examples.hex"  # no timestamps
    out = tmp_path / "anchored.mcap"
    assert main(["convert", str(src), "-o", str(out), "--start-time", "2026-11-22T15:30:00Z"]) == 0
    with open(out, "rb") as f:
        times = [m.log_time for _, _, m in make_reader(f).iter_messages(topics=["/rs30x/raw"])]
    start = datetime(2026, 11, 22, 15, 30, tzinfo=timezone.utc).timestamp()
    assert times[0] == round(start * 1e9) and times == sorted(times)
    assert main(["convert", str(src), "-o", str(tmp_path / "x.mcap"), "--start-time", "yesterday"]) == 2
    assert "--start-time yesterday: not an ISO 8601 time" in capsys.readouterr().err


def test_the_live_tap_stamps_wall_clock_time():
    import time

    from rs30x_sniff.sources.serial_tap import SerialTap

    tap = SerialTap("loop://", 115200)
    tap.open()
    try:
        tap._stamp(b"\x00" * 10, tap.clock())
        _, t = tap.queue.get(timeout=2)
    finally:
        tap.stop()
    assert abs(t - time.time()) < 5  # seconds since the epoch, not since the port opened


def test_a_wrong_baud_does_not_run_the_clock_ahead():
    """A 115200 bus decoded at 9600: every chunk comes too close; the clock must stay with the stamps
    (a 6 s recording once came out as 31.8 s of log)."""
    chunks = list(run("hexapod", duration=2.0))
    dec = FrameDecoder(9600)
    events = [e for d, t in chunks for e in dec.feed(d, t)] + dec.close()
    last_stamp = chunks[-1][1]
    assert max(e.t_start for e in events) <= last_stamp + 1e-9
    assert dec.time_faults[TIME_TOO_CLOSE].count > 100
