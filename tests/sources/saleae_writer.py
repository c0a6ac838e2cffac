"""Writes captured bytes as Saleae Logic Async Serial exports (Logic 2 tables, Logic 1.x files), for tests and samples.

    python -m tests.sources.saleae_writer IN.thex -o OUT.csv --format logic2 [--radix hex] [--names TX,RX]
        [--name "Async Serial"] [--iso 2026-11-22T14:14:50+00:00] [--flag 12:framing ...] [--echo]
        [--sample-rate 12.5e6]

Each byte gets its own row at its start bit (a chunk's later bytes one byte time apart at --baud).
With two analyzer names, chunks that start FA AF are the host's and go to the first, every other
byte to the second (the bus side); --echo also lists the host's bytes on the bus side, as a bus
analyzer sees them. --flag N:framing|parity marks the N-th byte (0-based) as the analyzer would.
"""

from __future__ import annotations

import argparse
import math
import sys
from datetime import datetime, timedelta
from typing import Iterable, TextIO

from rs30x_sniff.protocol.chunks import FRAMING_ERROR, HOST, PARITY_ERROR, SERVO
from rs30x_sniff.protocol.wire import byte_time

FRAME_BITS = 9.5  # Logic 2's frame: start bit to the middle of the stop bit
_ERRORS = {"framing": FRAMING_ERROR, "parity": PARITY_ERROR, FRAMING_ERROR: FRAMING_ERROR, PARITY_ERROR: PARITY_ERROR}


def byte_rows(chunks: Iterable[tuple[bytes, float | None]], baud: int,
              sample_rate: float | None = None) -> list[tuple[float, int, str]]:
    """(start time, byte, sender) per byte: a chunk that starts FA AF is the host's, any other the servos'.

    With ``sample_rate``, each start is the first sample at or after the start bit's edge, as an
    analyzer sampling at that rate sees it.
    """
    bt = byte_time(baud)
    rows = []
    for data, t in chunks:
        sender = HOST if data[:2] == b"\xfa\xaf" else SERVO
        for k, v in enumerate(data):
            start = (t or 0.0) + k * bt
            if sample_rate:
                start = math.ceil(start * sample_rate - 1e-6) / sample_rate
            rows.append((start, v, sender))
    return rows


def value_text(v: int, radix: str, logic1: bool = False) -> str:
    """A byte as the software shows it in ``radix`` (hex, decimal, binary, ascii)."""
    if radix == "hex":
        return f"0x{v:02X}"
    if radix == "decimal":
        return str(v)
    if radix == "binary":
        return f"0b{v:08b}"
    if radix != "ascii":
        raise ValueError(f"unknown radix {radix!r}")
    named = {13: "\\r", 10: "\\n", 9: "\\t"}
    if v in named:
        return named[v]
    if logic1:
        if v == 0x2C:
            return "COMMA"
        if v == 0x20:
            return "' '"
        return chr(v) if 0x21 <= v <= 0x7E else f"'{v}'"
    if v == 0:
        return "\\0"
    return chr(v) if 0x20 <= v <= 0x7E else f"\\x{v:02X}"


def _quote(s: str) -> str:
    return '"' + s.replace('"', '""') + '"'


