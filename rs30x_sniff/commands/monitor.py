"""`rs30x-sniff monitor`: the live timeline of the bus in a terminal UI (a capture file, a port, or the simulator)."""

from __future__ import annotations

import argparse
import os
import stat

from ..io.captures import CaptureError
from .common import CliError, add_decode_options, decode_options


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("monitor", help="watch the bus in a terminal UI",
                       description="A live timeline of the bus: every packet explained, every problem flagged, "
                                   "every servo's state at a glance. Press ? in the monitor for its keys.")
    p.add_argument("input", metavar="INPUT", nargs="?",
                   help="capture file (.bin/.raw, .hex, timestamped hex, .mcap) or serial port (/dev/ttyUSB0, COM3)")
    add_decode_options(p)
    p.add_argument("--replay", action="store_true", help="play a capture file at its own pace instead of at once")
    p.add_argument("--speed", type=float, default=1.0, metavar="X", help="replay X times faster (default 1)")
    p.add_argument("--simulate", metavar="SCENARIO", help="watch the built-in simulator run SCENARIO instead of INPUT")
    p.add_argument("--history", type=int, default=None, metavar="N",
                   help="records kept for scrolling back (default 1,000,000; older ones are dropped)")
    p.add_argument("--record-dir", default=".", metavar="DIR", help="where `r` writes MCAP recordings (default .)")
    p.set_defaults(run=run)


def _is_port(path: str) -> bool:
    """A serial device rather than a capture file: a character device, or a Windows COM name."""
    if path.upper().startswith("COM") and path[3:].isdigit():
        return True
    try:
        return stat.S_ISCHR(os.stat(path).st_mode)
    except OSError:
        return path.startswith("/dev/")


def make_source(args: argparse.Namespace, baud: int):
    """The source the command line asks for, opened now so a bad one fails before the screen starts."""
    from ..tui.feed import FileSource, ReplaySource

    if args.simulate:
        if args.input:
            raise CliError("give either INPUT or --simulate SCENARIO, not both")
        return _simulator_source(args.simulate, baud)
    if not args.input:
        raise CliError("monitor needs INPUT (a capture file or a serial port) or --simulate SCENARIO")
    if _is_port(args.input):
        if args.replay:
            raise CliError("--replay plays a capture file; a port is live already")
        return _port_source(args.input, baud)
    if args.replay:
        return ReplaySource(args.input, args.input_format, speed=args.speed, baud=baud)
    return FileSource(args.input, args.input_format)


def _port_source(port: str, baud: int):
    try:
        from ..tui.sources import PortSource
    except ImportError:
        raise CliError(f"{port}: live ports need the serial tap (rs30x_sniff.io.serial_tap), "
                       "which this installation lacks") from None
    return PortSource(port, baud)


def _simulator_source(scenario: str, baud: int):
    try:
        from ..tui.sources import SimulatorSource
    except ImportError:
        raise CliError("--simulate needs the simulator (rs30x_sniff.sim), which this installation lacks") from None
    return SimulatorSource(scenario, baud)


def run(args: argparse.Namespace) -> int:
    opts = decode_options(args)
    if not args.speed > 0:
        raise CliError(f"--speed {args.speed}: must be positive")
    if args.history is not None and args.history < 1:
        raise CliError(f"--history {args.history}: must be at least 1")
    if not os.path.isdir(args.record_dir):
        raise CliError(f"--record-dir {args.record_dir}: no such directory")
    try:
        source = make_source(args, opts.baud)
    except CaptureError:
        raise
    except OSError as e:
        raise CliError(f"{args.input}: {e.strerror or e}") from None
    from ..tui.app import make_app  # Textual is imported only when the screen is about to start

    config = {"record_dir": args.record_dir}
    if args.history is not None:
        config["history"] = args.history
    app = make_app(source, opts, **config)
    app.run()
    return app.return_code or 0
