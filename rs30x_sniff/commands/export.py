"""`rs30x-sniff export`: the raw channel of an MCAP log back out as a bin, hex or timestamped hex capture."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator

from ..sources.captures import BINARY, HEX, MCAP, TIMESTAMPED, Chunk, detect_format, format_for_output, write_capture
from ..sinks.tables import KINDS, table_format
from .options import add_format_option
from .common import CliError
from ..sinks.outputs import STDOUT, check_output, output_path, write_stream


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("export", help="write the raw bytes of an MCAP log back out as a capture",
                       description="Write the /rs30x/raw channel of an MCAP file as a capture: byte for byte "
                                   "what was on the bus, with the original timestamps for --format timestamped. "
                                   "A table of a capture is `table --of KIND` (`export --table KIND` says the same).")
    p.add_argument("input", metavar="INPUT", help="MCAP file written by rs30x-sniff")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="capture to write (.bin/.raw binary, .hex hex text, .thex/.log timestamped); - for stdout")
    # The bytes as they were: nothing is decoded, so no model, baud rate or rule selection applies.
    add_format_option(p, (BINARY, HEX, TIMESTAMPED), default=None,
                      help="output format (default: from OUT's extension, else hex)")
    p.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.format is None and args.output != "-" and table_format(args.output, None) is not None:
        raise CliError(f"{args.output}: a table is written by `table --of KIND` ({', '.join(KINDS)})")
    from ..sources.mcap_reader import McapRawReader

    if detect_format(args.input) != MCAP:
        raise CliError(f"{args.input}: not an MCAP file (export reads MCAP logs; convert makes them)")
    fmt = args.format or format_for_output(args.output, None)
    if fmt == MCAP:
        raise CliError(f"{args.output}: export writes bin, hex or timestamped captures, not MCAP (use convert)")
    check_output(args.output, args.force, (args.input,))
    reader = McapRawReader(args.input)

    def chunks() -> Iterator[Chunk]:
        # A capture that had no timestamps keeps none, except in timestamped output, which gets
        # the synthetic (byte position) times the log was written with.
        for data, t, log_time, _ in reader:  # bin and hex text cannot say who sent a byte or flag one
            yield data, (t if t is not None or fmt != TIMESTAMPED else log_time / 1e9)

    if args.output == STDOUT:
        write_stream(sys.stdout.buffer, chunks(), fmt)
        return 0
    with output_path(args.output, force=args.force, inputs=(args.input,)) as tmp:
        write_capture(tmp, chunks(), fmt)  # a write error: output_path names OUT and says what is left
    return 0
