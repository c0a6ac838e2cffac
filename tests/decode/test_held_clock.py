"""A reply that came in the same read as its request is laid out right after it at the line rate: its latency
was never measured, so it has none (never a held clock's 0.000 ms), on both decoding paths and in info."""

from __future__ import annotations

import pytest

from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.protocol.wire import byte_time, encode_return, encode_short
from rs30x_sniff.sinks.pipeline import decode_records, drive
from rs30x_sniff.sinks.stats import CaptureStats

BT = byte_time(115200)
POLL = encode_short(1, 0x09, 0, b"", length=0, count=1)
RET = encode_return(1, 42, bytes(18))


def polls(n: int, together: bool) -> list:
    """``n`` polls and returns, 20 ms apart: each pair in one chunk (``together``), or the return in its own,
    stamped 150 us after the poll's last byte."""
    out = []
    for k in range(n):
        t = 1.0 + 0.02 * k
        if together:
            out.append((POLL + RET, t))
        else:
            out += [(POLL, t), (RET, t + len(POLL) * BT + 150e-6)]
    return out


@pytest.mark.parametrize("columnar", [False, True])
def test_a_reply_read_with_its_request_has_no_latency(columnar):
    stats = CaptureStats(115200)
    drive(polls(200, together=True), Decoder(columnar=columnar), stats)
    lat = stats.as_dict()["latency_s"]
    assert lat["count"] == 0 and lat["p50"] is None and lat["unmeasured"] == 200
    assert "laid out with it at the line rate" in lat["absent"]


@pytest.mark.parametrize("columnar", [False, True])
def test_a_reply_stamped_apart_is_measured(columnar):
    stats = CaptureStats(115200)
    drive(polls(200, together=False), Decoder(columnar=columnar), stats)
    lat = stats.as_dict()["latency_s"]
    assert lat["count"] == 200 and lat["p50"] == pytest.approx(150e-6, abs=2e-6) and "absent" not in lat


def test_the_records_say_so_too():
    recs = list(decode_records(polls(3, together=True)))
    replies = [r for r in recs if r.event.kind == "return"]
    assert replies and all(r.status == "paired" and r.latency is None for r in replies)
