"""Benchmark: full decode (framing, pairing, field annotation) against a bare split-and-XOR loop.

Run: python bench/decode.py [--frames N]
Target (issues 2, 12): the full decode reaches at least 0.5 of the bare loop's frames/s. Two paths:
the record path (a Record per frame, every field's value decoded, as a live port is decoded) and the
columnar path files take (framing and pairing into Blocks: rs30x_sniff.decode.blocks; each sink decodes a
Block's values in its own form, measured by bench/jsonl.py, bench/convert.py and bench/lint.py), each fed as
4 KiB blocks without timestamps and as one timestamped chunk per frame. The columnar path runs as the
commands run it: drive() (rs30x_sniff.sinks.pipeline.Pipeline) groups the chunks, about 64 KiB at a time
(GROUP_BYTES), and hands each step to a sink that counts.
"""

from __future__ import annotations

import argparse
import gc
import sys
import time
from functools import reduce
from operator import xor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from traffic import bench_inputs  # noqa: E402

from rs30x_sniff.decode.decoder import Decoder  # noqa: E402
from rs30x_sniff.sinks.pipeline import Sink, drive


class Count(Sink):
    """Counts the records of every step handed out (a Block's rows, without making Records of them)."""

    takes_blocks = True

    def __init__(self) -> None:
        self.n = 0

    def batch(self, step) -> None:
        self.n += step.count


def bare_loop(data: bytes) -> int:
    """Only split frames with bytes.find and check the XOR: the floor any decoder pays."""
    frames = 0
    i, n = 0, len(data)
    find = data.find
    while i < n:
        a = find(b"\xfa\xaf", i)
        b = find(b"\xfd\xdf", i)
        if a < 0 and b < 0:
            break
        j = a if b < 0 or 0 <= a < b else b
        if j + 7 > n:
            break
        size = data[j + 5] * data[j + 6] if data[j] == 0xFA else data[j + 5]
        end = j + 8 + size
        if end > n:
            break
        if reduce(xor, data[j + 2:end - 1], 0) == data[end - 1]:
            frames += 1
            i = end
        else:
            i = j + 1
    return frames


def full_decode(chunks: list[tuple[bytes, float]]) -> tuple[int, int]:
    """Frame, pair and annotate every record (every field's engineering value decoded)."""
    dec = Decoder()
    records = 0
    fields = 0
    for data, t in chunks:
        for rec in dec.feed(data, t):
            records += 1
            fields += len(rec.values)
    for rec in dec.close():
        records += 1
        fields += len(rec.values)
    return records, fields


def columnar_decode(chunks: list[tuple[bytes, float]]) -> int:
    """The columnar path, driven as a command drives a file: frame and pair (a clean run into a Block)."""
    count = Count()
    drive(chunks, Decoder(columnar=True), count)
    return count.n


def best_of(fn, arg, repeat: int) -> tuple[float, object]:
    best, result = float("inf"), None
    for _ in range(repeat):
        gc.collect()
        t0 = time.perf_counter()
        result = fn(arg)
        best = min(best, time.perf_counter() - t0)
    return best, result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    chunks, data, blocks = bench_inputs(args.frames)
    # Untimed 4 KiB blocks (as a file reader delivers them) and timestamped per-frame chunks.
    t_bare, n_bare = best_of(bare_loop, data, args.repeat)
    t_full, (n_full, n_fields) = best_of(full_decode, blocks, args.repeat)
    t_timed, (n_timed, _) = best_of(full_decode, chunks, args.repeat)
    t_col, n_col = best_of(columnar_decode, blocks, args.repeat)
    t_col_timed, n_col_timed = best_of(columnar_decode, chunks, args.repeat)
    assert n_bare == args.frames, (n_bare, args.frames)
    assert n_full == n_timed == n_col == n_col_timed == args.frames, (n_full, n_timed, n_col, n_col_timed)
    bare = n_bare / t_bare
    print(f"capture: {args.frames} frames, {len(data) / 1e6:.1f} MB, {n_fields} fields decoded")
    print(f"bare split+XOR loop:                      {bare:12,.0f} frames/s")
    for label, n, t in (("record path (4 KiB blocks)", n_full, t_full),
                        ("record path (timestamped/frame)", n_timed, t_timed),
                        ("columnar path (4 KiB blocks)", n_col, t_col),
                        ("columnar path (timestamped/frame)", n_col_timed, t_col_timed)):
        print(f"{label + ':':<42}{n / t:12,.0f} frames/s   ratio {n / t / bare:.2f}")
    print("target: ratio >= 0.50 (files take the columnar path; a live port the record path)")


if __name__ == "__main__":
    main()
