"""The monitor on the columnar path: CaptureStats and the Store fed Blocks answer as fed Records."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from rs30x_sniff.blocks import Block
from rs30x_sniff.lint import Linter
from rs30x_sniff.pipeline import DecodeOptions, Decoder, Sink, drive
from rs30x_sniff.sim import scenarios
from rs30x_sniff.stats import CaptureStats

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from bench.traffic import hexapod_frames  # noqa: E402

SCENARIOS = list(scenarios.SCENARIOS)


class Keep(Sink):
    """Every step as the decoder gave it (Blocks and Records), with its findings."""

    takes_blocks = True

    def __init__(self) -> None:
        self.steps = []

    def batch(self, step) -> None:
        self.steps.append(step)


def capture(name: str) -> list:
    if name == "bench":
        return hexapod_frames(6000)
    if name == "bench-untimed":
        return [(d, None) for d, _ in hexapod_frames(3000)]
    return list(scenarios.run(name, duration=2.0))


def decoded(chunks, columnar: bool, lint: bool = True) -> tuple[list, Decoder]:
    keep = Keep()
    dec = drive(chunks, Decoder(DecodeOptions(), Linter() if lint else None, columnar=columnar), keep)
    return keep.steps, dec


CAPTURES = SCENARIOS + ["bench", "bench-untimed"]
NO_BLOCKS = {"setup", "silent-servo", "duplicate-id"}  # too irregular in 2 s for a clean stretch


@pytest.mark.parametrize("name", CAPTURES)
def test_capture_stats_count_a_block_as_its_records(name):
    chunks = capture(name)
    by_record, by_block = CaptureStats(115200), CaptureStats(115200)
    drive(chunks, Decoder(DecodeOptions(), Linter()), by_record)
    steps, _ = decoded(chunks, True)
    drive(chunks, Decoder(DecodeOptions(), Linter(), columnar=True), by_block)
    assert any(type(x) is Block for s in steps for x in s) == (name not in NO_BLOCKS)  # the columnar path was taken
    a, b = by_record.as_dict(), by_block.as_dict()
    assert a == b
    assert by_record.latency.bins == by_block.latency.bins
    assert {i: (h.model, h.lo, h.hi, h.samples, h.flags) for i, h in by_record.health.servos.items()} == \
        {i: (h.model, h.lo, h.hi, h.samples, h.flags) for i, h in by_block.health.servos.items()}


def test_capture_stats_of_a_block_fed_in_pieces():
    """The load windows and the health buffers' flushes fall inside Blocks as they do between records."""
    chunks = hexapod_frames(40_000)
    by_record = CaptureStats(115200)
    for rec in (r for s in decoded(chunks, False, lint=False)[0] for r in s):
        by_record.add(rec)
    by_block = CaptureStats(115200)
    for s in decoded(chunks, True, lint=False)[0]:
        by_block.batch(s)
    assert by_record.as_dict() == by_block.as_dict()


def test_capture_stats_of_servos_of_mixed_models():
    """A long packet to servos of two models: its health goes record by record, as on the record path."""
    chunks = hexapod_frames(6000)
    opts = DecodeOptions(models={4: "RS304MD", 7: "RS304MD"})
    by_record, by_block = CaptureStats(115200), CaptureStats(115200)
    drive(chunks, Decoder(opts, Linter()), by_record)
    keep = Keep()
    drive(chunks, Decoder(opts, Linter(), columnar=True), by_block, keep)
    assert any(type(x) is Block and x.vid_models is not None for s in keep.steps for x in s)
    assert by_record.as_dict() == by_block.as_dict()
