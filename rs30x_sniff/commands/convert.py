"""`rs30x-sniff convert`: a capture of any format into a Foxglove-ready MCAP file, streamed."""

from __future__ import annotations

import argparse
import itertools
import os
import sys
from typing import Any, Iterator

from ..io.captures import MCAP, Chunk, detect_format
from ..pipeline import DecodeOptions, Decoder
from .common import CliError, add_decode_options, decode_options, open_input
from .lint import add_lint_selection, build_config, settings_from


# A file is converted in chunks of up to 1 MiB (still cut at 1 s of log time): the summary lists every
# chunk, so fewer chunks keep the writer's memory flat on long captures, and zstd compresses them better.
CHUNK_SIZE = 1 << 20


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("convert", help="convert a capture into an MCAP log for Foxglove",
                       description="Convert a capture (bin, hex, timestamped hex or MCAP) into an MCAP file: raw "
                                   "bytes, decoded packets, per-servo state, transactions and lint findings.")
    p.add_argument("input", metavar="INPUT", help="capture file, or - for raw bytes on stdin")
    p.add_argument("-o", "--output", required=True, metavar="OUT.mcap", help="MCAP file to write")
    p.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    add_decode_options(p)
    add_lint_options(p)
    p.set_defaults(run=run)


# ---- shared with `info` --------------------------------------------------------------------------
def add_lint_options(p: argparse.ArgumentParser) -> None:
    """The linter's rule selection, as `lint` takes it, and --no-lint."""
    add_lint_selection(p)
    p.add_argument("--no-lint", action="store_true", help="do not run the linter")


def prepare(args: argparse.Namespace) -> tuple[DecodeOptions, Any]:
    """Decode options and a Linter (None with --no-lint) from the command line, the settings file
    (--config, else the nearest one) and, for an MCAP input, the baud and models it was recorded with;
    in that order of precedence."""
    config: dict[str, Any] = {}
    fmt = args.input_format or (detect_format(args.input) if args.input != "-" else None)
    if fmt == MCAP:
        from ..io.mcap_source import McapRawReader
        reader = McapRawReader(args.input)
        reader.read_metadata()
        if reader.baud:
            config["baud"] = reader.baud
        if reader.models:
            config["models"] = reader.models
    settings = settings_from(args)
    models = {**config.get("models", {}), **settings.get("models", {})}
    config.update(settings)
    if models:
        config["models"] = models
    opts = decode_options(args, config)
    if args.no_lint:
        return opts, None
    from ..lint import Linter  # imported here: only linting commands pay for the rules
    return opts, Linter(build_config(args, settings, opts))


def peek(chunks: Iterator[Chunk]) -> tuple[bool, Iterator[Chunk]]:
    """(whether the capture has timestamps, the same chunks)."""
    first = next(chunks, None)
    if first is None:
        return False, iter(())
    return first[1] is not None, itertools.chain((first,), chunks)


def check_output(path: str, force: bool, inputs: tuple[str, ...] = ()) -> None:
    """Refuse to overwrite a file (without --force) and never write over an input."""
    if os.path.isdir(path):
        raise CliError(f"{path}: is a directory")
    if os.path.exists(path):
        for i in inputs:
            if i != "-" and os.path.exists(i) and os.path.samefile(i, path):
                raise CliError(f"{path}: is the input file; write to another file")
        if not force:
            raise CliError(f"{path}: already exists (use --force to overwrite)")


def progress_bar(enabled: bool):
    """A rich progress display on stderr when it is a terminal, else None."""
    if not enabled:
        return None
    from rich.console import Console
    from rich.progress import BarColumn, DownloadColumn, Progress, TextColumn, TimeElapsedColumn, TransferSpeedColumn
    return Progress(TextColumn("[bold]{task.description}"), BarColumn(), DownloadColumn(), TransferSpeedColumn(),
                    TimeElapsedColumn(), console=Console(stderr=True), transient=True)


# ---- the command ---------------------------------------------------------------------------------
def run(args: argparse.Namespace) -> int:
    from ..io.mcap_sink import McapSink, convert

    check_output(args.output, args.force, (args.input,))
    opts, linter = prepare(args)
    timed, chunks = peek(open_input(args.input, args.input_format))
    decoder = Decoder(opts, linter=linter)
    source = "stdin" if args.input == "-" else args.input
    total = os.path.getsize(args.input) if args.input != "-" and (
        (args.input_format or detect_format(args.input)) == "bin") else None
    bar = progress_bar(sys.stderr.isatty())
    try:
        sink = McapSink(args.output, source=source, baud=opts.baud, time_base="capture" if timed else "synthetic",
                        models=opts.models, extra_metadata={"default_model": opts.default_model or ""},
                        chunk_size=CHUNK_SIZE)
    except OSError as e:
        raise CliError(f"{args.output}: cannot write: {e.strerror}") from None
    with sink:
        if bar is None:
            convert(chunks, sink, decoder)
        else:
            with bar:
                task = bar.add_task("converting", total=total)
                convert(chunks, sink, decoder, progress=lambda n: bar.advance(task, n))
    print(f"{args.output}: {decoder.bytes_in} bytes, {sink.messages} messages, {sink.bytes_written} bytes written",
          file=sys.stderr)
    return 0
