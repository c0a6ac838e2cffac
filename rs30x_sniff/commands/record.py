"""`rs30x-sniff record`: capture a serial port to MCAP while decoding, with a status line and clean stops."""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import IO, Any

from ..sinks.mcap.writer import McapSink
from ..sources.serial_tap import GATHER_SECONDS, LOST, STOPPED, LiveSource, SerialTap
from ..decode.blocks import Block
from ..decode.decoder import Decoder, Step
from ..sinks.pipeline import Sink
from ..sinks.lines import TextSink
from ..sinks.stats import RecentLoad
from .common import CliError, check_positive, lint_config, live_sinks, make_linter, no_data, settings_for, time_form
from .options import add_bus_options, add_lint_selection, add_live_options, add_time_format_option
from ..sinks.outputs import STDOUT, check_output, write_error
from .live import add_foxglove_option, start_foxglove
from ..sinks.parts import MIN_SPLIT_MB, MIN_SPLIT_SECONDS, Parts, parse_keep, parse_span
from .blackbox import POST, PRE, add_trigger_options, check_mode, parse_max_saves, triggers_of
from ..sinks.windows import window_folder, window_writer
from ..lint import Linter
from ..sinks.blackbox import MAX_WINDOW_S, BlackBox
from ..sinks.pipeline import Pipeline, columnar_for
from ..sources.reconnect import ReconnectingSource

STATUS_INTERVAL = 0.25  # seconds between status line refreshes
IDLE_INTERVAL = 0.1     # a quiet port still hands the loop an empty chunk this often
UNWATCHED_GATHER_SECONDS = 1.0  # a recording nobody watches live: the bytes of a busy bus decoded a second at a time
PRINT_GATHER_SECONDS = 0.25     # --print: lines a person reads, a quarter of a second at a time


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("record", help="record a serial port to MCAP (a passive tap; never writes to the port)",
                       description="Capture the bus from a serial port (a device or a pyserial URL) into an MCAP "
                                   "file, decoding and linting as it goes. The file holds every byte as it came, "
                                   "the findings and the figures; every command reads it decoded, and convert "
                                   "writes its decoded topics for Foxglove (or give --decoded). Ctrl-C, SIGTERM, "
                                   "--duration and a lost port all leave a finalized file.")
    p.add_argument("port", metavar="PORT", help="serial device (/dev/ttyUSB0) or pyserial URL (socket://host:port)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.mcap",
                   help="MCAP file to write (- streams it to stdout)")
    p.add_argument("--force", action="store_true", help="replace OUT (and its numbered parts) if they exist")
    add_bus_options(p)  # a port: no capture format, no capture times, no logic channel
    add_live_options(p, help="stop after TIME (30s, 10min, 2h; default: run until Ctrl-C)")
    p.add_argument("--print", dest="print_lines", action="store_true",
                   help="also print each decoded packet as a text line (like decode)")
    p.add_argument("--decoded", action="store_true",
                   help="also write each packet, transaction and servo state as it comes (Foxglove plots the file "
                        "as it is; about three times the CPU of the bytes alone; convert makes them later; "
                        "--trigger's windows always hold them)")
    add_time_format_option(p)
    p.add_argument("--split-size", type=float, default=None, metavar="MB",
                   help="start a new numbered file (OUT-001.mcap, OUT-002.mcap, ...) after about MB megabytes "
                        "(at least 0.01)")
    p.add_argument("--split-time", default=None, metavar="TIME",
                   help="start a new numbered file every TIME (30s, 10min, 1h; at least 1s), beside or instead of "
                        "--split-size; a part ends at the first byte past it, so a quiet bus makes no empty parts. "
                        "A file's index stays in memory until it closes (about 1 MB an hour): a recorder left on "
                        "for days wants parts")
    p.add_argument("--keep", default=None, metavar="AGE|SIZE",
                   help="with numbered files: delete the oldest closed ones past an age (24h, 7d) or a total size "
                        "(500MB, 5GB; a part then ends at half of it at most); numbering goes on after the parts "
                        "already there")
    p.add_argument("--no-reconnect", action="store_true",
                   help="stop when the port goes away (by default the recorder waits for it, by its path or its "
                        "/dev/serial/by-id link, and goes on, marking the gap)")
    add_trigger_options(p)
    add_lint_selection(p)
    p.add_argument("--no-lint", action="store_true", help="do not run the linter while recording")
    add_foxglove_option(p)
    p.set_defaults(run=run)


