"""`rs30x-sniff info`: what a capture holds: duration, traffic by type, per-servo polls, latencies, bus load."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ..pipeline import Decoder, drive
from ..stats import CaptureStats
from .common import (add_decode_options, add_lint_options, add_live_options, check_positive, live_sinks, make_linter, no_data,
                     open_input, settings_for)
from .outputs import add_output_options, check_output, output_stream


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("info", help="summarize a capture: duration, packets, polls, latencies, bus load",
                       description="Summarize a capture of any format: duration, bytes, packets by type, per-servo "
                                   "request and return counts, poll rates, reply latency, bus load, findings.")
    p.add_argument("input", metavar="INPUT", help="capture file (.bin/.raw, .hex, timestamped hex, .mcap) or - for stdin")
    add_decode_options(p)
    add_live_options(p)
    add_lint_options(p)
    p.add_argument("--format", choices=("text", "json"), default="text", help="output format (default text)")
    add_output_options(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    check_positive("--duration", args.duration)
    if args.output:
        check_output(args.output, args.force, (args.input,))  # before the work, not after
    settings = settings_for(args, args.input)
    opts = settings.decode_options()
    linter = make_linter(args, settings)
    source = open_input(args.input, args.input_format, settings, duration=args.duration)
    stats = CaptureStats(opts.baud)
    drive(source, Decoder(opts, linter), stats, *live_sinks(settings, source, args.input))
    no_data(args.input, stats, source)
    shown = settings.as_json()
    time_ref = getattr(source, "time_ref", None) if stats.timed else None  # what the times mark, and why
    if time_ref is not None:
        shown["time_ref"] = time_ref.ref
        shown["origin"]["time_ref"] = time_ref.reason
    with output_stream(args.output, force=args.force, inputs=(args.input,)) as out:
        if args.format == "json":
            out.write(json.dumps({"input": args.input, "linted": linter is not None, "settings": shown,
                                  **stats.as_dict()}, indent=2) + "\n")
        else:
            _print_text(out, args.input, stats, linter is not None, time_ref)
    return 0


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v * 1e3:.3f} ms"


def _print_text(out: Any, name: str, s: CaptureStats, linted: bool, time_ref: Any = None) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    con = Console(file=out, highlight=False, width=100 if not out.isatty() else None)
    d = s.as_dict()
    load = "-" if s.bus_load is None else f"{s.bus_load * 100:.1f} %"
    timing = "" if s.timed else " (no timestamps: line time at the baud rate)"
    con.print(f"[bold]{escape(name)}[/bold]")
    con.print(f"  duration   {s.duration:.6f} s{timing}")
    if time_ref is not None and s.timed:
        con.print(f"  times      {escape(time_ref.reason)}")
    con.print(f"  bytes      {s.bytes} at {s.baud} bit/s, bus load {load}")
    kinds = ", ".join(f"{k} {v}" for k, v in d["by_type"].items()) or "none"
    con.print(f"  records    {s.records}: {kinds}")
    if d["by_op"]:
        con.print("  requests   " + ", ".join(f"{k} {v}" for k, v in d["by_op"].items()))
    con.print(f"  faults     {s.bad_checksums} bad checksums, {s.garbage_bytes} garbage bytes")
    lat = s.latency
    con.print(f"  latency    p50 {_ms(lat.percentile(50))}, p95 {_ms(lat.percentile(95))}, max {_ms(lat.max)} "
              f"over {lat.count} replies")
    if linted:
        f = d["findings"]
        con.print(f"  findings   {f['error']} errors, {f['warning']} warnings, {f['info']} info")
        for rule, n in list(d["findings_by_rule"].items())[:10]:
            con.print(f"             {n:>6} {rule}")
    if s.servos:
        table = Table(title=None, box=None, pad_edge=False, padding=(0, 2, 0, 0))
        for col in ("id", "requests", "reads", "long writes", "returns", "acks", "nacks", "missing", "poll rate"):
            table.add_column(col, justify="right")
        for sid, v in d["servos"].items():
            rate = "-" if v["poll_rate_hz"] is None else f"{v['poll_rate_hz']:.1f} Hz"
            table.add_row(sid, *(str(v[k]) for k in ("requests", "reads", "long_writes", "returns", "acks", "nacks",
                                                      "missing")), rate)
        con.print()
        con.print(table)
