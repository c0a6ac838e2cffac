"""Long packets to servos of mixed models: the column form of the health figures (HealthRecorder's
long_written_rows) equals the record form (long_written per record), on any shape such packets take."""

from __future__ import annotations

import random

import pytest

from rs30x_sniff.decode import blocks as blocks_module
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.protocol.wire import byte_time, encode_long, encode_read, encode_return
from rs30x_sniff.sim import scenarios
from rs30x_sniff.sinks.pipeline import drive
from rs30x_sniff.sinks.stats import CaptureStats

BT = byte_time(115200)
MIXED = DecodeOptions(models={2: "RS304MD", 4: "RS304MD"})  # the rest are the default RS303MR


def _both(chunks, options=None):
    got = []
    for columnar in (False, True):
        stats = CaptureStats(115200)
        drive(chunks, Decoder(options, columnar=columnar), stats)
        got.append(stats.as_dict())
    return got


def _long_packets(seed: int, n: int) -> list[tuple[bytes, float]]:
    """Polls and long packets of many shapes: VIDs the same or shuffled row after row, records starting before,
    at or after goal_position, a last record cut short, records of a VID alone."""
    rng = random.Random(seed)
    out, t = [], 0.0
    shapes = [(30, 4, [1, 2, 3, 4]), (29, 5, [2, 1]), (31, 3, [4, 3, 2]), (30, 3, [1, 2]), (30, 1, [1, 2, 3]),
              (28, 6, [5, 4, 1]), (30, 2, [3, 4])]
    for _ in range(n):
        r = rng.random()
        if r < 0.2:
            sid = rng.randint(1, 5)
            frames = [encode_read(sid, 42, 18), encode_return(sid, 42, bytes(rng.randrange(256) for _ in range(18)))]
        else:
            address, length, vids = rng.choice(shapes)
            if rng.random() < 0.3:
                vids = rng.sample(vids, len(vids))
            records = [(v, bytes(rng.randrange(256) for _ in range(length - 1))) for v in vids]
            frame = bytearray(encode_long(address, records))
            frames = [bytes(frame)]
        for f in frames:
            out.append((f, t))
            t += len(f) * BT + 0.0002
    return out


@pytest.mark.parametrize("min_block", [1, 3, 64])
@pytest.mark.parametrize("seed", range(4))
def test_mixed_long_packets_give_the_same_health_both_ways(monkeypatch, min_block, seed):
    monkeypatch.setattr(blocks_module, "MIN_BLOCK", min_block)
    record, column = _both(_long_packets(seed, 400), MIXED)
    assert record == column
    written = {sid for sid, h in record["health"].items() if "goal_position" in h["registers"]}
    assert len(written) >= 4  # servos of both models had goal positions taken


def test_the_two_model_hexapod_gives_the_same_health_both_ways():
    record, column = _both(list(scenarios.run("hexapod", duration=2.0)))
    assert record == column
    models = {h.get("model") for h in record["health"].values() if "goal_position" in h["registers"]}
    assert len(models) == 2, models
