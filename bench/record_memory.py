"""The recorder's memory over an hour of traffic in minutes: `record`'s pipeline fed in-process, as fast as it goes.

bench/live.py measures an hour of `record` live on a pty, which takes the hour and shares the machine's scheduler
with the simulator. This feeds the same hour (the hexapod at 230400 baud: 72 MB, one MCAP chunk a second) through
the pieces `record` wires together (Decoder with the linter, columnar, a gather a second; Parts and McapSink, the
raw recording) with no port and no reader process, and prints the process's resident memory at each tenth of the
capture's time, with glibc's heap: its size, the memory in use and the memory free in it (free: holes the heap
keeps). What grows here grows with the capture, not with the machine's load.
Target (issue 31): flat, as bench/live.py says it: the second half's peak at most 2 % over the first half's.

With --split-time, `record --split-time`'s parts (Parts closes each, and the MCAP writer's index with it).

Run: .venv/bin/python bench/record_memory.py [--duration 3600] [--scenario hexapod] [--baud 230400] [--split-time S]
"""

from __future__ import annotations

import argparse
import ctypes
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rs30x_sniff import allocator  # noqa: E402
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder  # noqa: E402
from rs30x_sniff.lint import LintConfig, Linter  # noqa: E402
from rs30x_sniff.protocol.wire import byte_time  # noqa: E402
from rs30x_sniff.sim import run  # noqa: E402
from rs30x_sniff.sinks.mcap.writer import McapSink  # noqa: E402
from rs30x_sniff.sinks.parts import Parts  # noqa: E402
from rs30x_sniff.sinks.pipeline import Pipeline  # noqa: E402

EPOCH = 1.79e9  # a live recording's times are wall-clock seconds


class MallInfo2(ctypes.Structure):
    """glibc's struct mallinfo2 (<malloc.h>): the main heap's figures."""

    _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                     "fsmblks", "uordblks", "fordblks", "keepcost")]


def heap_reader():
    """A function giving (heap, in use, free) in MB from glibc's mallinfo2, or None off glibc."""
    libc = allocator.glibc()
    if libc is None or not hasattr(libc, "mallinfo2"):
        return None
    libc.mallinfo2.restype = MallInfo2

    def read() -> tuple[float, float, float]:
        m = libc.mallinfo2()
        return m.arena / 1e6, m.uordblks / 1e6, m.fordblks / 1e6
    return read


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=3600.0, help="seconds of capture (default: an hour)")
    ap.add_argument("--scenario", default="hexapod")
    ap.add_argument("--baud", type=int, default=230400)
    ap.add_argument("--split-time", type=float, default=None, metavar="S",
                    help="a new part every S seconds of capture, as record --split-time (default: one file)")
    args = ap.parse_args()
    allocator.keep_large_buffers()  # as cli.main does for every command
    heap = heap_reader()
    bt = byte_time(args.baud)
    clock = {"now": 0.0}  # the capture's time: Parts flushes the open chunk a second at a time by it
    rows: list[tuple[float, float, tuple | None]] = []

    def chunks():
        """Frames stamped at their last byte, as a port's reader stamps them; an empty chunk after each second."""
        second, mark = 1.0, args.duration / 10
        for data, t in run(args.scenario, baud=args.baud, duration=args.duration):
            end = t + len(data) * bt
            while end >= second:
                clock["now"] = second
                yield b"", None
                second += 1.0
            while end >= mark and mark < args.duration - 1e-9:
                rows.append((mark, rss_mb(), heap() if heap else None))
                mark += args.duration / 10
            yield data, EPOCH + end
        yield b"", None
        rows.append((args.duration, rss_mb(), heap() if heap else None))

    opts = DecodeOptions(baud=args.baud)
    with tempfile.TemporaryDirectory(prefix="record-memory-") as tmp:
        out = str(Path(tmp) / "bus.mcap")

        def make_sink(path, part):
            return McapSink(path, source="bench", baud=args.baud, time_base="wall", decoded=False)

        files = Parts(out, make_sink, split_seconds=args.split_time, say=lambda *a: None, clock=lambda: clock["now"])
        cpu0 = time.process_time()
        Pipeline(Decoder(opts, Linter(LintConfig(), keep_findings=False), columnar=True), [files],
                 group_bytes=max(256, args.baud // 10)).run(chunks())
        cpu = time.process_time() - cpu0
        size = sum(Path(p).stat().st_size for p in files.paths)
    parts = f" in {len(files.paths)} parts" if len(files.paths) > 1 else f", {files.sink.chunks:,} chunks"
    print(f"{args.scenario} at {args.baud} baud, {args.duration:g} s of capture through record's pipeline in "
          f"{cpu:.0f} s of CPU: {size / 1e6:.1f} MB of MCAP{parts}")
    print(f"  {'capture time':>12s}  {'RSS MB':>7s}  {'heap MB':>7s}  {'in use':>7s}  {'free':>6s}")
    for mark, rss, h in rows:
        figures = f"{h[0]:7.2f}  {h[1]:7.2f}  {h[2]:6.2f}" if h else f"{'-':>7s}  {'-':>7s}  {'-':>6s}"
        print(f"  {mark:11.0f}s  {rss:7.1f}  {figures}")
    rss = [r for _, r, _ in rows]
    half = len(rss) // 2
    first, last = max(rss[:half]), max(rss[half:])
    verdict = "flat" if last <= first * 1.02 else "GROWING"
    print(f"  RSS {verdict}: peak {first:.1f} MB in the first half, {last:.1f} MB in the second "
          f"({(last / first - 1) * 100:+.1f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