def iso_time(start: datetime, t: float) -> str:
    """``start`` + ``t`` seconds as Logic 2's ISO 8601 export writes it, to the nanosecond."""
    total = start.microsecond * 1000 + round(t * 1e9)
    when = start.replace(microsecond=0) + timedelta(seconds=total // 1_000_000_000)
    frac = total % 1_000_000_000
    zone = when.strftime("%z")
    zone = "+00:00" if not zone else f"{zone[:3]}:{zone[3:]}"
    return when.strftime("%Y-%m-%dT%H:%M:%S") + f".{frac:09d}{zone}"


def write_logic2(out: TextIO, rows: list[tuple[float, int, str]], *, baud: int = 115200, radix: str = "hex",
                 names: tuple[str, ...] = ("Async Serial",), iso: datetime | None = None,
                 flags: dict[int, str] | None = None, echo: bool = False, sample_rate: float | None = None) -> int:
    """A Logic 2 data table of ``rows``; one name puts every byte on one analyzer. Returns the rows written.

    Each row's duration is the analyzer's frame (9.5 bit times), in whole samples with ``sample_rate``.
    """
    flags = flags or {}
    frame = FRAME_BITS / baud
    duration = repr(math.floor(frame * sample_rate) / sample_rate if sample_rate else frame)
    table = []
    for i, (t, v, sender) in enumerate(rows):
        err = flags.get(i)
        if len(names) == 1:
            table.append((t, names[0], v, err))
            continue
        table.append((t, names[0] if sender == HOST else names[1], v, err))
        if echo and sender == HOST:
            table.append((t, names[1], v, err))
    with_error = bool(flags)
    out.write("name,type,start_time,duration,data" + (",error" if with_error else "") + "\n")
    for t, name, v, err in table:
        when = iso_time(iso, t) if iso is not None else repr(t)
        data = value_text(v, radix)
        if radix == "ascii":
            data = _quote(data)
        line = f"{_quote(name)},{_quote('data')},{when},{duration},{data}"
        if with_error:
            line += "," + ({FRAMING_ERROR: "framing", PARITY_ERROR: "parity"}[err] if err else "")
        out.write(line + "\n")
    return len(table)


def write_logic1(out: TextIO, rows: list[tuple[float, int, str]], *, radix: str = "hex",
                 flags: dict[int, str] | None = None) -> int:
    """A Logic 1.x Async Serial export of ``rows`` (one analyzer). Returns the rows written."""
    flags = flags or {}
    out.write("Time [s],Value,Parity Error,Framing Error\n")
    for i, (t, v, _) in enumerate(rows):
        err = flags.get(i)
        parity = "Error" if err == PARITY_ERROR else ""
        framing = "Error" if err == FRAMING_ERROR else ""
        out.write(f"{t:.15f},{value_text(v, radix, logic1=True)},{parity},{framing}\n")
    return len(rows)


def main(argv: list[str] | None = None) -> int:
    from rs30x_sniff.sources.captures import read_capture

    p = argparse.ArgumentParser(prog="python -m tests.sources.saleae_writer", description=__doc__.split("\n")[0])
    p.add_argument("input", help="a capture (timestamped hex from `rs30x-sniff simulate`)")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--format", choices=("logic2", "logic1"), default="logic2")
    p.add_argument("--baud", type=int, default=115200)
    p.add_argument("--radix", choices=("hex", "decimal", "binary", "ascii"), default="hex")
    p.add_argument("--names", help="two analyzer names, host's first: TX,RX")
    p.add_argument("--name", default="Async Serial", help="the one analyzer's name")
    p.add_argument("--iso", help="write ISO 8601 times from this wall-clock start")
    p.add_argument("--flag", action="append", default=[], metavar="N:framing|parity")
    p.add_argument("--echo", action="store_true", help="list the host's bytes on the bus analyzer too")
    p.add_argument("--sample-rate", type=float, help="the analyzer's sample rate (S/s): times in whole samples")
    args = p.parse_args(argv)
    rows = byte_rows(read_capture(args.input), args.baud, args.sample_rate)
    flags = {}
    for item in args.flag:
        n, _, kind = item.partition(":")
        flags[int(n)] = _ERRORS[kind]
    with open(args.output, "w", encoding="utf-8", newline="") as out:
        if args.format == "logic1":
            n = write_logic1(out, rows, radix=args.radix, flags=flags)
        else:
            names = tuple(args.names.split(",")) if args.names else (args.name,)
            iso = datetime.fromisoformat(args.iso) if args.iso else None
            n = write_logic2(out, rows, baud=args.baud, radix=args.radix, names=names, iso=iso, flags=flags,
                             echo=args.echo, sample_rate=args.sample_rate)
    print(f"{args.output}: {n} rows", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
