"""`rs30x-sniff decode`: every event of a capture as a text line or a JSON object, with its lint findings."""

from __future__ import annotations

import argparse

from ..pipeline import Decoder, drive
from ..sinks import JsonlSink, TextSink
from .common import (add_decode_options, add_lint_selection, add_live_options, is_live, make_linter, open_input,
                     output_stream, settings_for)


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


def run(args: argparse.Namespace) -> int:
    settings = settings_for(args, args.input)
    opts = settings.decode_options()
    linter = make_linter(args, settings)
    chunks = open_input(args.input, args.input_format, baud=opts.baud, duration=args.duration)
    ids = set(args.id) if args.id else None
    with output_stream(args.output) as out:
        if args.format == "jsonl":
            sink = JsonlSink(out, ids=ids, flush=is_live(chunks))
        else:
            sink = TextSink(out, ids=ids, flush=is_live(chunks), verbose=args.verbose)
        drive(chunks, Decoder(opts, linter), sink)
    return 1 if getattr(chunks, "lost", False) else 0  # a live port that failed (the source said why)
