"""Saleae Logic exports of the Async Serial analyzer: Logic 2 data tables and Logic 1.x per-analyzer files.

Two formats are registered:

``saleae`` (Logic 2, "Export Table" of the data table): a CSV with the header
``name,type,start_time,duration,data`` and an optional ``error`` column (``framing`` or ``parity``),
one row of type ``data`` per byte. ``start_time`` is the start bit's edge, in seconds from the
trigger (plain or exponent notation; times before the trigger are negative, and then every time is
moved so that the first byte is at 0), or, with the export's ISO 8601 option, a wall-clock time
(``2026-11-22T14:14:50.000529253+00:00``; ``Z``, ``+0100`` or no zone, local time, also read): those
become seconds after the first row, and the first row's wall-clock time is kept in
``ctx.found["start_time"]`` (an aware datetime). ``duration`` runs from the start bit to the middle of
the stop bit, 9.5 bit times at 8N1 (Saleae's analyzer ends a frame where it samples the stop bit), so
:func:`probe` reads the analyzer's bit rate off it. ``--input-format saleae`` also reads a Logic 1.x
file.

``saleae-v1`` (Logic 1.x, the analyzer's "Export as text/csv file"): the header
``Time [s],Value,Parity Error,Framing Error``, one line per byte, ``Error`` in the flagged column.

Byte values may be in any display radix the software offers: hex (``0xC8``), decimal (``200``),
binary (``0b11001000``) or ASCII (the character; ``\\r``, ``\\n``, ``\\t``, ``\\0``, ``\\xC8``; Logic
1.x's ``'8'`` for a control byte, ``' '`` and ``COMMA``). A table is in one radix, told by its first
value that can only be one (a lone digit could be decimal or ASCII: read as decimal if nothing else
tells). Hex is the one to export: the software's ASCII view may show different control bytes alike.
A byte the analyzer flagged becomes a chunk of its own with ``error`` set (garbage with that reason).

Who sent the bytes: a table with one analyzer says nothing. With two (the host's TX pin and the bus or
the host's RX pin, say), each analyzer's ``name`` is read first: a party word (``host``, ``master``,
``mcu``, ``controller``, ``pc`` / ``servo``, ``slave``, ``device``) says who, ``TX`` or ``RX`` after it
says that party sends or receives (``Host RX`` is the servos' bytes), two parties are read as "from
the first to the second" (``host->servo``), and a bare ``TX`` is the host's and ``RX`` the servos'
(named from the host's UART, as the wires are). If one name tells, the other analyzer is the other
party. If neither does (``Async Serial [1]``, ``Async Serial [2]``), the content does: the analyzer
that carries a return header (``FD DF``) is the servos' side, else the one alone in carrying a request
header (``FA AF``) is the host's; the first 4096 rows are looked at, then the bytes go on with no
sender (said once). The host's own bytes, echoed on the bus analyzer within half a byte of the same
byte on the host's, are dropped there (counted in ``ctx.found["echo_bytes"]``). A third analyzer in
one table is an error.
"""

from __future__ import annotations

import codecs
import contextlib
import csv
import io
import itertools
import math
import os
import re
from datetime import datetime, timedelta, timezone, UTC
from typing import Any, BinaryIO
from collections.abc import Callable, Iterable, Iterator

from ..protocol.chunks import FRAMING_ERROR, HOST, PARITY_ERROR, SERVO, Marked
from .timebase import FIRST
from ..protocol.memmap import bus_rates
from ..protocol.wire import BITS_PER_BYTE, REQUEST_HEADER, RETURN_HEADER
from .captures import CaptureError
from .foreign import ForeignFormat, ReadContext, register

LOGIC2, LOGIC1 = "saleae", "saleae-v1"
# The two bytes of each header as consecutive rows carry them (one value a row): (0xFA, 0xAF), (0xFD, 0xDF).
_REQUEST_PAIR = tuple(REQUEST_HEADER)
_RETURN_PAIR = tuple(RETURN_HEADER)

