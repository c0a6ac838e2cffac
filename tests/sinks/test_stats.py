"""CaptureStats: the figures `info` prints, from records (pure, no files)."""

from __future__ import annotations

import pytest

from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.sinks.pipeline import decode_records
from rs30x_sniff.sinks.stats import CaptureStats, LatencyHistogram
from rs30x_sniff.protocol.wire import byte_time, encode_return, encode_short


def test_latency_percentiles_use_nearest_rank():
    h = LatencyHistogram()
    for us in range(1, 101):  # 1..100 us
        h.add(us * 1e-6)
    assert h.percentile(50) == pytest.approx(50e-6)
    assert h.percentile(95) == pytest.approx(95e-6)
    assert h.percentile(100) == pytest.approx(100e-6) == h.max
    assert LatencyHistogram().percentile(50) is None


def stats_of(chunks, baud=115200):
    s = CaptureStats(baud)
    for rec in decode_records(chunks, DecodeOptions(baud=baud)):
        s.add(rec)
    return s


def test_untimed_capture_is_measured_in_line_time():
    frames = [encode_short(1, 0, 0x1E, b"\x00\x00"), b"\x00\x00\x00", encode_short(2, 0x09, 0, b"", length=0, count=1)]
    s = stats_of([(b"".join(frames), None)], baud=9600)
    assert not s.timed and s.bus_load is None
    assert s.bytes == sum(map(len, frames))
    assert s.duration == pytest.approx(s.bytes * byte_time(9600))
    assert s.garbage_bytes == 3 and s.by_kind["garbage"] == 1 and s.packets == 2
    # The capture ends right after ID 2's poll: its reply may have come after, so it is not counted missing.
    assert s.servos[2].missing == 0 and s.servos[1].requests == 1 and s.servos[1].reads == 0


def test_timed_capture_load_latency_and_poll_rate():
    bt = byte_time(115200)
    chunks = []
    for k in range(11):  # servo 4 polled every 0.1 s and answering 200 us after each request
        t = k * 0.1
        req = encode_short(4, 0x09, 0, b"", length=0, count=1)
        chunks.append((req, t))
        chunks.append((encode_return(4, 42, bytes(18)), t + len(req) * bt + 0.0002))
    s = stats_of(chunks)
    d = s.as_dict()
    assert s.timed and d["servos"]["4"]["poll_rate_hz"] == pytest.approx(10.0)
    assert d["servos"]["4"]["returns"] == 11 and d["latency_s"]["count"] == 11
    # The latency runs from the end of the request's last byte to the reply's first.
    assert d["latency_s"]["p50"] == pytest.approx(0.0002, abs=1e-6) and d["latency_s"]["max"] == pytest.approx(0.0002)
    assert s.duration == pytest.approx(1.0 + 8 * bt + 0.0002 + 26 * bt, rel=1e-3)
    assert s.bus_load == pytest.approx(s.bytes * bt / s.duration)
