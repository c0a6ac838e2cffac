"""`rs30x-sniff decode`: every event of a capture as a text line or a JSON object, with its lint findings."""

from __future__ import annotations

import argparse

from ..filters import FilterError, parse_filter
from ..protocol.memmap import ModelRegistry, default_registry
from ..render.columns import ColumnError, Columns, parse_columns
from ..decode.decoder import Decoder
from ..sinks.pipeline import columnar_for, drive
from ..sinks.lines import FieldsSink, JsonlSink, TextSink
from .common import (CliError, capture_start_time, check_positive, is_live, live_sinks, make_linter, no_data,
                     open_input, settings_for, time_form)
from .options import (SERVO_IDS, add_decode_options, add_format_option, add_lint_selection, add_live_options,
                      add_time_format_option, servo_ids)
from ..sinks.outputs import output_stream
from .outputs import add_output_options


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("decode", help="decode a capture into named, scaled fields",
                       description="Decode every packet of a capture: one line (or JSON object) per event, "
                                   "with the lint findings of each event beside it.")
    p.add_argument("input", metavar="INPUT",
                   help="capture file (.bin/.raw, .hex, timestamped hex, .mcap), - for stdin, or a serial port")
    add_decode_options(p)
    add_live_options(p)
    add_format_option(p, ("text", "jsonl", "fields"), default=None,
                      help="output format (default text; fields: the --fields columns, tab-separated)")
    p.add_argument("--fields", metavar="NAMES",
                   help="columns for --format fields (implied), comma-separated: keys of the JSON lines (t, offset, "
                        "type, id, op, latency_s, status, diagnostics, ...) and registers' names "
                        "(present_position; a long packet's values joined by spaces)")
    p.add_argument("--id", type=servo_ids, action="append", default=None, metavar="IDS",
                   help=f"only events to or from these servos: an ID or a range (3, 1-6,9; {SERVO_IDS}); repeatable")
    p.add_argument("--filter", metavar="EXPR",
                   help="only events matching EXPR, the monitor's filter language (e.g. "
                        "'id:1-6 present_temperature>40', 'latency>1ms', 't:1.5-3.0', 'sev>=warning')")
    p.add_argument("-v", "--verbose", action="store_true", help="add a field tree with each field's raw bytes")
    add_time_format_option(p)
    add_output_options(p)
    add_lint_selection(p)
    p.add_argument("--no-lint", action="store_true", help="do not run the linter")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    check_positive("--duration", args.duration)
    settings = settings_for(args, args.input)
    opts = settings.decode_options()
    try:  # before the input opens: a typo must not cost a serial port's session
        flt = parse_filter(args.filter or "", opts.registry)
    except FilterError as e:
        raise CliError(f"--filter: {e}") from None
    columns = _columns(args, opts.registry or default_registry())
    linter = make_linter(args, settings)
    chunks = open_input(args.input, args.input_format, settings, duration=args.duration)
    ids = {sid for given in args.id for sid in given} if args.id else None
    with output_stream(args.output, force=args.force, inputs=(args.input,)) as out:
        sink: JsonlSink | TextSink | FieldsSink
        if args.format == "jsonl":
            sink = JsonlSink(out, ids=ids, filter=flt, flush=is_live(chunks))
        elif columns is not None:
            sink = FieldsSink(out, columns, ids=ids, filter=flt, flush=is_live(chunks))
        else:
            sink = TextSink(out, ids=ids, filter=flt, flush=is_live(chunks), verbose=args.verbose,
                            times=time_form(settings, lambda: capture_start_time(chunks)))
        # A file takes the columnar path (the same lines); a port or a pipe, record by record as they come.
        dec = drive(chunks, Decoder(opts, linter, columnar=columnar_for(chunks, follow=True)), sink,
                    *live_sinks(settings, chunks, args.input))
    no_data(args.input, dec, chunks)
    return 1 if getattr(chunks, "lost", False) else 0  # a live port that failed (the source said why)


def _columns(args: argparse.Namespace, registry: ModelRegistry) -> Columns | None:
    """--format fields and --fields (each implies the other's need): the columns, checked before the input opens."""
    if args.format is None:
        args.format = "fields" if args.fields is not None else "text"
    if args.format != "fields":
        if args.fields is not None:
            raise CliError(f"--fields: only with --format fields, not {args.format}")
        return None
    if args.fields is None:
        raise CliError("--format fields: name the columns with --fields (e.g. --fields t,id,type,present_position)")
    if args.verbose:
        raise CliError("--verbose: a field tree is text's, not --format fields'")
    try:
        return parse_columns(args.fields, registry)
    except ColumnError as e:
        raise CliError(f"--fields: {e}") from None