_LOGIC2_COLUMNS = ("name", "type", "start_time", "duration", "data")
_LOGIC2_OPTIONAL = ("error",)
_LOGIC1_COLUMNS = ("time [s]", "value", "parity error", "framing error")
# Logic 2's frame: start bit to the middle of the stop bit (8N1, one stop bit).
FRAME_BITS = 9.5
DECIDE_ROWS = 4096   # rows looked at to tell which analyzer is the host's, when the names do not say
PROBE_ROWS = 4096    # rows probe() reads for the bit rate
MATCH = 0.05         # a duration within this factor of a rate's frame time names that rate
AGREE = 0.90         # share of durations that must sit within MATCH of their median


# ---- sniffing ------------------------------------------------------------------------------------
def _first_line(head: bytes) -> str | None:
    line = head.split(b"\n", 1)[0].rstrip(b"\r")
    if line.startswith(codecs.BOM_UTF8):
        line = line[len(codecs.BOM_UTF8):]
    try:
        return line.decode("utf-8")
    except UnicodeDecodeError:
        return None


def _columns(line: str) -> list[str]:
    try:
        row = next(csv.reader([line]))
    except (csv.Error, StopIteration):
        return []
    return [c.strip().lower() for c in row]


def _logic2_header(cols: list[str]) -> bool:
    """Columns a Logic 2 Async Serial table may have: the core ones, start_time and data at least."""
    allowed = set(_LOGIC2_COLUMNS) | set(_LOGIC2_OPTIONAL)
    return len(set(cols)) == len(cols) and set(cols) <= allowed and {"start_time", "data"} <= set(cols)


def sniff_logic2(head: bytes) -> bool:
    """Exactly the Logic 2 export's header (any order): all five default columns, and error if any."""
    line = _first_line(head)
    if line is None:
        return False
    cols = _columns(line)
    return _logic2_header(cols) and set(_LOGIC2_COLUMNS) <= set(cols)


def sniff_logic1(head: bytes) -> bool:
    line = _first_line(head)
    return line is not None and tuple(c.strip().lower() for c in line.split(",")) == _LOGIC1_COLUMNS


# ---- byte values in each radix -------------------------------------------------------------------
HEX, DEC, BIN, ASCII = "hex", "decimal", "binary", "ASCII"
_HEX = re.compile(r"0[xX]([0-9A-Fa-f]{1,2})")
_BIN = re.compile(r"0[bB]([01 _]{1,12})")
_DEC = re.compile(r"[0-9]{1,3}")
_ASCII_NAMES = {"\\0": 0, "\\a": 7, "\\b": 8, "\\t": 9, "\\n": 10, "\\v": 11, "\\f": 12, "\\r": 13, "\\e": 27,
                "\\\\": 92, "\\'": 39, '\\"': 34, "COMMA": 44, "' '": 32}
_ASCII_HEX = re.compile(r"\\[xX]([0-9A-Fa-f]{2})")
_ASCII_QUOTED_NUMBER = re.compile(r"'([0-9]{1,3})'")  # Logic 1.x: a control byte as its decimal value
_ASCII_QUOTED_CHAR = re.compile(r"'(.)'", re.S)


class _BadValue(ValueError):
    pass


def _hex(cell: str) -> int:
    m = _HEX.fullmatch(cell.strip())
    if m is None:
        raise _BadValue(f"not a hex byte: {_show(cell)} (the table's values are hex, as 0xC8)")
    return int(m.group(1), 16)


def _dec(cell: str) -> int:
    s = cell.strip()
    if _DEC.fullmatch(s) is None or int(s) > 255:
        raise _BadValue(f"not a decimal byte 0-255: {_show(cell)} (the table's values are decimal)")
    return int(s)


def _bin(cell: str) -> int:
    m = _BIN.fullmatch(cell.strip())
    bits = m.group(1).replace(" ", "").replace("_", "") if m else ""
    if not bits or len(bits) > 8:
        raise _BadValue(f"not a binary byte: {_show(cell)} (the table's values are binary, as 0b11001000)")
    return int(bits, 2)


