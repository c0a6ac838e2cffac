"""`rs30x-sniff info`: what a capture holds: traffic, polls, latencies, bus load, per-servo health, what happened."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ..decode.decoder import Decoder
from ..sinks.pipeline import columnar_for, drive
from ..sinks.stats import CaptureStats
from ..protocol.wire import byte_time
from ..sinks.summary import seconds_text, timer, what_happened
from .common import (capture_start_time, check_positive, live_sinks, make_linter, no_data, open_input, settings_for,
                     time_form)
from .options import add_decode_options, add_format_option, add_lint_options, add_live_options, add_time_format_option
from ..sinks.outputs import check_output, output_stream
from .outputs import add_output_options


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("info", help="summarize a capture: duration, packets, polls, latencies, bus load",
                       description="Summarize a capture of any format: duration, bytes, packets by type, per-servo "
                                   "request and return counts, poll rates, reply latency, bus load, findings.")
    p.add_argument("input", metavar="INPUT",
                   help="capture file (.bin/.raw, .hex, timestamped hex, .mcap) or - for stdin")
    add_decode_options(p)
    add_live_options(p)
    add_lint_options(p)
    add_format_option(p, ("text", "json"), default="text",
                      help="output format (default text)")
    add_time_format_option(p)
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
    stats.timing_unsupported = getattr(settings, "timing_unsupported", None)  # the times contradict the baud
    stats.stalls = getattr(source, "stalls", stats.stalls)  # a live reader that fell behind (its own list)
    # A file takes the columnar path (the same figures); a port, record by record.
    drive(source, Decoder(opts, linter, columnar=columnar_for(source)), stats,
          *live_sinks(settings, source, args.input))
    no_data(args.input, stats, source)
    stats.wall_anchor = capture_start_time(source)  # wall-clock times beside capture times, where the log has them
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
            form = time_form(settings, stats.wall_anchor)
            if stats.timed and stats.first_t is not None:
                form.start(stats.first_t)
            _print_text(out, args.input, stats, linter is not None, time_ref, form)
    return 0


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v * 1e3:.3f} ms"


def _print_text(out: Any, name: str, s: CaptureStats, linted: bool, time_ref: Any = None, form: Any = None) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    con = Console(file=out, highlight=False, width=100 if not out.isatty() else None)
    d = s.as_dict()
    if form is not None and form.started:
        # The lines' times as --time-format shows them (the JSON keeps the capture's own).
        d["what_happened"] = what_happened(s, d["health"], timer(s.first_t, s.timed, byte_time(s.baud), s.wall_anchor),
                                           form)
    load = "-" if s.bus_load is None else f"{s.bus_load * 100:.1f} %"
    if s.timed and s.timing_unsupported:
        load += f" ({escape(s.timing_unsupported)})"
    timing = "" if s.timed else " (no timestamps: line time at the baud rate)"
    if s.timed and d["segments"] > 1:
        timing = f" in {d['segments']} time segments (F010: the clock restarts or resumes; gaps not counted)"
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
    lat = d["latency_s"]
    if s.timing_unsupported and s.timed:
        con.print(f"  latency    - ({escape(s.timing_unsupported)})")
    else:
        why = f"; {lat['absent']}" if lat.get("absent") else ""
        con.print(f"  latency    p50 {_ms(lat['p50'])}, p95 {_ms(lat['p95'])}, max {_ms(lat['max'])} "
                  f"over {lat['count']} replies{escape(why)}")
    if linted:
        f = d["findings"]
        con.print(f"  findings   {f['error']} errors, {f['warning']} warnings, {f['info']} info")
        for rule, n in list(d["findings_by_rule"].items())[:10]:
            con.print(f"             {n:>6} {rule}")
    if s.servos:
        table = Table(title=None, box=None, pad_edge=False, padding=(0, 2, 0, 0))
        for col in ("id", "requests", "reads", "long writes", "returns", "acks", "nacks", "missing", "poll rate",
                    "latency p95"):
            table.add_column(col, justify="right")
        for sid, v in d["servos"].items():
            rate = "-" if v["poll_rate_hz"] is None else f"{v['poll_rate_hz']:.1f} Hz"
            p95 = (v.get("latency_s") or {}).get("p95")  # absent: no reply of it had a latency (or none is whole)
            table.add_row(sid, *(str(v[k]) for k in ("requests", "reads", "long_writes", "returns", "acks", "nacks",
                                                      "missing")), rate, "-" if p95 is None else _ms(p95))
        con.print()
        con.print(table)
    _print_health(con, d, linted, form)


# Health table columns: (register, heading); the unit comes from the register map via the JSON.
_HEALTH_COLUMNS = (("present_position", "position"), ("present_speed", "speed"), ("present_current", "current"),
                   ("present_temperature", "temp"), ("present_voltage", "voltage"), ("goal_position", "goal"))


def _range(r: dict[str, Any] | None) -> str:
    if r is None:
        return "-"
    lo, hi = f"{r['min']:g}", f"{r['max']:g}"
    return lo if lo == hi else f"{lo}..{hi}"


def _print_health(con: Any, d: dict[str, Any], linted: bool, form: Any = None) -> None:
    """The per-servo health table, the flags and findings per servo, and the "what happened" lines."""
    from rich.table import Table

    health = d["health"]
    if health:
        units: dict[str, str] = {}
        for h in health.values():
            for name, r in h["registers"].items():
                units.setdefault(name, r["unit"] or "")
        shown = [(name, head) for name, head in _HEALTH_COLUMNS if name in units]
        table = Table(title=None, box=None, pad_edge=False, padding=(0, 2, 0, 0))
        table.add_column("id", justify="right")
        table.add_column("model")
        for name, head in shown:
            table.add_column(f"{head} {units[name]}".rstrip(), justify="right")
        for sid, h in health.items():
            table.add_row(sid, h["model"] or "-", *(_range(h["registers"].get(name)) for name, _ in shown))
        con.print()
        con.print("[bold]health[/bold] (min..max from the returns; goal from the writes)")
        con.print(table)
        for sid, h in health.items():
            parts = [f"{name} {v['count']}x" + ("" if v["first_t"] is None else
                                                 f", first at {seconds_text(v['first_t'], form)}")
                     for name, v in h["flags"].items()]
            if h["findings"]:
                parts.append("findings " + ", ".join(f"{code} {n}" for code, n in h["findings"].items()))
            if parts:
                _wrapped(con, f"  ID {sid:<4} ", "; ".join(parts))
    con.print()
    con.print("[bold]what happened[/bold]" + ("" if linted else " (not linted: from the figures alone)"))
    colour = {"error": "red", "warning": "yellow"}
    for item in d["what_happened"]:
        sev = item["severity"]
        _wrapped(con, f"  {sev:<9}", item["text"], colour.get(sev))


def _wrapped(con: Any, head: str, text: str, style: str | None = None) -> None:
    """``head`` then ``text`` wrapped under itself (a rich grid would pad every line to the width)."""
    import textwrap

    from rich.markup import escape

    lines = textwrap.wrap(text, width=max(40, con.width - len(head)), break_on_hyphens=False) or [""]
    first = f"[{style}]{escape(head)}[/{style}]" if style else escape(head)
    con.print(first + escape(lines[0]))
    for line in lines[1:]:
        con.print(" " * len(head) + escape(line))
