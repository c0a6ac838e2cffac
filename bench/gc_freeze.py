"""Benchmark: the monitor's gc.freeze (every FREEZE_ROWS rows, as it was) over an hour of live traffic, and without.

The simulator's hexapod at 230400 baud (the bus about 83 % busy), made once for --make seconds and laid end to end
(times shifted) up to --hours of capture, is replayed into the monitor as a port feeds it (a ReplaySource: paced,
decoded record by record, the live path's batches), as fast as the monitor takes it, headless at 160x48. Each
variant runs in a process of its own: `none` as shipped (the monitor freezes nothing since this bench), `freeze` with
the policy it measured and removed (after each FREEZE_ROWS rows the store takes, gc.collect() then gc.freeze()). Per
variant: the process's CPU time, the cyclic collector's pauses (gc.callbacks: count, total and longest per
generation, the freezes' own gc.collect included), objects left frozen, peak RSS and the rows seen.

Run: .venv/bin/python bench/gc_freeze.py [--hours 1] [--make 300] [--variants freeze,none]
Keep gc.freeze only if it measurably helps (CPU or pauses) over the hour. Two runs on a shared 2-core machine (the
variants' order swapped): freeze/none CPU 0.92 and 1.11 (the variant run second was the slower both times),
collector time 1.51 and 1.34, pauses over 500 ms 31 against 9 (second run). It did not help, and went.
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import json
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.sim.source import SimulatorSource
from rs30x_sniff.sources.captures import write_capture
from rs30x_sniff.sources.feeds import ReplaySource
from rs30x_sniff.tui.app import make_app

BAUD = 230400
FREEZE_ROWS = 100_000  # the removed policy: rows between two gc.freeze


def make_hour(path: str, hours: float, make: float) -> int:
    """--make seconds of the simulated hexapod, repeated end to end (times shifted) to ``hours`` of capture."""
    piece = list(SimulatorSource("hexapod", BAUD, speed=1e9, duration=make).chunks(threading.Event()))
    span = piece[-1][1] + 0.001 - piece[0][1]
    copies = max(1, round(hours * 3600 / span))
    t0 = piece[0][1]
    write_capture(path, ((d, (t - t0) + k * span) for k in range(copies) for d, t in piece), "timestamped")
    return copies


class Pauses:
    """The cyclic collector's pauses, per generation (gc.callbacks)."""

    def __init__(self) -> None:
        self.start = 0.0
        self.count = [0, 0, 0]
        self.total = [0.0, 0.0, 0.0]
        self.longest = [0.0, 0.0, 0.0]
        self.all: list[float] = []  # every pause, for the ones long enough to be seen on the screen

    def __call__(self, phase: str, info: dict) -> None:
        if phase == "start":
            self.start = time.perf_counter()
            return
        took = time.perf_counter() - self.start
        g = info["generation"]
        self.count[g] += 1
        self.total[g] += took
        self.longest[g] = max(self.longest[g], took)
        self.all.append(took)


def freeze_every(store, rows: int) -> None:
    """The policy the monitor had: after each ``rows`` rows the store took, a full collection, then gc.freeze."""
    add = store.add
    unfrozen = [0]

    def adding(*args, **kw):
        end = store.end_seq
        add(*args, **kw)
        unfrozen[0] += store.end_seq - end
        if unfrozen[0] >= rows:
            gc.collect()
            gc.freeze()
            unfrozen[0] = 0

    store.add = adding


async def watch(path: str, limit: float, freeze: bool) -> dict:
    app = make_app(ReplaySource(path, speed=1e9), DecodeOptions())
    if freeze:
        freeze_every(app.store, FREEZE_ROWS)
    pauses = Pauses()
    cpu0 = time.process_time()
    t0 = time.perf_counter()
    async with app.run_test(size=(160, 48)):
        gc.callbacks.append(pauses)
        try:
            while not app.done and time.perf_counter() - t0 < limit:
                await asyncio.sleep(0.05)
        finally:
            gc.callbacks.remove(pauses)
        wall = time.perf_counter() - t0
        cpu = time.process_time() - cpu0
        rows = app.store.end_seq
    return {"wall": wall, "cpu": cpu, "rows": rows, "done": app.done, "gc_count": pauses.count,
            "gc_total": pauses.total, "gc_longest": pauses.longest, "frozen": gc.get_freeze_count(),
            "over_100ms": sum(1 for p in pauses.all if p > 0.1), "over_500ms": sum(1 for p in pauses.all if p > 0.5),
            "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def run_variant(path: str, variant: str, limit: float) -> dict:
    out = subprocess.run([sys.executable, __file__, "--child", variant, "--path", path, "--limit", str(limit)],
                         stdout=subprocess.PIPE, text=True, check=True)
    return json.loads(out.stdout.splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0, help="hours of capture fed to the monitor")
    ap.add_argument("--make", type=float, default=300.0, help="seconds of simulated traffic made, then repeated")
    ap.add_argument("--variants", default="freeze,none")
    ap.add_argument("--limit", type=float, default=3000.0, help="give up a variant after this many seconds")
    ap.add_argument("--child", choices=("freeze", "none"), help=argparse.SUPPRESS)
    ap.add_argument("--path", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(asyncio.run(watch(args.path, args.limit, args.child == "freeze"))))
        return
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "hour.thex")
        copies = make_hour(path, args.hours, args.make)
        print(f"capture: {args.make:g} s of the hexapod at {BAUD} baud x {copies} = {args.hours:g} h, "
              f"{Path(path).stat().st_size / 1e6:.0f} MB timestamped hex")
        results = {v: run_variant(path, v, args.limit) for v in args.variants.split(",")}
    for v, r in results.items():
        gens = ", ".join(f"gen{g} {r['gc_count'][g]} x, {r['gc_total'][g]:.2f} s, "
                         f"longest {r['gc_longest'][g] * 1e3:.0f} ms" for g in range(3))
        print(f"{v:7s} cpu {r['cpu']:7.1f} s  wall {r['wall']:7.1f} s  rows {r['rows']:,}"
              f"{'' if r['done'] else ' (not done)'}  frozen {r['frozen']:,}  peak RSS {r['rss_mb']:.0f} MB")
        print(f"        gc: {gens}; all {sum(r['gc_total']):.2f} s; pauses over 100 ms {r['over_100ms']}, "
              f"over 500 ms {r['over_500ms']}")
    if {"freeze", "none"} <= results.keys():
        f, n = results["freeze"], results["none"]
        gc_ratio = sum(f["gc_total"]) / max(sum(n["gc_total"]), 1e-9)
        print(f"freeze / none: cpu {f['cpu'] / n['cpu']:.3f}, gc time {gc_ratio:.3f}, "
              f"longest pause {max(f['gc_longest']) / max(max(n['gc_longest']), 1e-9):.3f}")


if __name__ == "__main__":
    main()