def _ascii(cell: str) -> int:
    if len(cell) == 1:
        c = ord(cell)
        if 0xDC80 <= c <= 0xDCFF:  # a byte that was not UTF-8 (surrogateescape): the byte itself
            return c - 0xDC00
        if c <= 0xFF:
            return c
        raise _BadValue(f"character {_show(cell)} is not one byte")
    v = _ASCII_NAMES.get(cell)
    if v is not None:
        return v
    for pattern, base in ((_ASCII_HEX, 16), (_ASCII_QUOTED_NUMBER, 10)):
        m = pattern.fullmatch(cell)
        if m is not None and int(m.group(1), base) <= 255:
            return int(m.group(1), base)
    m = _ASCII_QUOTED_CHAR.fullmatch(cell)
    if m is not None:
        return _ascii(m.group(1))
    raise _BadValue(f"not a byte: {_show(cell)}" if cell else "no byte value")


_PARSERS = {HEX: _hex, DEC: _dec, BIN: _bin, ASCII: _ascii}
_TABLES = {
    HEX: {f"0{x}{v:02{h}}": v for v in range(256) for x in "xX" for h in "Xx"},
    DEC: {str(v): v for v in range(256)},
    BIN: {f"0b{v:08b}": v for v in range(256)},
    ASCII: {chr(v): v for v in range(0x21, 0x7F)},
}


def _radix_of(cell: str) -> str | None:
    """The radix a first value can only be in (None for a lone digit: decimal or ASCII)."""
    s = cell.strip()
    if s[:2] in ("0x", "0X") and len(s) > 2:
        return HEX
    if s[:2] in ("0b", "0B") and len(s) > 2 and _BIN.fullmatch(s):
        return BIN
    if len(s) > 1 and s.isdigit():
        return DEC
    if len(cell) == 1 and cell.isdigit():
        return None
    return ASCII


# ---- times ---------------------------------------------------------------------------------------
_ISO = re.compile(r"\s*(\d{4}-\d{2}-\d{2})[T ](\d{2}):(\d{2}):(\d{2})(?:[.,](\d{1,12}))?\s*"
                  r"(Z|z|[+-]\d{2}(?::?\d{2})?)?\s*")


def _seconds(cell: str) -> float:
    try:
        t = float(cell)
    except ValueError:
        raise _BadValue(f"not a time in seconds: {_show(cell)}") from None
    if t - t != 0 or "_" in cell:  # nan and inf; float() reads 1_000, which no tool writes
        raise _BadValue(f"not a finite time in seconds: {_show(cell)}")
    return t


class _IsoClock:
    """ISO 8601 times as nanoseconds since the epoch (exact to the digits given), whole seconds cached."""

    def __init__(self) -> None:
        self._cache: dict[tuple[str, str, str, str, str | None], tuple[int, Any]] = {}

    def parse(self, cell: str) -> tuple[int, Any]:
        m = _ISO.fullmatch(cell)
        if m is None:
            raise _BadValue(f"not an ISO 8601 time: {_show(cell)}")
        date, hh, mm, ss, frac, zone = m.groups()
        key = (date, hh, mm, ss, zone)
        hit = self._cache.get(key)
        if hit is None:
            try:
                when = datetime.fromisoformat(f"{date}T{hh}:{mm}:{ss}")
            except ValueError:
                raise _BadValue(f"not a valid date and time: {_show(cell)}") from None
            tz = _zone(zone)
            when = when.replace(tzinfo=tz) if tz is not None else when.astimezone()  # no zone: local time
            if len(self._cache) > 4096:
                self._cache.clear()
            hit = self._cache[key] = (int(when.timestamp()) * 1_000_000_000, when.tzinfo)
        ns = hit[0] + (int(frac.ljust(9, "0")[:9]) if frac else 0)
        return ns, hit[1]


def _zone(zone: str | None) -> timezone | None:
    if zone is None:
        return None
    if zone in ("Z", "z"):
        return UTC
    sign = -1 if zone[0] == "-" else 1
    digits = zone[1:].replace(":", "")
    minutes = int(digits[:2]) * 60 + (int(digits[2:4]) if len(digits) > 2 else 0)
    return timezone(sign * timedelta(minutes=minutes))


