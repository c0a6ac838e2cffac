"""`rs30x-sniff monitor`: the live timeline of the bus in a terminal UI (a capture file, a port, or the simulator)."""

from __future__ import annotations

import argparse
import os
from typing import Any

from ..decode.decoder import DecodeOptions
from .common import CliError, check_positive, lint_config, settings_for
from .options import add_decode_options, add_lint_options, add_time_format_option
from .live import add_foxglove_option, live_start_time, make_source, start_foxglove


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("monitor", help="watch the bus in a terminal UI",
                       description="A live timeline of the bus: every packet explained, every problem flagged, "
                                   "every servo's state at a glance. Press ? in the monitor for its keys.")
    p.add_argument("input", metavar="INPUT", nargs="?",
                   help="capture file (.bin/.raw, .hex, timestamped hex, .mcap) or serial port (/dev/ttyUSB0, COM3)")
    add_decode_options(p)
    p.add_argument("--replay", action="store_true", help="play a capture file at its own pace instead of at once")
    p.add_argument("--speed", type=float, default=1.0, metavar="X",
                   help="replay (or simulate) X times faster than real time (default 1)")
    p.add_argument("--simulate", metavar="SCENARIO", help="watch the built-in simulator run SCENARIO instead of INPUT")
    p.add_argument("--history", type=int, default=None, metavar="N",
                   help="records kept for scrolling back (default 1,000,000; older ones are dropped)")
    p.add_argument("--record-dir", default=".", metavar="DIR", help="where `r` writes MCAP recordings (default .)")
    add_time_format_option(p)
    add_foxglove_option(p)
    add_lint_options(p)
    p.set_defaults(run=run)


def prepare(args: argparse.Namespace) -> tuple[Any, DecodeOptions, dict[str, Any]]:
    """The source (opened), decode options and app configuration the command line asks for.

    The settings come the way every command takes them, so the monitor's linter, models and baud
    agree with `lint`, `info` and `decode` on the same capture.
    """
    settings = settings_for(args, None if args.simulate else args.input)
    opts = settings.decode_options()
    check_positive("--speed", args.speed)
    if args.history is not None and args.history < 1:
        raise CliError(f"--history {args.history}: must be at least 1")
    if not os.path.isdir(args.record_dir):
        raise CliError(f"--record-dir {args.record_dir}: no such directory")
    config: dict[str, Any] = {"record_dir": args.record_dir, "time_format": settings.time_format}
    if args.no_lint:
        config["linter_factory"] = lambda: None
    else:
        from ..lint import Linter

        cfg = lint_config(settings)
        config["linter_factory"] = lambda: Linter(cfg, keep_findings=False)
    if args.history is not None:
        config["history"] = args.history
    try:
        source = make_source(args, settings)
    except OSError as e:
        raise CliError(f"{args.input}: {e.strerror or e}") from None
    config["time_anchor"] = live_start_time(source)  # the simulator's times count from 0: its start is now
    return source, opts, config


def run(args: argparse.Namespace) -> int:
    source, opts, config = prepare(args)
    from ..tui.app import make_app  # Textual is imported only when the screen is about to start

    app = make_app(source, opts, **config)
    # Said before the screen takes the terminal; the feeder's pipeline closes it with its other sinks.
    fox = start_foxglove(getattr(args, "foxglove", None), source=source.name, baud=opts.baud, models=opts.models,
                         start_time=config["time_anchor"])  # the simulator's times count from 0, not 1970
    if fox is not None:
        app.feeder.pipeline.add(fox)
    app.run()
    return app.return_code or 0
