"""Benchmark: `decode --format jsonl` as a whole process against a bare split + XOR + json.dumps loop.

Run: python bench/jsonl.py [--frames N] [--repeat R]
Target (issue 12): the decode command reaches at least 0.3 of the bare loop's frames per second.
Beside it, `decode --fields` of five columns (issue 35's compact form for scripts), its time and its size
against the JSON lines'.
The bare loop reads the same file, splits frames with bytes.find, checks each Sum, and writes one
json.dumps line per frame (offset, hex and the header fields): the floor any JSON-lines decoder pays.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from traffic import hexapod_bytes  # noqa: E402

FIELDS = "t,id,kind,goal_position,present_position"
BARE = r'''
import json, sys
from functools import reduce
from operator import xor
data = open(sys.argv[1], "rb").read()
out = open(sys.argv[2], "w")
i, n, find, frames = 0, len(data), data.find, 0
while i < n:
    a = find(b"\xfa\xaf", i); b = find(b"\xfd\xdf", i)
    if a < 0 and b < 0:
        break
    j = a if b < 0 or 0 <= a < b else b
    size = data[j + 5] * data[j + 6] if data[j] == 0xFA else data[j + 5]
    end = j + 8 + size
    if end > n:
        break
    raw = data[j:end]
    if reduce(xor, raw[2:-1], 0) == raw[-1]:
        out.write(json.dumps({"offset": j, "raw": raw.hex(), "id": raw[2], "flag": raw[3], "address": raw[4],
                              "length": raw[5], "count": raw[6], "checksum_ok": True}) + "\n")
        frames += 1
        i = end
    else:
        i = j + 1
'''


def best(cmd: list[str], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        cap = os.path.join(tmp, "bus.bin")
        Path(cap).write_bytes(hexapod_bytes(args.frames))
        out = os.path.join(tmp, "out.jsonl")
        bare = best([sys.executable, "-c", BARE, cap, out], args.repeat)
        full = best([sys.executable, "-m", "rs30x_sniff", "decode", cap, "--format", "jsonl", "-o", out, "--force"],
                    args.repeat)
        lines, size = sum(1 for _ in open(out)), os.path.getsize(out)
        tsv = os.path.join(tmp, "out.tsv")
        cols = best([sys.executable, "-m", "rs30x_sniff", "decode", cap, "--fields", FIELDS, "-o", tsv, "--force"],
                    args.repeat)
        tsv_size = os.path.getsize(tsv)
    print(f"capture: {args.frames} frames ({lines} JSON lines written by decode, {size / 1e6:.0f} MB)")
    print(f"bare split+XOR+json.dumps:  {args.frames / bare:10,.0f} frames/s  ({bare:.2f} s)")
    print(f"decode --format jsonl:      {args.frames / full:10,.0f} frames/s  ({full:.2f} s)   ratio {bare / full:.2f}")
    print("target: ratio >= 0.30")
    print(f"decode --fields {FIELDS}: {args.frames / cols:,.0f} frames/s ({cols:.2f} s), "
          f"{tsv_size / 1e6:.1f} MB: {cols / full:.2f} of the JSON lines' time, {tsv_size / size:.3f} of their size")


if __name__ == "__main__":
    main()