def _wall_clock(ns: int, tz: Any) -> datetime:
    return datetime.fromtimestamp(ns // 1_000_000_000, tz) + timedelta(microseconds=(ns % 1_000_000_000) // 1000)


def _show(cell: str) -> str:
    return repr(cell[:24])


# ---- rows ----------------------------------------------------------------------------------------
# One byte as a table gives it: (t, value, analyzer name, error, duration or None, line number).
Row = tuple


def _error_of(cell: str) -> str | None:
    s = cell.strip().lower()
    if not s:
        return None
    if "framing" in s:  # the stop bit was low: the worse of the two when both are flagged
        return FRAMING_ERROR
    if "parity" in s:
        return PARITY_ERROR
    raise _BadValue(f"unknown error {_show(cell)} (the Async Serial analyzer writes framing or parity)")


class _Values:
    """Cells to bytes in the table's radix, which the first cell that can only be one radix decides."""

    def __init__(self) -> None:
        self.radix: str | None = None
        self.parse: Callable[[str], int] | None = None
        self.table: dict[str, int] = {}  # the radix's usual spellings, looked up before parsing

    def decide(self, cell: str) -> bool:
        radix = _radix_of(cell)
        if radix is None:
            return False
        self.set(radix)
        return True

    def set(self, radix: str) -> None:
        self.radix, self.parse, self.table = radix, _PARSERS[radix], _TABLES[radix]


def _logic2_rows(lines: Iterable[str], ctx: ReadContext) -> Iterator[Row]:
    """The rows of a Logic 2 table, its header line first."""
    path = ctx.path
    reader = csv.reader(lines)
    try:
        cols = [c.strip().lower() for c in next(reader, [])]
    except csv.Error as e:
        raise CaptureError(f"{path}:1: not CSV: {e}", line=1) from None
    if not _logic2_header(cols):
        extra = [c for c in cols if c not in _LOGIC2_COLUMNS and c not in _LOGIC2_OPTIONAL]
        why = (f"column {extra[0]!r} is not the Async Serial analyzer's (export its table alone)" if extra else
               "the header needs start_time and data columns, each once")
        raise CaptureError(f"{path}:1: not a Saleae Logic 2 Async Serial table: {why}", line=1)
    at = {c: i for i, c in enumerate(cols)}
    i_name, i_type, i_dur, i_err = at.get("name"), at.get("type"), at.get("duration"), at.get("error")
    i_time, i_data = at["start_time"], at["data"]
    ncols = len(cols)
    # A row may stop before a trailing optional column (an empty error cell left out).
    short_ok = ncols - 1 if cols[-1] in _LOGIC2_OPTIONAL else ncols
    values = _Values()
    pending: list[tuple] = []  # rows whose value waits for the radix to be told
    iso = None                 # decided by the first row: ISO 8601 times or seconds
    clock = _IsoClock()
    origin: Any = None         # ns of the first row (ISO), or the shift of a pre-trigger capture
    line = last = 1
    try:
        for row in reader:
            line, last = last + 1, reader.line_num  # a quoted cell may span lines: name the row's first
            if not row or (len(row) == 1 and not row[0].strip()):
                continue
            n = len(row)
            if n != ncols:
                if short_ok <= n < ncols:
                    row = row + [""] * (ncols - n)
                else:
                    raise _BadValue(f"expected {ncols} fields, got {n}")
            if i_type is not None and row[i_type] != "data" and row[i_type].strip().lower() != "data":
                raise _BadValue(f"a row of type {_show(row[i_type])}: the Async Serial analyzer writes only "
                                "'data' rows (export its table alone)")
            cell = row[i_time]
            if iso is None:
                iso = _ISO.fullmatch(cell) is not None
            if iso:
                ns, tz = clock.parse(cell)
                if origin is None:
                    origin = ns
                    ctx.found["start_time"] = _wall_clock(ns, tz)
                t = (ns - origin) / 1e9
            else:
                t, origin = _after_trigger(_seconds(cell), origin, ctx, "table")
            dur = _seconds(row[i_dur]) if i_dur is not None and row[i_dur] else None
            err = _error_of(row[i_err]) if i_err is not None and row[i_err] else None
            name = row[i_name] if i_name is not None else ""
            yield from _valued(values, pending, path, (t, row[i_data], name, err, dur, line))
    except _BadValue as e:
        raise CaptureError(f"{path}:{line}: {e}", line=line) from None
    except csv.Error as e:
        raise CaptureError(f"{path}:{last + 1}: not CSV: {e}", line=last + 1) from None
    if pending:
        values.set(DEC)  # nothing but lone digits: read as decimal
        yield from _decided(pending, values, path)


def _valued(values: _Values, pending: list[tuple], path: str, row: tuple) -> Iterator[Row]:
    """A row ``(t, cell, name, err, dur, line)`` with its cell read as a byte, once the table's radix is
    known; until then rows wait in ``pending`` (a lone digit fits several radixes) and go out first."""
    t, cell, name, err, dur, line = row
    v = values.table.get(cell)
    if v is None:
        if values.parse is None and not values.decide(cell):
            pending.append(row)
            return
        v = values.table.get(cell)
        if v is None:
            parse = values.parse
            assert parse is not None  # the radix is decided (above), so its parser is set
            v = parse(cell)
    if pending:
        yield from _decided(pending, values, path)
        pending.clear()
    yield t, v, name, err, dur, line


def _decided(pending: list[tuple], values: _Values, path: str) -> Iterator[Row]:
    parse = values.parse
    assert parse is not None  # called once the radix is decided
    for t, cell, name, err, dur, line in pending:
        try:
            yield t, parse(cell), name, err, dur, line
        except _BadValue as e:
            raise CaptureError(f"{path}:{line}: {e}", line=line) from None


def _logic1_rows(lines: Iterable[str], ctx: ReadContext, first_line: int = 2) -> Iterator[Row]:
    """The rows of a Logic 1.x export, after its header line."""
    path = ctx.path
    values = _Values()
    pending: list[tuple] = []
    origin: float | None = None
    line = first_line - 1
    try:
        for line, text in enumerate(lines, first_line):
            text = text.rstrip("\r\n")
            if not text.strip():
                continue
            # No quoting in this format (a comma value is written COMMA), so a plain split is exact.
            fields = text.split(",")
            if len(fields) != 4:
                raise _BadValue(f"expected 4 fields (Time [s],Value,Parity Error,Framing Error), got {len(fields)}")
            t, origin = _after_trigger(_seconds(fields[0]), origin, ctx, "export")
            parity, framing = fields[2].strip(), fields[3].strip()
            for cell in (parity, framing):
                if cell and cell.lower() != "error":
                    raise _BadValue(f"an error cell holds {_show(cell)}, not Error or nothing")
            err = FRAMING_ERROR if framing else PARITY_ERROR if parity else None
            yield from _valued(values, pending, path, (t, fields[1], "", err, None, line))
    except _BadValue as e:
        raise CaptureError(f"{path}:{line}: {e}", line=line) from None
    if pending:
        values.set(DEC)
        yield from _decided(pending, values, path)


# ---- who sent it ---------------------------------------------------------------------------------
_HOST_WORDS = {"host", "master", "mcu", "controller", "pc", "cpu"}
_SERVO_WORDS = {"servo", "servos", "slave", "device", "motor", "motors"}
_TX_WORDS = {"tx", "txd", "transmit", "send", "out", "request", "requests", "cmd", "command", "commands"}
_RX_WORDS = {"rx", "rxd", "receive", "recv", "in", "reply", "replies", "return", "returns", "response",
             "responses"}


def sender_of_name(name: str) -> str | None:
    """Who an analyzer's name says sends its bytes (None when it does not say); see the module doc."""
    words = re.findall(r"[a-z]+", name.lower())
    parties = [HOST if w in _HOST_WORDS else SERVO for w in words if w in _HOST_WORDS or w in _SERVO_WORDS]
    tx = any(w in _TX_WORDS for w in words)
    rx = any(w in _RX_WORDS for w in words)
    if len(set(parties)) > 1:
        return parties[0]  # "host -> servo", "servo to host": from the first to the second
    other = {HOST: SERVO, SERVO: HOST}
    if parties:
        if tx == rx:
            return parties[0]
        return parties[0] if tx else other[parties[0]]
    if tx != rx:
        return HOST if tx else SERVO
    return None


class _Senders:
    """Tells which analyzer of a table is the host's (by names, else by content) and marks the rows."""

    def __init__(self, ctx: ReadContext) -> None:
        self.ctx = ctx
        self.names: list[str] = []
        self.map: dict[str, str | None] | None = None
        self._last: dict[str, int] = {}
        self._requests: dict[str, int] = {}
        self._returns: dict[str, int] = {}

    def run(self, rows: Iterable[Row]) -> Iterator[tuple]:
        buf: list[Row] = []
        for row in rows:
            name = row[2]
            if name not in self.names:
                self._new_name(name, row[5])
            if self.map is None:
                buf.append(row)
                self._look(row)
                self._set(self._by_names() or self._by_content(final=len(buf) >= DECIDE_ROWS))
                if self.map is None:
                    continue
                for r in buf:
                    yield r[0], r[1], self.map.get(r[2]), r[3], r[4]
                buf = []
                continue
            yield row[0], row[1], self.map.get(name), row[3], row[4]
        if self.map is None:
            self._set(self._by_content(final=True) or {})
        assert self.map is not None  # _set just gave it one (empty at worst)
        for r in buf:
            yield r[0], r[1], self.map.get(r[2]), r[3], r[4]

    def _new_name(self, name: str, line: int) -> None:
        if len(self.names) == 2:
            a, b = self.names
            raise CaptureError(f"{self.ctx.path}:{line}: a third analyzer {name!r} (after {a!r} and {b!r}): "
                               "export only the RS30x bus's analyzers, one or two", line=line)
        self.names.append(name)
        if self.map is not None and len(self.names) == 2:
            # A second analyzer after the first was taken alone: its name, or the first's, may tell.
            self._set(self._by_names() or {})
            if not self.map:
                self._undecided()

    def _set(self, senders: dict[str, str | None] | None) -> None:
        self.map = senders
        if senders:
            self.ctx.found["analyzers"] = dict(senders)  # told as soon as known (info, the monitor)

    def _look(self, row: Row) -> None:
        name, v = row[2], row[1]
        prev = self._last.get(name)
        self._last[name] = v if row[3] is None else -1
        if (prev, v) == _REQUEST_PAIR:
            self._requests[name] = self._requests.get(name, 0) + 1
        elif (prev, v) == _RETURN_PAIR:
            self._returns[name] = self._returns.get(name, 0) + 1

    def _by_names(self) -> dict[str, str | None] | None:
        if len(self.names) != 2:
            return None
        a, b = self.names
        sa, sb = sender_of_name(a), sender_of_name(b)
        other = {HOST: SERVO, SERVO: HOST}
        if sa is not None and sa != sb:
            return {a: sa, b: other[sa]}
        if sb is not None and sa is None:
            return {a: other[sb], b: sb}
        return None

    def _by_content(self, final: bool) -> dict[str, str | None] | None:
        if len(self.names) < 2:
            return {} if final else None  # one analyzer: it says nothing about direction
        a, b = self.names
        other = {a: b, b: a}
        returns = [n for n in self.names if self._returns.get(n)]
        if len(returns) == 1:
            return {returns[0]: SERVO, other[returns[0]]: HOST}
        if final:
            requests = [n for n in self.names if self._requests.get(n)]
            if len(requests) == 1 and not returns:
                return {requests[0]: HOST, other[requests[0]]: SERVO}
            self._undecided()
            return {}
        return None

    def _undecided(self) -> None:
        if self.ctx.warn is not None:
            a, b = self.names
            self.ctx.warn(f"{self.ctx.path}: cannot tell which of the analyzers {a!r} and {b!r} is the host's "
                          "(name one of them host or TX): read without senders")


def _drop_echoes(rows: Iterable[tuple], ctx: ReadContext) -> Iterator[tuple]:
    """The host's bytes as the bus analyzer sees them too, at the same time: kept once, as the host's.

    A servo-side byte is held until the next row, so an echo that the table lists just before the
    host's byte is caught as well as one listed just after.
    """
    held: tuple | None = None     # the last servo-side row, not yet passed on
    last_host: tuple | None = None
    dropped = 0
    for row in rows:
        sender = row[2]
        if sender == HOST:
            if held is not None:
                if _same_byte(held, row):
                    dropped += 1
                else:
                    yield held
                held = None
            last_host = row
            yield row
        elif sender == SERVO:
            if last_host is not None and _same_byte(row, last_host):
                dropped += 1
                continue
            if held is not None:
                yield held
            held = row
        else:
            if held is not None:
                yield held
                held = None
            yield row
    if held is not None:
        yield held
    if dropped:
        ctx.found["echo_bytes"] = dropped


def _same_byte(a: tuple, b: tuple) -> bool:
    if a[1] != b[1] or a[3] is not None or b[3] is not None:
        return False
    d = a[4] or b[4]
    return d is not None and abs(a[0] - b[0]) < d / 2


def _chunks(rows: Iterable[tuple], baud: int | None) -> Iterator[Any]:
    """Bytes as chunks: a run of one sender's bytes that start back to back at ``baud`` is one chunk.

    The decoder places a chunk's later bytes one byte time apart at its baud, so a byte joins the run
    only if its own start time is within a quarter bit of that place (a sender whose clock is a little
    off starts a new chunk rather than drifting). Without the decoder's baud (``None``), and for every
    byte the UART flagged, each byte is a chunk of its own, at its own time.
    """
    bt = BITS_PER_BYTE / baud if baud else None
    tol = bt / (4 * BITS_PER_BYTE) if bt else 0.0
    run = bytearray()
    t0 = 0.0
    who = None
    for t, v, sender, err, _ in rows:
        if run:
            if err is None and sender == who and bt is not None and abs(t - t0 - len(run) * bt) <= tol:
                run.append(v)
                continue
            yield (bytes(run), t0) if who is None else Marked(bytes(run), t0, sender=who)
            run.clear()
        if err is not None:
            yield Marked(bytes((v,)), t, sender=sender, error=err)
            continue
        run.append(v)
        t0, who = t, sender
    if run:
        yield (bytes(run), t0) if who is None else Marked(bytes(run), t0, sender=who)


def _baud(ctx: ReadContext) -> int | None:
    baud = ctx.options.get("baud")
    return baud if isinstance(baud, int) and baud > 0 else None


# ---- reading -------------------------------------------------------------------------------------
def _text(stream: BinaryIO) -> io.TextIOWrapper:
    # surrogateescape: a byte that is not UTF-8 (an ASCII-radix export on Windows) reaches the value
    # parser as itself, and a bad byte elsewhere is reported with its line like any other bad cell.
    return io.TextIOWrapper(stream, encoding="utf-8", errors="surrogateescape", newline="")


@contextlib.contextmanager
def _table(stream: BinaryIO) -> Iterator[tuple[io.TextIOWrapper, str, bool]]:
    """The export as text, its header line (without a BOM) and whether that is Logic 1.x's; the
    stream is handed back, not closed, at the end."""
    text = _text(stream)
    try:
        first = text.readline()
        first = first[1:] if first.startswith("\ufeff") else first
        logic1 = tuple(c.strip().lower() for c in first.rstrip("\r\n").split(",")) == _LOGIC1_COLUMNS
        yield text, first, logic1
    finally:
        text.detach()


def _rows(text: io.TextIOWrapper, first: str, logic1: bool, ctx: ReadContext) -> Iterator[tuple]:
    """The rows of either kind of export, after its header line ``first``."""
    if logic1:
        return _logic1_rows(text, ctx)
    return _logic2_rows(itertools.chain((first,), text), ctx)


def _after_trigger(t: float, origin: float | None, ctx: ReadContext, what: str) -> tuple[float, float]:
    """``t`` from the trigger moved so that a capture starting before it starts at 0, and the origin
    (found at the first row, which is warned about when it moves the times)."""
    if origin is None:
        origin = min(t, 0.0)
        if origin < 0 and ctx.warn is not None:
            ctx.warn(f"{ctx.path}: the {what} starts {-t:.6f} s before the trigger: times moved so that its "
                     "first byte is at 0")
    return t - origin, origin


def read_logic2(stream: BinaryIO, ctx: ReadContext) -> Iterator[Any]:
    """Chunks of a Logic 2 data table (or, given a Logic 1.x export, of that)."""
    with _table(stream) as (text, first, logic1):
        if not first.strip():
            return
        yield from _chunks(_drop_echoes(_Senders(ctx).run(_rows(text, first, logic1, ctx)), ctx), _baud(ctx))


def read_logic1(stream: BinaryIO, ctx: ReadContext) -> Iterator[Any]:
    """Chunks of a Logic 1.x Async Serial export."""
    with _table(stream) as (text, first, logic1):
        if not first.strip():
            return
        if not logic1:
            hint = " (a Logic 2 table: --input-format saleae)" if _logic2_header(_columns(first)) else ""
            raise CaptureError(f"{ctx.path}:1: not a Saleae Logic 1.x export: the header is not "
                               f"'Time [s],Value,Parity Error,Framing Error'{hint}", line=1)
        rows = ((t, v, None, err, dur) for t, v, _, err, dur, _ in _logic1_rows(text, ctx))
        yield from _chunks(rows, _baud(ctx))


# ---- the bit rate --------------------------------------------------------------------------------
def probe(path: str, options: dict[str, Any]) -> dict[str, Any]:
    """The bus rate the file shows: Logic 2's frame durations, else back-to-back bytes' spacing."""
    if path == "-" or not os.path.isfile(path):
        return {}  # a pipe is read once, by the reader
    try:
        with open(path, "rb") as f, _table(f) as (text, first, logic1):
            rows = list(itertools.islice(_rows(text, first, logic1, ReadContext(path)), PROBE_ROWS))
    except (OSError, CaptureError, UnicodeError):
        return {}  # the reader says what is wrong, where
    durations = [r[4] for r in rows if r[4] is not None and r[4] > 0]
    if durations:
        return _from_durations(durations)
    return _from_spacing(rows)


def _from_durations(durations: list[float]) -> dict[str, Any]:
    durations.sort()
    mid = durations[len(durations) // 2]
    agree = sum(1 for d in durations if abs(d / mid - 1) <= MATCH) / len(durations)
    bit = mid / FRAME_BITS
    seen = (f"{len(durations)} frame durations, median {mid * 1e6:.2f} us "
            f"({FRAME_BITS:g} bit times: {1 / bit:,.0f} bit/s)")
    if agree < AGREE:
        return {"baud_note": f"{seen}, but only {agree:.0%} within {MATCH:.0%} of it: no one rate"}
    best = min(bus_rates(), key=lambda r: abs(math.log(bit * r)))
    if abs(bit * best - 1) > MATCH:
        return {"baud_note": f"{seen}: no rate of table 4.7 within {MATCH:.0%}"}
    return {"baud": best, "baud_note": f"the analyzer's bit rate, from {seen}"}


def _from_spacing(rows: list[Row]) -> dict[str, Any]:
    from ..protocol.baud import estimate_baud  # the same estimate as for timestamped hex

    est = estimate_baud((bytes((r[1],)), r[0]) for r in rows)
    if est.baud is None:
        return {"baud_note": est.evidence} if est.samples else {}
    return {"baud": est.baud, "baud_note": f"back-to-back bytes: {est.evidence}"}


register(ForeignFormat(LOGIC2, "Saleae Logic 2 Async Serial data table (CSV; also reads Logic 1.x exports)",
                       sniff_logic2, read_logic2, FIRST, probe=probe))
register(ForeignFormat(LOGIC1, "Saleae Logic 1.x Async Serial export (Time [s],Value,Parity Error,Framing Error)",
                       sniff_logic1, read_logic1, FIRST, probe=probe))