class _Status(Sink):
    """Counts what was recorded, and shows it in a status line on stderr (a terminal only)."""

    def __init__(self, enabled: bool, baud: int, out_name: str) -> None:
        self.out_name = out_name
        self.load = RecentLoad(baud)
        self.bytes = self.packets = self.findings = 0
        self.live = None
        self.start = self.last_show = time.monotonic()
        if enabled:
            from rich.console import Console
            from rich.live import Live

            self.live = Live("", console=Console(stderr=True), transient=True, auto_refresh=False,
                             redirect_stdout=True, redirect_stderr=False)
            self.live.start()

    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        self.bytes += len(data)
        if self.live is not None:  # the load is shown on the status line only
            if t is not None:
                self.load.add(t, len(data))
            self.idle()

    takes_blocks = True  # it counts rows: a Block is never made into Records for it

    def batch(self, step: Step) -> None:
        self.packets += sum(len(x) if type(x) is Block else 1 for x in step) if step.blocks else len(step)
        self.findings += len(step.findings)

    def idle(self) -> None:
        now = time.monotonic()
        if self.live is None or now - self.last_show < STATUS_INTERVAL:
            return
        self.last_show = now
        load = self.load.value
        self.live.update(f"[bold red]REC[/] {now - self.start:7.1f} s  {self.bytes:,} B  {self.packets:,} packets  "
                         f"{self.findings:,} findings  load {'-' if load is None else f'{load * 100:3.0f}%'}  "
                         f"-> {self.out_name}", refresh=True)

    def close(self) -> None:
        if self.live is not None:
            self.live.stop()
            self.live = None


