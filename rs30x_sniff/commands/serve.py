"""`rs30x-sniff serve`: the bus, live on a Foxglove WebSocket server (a port, the simulator, or a replayed capture)."""

from __future__ import annotations

import argparse
import sys
import threading

from ..decode.decoder import Decoder
from ..sinks.pipeline import Pipeline
from .common import CliError, check_positive, is_port_path, live_sinks, make_linter, settings_for
from .options import add_decode_options, add_lint_options
from .live import add_foxglove_option, live_start_time, make_source, start_foxglove


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
