"""`rs30x-sniff decode`: every event of a capture as a text line or a JSON object, with its lint findings."""

from __future__ import annotations

import argparse
import json

from ..lint.linter import Linter
from ..pipeline import Decoder
from ..render import record_json, text_line, verbose_lines
from .common import add_decode_options, add_live_options, decode_options, is_live, open_input, output_stream
from .lint import add_lint_selection, build_config, settings_from


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("decode", help="decode a capture into named, scaled fields",
                       description="Decode every packet of a capture: one line (or JSON object) per event, "
                                   "with the lint findings of each event beside it.")
    p.add_argument("input", metavar="INPUT",
                   help="capture file (.bin/.raw, .hex, timestamped hex, .mcap), - for stdin, or a serial port")
    add_decode_options(p)
    add_live_options(p)
    p.add_argument("--format", choices=("text", "jsonl"), default="text", help="output format (default text)")
    p.add_argument("--id", type=int, action="append", default=None, metavar="N",
                   help="only events to or from servo N (repeatable)")
    p.add_argument("-v", "--verbose", action="store_true", help="add a field tree with each field's raw bytes")
    p.add_argument("-o", "--output", metavar="OUT", help="write to OUT instead of stdout")
    add_lint_selection(p)
    p.add_argument("--no-lint", action="store_true", help="do not run the linter")
    p.set_defaults(run=run)


def involves(rec, ids: set[int]) -> bool:
    """Whether a record is to or from one of ``ids`` (a long packet: any of its VIDs)."""
    ev = rec.event
    if ev.kind == "long":
        return any(r.vid in ids for r in ev.records)
    return rec.id in ids


def run(args: argparse.Namespace) -> int:
    settings = settings_from(args)
    opts = decode_options(args, settings)
    linter = None if args.no_lint else Linter(build_config(args, settings, opts))
    chunks = open_input(args.input, args.input_format, baud=opts.baud, duration=args.duration)
    live = is_live(chunks)
    dec = Decoder(opts, linter)
    ids = set(args.id) if args.id else None
    with output_stream(args.output) as out:
        def emit(records):
            for rec in records:
                if ids is not None and not involves(rec, ids):
                    continue
                if args.format == "jsonl":
                    out.write(json.dumps(record_json(rec)) + "\n")
                else:
                    out.write(text_line(rec) + "\n")
                    if args.verbose:
                        out.write("\n".join(verbose_lines(rec)) + "\n")
            if live:
                out.flush()  # a person or a pipe is watching the bus: show each batch as it comes
        for data, t in chunks:
            emit(dec.feed(data, t))
        emit(dec.close())
        # Findings only the end of input reveals (e.g. a baud change never flashed): they belong to
        # records already printed, so they come last, each naming its record's offset.
        for f in dec.late_findings:
            if ids is not None and f.id not in ids:
                continue
            if args.format == "jsonl":
                out.write(json.dumps({"type": "diagnostic", **f.as_json()}) + "\n")
            else:
                ts = f"{f.t:12.6f}" if f.t is not None else f"{'-':>12}"
                out.write(f"{ts} @{f.offset:<8} lint  {f.code} {f.name}: {f.message}\n")
    return 1 if getattr(chunks, "lost", False) else 0  # a live port that failed (the source said why)
