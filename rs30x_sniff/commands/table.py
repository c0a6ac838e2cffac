"""`rs30x-sniff table`: servo states, transactions or lint findings of a capture as CSV or Parquet."""

from __future__ import annotations

import argparse
import sys
from typing import cast

from ..sources.captures import HEX, TIMESTAMPED
from ..sources.protocol import TextCapture
from ..sinks.tables import (
    CSV, KINDS, PARQUET, SINKS, TABLE_FORMATS, MissingPyarrow, open_table, require_pyarrow, table_format)
from ..protocol.memmap import default_registry
from ..decode.decoder import Decoder
from ..sinks.pipeline import columnar_for, drive
from .common import CliError, make_linter, no_data, open_input, settings_for
from .options import add_decode_options, add_format_option, add_lint_options
from ..sinks.outputs import STDOUT, check_output, output_path, report_end


def add_parser(sub: argparse._SubParsersAction) -> None:
    # `export --table KIND` is this command (cli.ALIASES): one implementation of the tables, under one name.
    p = sub.add_parser("table", help="servo states, transactions or findings as CSV or Parquet",
                       description="Write one table of a capture for spreadsheets and dataframes (pandas, polars, "
                                   "DuckDB): states (one row per servo whose registers a packet changes, every "
                                   "register in engineering units), transactions (one row per request that expects "
                                   "a reply) or findings (one row per lint finding). Times t are the capture's, in "
                                   "seconds (a capture without timestamps: each byte's position at the baud rate); "
                                   "wall_time is added when they are epoch times.")
    p.add_argument("input", metavar="INPUT", help="capture file (.bin/.raw, .hex, timestamped hex, .mcap), - for stdin")
    p.add_argument("--of", required=True, choices=KINDS,
                   help="which table (`export --table KIND` is read as `table --of KIND`)")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="table to write (.csv, .parquet); - writes CSV (or --format parquet) to stdout")
    add_format_option(p, TABLE_FORMATS, default=None,
                      help="table format (default: from OUT's extension)")
    p.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    add_decode_options(p)
    add_lint_options(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    fmt = table_format(args.output, args.format)
    if fmt is None:
        raise CliError(f"{args.output}: cannot tell the table format from the extension (use .csv or .parquet, "
                       "or --format)")
    if fmt == PARQUET:
        try:
            require_pyarrow()  # before any work: say so now, not after decoding the whole capture
        except MissingPyarrow as e:
            raise CliError(str(e)) from None
    if args.of == "findings" and args.no_lint:
        raise CliError("--of findings needs the linter (leave out --no-lint)")
    check_output(args.output, args.force, (args.input,))
    settings = settings_for(args, args.input)
    opts = settings.decode_options()
    # The findings table and the packets table's findings column need the rules run; the others read the records
    # alone.
    linter = make_linter(args, settings) if args.of in ("findings", "packets") else None
    chunks = open_input(args.input, args.input_format, settings, locate=args.of == "findings")
    decoder = Decoder(opts, linter, columnar=columnar_for(chunks))  # a file: the columnar path, the same rows
    kw: dict = {"baud": settings.baud}
    if args.of == "states":
        kw.update(registry=opts.registry or default_registry(), models=dict(settings.models))
    elif args.of == "findings" and getattr(chunks, "format", None) in (HEX, TIMESTAMPED):
        # text captures: where each finding's byte is written (a hex capture is a TextCapture by its format)
        kw["locate"] = cast(TextCapture, chunks).locate

    if args.output == STDOUT and fmt == CSV:  # streamed; Parquet to stdout is made whole, then copied
        sink = SINKS[args.of](open_table(STDOUT, CSV, sys.stdout), **kw)
        drive(chunks, decoder, sink)
        no_data(args.input, decoder, chunks)
        return 0
    # Written beside OUT and renamed at the end: an input error leaves nothing behind, while a stop
    # (Ctrl-C, SIGTERM) keeps the finished table of what was read so far.
    stopped = None
    sink = None
    try:
        with output_path(args.output, force=args.force, inputs=(args.input,),
                         keep_on_stop=lambda: sink is not None) as tmp:
            stream = open(tmp, "w", encoding="utf-8", newline="") if fmt == CSV else None
            try:
                sink = SINKS[args.of](open_table(tmp, fmt, stream), **kw)
                drive(chunks, decoder, sink)
            finally:
                if stream is not None:
                    stream.close()
    except KeyboardInterrupt as e:
        stopped = str(e) or "Ctrl-C"
    name = "stdout" if args.output == STDOUT else args.output
    if sink is None:  # stopped before the writer began: nothing read, so nothing to say of the capture
        return report_end(f"{name}: nothing saved", stopped)
    no_data(args.input, decoder, chunks)
    summary = f"{name}: {sink.rows} rows of {args.of}"
    return report_end(summary, stopped)
