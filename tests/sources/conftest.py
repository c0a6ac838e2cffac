"""Shared helpers for the input-side tests: captures in every format, and small MCAP files."""

from __future__ import annotations

from pathlib import Path

import pytest

from rs30x_sniff.sinks.mcap.writer import McapSink

ROOT = Path(__file__).resolve().parents[2]
CAPTURES = ROOT / "captures"

FRAME = bytes.fromhex("FAAF01001E020184039B")


def frames(n: int) -> list[tuple[bytes, float]]:
    """``n`` short packets (different IDs and lengths), 10 ms apart."""
    out = []
    for i in range(n):
        body = bytes([1 + i % 5, 0, 0x1E, 2, 1]) + bytes([i & 0xFF, i >> 8])
        s = 0
        for b in body:
            s ^= b
        out.append((b"\xfa\xaf" + body + bytes([s]), i * 0.01))
    return out


def make_mcap(path: Path, chunks: list[tuple[bytes, float | None]], chunk_seconds: float = 0.1) -> Path:
    with McapSink(str(path), source="test", baud=115200, time_base="capture", chunk_seconds=chunk_seconds) as sink:
        for data, t in chunks:
            sink.raw(data, t)
    return path


@pytest.fixture
def small_mcap(tmp_path):
    """About 5 chunks of raw messages, a few KiB."""
    chunks = frames(50)
    return make_mcap(tmp_path / "small.mcap", chunks), chunks
