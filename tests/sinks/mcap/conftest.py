"""Fixtures for the MCAP tests: captures to convert, and helpers to convert and read them back."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from rs30x_sniff.sources.captures import read_capture
from rs30x_sniff.sinks.mcap.writer import McapSink
from rs30x_sniff.sinks.pipeline import drive
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder

ROOT = Path(__file__).resolve().parents[3]
CAPTURES = sorted((ROOT / "captures").glob("*.hex"))
sys.path.insert(0, str(ROOT / "bench"))

from traffic import hexapod_frames  # noqa: E402


def to_mcap(chunks, path, *, baud=115200, linter=None, time_base=None, **sink_kw):
    """Convert chunks (a list) into an MCAP at ``path``; returns the sink."""
    chunks = list(chunks)
    if time_base is None:
        time_base = "capture" if chunks and chunks[0][1] is not None else "synthetic"
    dec = Decoder(DecodeOptions(baud=baud, models=dict(sink_kw.get("models") or {})), linter=linter)
    with McapSink(str(path), source="test", baud=baud, time_base=time_base, **sink_kw) as sink:
        drive(iter(chunks), dec, sink)
    return sink


@pytest.fixture
def hexapod_thex(tmp_path):
    """A small timestamped hex capture of the hexapod traffic (about 2 s of bus time)."""
    path = tmp_path / "hexapod.thex"
    with open(path, "w") as f:
        for data, t in hexapod_frames(700):
            f.write(f"{t:.6f} {data.hex(' ')}\n")
    return path


@pytest.fixture(params=[p.name for p in CAPTURES])
def sample_capture(request):
    return ROOT / "captures" / request.param


def chunks_of(path):
    return list(read_capture(str(path)))
