"""`rs30x-sniff record`: capture a serial port to MCAP while decoding, with a status line and clean stops."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..io.mcap_sink import McapSink
from ..io.serial_tap import LOST, STOPPED, LiveSource, SerialTap
from ..pipeline import Decoder
from ..render import text_line
from ..wire import byte_time
from .common import CliError, add_decode_options, decode_options
from .lint import add_lint_selection, build_config, settings_from

STATUS_INTERVAL = 0.25  # seconds between status line refreshes
FLUSH_INTERVAL = 1.0    # an idle bus still gets its open MCAP chunk written within about a second


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("record", help="record a serial port to MCAP (a passive tap; never writes to the port)",
                       description="Capture the bus from a serial port (a device or a pyserial URL) into an MCAP "
                                   "file, decoding and linting as it goes. Ctrl-C, SIGTERM, --duration and a lost "
                                   "port all leave a finalized file.")
    p.add_argument("port", metavar="PORT", help="serial device (/dev/ttyUSB0) or pyserial URL (socket://host:port)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.mcap", help="MCAP file to write")
    add_decode_options(p)
    p.add_argument("--duration", type=float, default=None, metavar="S", help="stop after S seconds")
    p.add_argument("--print", dest="print_lines", action="store_true",
                   help="also print each decoded packet as a text line (like decode)")
    p.add_argument("--split-size", type=float, default=None, metavar="MB",
                   help="start a new numbered file (OUT-001.mcap, OUT-002.mcap, ...) after about MB megabytes")
    add_lint_selection(p)
    p.add_argument("--no-lint", action="store_true", help="do not run the linter while recording")
    p.set_defaults(run=run)


class _Files:
    """The output: one MCAP file, or numbered ones rotated at a size."""

    def __init__(self, path: str, split_bytes: int | None, make) -> None:
        self.base = Path(path)
        self.split_bytes = split_bytes
        self.make = make
        self.index = 0
        self.paths: list[str] = []
        self.sink: McapSink = self._open()

    def _open(self) -> McapSink:
        if self.split_bytes is None:
            path = str(self.base)
        else:
            self.index += 1
            path = str(self.base.with_name(f"{self.base.stem}-{self.index:03d}{self.base.suffix or '.mcap'}"))
        try:
            sink = self.make(path, self.index)
        except OSError as e:
            raise CliError(f"{path}: cannot write: {e.strerror}") from None
        self.paths.append(path)
        return sink

    def maybe_rotate(self) -> None:
        if self.split_bytes is not None and self.sink.bytes_written >= self.split_bytes:
            self.sink.finish()
            self.sink = self._open()

    def finish(self) -> None:
        self.sink.finish()


class _Status:
    """The status line on stderr (a terminal only): bytes, packets, findings, bus load."""

    def __init__(self, enabled: bool, baud: int, out_name: str) -> None:
        self.enabled = enabled
        self.bt = byte_time(baud)
        self.out_name = out_name
        self.live = None
        self.start = time.monotonic()
        self.window: list[tuple[float, int]] = []  # (time, bytes) over the last second, for the load
        if enabled:
            from rich.console import Console
            from rich.live import Live

            self.live = Live("", console=Console(stderr=True), transient=True, auto_refresh=False,
                             redirect_stdout=True, redirect_stderr=False)
            self.live.start()

    def note(self, nbytes: int) -> None:
        if self.enabled:
            now = time.monotonic()
            self.window.append((now, nbytes))
            while self.window and self.window[0][0] < now - 1.0:
                self.window.pop(0)

    def show(self, nbytes: int, packets: int, findings: int) -> None:
        if self.live is None:
            return
        load = sum(n for _, n in self.window) * self.bt  # seconds of line time in the last second
        self.live.update(f"[bold red]REC[/] {time.monotonic() - self.start:7.1f} s  {nbytes:,} B  "
                         f"{packets:,} packets  {findings:,} findings  load {load * 100:3.0f}%  -> {self.out_name}",
                         refresh=True)

    def stop(self) -> None:
        if self.live is not None:
            self.live.stop()
            self.live = None


def run(args: argparse.Namespace) -> int:
    settings = settings_from(args)
    opts = decode_options(args, settings)
    linter = None
    if not args.no_lint:
        from ..lint import Linter

        linter = Linter(build_config(args, settings, opts))
    if args.duration is not None and args.duration <= 0:
        raise CliError(f"--duration {args.duration:g}: must be positive")
    if args.split_size is not None and args.split_size <= 0:
        raise CliError(f"--split-size {args.split_size:g}: must be positive")
    split = None if args.split_size is None else max(1, int(args.split_size * 1e6))

    src = LiveSource(args.port, opts.baud, duration=args.duration, announce=False,
                     tap=SerialTap(args.port, opts.baud))
    src.start()  # a port that cannot be opened fails here, before any file is created

    def make_sink(path: str, part: int) -> McapSink:
        extra = dict(src.metadata)
        if part:
            extra["part"] = str(part)
        return McapSink(path, source=args.port, baud=opts.baud, time_base="monotonic", models=opts.models,
                        extra_metadata=extra)

    try:
        files = _Files(args.output, split, make_sink)
    except BaseException:
        src.close()
        raise
    dec = Decoder(opts, linter)
    status = _Status(sys.stderr.isatty(), opts.baud, args.output)
    out = sys.stdout  # after the status line starts: on a terminal it routes stdout above itself
    nbytes = packets = seen = 0
    last_status = last_flush = time.monotonic()
    dirty = False

    def write_records(records) -> None:
        nonlocal packets, seen
        sink = files.sink
        for rec in records:
            sink.record(rec)
            if args.print_lines:
                out.write(text_line(rec) + "\n")
        packets += len(records)
        if linter is not None and len(linter.findings) > seen:
            sink.findings(linter.findings[seen:])
            seen = len(linter.findings)

    try:
        while not src.ended:
            batch = src.poll(0.1)
            for data, t in batch:
                # Raw bytes go to the file before decoding: nothing received is ever lost to a decoder error.
                files.sink.raw(data, t)
                nbytes += len(data)
                status.note(len(data))
                write_records(dec.feed(data, t))
            if batch:
                dirty = True
                if args.print_lines:
                    out.flush()
                files.maybe_rotate()
            now = time.monotonic()
            if dirty and now - last_flush >= FLUSH_INTERVAL:
                files.sink.flush()
                last_flush, dirty = now, False
            if now - last_status >= STATUS_INTERVAL:
                status.show(nbytes, packets, seen)
                last_status = now
    finally:
        src.close()
        status.stop()
        try:
            write_records(dec.close())  # also writes the findings only the end of input reveals
            if args.print_lines:
                out.flush()
        finally:
            files.finish()

    where = ", ".join(files.paths)
    summary = f"{nbytes:,} bytes, {packets:,} packets, {seen:,} findings in {where}"
    if src.reason == LOST:
        print(f"rs30x-sniff: error: {args.port}: port lost ({src.message}); {summary}", file=sys.stderr)
        return 1
    why = src.message if src.reason == STOPPED else f"{args.duration:g} s recorded"
    print(f"rs30x-sniff: {why}: {summary}", file=sys.stderr)
    return 0

