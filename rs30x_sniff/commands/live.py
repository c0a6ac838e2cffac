"""What the live commands share (monitor, serve, record): the ``--foxglove`` option and its server, and
the source a monitor or a server reads (a capture file, replayed or at once, a port, the simulator)."""

from __future__ import annotations

import argparse
import logging
import sys
import time
from typing import Any

from ..settings import Settings
from .common import CliError, input_options, is_port_path


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


def make_source(args: argparse.Namespace, settings: Settings):
    """The source the command line asks for, opened now so a bad one fails before the screen starts."""
    from ..sim.source import SimulatorSource
    from ..sources.feeds import FileSource, PortSource, ReplaySource

    if args.simulate:
        if args.input:
            raise CliError("give either INPUT or --simulate SCENARIO, not both")
        return SimulatorSource(args.simulate, settings.baud, speed=args.speed)
    if not args.input:
        raise CliError("monitor needs INPUT (a capture file or a serial port) or --simulate SCENARIO")
    if is_port_path(args.input, unplugged=True):
        if args.replay:
            raise CliError("--replay plays a capture file; a port is live already")
        return PortSource(args.input, settings.baud)
    if args.replay:
        return ReplaySource(args.input, args.input_format, speed=args.speed, baud=settings.baud,
                            time_ref=settings.time_ref, options=input_options(settings))
    return FileSource(args.input, args.input_format, baud=settings.baud, time_ref=settings.time_ref,
                      options=input_options(settings))
