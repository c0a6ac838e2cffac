"""`rs30x-sniff decode`: every event of a capture as a text line or a JSON object."""

from __future__ import annotations

import argparse
import json

from ..pipeline import Decoder
from ..render import record_json, text_line, verbose_lines
from .common import add_decode_options, decode_options, open_input, output_stream


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("decode", help="decode a capture into named, scaled fields",
                       description="Decode every packet of a capture: one line (or JSON object) per event.")
    p.add_argument("input", metavar="INPUT", help="capture file (.bin/.raw, .hex, timestamped hex, .mcap) or - for stdin")
    add_decode_options(p)
    p.add_argument("--format", choices=("text", "jsonl"), default="text", help="output format (default text)")
    p.add_argument("--id", type=int, action="append", default=None, metavar="N",
                   help="only events to or from servo N (repeatable)")
    p.add_argument("-v", "--verbose", action="store_true", help="add a field tree with each field's raw bytes")
    p.add_argument("-o", "--output", metavar="OUT", help="write to OUT instead of stdout")
    p.set_defaults(run=run)


def involves(rec, ids: set[int]) -> bool:
    """Whether a record is to or from one of ``ids`` (a long packet: any of its VIDs)."""
    ev = rec.event
    if ev.kind == "long":
        return any(r.vid in ids for r in ev.records)
    return rec.id in ids


def run(args: argparse.Namespace) -> int:
    opts = decode_options(args)
    chunks = open_input(args.input, args.input_format)
    dec = Decoder(opts)
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
        for data, t in chunks:
            emit(dec.feed(data, t))
        emit(dec.close())
    return 0
