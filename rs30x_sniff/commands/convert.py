"""`rs30x-sniff convert`: a capture of any format into a Foxglove-ready MCAP file or a pcapng for Wireshark."""

from __future__ import annotations

import argparse
import itertools
from datetime import datetime
import os
import sys
from typing import IO, Any
from collections.abc import Iterator

from ..sources.captures import Chunk, detect_format
from ..decode.decoder import Decoder
from ..sinks.pipeline import columnar_for, drive
from ..settings import Settings
from ..sinks.lines import ProgressSink
from .common import CliError, capture_start_time, make_linter, open_input, settings_for
from .options import add_decode_options, add_format_option, add_lint_options
from ..sinks.outputs import STDOUT, check_output, output_binary, report_end


# A file is converted in chunks of up to 1 MiB (still cut at 1 s of log time): the summary lists every
# chunk, so fewer chunks keep the writer's memory flat on long captures, and zstd compresses them better.
CHUNK_SIZE = 1 << 20

OUTPUT_KINDS = ("mcap", "pcapng")


def output_kind(path: str, to: str | None) -> str:
    """What ``convert`` writes: ``--to``, else pcapng for a file named *.pcapng, else MCAP. A name whose
    extension says another format (``x.bin``, or ``x.mcap --to pcapng``) is refused: what it names is not
    what would be in it. A name without an extension, ``-``, and a FIFO or device (its name is no format's)
    take either."""
    special = os.path.exists(path) and not os.path.isfile(path)
    ext = "" if path == STDOUT or special else os.path.splitext(path)[1].lower().lstrip(".")
    named = ext if ext in OUTPUT_KINDS else None
    if ext and named is None:
        kinds = " or ".join(f".{k}" for k in OUTPUT_KINDS)
        raise CliError(f"-o {path}: convert writes {' or '.join(OUTPUT_KINDS)}, not .{ext}: name the output {kinds}")
    if to is not None and named is not None and to != named:
        raise CliError(f"-o {path} and --format {to}: the name says {named}; name the output .{to} or drop --format")
    return to or named or "mcap"


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("convert", help="convert a capture into an MCAP log for Foxglove or a pcapng for Wireshark",
                       description="Convert a capture (bin, hex, timestamped hex or MCAP) into an MCAP file: raw "
                                   "bytes, decoded packets, per-servo state, transactions and lint findings; or, "
                                   "for OUT.pcapng (or --format pcapng), into a pcapng file for Wireshark and tshark "
                                   "with the dissector of `rs30x-sniff plugin wireshark`: a packet per frame and "
                                   "per garbage run, the findings as packet comments.")
    p.add_argument("input", metavar="INPUT", help="capture file, or - for raw bytes on stdin")
    p.add_argument("-o", "--output", required=True, metavar="OUT.mcap",
                   help="MCAP or pcapng file to write (- for stdout)")
    add_format_option(p, OUTPUT_KINDS, "what to write (default: pcapng for a name ending .pcapng, else mcap)",
                      aliases=("--to",))  # --to: its name before every command said --format
    p.add_argument("--force", action="store_true", help="overwrite OUT if it exists")
    add_decode_options(p)
    add_lint_options(p)
    p.add_argument("--start-time", metavar="ISO8601",
                   help="anchor the log's times to this wall-clock time (e.g. 2026-11-22T15:30:00Z): the start of a "
                        "capture without timestamps, or time 0 of one whose times count from 0")
    p.set_defaults(run=run)


# ---- shared with `simulate` -------------------------------------------------------------------
def peek(chunks: Iterator[Chunk]) -> tuple[Chunk | None, Iterator[Chunk]]:
    """(the first chunk, or None for an empty capture; the same chunks, that one included)."""
    first = next(chunks, None)
    if first is None:
        return None, iter(())
    return first, itertools.chain((first,), chunks)


def progress_bar(enabled: bool):
    """A rich progress display on stderr when it is a terminal, else None."""
    if not enabled:
        return None
    from rich.console import Console
    from rich.progress import BarColumn, DownloadColumn, Progress, TextColumn, TimeElapsedColumn, TransferSpeedColumn
    return Progress(TextColumn("[bold]{task.description}"), BarColumn(), DownloadColumn(), TransferSpeedColumn(),
                    TimeElapsedColumn(), console=Console(stderr=True), transient=True)


