"""Benchmark: `export --table states --format parquet` (and csv) of a 300,000-frame capture, whole process.

Run: python bench/tables.py [--frames N]
Prints seconds, frames/s and rows/s per format, and the file sizes; the capture is generated (hexapod
traffic, timestamped hex) in a temporary folder.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from traffic import hexapod_frames  # noqa: E402

from rs30x_sniff.sources.captures import write_capture  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=300_000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / "bus.thex"
        write_capture(src, hexapod_frames(args.frames), "timestamped")
        print(f"capture: {args.frames:,} frames, {src.stat().st_size / 1e6:.1f} MB timestamped hex")
        for fmt in ("parquet", "csv"):
            out = Path(d) / f"states.{fmt}"
            t0 = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "rs30x_sniff", "export", str(src), "--table", "states",
                                   "--format", fmt, "-o", str(out), "--isolated", "--baud", "115200"],
                                  capture_output=True, text=True)
            dt = time.perf_counter() - t0
            if proc.returncode:
                sys.exit(proc.stderr)
            rows = proc.stderr.strip().split(": ")[-1]
            print(f"{fmt:8} {dt:6.2f} s  {args.frames / dt:9,.0f} frames/s  {rows}  {out.stat().st_size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
