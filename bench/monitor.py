"""Benchmark: how long the monitor takes to open a large capture, against decoding and linting it.

Run: python bench/monitor.py [--frames N] [--repeat N] [--no-records]
Target (issue 12): a 1,000,000-frame capture is fully loaded in at most 1.2 times the time
`rs30x-sniff lint` takes to decode and lint it (the columnar path), and the store stays under 400 MB.
The monitor runs headless (Textual's test driver) at 160x48; "open" ends when every record is in
the store and on the timeline. The record path's decode + lint is shown beside it, for reference.
A capture this big is read by a second process (rs30x_sniff.sources.read_ahead) while the monitor decodes
it; `lint` reads it itself. Both processes' peak memory is shown.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from decode import Count  # noqa: E402
from traffic import hexapod_frames  # noqa: E402

from rs30x_sniff.sources.captures import read_capture, write_capture  # noqa: E402
from rs30x_sniff.lint import Linter  # noqa: E402
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder  # noqa: E402
from rs30x_sniff.sinks.pipeline import drive
from rs30x_sniff.tui.app import make_app  # noqa: E402
from rs30x_sniff.sources.feeds import FileSource  # noqa: E402


def decode_and_lint(path: str) -> int:
    """What `rs30x-sniff lint` does with a file: its chunks through a columnar decoder and the linter."""
    count = Count()
    drive(read_capture(path), Decoder(None, Linter(), columnar=True), count)
    return count.n


def decode_and_lint_records(path: str) -> int:
    """The record path: a Record per frame, each through the linter."""
    dec = Decoder(None, Linter())
    n = 0
    for data, t in read_capture(path):
        n += len(dec.feed(data, t))
    return n + len(dec.close())


async def open_in_monitor(path: str, limit: float, pilot_polls: bool = False) -> tuple[float, int, int]:
    app = make_app(FileSource(path), DecodeOptions())
    t0 = time.perf_counter()
    async with app.run_test(size=(160, 48)) as pilot:
        while not app.done and time.perf_counter() - t0 < limit:
            # The screen runs as it would in a terminal; pilot.pause() would also make every widget
            # answer a message and force a screen update each time it is called (--pilot-polls).
            await (pilot.pause(0.05) if pilot_polls else asyncio.sleep(0.05))
        await pilot.pause()  # the last batch drawn
        elapsed = time.perf_counter() - t0
        return elapsed, app.store.stats.records, app.store.memory_estimate()


def rss_mb(who: int = resource.RUSAGE_SELF) -> float:
    return resource.getrusage(who).ru_maxrss / 1024


def open_alone(path: str, limit: float, pilot_polls: bool) -> dict:
    """The monitor in a process of its own, so its peak RSS is its own (not the capture's making); its
    stderr goes through, so a failure shows the child's traceback."""
    out = subprocess.run([sys.executable, __file__, "--open", path, "--limit", str(limit)]
                         + (["--pilot-polls"] if pilot_polls else []), stdout=subprocess.PIPE, text=True, check=True)
    return json.loads(out.stdout.splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=1_000_000)
    ap.add_argument("--limit", type=float, default=600.0, help="give up after this many seconds")
    ap.add_argument("--no-records", action="store_true", help="skip the record path's reference")
    ap.add_argument("--pilot-polls", action="store_true",
                    help="poll for the end with Textual's pilot.pause(0.05), as before (adds its own screen work)")
    ap.add_argument("--repeat", type=int, default=1, help="best of N runs of each (the reference and the monitor in turn)")
    ap.add_argument("--open", metavar="PATH", help=argparse.SUPPRESS)  # the child: open PATH, print JSON
    args = ap.parse_args()
    if args.open:
        t_open, records, memory = asyncio.run(open_in_monitor(args.open, args.limit, args.pilot_polls))
        # RUSAGE_CHILDREN: the process that read the file (rs30x_sniff.sources.read_ahead), reaped by now.
        print(json.dumps({"t_open": t_open, "records": records, "memory": memory, "rss": rss_mb(),
                          "reader_rss": rss_mb(resource.RUSAGE_CHILDREN)}))
        return
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "big.thex")
        write_capture(path, hexapod_frames(args.frames), "timestamped")
        size = Path(path).stat().st_size
        # The reference and the monitor in turn, each the best of --repeat runs: on a shared machine
        # the best run is the one least disturbed.
        decodes, records, opens = [], [], []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            n = decode_and_lint(path)
            decodes.append(time.perf_counter() - t0)
            if not args.no_records:
                t0 = time.perf_counter()
                decode_and_lint_records(path)
                records.append(time.perf_counter() - t0)
            opens.append(open_alone(path, args.limit, args.pilot_polls))
    t_decode = min(decodes)
    t_records = min(records) if records else None
    got = min(opens, key=lambda o: o["t_open"])
    t_open = got["t_open"]

    def runs(ts: list[float]) -> str:
        return "" if len(ts) < 2 else "  (runs: " + ", ".join(f"{t:.1f}" for t in ts) + ")"

    print(f"capture: {args.frames} frames, {size / 1e6:.1f} MB timestamped hex")
    print(f"decode + lint (columnar, as `lint`): {t_decode:7.1f} s  ({n} records){runs(decodes)}")
    if t_records is not None:
        print(f"decode + lint (record path):         {t_records:7.1f} s{runs(records)}")
    print(f"monitor open (all):                  {t_open:7.1f} s  ({got['records']} records)   "
          f"ratio {t_open / t_decode:.2f}" + (f" ({t_open / t_records:.2f} of the record path)" if t_records else "")
          + runs([o["t_open"] for o in opens]))
    print(f"store memory estimate: {got['memory'] / 1e6:.0f} MB; peak RSS of the monitor's process "
          f"{max(o['rss'] for o in opens):.0f} MB, of its reading process {max(o['reader_rss'] for o in opens):.0f} MB")
    print("target: ratio <= 1.2, store < 400 MB")


if __name__ == "__main__":
    main()