def parse_start_time(text: str | None) -> float | None:
    """``--start-time`` as seconds since the epoch (a time without a zone is local time)."""
    if text is None:
        return None
    try:
        when = datetime.fromisoformat(text.strip())
    except ValueError:
        raise CliError(f"--start-time {text}: not an ISO 8601 time (e.g. 2026-11-22T15:30:00Z)") from None
    if when.tzinfo is None:
        when = when.astimezone()
    return when.timestamp()


def open_mcap_sink(path: str | IO[bytes], source: str, settings: Settings, *, timed: bool,
                   start_time: float | None = None, **extra: str) -> Any:
    """The MCAP sink of a converted (or simulated) capture, with its settings in the metadata; ``path``
    may be a file object (the writer only appends, so stdout will do)."""
    from ..sinks.mcap.writer import McapSink

    try:
        return McapSink(path, source=source, baud=settings.baud, time_base="capture" if timed else "synthetic",
                        models=dict(settings.models),
                        extra_metadata={"default_model": settings.default_model or "", **extra},
                        chunk_size=CHUNK_SIZE, start_time=start_time)
    except OSError as e:
        if e.filename is None and isinstance(path, str):
            e.filename = path
        raise  # the output's error: :func:`output_path` says what became of the file


def open_pcapng_sink(out: IO[bytes], source: str, settings: Settings, *, timed: bool,
                     start_time: float | None = None) -> Any:
    """The pcapng sink of a converted capture (it only appends: stdout will do)."""
    from ..sinks.pcapng import PcapngSink

    return PcapngSink(out, source=source, baud=settings.baud, timed=timed, start_time=start_time)


# ---- the command ---------------------------------------------------------------------------------
def run(args: argparse.Namespace) -> int:
    check_output(args.output, args.force, (args.input,))
    kind = output_kind(args.output, args.format)  # before anything is opened or written
    start_time = parse_start_time(args.start_time)
    settings = settings_for(args, args.input)
    linter = make_linter(args, settings)
    src = open_input(args.input, args.input_format, settings)  # no line index: diagnostics carry offsets
    first, chunks = peek(iter(src))  # a capture being read is its own iterator: the same chunks
    if first is None:
        raise CliError(f"{args.input}: no data (the capture is empty): nothing to convert")
    if start_time is None:
        # Another tool's log may carry the wall-clock time of its first stamp (a Saleae ISO table, a
        # socat or jpnevulator log): the MCAP is anchored there, as --start-time would (which wins).
        start_time = capture_start_time(src)
    # A file takes the columnar path (the same messages, in log-time order within each group of
    # GROUP_BYTES, 256 KiB).
    decoder = Decoder(settings.decode_options(), linter=linter, columnar=columnar_for(src))
    source = "stdin" if args.input == "-" else args.input
    total = os.path.getsize(args.input) if os.path.isfile(args.input) and (
        (args.input_format or detect_format(args.input)) == "bin") else None
    bar = progress_bar(sys.stderr.isatty())
    # Written beside OUT and renamed into place at the end: an input error leaves nothing behind, while
    # a stop (Ctrl-C, SIGTERM, SIGHUP) keeps the finalized log of what was converted so far.
    stopped = None
    sink = None
    try:
        # A stop before the writer began (a signal as the command starts) leaves no file: it would not be a log.
        with output_binary(args.output, force=args.force, inputs=(args.input,),
                           keep_on_stop=lambda: sink is not None) as out:
            opener = open_pcapng_sink if kind == "pcapng" else open_mcap_sink
            sink = opener(out, source, settings, timed=first[1] is not None, start_time=start_time)
            if bar is None:
                drive(chunks, decoder, sink)
            else:
                with bar:
                    task = bar.add_task("converting", total=total)
                    drive(chunks, decoder, sink, ProgressSink(lambda n: bar.advance(task, n)))
    except KeyboardInterrupt as e:
        stopped = str(e) or "Ctrl-C"  # the log of what was read so far is finished and kept
    name = "stdout" if args.output == STDOUT else args.output
    if sink is None:  # stopped before the writer began
        return report_end(f"{name}: nothing converted, nothing saved", stopped)
    count = f"{sink.packets} packets" if kind == "pcapng" else f"{sink.messages} messages"
    summary = f"{name}: {decoder.bytes_in} bytes, {count}, {sink.bytes_written} bytes written"
    return report_end(summary, stopped)
