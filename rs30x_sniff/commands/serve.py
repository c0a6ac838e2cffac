"""`rs30x-sniff serve`: the bus, live on a Foxglove WebSocket server (a port, the simulator, or a replayed capture)."""

from __future__ import annotations

import argparse
import logging
import sys
import threading
import time
from typing import Any

from ..decode.decoder import Decoder
from ..sinks.pipeline import Pipeline
from .common import (CliError, add_decode_options, add_lint_options, check_positive, is_port_path, live_sinks,
                     make_linter, settings_for)


def foxglove_address(text: str) -> tuple[str, int]:
    """argparse type of ``--foxglove [HOST:]PORT``."""
    from ..sinks.mcap.foxglove import parse_address

    try:
        return parse_address(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def add_foxglove_option(p: argparse.ArgumentParser, *, default: str | None = None) -> None:
    """``--foxglove [HOST:]PORT``: publish the MCAP channels on a Foxglove WebSocket server."""
    extra = f" (default {default})" if default else ""
    p.add_argument("--foxglove", type=foxglove_address, default=None if default is None else foxglove_address(default),
                   metavar="[HOST:]PORT",
                   help="also stream the bus to Foxglove over its WebSocket protocol, on PORT of HOST "
                        f"(default host 127.0.0.1; 0.0.0.0 for every interface){extra}; the app URL is printed")


class _SdkLog(logging.Handler):
    """The SDK's own warnings and errors (it logs through Python's logging: a client that dropped its
    connection, say) as one prefixed line each, on whatever ``sys.stderr`` is when they come: the
    monitor's screen takes it over while it runs, so they never land in the middle of it."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            print(f"rs30x-sniff: Foxglove: {record.getMessage()}", file=sys.stderr, flush=True)
        except Exception:  # noqa: BLE001 - a log line must not stop the capture
            self.handleError(record)


def _route_sdk_log() -> None:
    logger = logging.getLogger("foxglove")
    if not any(isinstance(h, _SdkLog) for h in logger.handlers):
        logger.addHandler(_SdkLog(logging.WARNING))
        logger.propagate = False  # not also Python's last-resort handler, unprefixed


def live_start_time(source: Any) -> float | None:
    """The wall-clock time (seconds since the epoch) to add to a live stream's times: now, for the
    simulator, whose bus times count from 0 and would be shown in 1970; None for any other source (a
    port's times are the wall clock already, and a replayed capture keeps the times it recorded)."""
    return time.time() if getattr(source, "kind", None) == "simulator" else None


def start_foxglove(address: tuple[str, int] | None, *, source: str, baud: int,
                   models: dict[int, str] | None = None, start_time: float | None = None) -> Any:
    """The Foxglove sink for ``address`` (None: no server), its URLs said on stderr; ``start_time``
    anchors times that count from 0 to the wall clock (:func:`live_start_time`)."""
    if address is None:
        return None
    from ..sinks.mcap.foxglove import FoxgloveError, FoxgloveSink

    _route_sdk_log()

    try:
        sink = FoxgloveSink(*address, source=source, baud=baud, models=models, start_time=start_time)
    except FoxgloveError as e:
        raise CliError(f"--foxglove: {e}") from None
    print(f"rs30x-sniff: Foxglove server on {sink.ws_url}; open {sink.app_url()}", file=sys.stderr, flush=True)
    return sink


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("serve", help="stream the bus live to Foxglove (WebSocket server)",
                       description="Publish the bus on a Foxglove WebSocket server: the channels of an MCAP "
                                   "recording (raw bytes, packets, servo state, transactions, lint findings), with "
                                   "the same schemas and log times, as they happen. INPUT is a serial port, a "
                                   "capture file (replayed at its own pace) or, with --simulate, the simulator.")
    p.add_argument("input", metavar="INPUT", nargs="?",
                   help="serial port (/dev/ttyUSB0, socket://host:port) or capture file (.bin, .hex, .mcap, ...)")
    add_decode_options(p)
    p.add_argument("--replay", action="store_true",
                   help="play a capture file at its own pace (always so: a file served at once is over before "
                        "a client can subscribe)")
    p.add_argument("--speed", type=float, default=1.0, metavar="X",
                   help="replay (or simulate) X times faster than real time (default 1)")
    p.add_argument("--simulate", metavar="SCENARIO", help="serve the built-in simulator running SCENARIO")
    add_foxglove_option(p, default="127.0.0.1:8765")
    add_lint_options(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from .monitor import make_source

    if not args.input and not args.simulate:
        raise CliError("serve needs INPUT (a serial port or a capture file) or --simulate SCENARIO")
    settings = settings_for(args, None if args.simulate else args.input)
    opts = settings.decode_options()
    check_positive("--speed", args.speed)
    linter = make_linter(args, settings)
    if args.input and not args.simulate and not is_port_path(args.input, unplugged=True):
        args.replay = True
    try:
        source = make_source(args, settings)
    except OSError as e:
        raise CliError(f"{args.input}: {e.strerror or e}") from None
    stop = threading.Event()
    try:
        sink = start_foxglove(args.foxglove, source=source.name, baud=opts.baud, models=opts.models,
                              start_time=live_start_time(source))
        pipeline = Pipeline(Decoder(opts, linter), [sink, *live_sinks(settings, source, source.name)])
        try:
            # Ctrl-C (and SIGTERM, which the CLI turns into one) ends the stream; the pipeline
            # closes its sinks (the server) either way.
            pipeline.run(source.chunks(stop))
        except KeyboardInterrupt:
            stop.set()
    finally:
        source.close()
    warnings = getattr(source, "warnings", None)
    for w in warnings or ():
        print(f"rs30x-sniff: warning: {w}", file=sys.stderr)
    dec = pipeline.decoder
    print(f"rs30x-sniff: {source.name}: {dec.bytes_in:,} bytes, {sink.messages:,} messages published",
          file=sys.stderr)
    return 0
