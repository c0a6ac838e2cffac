"""`rs30x-sniff simulate`: run a scripted bus of emulated servos into a capture file or onto a port."""

from __future__ import annotations

import argparse
import itertools
import sys
from typing import IO
from collections.abc import Iterable

from ..sources.captures import FORMATS, MCAP, format_for_output, write_capture
from ..protocol.memmap import bus_rates
from ..protocol.wire import DEFAULT_BAUD
from .common import CliError, check_positive
from .options import add_format_option, duration
from ..sinks.outputs import STDOUT, output_binary, output_path, write_stream


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="a simulated servo bus: scenarios to a capture file or a port",
                       description="Emulated RS30x servos driven by a scripted host: a healthy hexapod gait, a "
                                   "setup session, or faults the linter should catch. Writes a capture file "
                                   "(-o, times at baud-rate pacing) or plays the bus in real time onto a "
                                   "serial port or pseudo-terminal (--port).")
    p.add_argument("--scenario", default="hexapod", metavar="NAME", help="what to simulate (see --list)")
    p.add_argument("--list", action="store_true", help="list the scenarios and exit")
    p.add_argument("-o", "--output", metavar="FILE",
                   help="capture file to write (.bin/.raw, .hex, .thex/.log timestamped hex, .mcap); - for stdout")
    add_format_option(p, FORMATS, "capture format, if not by extension",
                      aliases=("--output-format",))  # --output-format: its name before every command said --format
    p.add_argument("--port", metavar="PORT",
                   help="play the bus in real time onto a serial device, pty or pyserial URL")
    p.add_argument("--baud", type=int, default=DEFAULT_BAUD, metavar="BPS",
                   help=f"bus baud rate, one of table 4.7 (default {DEFAULT_BAUD})")
    p.add_argument("--duration", type=duration, default=None, metavar="TIME",
                   help="simulated time (30s, 2min; default: the scenario's own length)")
    p.add_argument("--seed", type=int, default=0, metavar="N",
                   help="random seed, a whole number: the same seed gives the same bytes (default 0)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.set_defaults(run=run)


def list_scenarios() -> None:
    from rich.console import Console
    from rich.table import Table

    from ..sim.scenarios import SCENARIOS

    table = Table(box=None, pad_edge=False)
    for col in ("scenario", "servos", "seconds", "lint findings", "what happens"):
        table.add_column(col, overflow="fold")
    for sc in SCENARIOS.values():
        table.add_row(sc.name, str(sc.servos), f"{sc.duration:g}", " ".join(sc.expects) or "none", sc.summary)
    Console(width=max(100, Console().width)).print(table)


def run(args: argparse.Namespace) -> int:
    if args.list:
        list_scenarios()
        return 0
    from ..sim import scenarios

    if args.scenario not in scenarios.SCENARIOS:
        raise CliError(f"--scenario {args.scenario}: unknown (known: {', '.join(scenarios.SCENARIOS)})")
    if args.baud not in bus_rates():
        raise CliError(f"--baud {args.baud}: the servos run at one of {', '.join(map(str, bus_rates()))} (table 4.7, "
                       "and 460800 for models whose baud table has it)")
    check_positive("--duration", args.duration)
    if not args.output and not args.port:
        raise CliError("say where the bus goes: -o FILE, --port PORT, or both")
    played = scenarios.run(args.scenario, baud=args.baud, seed=args.seed, duration=args.duration)
    try:
        first = next(played, None)  # the servos are made here: one whose model lacks the rate says so
    except ValueError as e:
        raise CliError(f"--baud {args.baud}: {e}") from None
    chunks: Iterable[tuple[bytes, float]] = played if first is None else itertools.chain((first,), played)
    if args.output:
        fmt = format_for_output(args.output, args.format)
        if args.port:
            chunks = list(chunks)  # the same bytes go to both
        if fmt == MCAP:
            with output_binary(args.output, force=args.force) as out:  # - streams it to stdout
                n = write_file(out, chunks, fmt, args.baud)
        elif args.output == STDOUT:
            n = write_stream(sys.stdout.buffer, chunks, fmt)
        else:
            with output_path(args.output, force=args.force) as tmp:
                n = write_file(tmp, chunks, fmt, args.baud)
        if not args.port:
            where = "stdout" if args.output == STDOUT else args.output
            print(f"rs30x-sniff: {args.scenario}: {n:,} bytes to {where}", file=sys.stderr)
    if args.port:
        return play_port(args.port, args.baud, chunks, args.scenario)
    return 0


def write_file(path: str | IO[bytes], chunks, fmt: str, baud: int) -> int:
    """Write the simulated chunks as a capture of ``fmt``; an MCAP file is decoded and linted too, by
    the same settings and sink as `convert` (so both give the same file for the same bytes). A write
    error is raised as it is: :func:`output_path` names the output and says what became of it."""
    if fmt == MCAP:
        from ..lint import Linter
        from ..decode.decoder import Decoder
        from ..sinks.pipeline import drive
        from ..settings import resolve
        from .convert import open_mcap_sink

        settings = resolve({"baud": baud})
        sink = open_mcap_sink(path, "rs30x-sniff simulate", settings, timed=True)
        linter = Linter(settings.lint_config(), keep_findings=False)
        dec = drive(chunks, Decoder(settings.decode_options(), linter), sink)
        return dec.bytes_in
    assert isinstance(path, str), "only an MCAP is written to a stream; a capture goes to a named file"
    return write_capture(path, chunks, fmt)


def play_port(port: str, baud: int, chunks, name: str) -> int:
    from ..protocol.wire import byte_time
    from ..sim.port import open_port, play

    try:
        ser = open_port(port, baud)
    except Exception as e:  # noqa: BLE001 - SerialException, OSError, ValueError: all one line
        raise CliError(f"{port}: cannot open port: {' '.join(str(e).split())}") from None
    sent = 0

    def counted_write(data):
        nonlocal sent
        n = ser.write(data)
        sent += len(data) if n is None else n
        return n

    try:
        # Each frame when its last byte is in, as a UART hands it over: a reader stamping arrivals times it true.
        play(chunks, counted_write, byte_seconds=byte_time(baud))
        ser.flush()
    except KeyboardInterrupt:
        print(f"rs30x-sniff: {name}: stopped (Ctrl-C) after {sent:,} bytes to {port}", file=sys.stderr)
        return 0
    except Exception as e:  # noqa: BLE001 - the port went away mid-run
        print(f"rs30x-sniff: error: {port}: port lost ({' '.join(str(e).split())}) after {sent:,} bytes",
              file=sys.stderr)
        return 1
    finally:
        try:
            ser.close()
        except Exception:  # noqa: BLE001
            pass
    print(f"rs30x-sniff: {name}: {sent:,} bytes to {port}", file=sys.stderr)
    return 0