class _Log:
    """Lines for the log (a lost port, one found again, a part or window saved or deleted): above the status line
    once there is one on a terminal, else on stderr (a service's journal)."""

    def __init__(self) -> None:
        self.status: _Status | None = None

    def say(self, line: str) -> None:
        status = self.status
        if status is not None and status.live is not None:
            status.live.console.print(line, markup=False, highlight=False)
        else:
            print(line, file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    check_mode(args)
    if args.trigger:
        return run_black_box(args)
    check_output(args.output, args.force)  # before the port is opened
    settings = settings_for(args, args.port)
    opts = settings.decode_options()
    linter = make_linter(args, settings)
    check_positive("--duration", args.duration)
    check_positive("--split-size", args.split_size)
    if args.split_size is not None and args.split_size < MIN_SPLIT_MB:
        raise CliError(f"--split-size {args.split_size:g}: must be at least {MIN_SPLIT_MB:g} MB (a part holds "
                       "its own header and summary)")
    split = None if args.split_size is None else max(1, int(args.split_size * 1e6))
    split_time = (None if args.split_time is None
                  else parse_span("--split-time", args.split_time, least=MIN_SPLIT_SECONDS))
    keep = None if args.keep is None else parse_keep(args.keep)
    if args.output == STDOUT and (split is not None or split_time is not None):
        raise CliError(f"{'--split-size' if split is not None else '--split-time'}: numbered files need a file "
                       f"name, not - (stdout)")
    if keep is not None and split is None and split_time is None:
        raise CliError("--keep: deletes old numbered files: give --split-size or --split-time too")
    if args.output == STDOUT and args.print_lines:
        raise CliError("--print: stdout carries the MCAP stream (-o -); leave out one of them")

    log = _Log()
    say = log.say

    # The columnar path, a gather at a time (sinks.pipeline.columnar_for). A group costs about a millisecond
    # whatever it holds, so the gather is as long as what watches allows: a tenth of a second for Foxglove's live
    # plots, a quarter for --print's lines (a person reading them), a second for the file alone (its chunks
    # are cut a second at a time anyway).
    gather = (GATHER_SECONDS if args.foxglove is not None else PRINT_GATHER_SECONDS if args.print_lines
              else UNWATCHED_GATHER_SECONDS)
    src = open_port(args, opts.baud, say, gather=gather)
    columnar = columnar_for(src)

    def make_sink(path: str | IO[bytes], part: int) -> McapSink:
        extra = dict(src.metadata)
        if part:
            extra["part"] = str(part)
        sink = McapSink(path, source=args.port, baud=opts.baud, time_base="wall", models=opts.models,
                        extra_metadata=extra, decoded=args.decoded)
        sink.stats.stalls = src.stalls  # where the reader fell behind: in rs30x.stats, and no load over them
        return sink

    fox = None
    try:
        # Same log times as the file (wall clock), so the live view and the recording line up; started
        # first, so a busy address leaves no empty file behind.
        fox = start_foxglove(args.foxglove, source=args.port, baud=opts.baud, models=opts.models)
        # Each deleted part gets a line (say): in a service's journal, or above the status line.
        files = Parts(args.output, make_sink, split_bytes=split, split_seconds=split_time, keep=keep,
                      force=args.force, say=say)
    except BaseException:
        src.close()
        if fox is not None:
            fox.close()
        raise
    status = log.status = _Status(sys.stderr.isatty(), opts.baud, args.output)
    sinks: list[Sink] = [files, status, *live_sinks(settings, src, args.port)]
    if fox is not None:
        sinks.append(fox)
    if args.print_lines:
        # After the status line starts: on a terminal it routes stdout above itself.
        sinks.append(TextSink(sys.stdout, flush=True, times=time_form(settings)))
    try:
        dec = Pipeline(Decoder(opts, linter, columnar=columnar), sinks,
                       group_bytes=max(256, opts.baud // 10)).run(src.chunks(IDLE_INTERVAL))
    except OSError as e:
        if files.sink.failed is None:
            raise
        raise write_error(files.paths[-1], e, _what_is_left(files.sink, files.paths[-1], status.bytes)) from None
    no_data(args.port, dec, src)

    where = files.describe()
    summary = f"{status.bytes:,} bytes, {status.packets:,} packets, {status.findings:,} findings in {where}"
    return _end_line(args, src, summary)


def open_port(args: argparse.Namespace, baud: int, say: Any,
              gather: float = GATHER_SECONDS) -> LiveSource | ReconnectingSource:
    """The port as a source: one that waits for a lost port to come back, or (--no-reconnect) one that stops.
    A port that cannot be opened fails here, before any file is made. ``gather``: how long the bytes of a
    busy bus are let pile up between passes of the drive loop (LiveSource)."""
    if args.no_reconnect:
        src = LiveSource(args.port, baud, duration=args.duration, announce=False, tap=SerialTap(args.port, baud),
                         gather=gather)
        src.start()
        return src
    return ReconnectingSource(args.port, baud, duration=args.duration, say=say, gather=gather)


def _end_line(args: argparse.Namespace, src: Any, summary: str) -> int:
    """The last line on stderr, and the exit code: 1 for a lost port (--no-reconnect), else 0."""
    gaps = getattr(src, "gaps", ())
    if gaps:
        lost = sum(back - (gone or back) for gone, back, _ in gaps)
        summary += f"; the port was lost {len(gaps)} time{'s' if len(gaps) != 1 else ''} ({lost:.1f} s without it)"
    if src.reason == LOST:
        print(f"rs30x-sniff: error: {args.port}: port lost ({src.message}); {summary}", file=sys.stderr)
        return 1
    why = src.message if src.reason == STOPPED else f"{args.duration:g} s recorded"
    print(f"rs30x-sniff: {why}: {summary}", file=sys.stderr)
    return 0


def run_black_box(args: argparse.Namespace) -> int:
    """record --trigger: the last --pre of the bus in a ring, each window around a fire saved to -o DIR/."""
    folder = window_folder(args.output)
    settings = settings_for(args, args.port)
    opts = settings.decode_options()
    check_positive("--duration", args.duration)
    pre, post = parse_span("--pre", args.pre or PRE), parse_span("--post", args.post or POST)
    if pre + post > MAX_WINDOW_S:  # the ring holds --pre of the bus in memory; a window is at most this long
        raise CliError(f"--pre {args.pre or PRE} --post {args.post or POST}: a window is at most "
                       f"{MAX_WINDOW_S / 60:g} min in all (the ring holds --pre of the bus in memory)")
    keep = None if args.keep is None else parse_keep(args.keep)
    max_saves = parse_max_saves(args.max_saves)
    config = lint_config(settings)
    triggers = triggers_of(args.trigger, [r.code for r in Linter(config).rules])
    # The bus is linted as it goes only for triggers that fire on findings; each window is linted in full as it
    # is saved.
    linter = make_linter(args, settings) if any(t.needs_lint for t in triggers) else None
    if linter is None and any(t.needs_lint for t in triggers):
        raise CliError("--no-lint: a trigger fires on findings (a rule code, sev:): it needs the linter")

    log = _Log()
    say = log.say

    # Nothing is shown as it comes: the bus is taken a tenth of a second at a time, for fewer passes of the loop.
    src = open_port(args, opts.baud, say)
    try:
        window_folder(args.output, make=True)
    except BaseException:
        src.close()
        raise
    save = window_writer(folder, opts=opts, lint_config=config, source=args.port, metadata=lambda: src.metadata,
                         keep=keep, now=time.time, say=say)
    box = BlackBox(triggers, pre, post, save, max_per_hour=max_saves, now=time.time, say=say)
    status = log.status = _Status(sys.stderr.isatty(), opts.baud, str(folder) + os.sep)
    # The columnar path, about a second of the line at a time: the triggers read Blocks' columns.
    group = max(256, opts.baud // 10)
    pipeline = Pipeline(Decoder(opts, linter, columnar=True), [box, status, *live_sinks(settings, src, args.port)],
                        group_bytes=group)
    dec = pipeline.run(src.chunks(IDLE_INTERVAL))
    no_data(args.port, dec, src)
    n = len(box.saved)
    summary = (f"{status.bytes:,} bytes, {n} window{'s' if n != 1 else ''} saved in {folder}"
               + (f" ({box.suppressed} fires over --max-saves not saved)" if box.suppressed else ""))
    return _end_line(args, src, summary)


def _what_is_left(sink: McapSink, name: str, received: int) -> str:
    """After a failed write: how much of the recording was kept, and whether it reads as a finished file."""
    kept = f"recording stopped after {received:,} bytes received; "
    if sink.finalized:
        return kept + f"{name} is finalized: {sink.readable_bytes:,} bytes, readable to its end"
    return kept + (f"{name} is not finalized: its first {sink.readable_bytes:,} bytes are whole chunks, "
                   "readable (`rs30x-sniff info` reads it up to its damage)")
