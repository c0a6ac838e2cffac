"""Serial loggers' logs (pyserial spy://, socat -x, interceptty, jpnevulator, slsnif) as chunks saying who sent them.

These tools sit on the host's port (or on a pty in front of it) and write one entry per read or write
call, so each entry is one chunk, marked with its sender (:class:`rs30x_sniff.protocol.chunks.Marked`):

- ``spy``: pyserial's ``spy://`` hex dump (FormatHexdump). Host: ``TX``, what the program wrote.
  Times: seconds since the port opened, to the millisecond. No wall clock. Control lines (``RTS``,
  ``Q-RX`` ...) and ``RX <empty>`` are skipped.
- ``socat``: ``socat -x -v`` (or ``-x``) on stderr. Host: the side whose first block is a request
  (``>`` is whatever the first address sent). Times: wall clock; ``start_time`` is the first block's.
  Its ``-d`` diagnostics are skipped; a block's ``from=``/``to=`` must follow on from the last.
- ``interceptty``: a line a byte, ``< 0xfa`` from the program (front device, the host) and ``>``,
  a tab and ``0xfd`` from the device. Times: only in builds that stamp (``[HH:MM SS.uuuuuu]``), a time
  of day without a date, so no ``start_time``; without stamps a read is a run of one direction.
- ``jpnevulator``: ``--read --timing-print`` (with ``--ascii``, ``--byte-count``, ``--base=2``,
  any ``--width``). Host: the device (alias) whose first group is a request; one device makes no
  claim. Times: wall clock; ``start_time`` is the first timing line's.
- ``slsnif``: ``Host   --> `` (host) and ``Device --> `` lines of ``c (xx)`` (``-x``) or ``c (ddd)``
  items. No times (below); ``start_time`` is its first ``-t`` stamp, to the second.

**Direction.** A logger on the host's port sees what the host program wrote on one side and what it
read on the other. spy://, interceptty and slsnif name those sides themselves, so their words map to
host and servo; when the log is the other way round (the program was a servo emulator), the direction
check F009 says so. socat's ``>``/``<`` only say "from the first address" and "from the second", and
jpnevulator's devices are whatever the user named them, so for those two the content decides: the
side whose first chunk starts with a request header (FA AF) is the host's. Until one does, chunks
are held (up to :data:`_HOLD` of them), and a log where none does makes no claim (plain chunks).
A one-wire half-duplex adapter reads back what the host sends: bytes on a servo side that repeat,
in order, what the host side has just written are that echo, the same bytes on the wire, and are
dropped (counted in ``ctx.found["echo_bytes"]``).

**Times.** Each tool stamps an entry when its read returned, i.e. when the last byte had arrived:
``time_ref`` is ARRIVAL, and the reading commands lay each chunk back to its first byte. Where a
tool stamps otherwise, the reader moves the time to the arrival, at the baud rate of
``ctx.options["baud"]`` (else 115200):

- pyserial stamps a ``TX`` entry *before* the write, about its first byte: moved on by its bytes'
  time. Its stamps are rounded to the millisecond, coarser than a byte at most rates: a stamp the
  rounding put before the previous entry's bytes could have ended is moved later, by at most the
  millisecond two roundings can hide.
- jpnevulator stamps a group (bytes closer than ``--timing-delta``, 100 ms unless told) when its
  *first* read returned: a group is split after its first frame, which keeps the stamp, and the rest
  is laid back to back after it.
- slsnif prints two characters of the milliseconds (``.45`` may be 45 or 450 ms): its stamps are
  good to the second only, so its chunks have no times (``t`` None).

Wall-clock stamps (socat, jpnevulator) are local time without a zone: chunks get seconds from the
first stamp, and ``ctx.found["start_time"]`` holds that stamp as an aware datetime in the reading
machine's zone (as ``--start-time`` reads a time without a zone). A stamp is only as good as the
program's reads: pyserial's ``read(n)`` that waits for its timeout is stamped when the timeout ends.

Bad input is a :class:`~rs30x_sniff.sources.captures.CaptureError` naming the file and line.
"""

from __future__ import annotations

import re
from datetime import datetime
from typing import BinaryIO, cast
from collections.abc import Callable, Iterator

from ..protocol.chunks import HOST, SERVO, Marked
from .timebase import ARRIVAL
from ..protocol.wire import ACK, DEFAULT_BAUD, NACK, REQUEST_HEADER, RETURN_HEADER, byte_time
from .captures import CaptureError
from .foreign import ForeignFormat, ReadContext, register

_MAX_LINE = 1 << 20   # a longer line is not one of these logs
_HOLD = 4096          # chunks held while the content has not said which side is the host ...
_HOLD_BYTES = 1 << 20  # ... or this many bytes of them
_ECHO_MAX = 4096      # host bytes remembered for the echo check (an adapter that never echoes)
_BOM = b"\xef\xbb\xbf"

Chunk = tuple


# ---- shared: lines, errors, directions ---------------------------------------------------------
def _lines(stream: BinaryIO, path: str) -> Iterator[tuple[int, bytes]]:
    """``(line number, line without its end)`` for every line of ``stream``."""
    readline = stream.readline
    lineno = 0
    while True:
        line = readline(_MAX_LINE)
        if not line:
            return
        lineno += 1
        if len(line) == _MAX_LINE and not line.endswith(b"\n"):
            raise CaptureError(f"{path}:{lineno}: the line is longer than {_MAX_LINE >> 20} MiB: not a serial log",
                               line=lineno)
        if lineno == 1 and line.startswith(_BOM):
            line = line[len(_BOM):]
        yield lineno, line.rstrip(b"\r\n")


def _error(path: str, lineno: int, what: str, line: bytes | None = None) -> CaptureError:
    shown = "" if line is None else f": {line.decode('latin-1')[:60]!r}"
    return CaptureError(f"{path}:{lineno}: {what}{shown}", line=lineno)


def _head_lines(head: bytes) -> list[bytes]:
    """The lines of a file's head; the last is dropped when it may be cut (unless it is the only one)."""
    if head.startswith(_BOM):
        head = head[len(_BOM):]
    lines = head.split(b"\n")
    if len(lines) > 1:
        lines.pop()  # empty after the final newline, or cut by the 4 KiB window
    return [ln.rstrip(b"\r") for ln in lines]


class _Sides:
    """Turns ``(side, data, t)`` entries into chunks marked with their sender.

    ``host`` names the host's side when the tool's words say it; with ``decide`` the side of the first
    entry that starts with a request header becomes the host's (entries are held until then). Every
    other side is a servo's, minus the echo of the host's bytes a one-wire adapter reads back.
    """

    def __init__(self, ctx: ReadContext, host: object = None, *, decide: bool = False) -> None:
        self.ctx = ctx
        self.host = host
        self.deciding = decide and host is None
        self.held: list[tuple[object, bytes, float | None]] = []
        self.held_bytes = 0
        self.echo = bytearray()
        self.echoed = 0

    def push(self, side: object, data: bytes, t: float | None) -> list[Chunk]:
        if not data:
            return []
        if self.deciding:
            if side is None:
                return self._release() + [(data, t)]  # a log without sides: nothing to decide
            self.held.append((side, data, t))
            self.held_bytes += len(data)
            if data.startswith(REQUEST_HEADER):
                self.host = side
            elif len(self.held) < _HOLD and self.held_bytes < _HOLD_BYTES:
                return []
            return self._release()
        return self._mark(side, data, t)

    def finish(self) -> list[Chunk]:
        out = self._release() if self.deciding else []
        if self.echoed:
            self.ctx.found["echo_bytes"] = self.echoed
        return out

    def _release(self) -> list[Chunk]:
        self.deciding = False
        held, self.held = self.held, []
        out: list[Chunk] = []
        for side, data, t in held:
            out += self._mark(side, data, t)
        return out

    def _mark(self, side: object, data: bytes, t: float | None) -> list[Chunk]:
        host = self.host
        if host is None:
            return [(data, t)]
        echo = self.echo
        if side == host:
            echo += data
            if len(echo) > _ECHO_MAX:
                del echo[:-_ECHO_MAX]
            return [Marked(data, t, sender=HOST)]
        if echo:
            k = min(len(data), len(echo))
            if data[:k] == echo[:k]:
                # The adapter's echo of what the host wrote: the host's line already has these bytes.
                del echo[:k]
                self.echoed += k
                data = data[k:]
                if not data:
                    return []
            else:
                echo.clear()  # this adapter does not echo (or the echo was lost): nothing to match
        return [Marked(data, t, sender=SERVO)]


def _wall(y: int, mo: int, d: int, h: int, mi: int, s: int) -> int | None:
    """Seconds of a wall-clock time on a uniform scale (differences are wall-clock differences), None
    if it is no time (a leap second's :60 is taken as it comes)."""
    import calendar  # a dated log line only: not a cost of every command's start-up

    if not (1 <= mo <= 12 and 1 <= d <= calendar.monthrange(y, mo)[1] and h <= 23 and mi <= 59 and s <= 60):
        return None
    return calendar.timegm((y, mo, d, h, mi, s, 0, 0, 0))


def _start(ctx: ReadContext, y: int, mo: int, d: int, h: int, mi: int, s: int, us: int, path: str,
           lineno: int) -> None:
    """Record a log's first wall-clock stamp (local time: the log has no zone) as ``start_time``."""
    try:
        ctx.found["start_time"] = datetime(y, mo, d, h, mi, s, us).astimezone()
    except (ValueError, OverflowError):
        raise _error(path, lineno, "not a valid date and time") from None


def _baud(ctx: ReadContext) -> int:
    baud = ctx.options.get("baud")
    return baud if isinstance(baud, int) and baud > 0 else DEFAULT_BAUD


def _ascii_ok(text: bytes, data: bytes) -> bool:
    """Whether a dump's character column fits ``data``: each byte itself or '.', trailing spaces optional."""
    if len(text) > len(data):
        return False
    for c, b in zip(text, data):
        if c != b and c != 0x2E:
            return False
    return all(b == 0x20 for b in data[len(text):])


# ---- pyserial spy:// ----------------------------------------------------------------------------
_SPY_LABELS = (b"TX", b"RX", b"Q-RX", b"Q-TX", b"BRK", b"RTS", b"DTR", b"CTS", b"DSR", b"RI", b"CD")
_SPY_CONTROL = frozenset(_SPY_LABELS[2:])
_SPY = re.compile(rb"(\d{6,}\.\d{3}) (TX  |RX  |Q-RX|Q-TX|BRK |RTS |DTR |CTS |DSR |RI  |CD  ) (.*)", re.S)
_SPY_ROW = re.compile(rb"([0-9A-F]{4,})  (.*)", re.S)
_COLOR = re.compile(rb"^(?:\x1b\[[0-9;]*m)+")  # the ?color option starts a call's first line with these


def _spy_row(data: bytes) -> bytes:
    """pyserial's hexdump row of up to 16 bytes: hex with a space after the 8th, then the characters."""
    hexs = bytearray()
    chars = bytearray()
    for i, b in enumerate(data):
        hexs += b"%02X " % b
        chars.append(b if 32 <= b < 127 else 0x2E)
        if i == 7:
            hexs += b" "
    for k in range(len(data), 16):
        if k == 7:
            hexs += b" "  # the padding puts its extra space before the 8th slot
        hexs += b"   "
        chars += b" "
    return bytes(hexs) + b" " + bytes(chars)


def _sniff_spy(head: bytes) -> bool:
    # The first line is spy's (seconds, a label it writes), and some line is a whole TX/RX dump row: the
    # reader, not the sniffer, names a bad line further on.
    lines = [_COLOR.sub(b"", ln) for ln in _head_lines(head) if ln.strip()]
    return bool(lines) and _SPY.fullmatch(lines[0]) is not None and any(_spy_data(ln) for ln in lines)


def _spy_data(line: bytes) -> bytes | None:
    """The bytes of a TX/RX dump row (None if the line is not one)."""
    m = _SPY.fullmatch(line)
    if m is None or m.group(2).rstrip() not in (b"TX", b"RX"):
        return None
    r = _SPY_ROW.fullmatch(m.group(3))
    if r is None:
        return None
    try:
        data = bytes.fromhex(r.group(2)[:49].decode("ascii"))
    except (ValueError, UnicodeDecodeError):
        return None
    if not data or len(data) > 16 or r.group(2).rstrip() != _spy_row(data).rstrip():
        return None
    return data


def _read_spy(stream: BinaryIO, ctx: ReadContext) -> Iterator[Chunk]:
    path = ctx.path
    bt = byte_time(_baud(ctx))
    sides = _Sides(ctx, b"TX")
    call: bytearray | None = None  # the bytes of the read or write call being dumped
    label = b""
    t0 = 0.0
    offset = 0
    full = True  # the call's last line held 16 bytes (so another may follow)

    prev = float("-inf")  # arrival of the previous call's last byte

    def done() -> list[Chunk]:
        nonlocal prev
        if call is None:
            return []
        data = bytes(call)
        span = len(data) * bt
        # pyserial stamps a write before it happens (about its first byte): moved to its arrival.
        t = t0 + span if label == b"TX" else t0
        if t - span < prev:
            # Stamps are rounded to the millisecond, coarser than a byte at most rates: where the rounding
            # put a call's first byte before the previous call's last, it is moved later, by no more than
            # the rounding of the two stamps could have hidden (half a millisecond each).
            t = min(t + 0.001, prev + span)
        prev = t
        return sides.push(label, data, t)

    for lineno, line in _lines(stream, path):
        body = _COLOR.sub(b"", line)
        if not body.strip():
            continue
        m = _SPY.fullmatch(body)
        if m is None:
            raise _error(path, lineno, "not a pyserial spy:// line (seconds, TX/RX or a control name, hex dump)", line)
        kind = m.group(2).rstrip()
        rest = m.group(3)
        if kind in _SPY_CONTROL or rest == b"<empty>":
            yield from done()
            call = None
            continue
        data = _spy_data(body)
        if data is None:
            raise _error(path, lineno, "not a spy:// hex dump row (offset, 16 bytes, characters)", line)
        r = cast("re.Match[bytes]", _SPY_ROW.fullmatch(rest))  # _spy_data matched this same row
        off = int(r.group(1), 16)
        if off == 0:
            yield from done()
            call = bytearray(data)
            label, t0, offset = kind, float(m.group(1)), 0
        elif call is not None and kind == label and full and off == offset + 16:
            call += data
            offset = off
        else:
            raise _error(path, lineno, f"row {r.group(1).decode()} does not continue a dump", line)
        full = len(data) == 16
    yield from done()
    yield from sides.finish()


# ---- socat -x [-v] -----------------------------------------------------------------------------
_SOCAT_HEAD = re.compile(
    rb"([<>]) (\d{4})/(\d\d)/(\d\d) (\d\d):(\d\d):(\d\d)\.(\d{1,9})  length=(\d+) from=(\d+) to=(\d+)")
_SOCAT_DIAG = re.compile(rb"\d{4}/\d\d/\d\d \d\d:\d\d:\d\d(?:\.\d+)? socat\[\d+\] [DINWEF] ")
_SOCAT_HEX = re.compile(rb"(?: [0-9a-f]{2})+")


def _socat_row(data: bytes) -> bytes:
    """socat's -x -v row: ' xx' per byte, padded to 16, two spaces, the characters ('\\n' as '.')."""
    return b"".join(b" %02x" % b for b in data) + b"   " * (16 - len(data)) + b"  " + \
        bytes(b if 32 <= b < 127 else 0x2E for b in data)


def _sniff_socat(head: bytes) -> bool:
    # The first line past socat's own diagnostics is a block header: specific enough on its own.
    for ln in _head_lines(head):
        if ln.strip() and not _SOCAT_DIAG.match(ln):
            return _SOCAT_HEAD.fullmatch(ln) is not None
    return False


def _socat_fraction(digits: bytes) -> float:
    # socat prints clock_gettime's nanoseconds divided by 1000 with a 9-digit format: microseconds,
    # zero-padded (".000566076" is 0.566076 s); a 6-digit fraction (gettimeofday builds) is microseconds
    # too. A 9-digit value no microsecond count can reach would be true nanoseconds.
    v = int(digits)
    if len(digits) == 9:
        return v / 1e6 if v < 1_000_000 else v / 1e9
    return v / 10 ** len(digits)


def _read_socat(stream: BinaryIO, ctx: ReadContext) -> Iterator[Chunk]:
    path = ctx.path
    sides = _Sides(ctx, decide=True)
    first: int | None = None    # wall-clock seconds of the first block
    first_frac = 0.0
    nxt: dict[bytes, int] = {}  # per direction: the from= the next block must have
    block: bytearray | None = None
    want = 0
    side = b""
    t = 0.0
    head_line = 0
    for lineno, line in _lines(stream, path):
        if not line.strip() or _SOCAT_DIAG.match(line):
            continue
        m = _SOCAT_HEAD.fullmatch(line)
        if m is not None:
            if block is not None and len(block) < want:
                raise _error(path, lineno, f"the block of line {head_line} ended after {len(block)} of its "
                                           f"{want} bytes", line)
            y, mo, d, h, mi, s = (int(x) for x in m.group(2, 3, 4, 5, 6, 7))
            want, frm, to = int(m.group(9)), int(m.group(10)), int(m.group(11))
            side = m.group(1)
            if want == 0 or to != frm + want - 1:
                raise _error(path, lineno, "the block's length, from and to do not agree", line)
            if side in nxt and frm != nxt[side]:
                raise _error(path, lineno, f"from={frm}, but the previous '{side.decode()}' block ended at "
                                           f"to={nxt[side] - 1}: a block is missing from the log", line)
            nxt[side] = to + 1
            wall = _wall(y, mo, d, h, mi, s)
            if wall is None:
                raise _error(path, lineno, "not a valid date and time", line)
            frac = _socat_fraction(m.group(8))
            if first is None:
                _start(ctx, y, mo, d, h, mi, s, round(frac * 1e6) % 1_000_000, path, lineno)
                first, first_frac = wall, frac
            t = (wall - first) + (frac - first_frac)
            block = bytearray()
            head_line = lineno
            continue
        if line == b"--":
            if block is None or len(block) != want:
                raise _error(path, lineno, "a block end ('--') where no complete block is", line)
            continue
        if block is None or len(block) >= want:
            raise _error(path, lineno, "hex bytes outside a block (no 'length=' line before them)", line)
        data = _socat_data(line, want - len(block))
        if data is None:
            raise _error(path, lineno, "not a socat -x hex dump line (record with socat -x -v, or -x)", line)
        block += data
        if len(block) == want:
            yield from sides.push(side, bytes(block), t)
    if block is not None and len(block) < want:
        raise CaptureError(f"{path}:{head_line}: the log ends inside this block, after {len(block)} of its {want} "
                           "bytes", line=head_line)
    yield from sides.finish()


def _socat_data(line: bytes, left: int) -> bytes | None:
    """The bytes of one data line of a block with ``left`` bytes to go (None if it is not one)."""
    if _SOCAT_HEX.fullmatch(line):
        data = bytes.fromhex(line.decode("ascii"))
        if len(data) == left:
            return data  # -x alone: the whole block on one line
        if len(data) > 16:
            return None
    m = _SOCAT_HEX.match(line)
    if m is None or len(m.group()) > 48:
        return None
    data = bytes.fromhex(m.group().decode("ascii"))
    # -x -v: 16 bytes a row, and a row also ends after a '\n' byte (0a) or with the block.
    if b"\n" in data[:-1] or (len(data) < 16 and data[-1] != 0x0A and len(data) != left) or len(data) > left:
        return None
    if line.rstrip() != _socat_row(data).rstrip():
        return None
    return data


# ---- interceptty -------------------------------------------------------------------------------
# "< 0xfa" from the program (front device), ">\t0xfd" from the device (back); one byte a line, with
# " (c)" for a printable byte; builds with timestamps put "[HH:MM SS.uuuuuu]" before a read's first
# line and as many spaces before the others.
_ICT = re.compile(rb"(?:\[(\d\d):(\d\d) (\d\d)\.(\d{6})\]|( {17}))?(?:(<) |(>) ?\t)0x([0-9a-f]{2})(?: \((.+)\))?", re.S)
_ICT_NAMES = (b"[NUL]", b"[SOH]", b"[STX]", b"[ETX]", b"[EOT]", b"[ENQ]", b"[ACK]", b"[BEL]", b"[BS]", b"[TAB]",
              b"[LF]", b"[VT]", b"[FF]", b"[CR]", b"[SO]", b"[SI]", b"[DLE]", b"[DC1]", b"[DC2]", b"[DC3]", b"[DC4]",
              b"[NAK]", b"[SYN]", b"[ETB]", b"[CAN]", b"[EM]", b"[SUB]", b"[ESC]", b"[FS]", b"[GS]", b"[RS]", b"[US]")


def _ict_char_ok(shown: bytes, b: int) -> bool:
    if len(shown) == 1:
        return shown[0] == b
    if b < 32:
        return shown == _ICT_NAMES[b]
    return (b == 32 and shown == b"' '") or (b == 127 and shown == b"[DEL]")


_ICT_START = re.compile(rb"(?:\[\d\d:\d\d \d\d\.\d{6}\]| {17})?(?:< |> ?\t)0x[0-9a-f]{2}(?: \(|$)")


def _sniff_interceptty(head: bytes) -> bool:
    # The first line's start: a pipe's head stops at the first byte above 0xF7, and builds that show
    # every byte's character print it raw, so the line may be cut inside its " (c)".
    text = head[len(_BOM):] if head.startswith(_BOM) else head
    first = next((ln.rstrip(b"\r") for ln in text.split(b"\n") if ln.strip()), b"")
    return _ICT_START.match(first) is not None


def _read_interceptty(stream: BinaryIO, ctx: ReadContext) -> Iterator[Chunk]:
    path = ctx.path
    sides = _Sides(ctx, b"<")
    stamped: bool | None = None
    pending = bytearray()
    side = b""
    t: float | None = None
    first: float | None = None
    last = 0.0
    days = 0
    for lineno, line in _lines(stream, path):
        if not line.strip():
            continue
        m = _ICT.fullmatch(line)
        if m is None:
            raise _error(path, lineno, "not an interceptty line ('< 0xNN' or '>\\t0xNN')", line)
        b = int(m.group(8), 16)
        shown = m.group(9)
        if shown is not None and not _ict_char_ok(shown, b):
            raise _error(path, lineno, f"the character shown is not byte 0x{b:02x}", line)
        this = m.group(6) or m.group(7)
        has_stamp = m.group(1) is not None
        if stamped is None:
            stamped = has_stamp
        if stamped != (has_stamp or m.group(5) is not None):
            raise _error(path, lineno, "lines with and without timestamps mixed", line)
        if has_stamp or (not stamped and (this != side or len(pending) >= 4096)):
            # A stamp starts a new read; without stamps, a change of direction is all that shows one.
            if pending:
                yield from sides.push(side, bytes(pending), t)
                pending.clear()
            side = this
            if has_stamp:
                h, mi, s, us = (int(x) for x in m.group(1, 2, 3, 4))
                if h > 23 or mi > 59 or s > 60:
                    raise _error(path, lineno, "not a valid time of day", line)
                now = h * 3600 + mi * 60 + s + us / 1e6
                if first is None:
                    first = last = now
                if now < last - 43200:
                    days += 1  # past midnight: the stamps hold no date
                last = now
                t = now + days * 86400 - first
        elif this != side:
            raise _error(path, lineno, "a read's bytes change direction without a new timestamp", line)
        pending.append(b)
    if pending:
        yield from sides.push(side, bytes(pending), t)
    yield from sides.finish()


# ---- jpnevulator --read --timing-print -----------------------------------------------------------
_JPN_HEAD = re.compile(rb"(\d{4})-(\d\d)-(\d\d) (\d\d):(\d\d):(\d\d)\.(\d{6}):(?: (.+))?", re.S)
_JPN_COUNT = re.compile(rb"([0-9A-Fa-f]{8})\t(.*)", re.S)
_JPN_BYTES = re.compile(rb" *(?:(?:[0-9A-Fa-f]{2}|[01]{8})(?: +|$))+")


def _sniff_jpnevulator(head: bytes) -> bool:
    # A timing line, then bytes (or the next timing line): nothing else starts with a date and a colon.
    lines = [ln for ln in _head_lines(head) if ln.strip()]
    return bool(lines) and _JPN_HEAD.fullmatch(lines[0]) is not None and \
        (len(lines) == 1 or _JPN_HEAD.fullmatch(lines[1]) is not None or _jpn_data(lines[1]) is not None)


def _jpn_data(line: bytes) -> tuple[int | None, bytes] | None:
    """``(byte count or None, bytes)`` of a data line (hex, or binary with --base=2), else None."""
    count = None
    m = _JPN_COUNT.fullmatch(line)
    if m is not None:
        count, line = int(m.group(1), 16), m.group(2)
    part, tab, chars = line.partition(b"\t")
    if not _JPN_BYTES.fullmatch(part):
        return None
    toks = part.split()
    data = bytes(int(x, 2) if len(x) == 8 else int(x, 16) for x in toks)
    if tab and not _ascii_ok(chars, data):
        return None
    return count, data


def _first_frame(data: bytes) -> int:
    """How many bytes the frame ``data`` starts with spans (all of them if it starts with none)."""
    if data[:2] in (REQUEST_HEADER, RETURN_HEADER) and len(data) >= 7:
        return min(len(data), 8 + data[5] * data[6])
    if data[0] in (ACK, NACK):
        return 1
    return len(data)


def _read_jpnevulator(stream: BinaryIO, ctx: ReadContext, split: bool = True) -> Iterator[Chunk]:
    path = ctx.path
    bt = byte_time(_baud(ctx))
    sides = _Sides(ctx, decide=True)
    counts: dict[bytes | None, int] = {}
    group: bytearray | None = None
    name: bytes | None = None
    t = 0.0
    first: int | None = None
    first_us = 0

    def done() -> list[Chunk]:
        if not group:
            return []
        data = bytes(group)
        # The stamp is when the group's first read returned: taken to be its first frame's arrival;
        # the rest of the group follows it back to back.
        k = _first_frame(data) if split else len(data)
        out = sides.push(name, data[:k], t)
        if k < len(data):
            out += sides.push(name, data[k:], t + (len(data) - k) * bt)
        return out

    for lineno, line in _lines(stream, path):
        if not line.strip():
            continue
        m = _JPN_HEAD.fullmatch(line)
        if m is not None:
            yield from done()
            y, mo, d, h, mi, s, us = (int(x) for x in m.group(1, 2, 3, 4, 5, 6, 7))
            wall = _wall(y, mo, d, h, mi, s)
            if wall is None:
                raise _error(path, lineno, "not a valid date and time", line)
            if first is None:
                _start(ctx, y, mo, d, h, mi, s, us, path, lineno)
                first, first_us = wall, us
            t = (wall - first) + (us - first_us) / 1e6
            name = m.group(8)
            group = bytearray()
            continue
        parsed = _jpn_data(line)
        if parsed is None:
            raise _error(path, lineno, "not a jpnevulator hex line", line)
        if group is None:
            raise _error(path, lineno, "bytes before the first timing line (record with --timing-print)", line)
        count, data = parsed
        if count is not None:
            if name in counts and count != counts[name]:
                raise _error(path, lineno, f"byte count {count:08X}, but {counts[name]:08X} bytes of this "
                                           "device came before it: lines are missing from the log", line)
            counts[name] = count + len(data)
        group += data
    yield from done()
    yield from sides.finish()


# ---- slsnif --------------------------------------------------------------------------------------
_SLS_DATA = re.compile(rb"(Host   |Device )--> (.*)", re.S)
_SLS_BYTE = re.compile(rb"(<[A-Z0-9]+>|[\x21-\xff]) \(([0-9a-f]{2}|[0-9]{3})\) ")
# ctime() with ".%2u" of the milliseconds cut to two characters and, from slsnif's write of the
# whole buffer, a NUL at the end.
_SLS_TIME = re.compile(rb"(?:Sun|Mon|Tue|Wed|Thu|Fri|Sat) ([A-Z][a-z]{2}) ([ \d]\d) (\d\d):(\d\d):(\d\d)"
                       rb"(?:\.[ \d]\d)? (\d{4})\x00*")
_SLS_TOTAL = re.compile(rb"Total bytes transmitted: (\d+)")
_SLS_BANNER = (b"Serial Line Sniffer.", b"\tCopyright (C)", b"Started logging", b"Opened pty:", b"Opened port:",
               b"Saved name of the pty", b"Baudrate is set to", b"Synchronizing ports...")
_SLS_NAMES = (b"<NUL>", b"<SOH>", b"<STX>", b"<ETX>", b"<EOT>", b"<ENQ>", b"<ACK>", b"<BEL>", b"<BS>", b"<HT>",
              b"<LF>", b"<VT>", b"<FF>", b"<CR>", b"<SO>", b"<SI>", b"<DLE>", b"<DC1>", b"<DC2>", b"<DC3>", b"<DC4>",
              b"<NAK>", b"<SYN>", b"<ETB>", b"<CAN>", b"<EM>", b"<SUB>", b"<ESC>", b"<FS>", b"<GS>", b"<RS>", b"<US>",
              b"<SPACE>")
_MONTHS = {m: i for i, m in enumerate((b"Jan", b"Feb", b"Mar", b"Apr", b"May", b"Jun", b"Jul", b"Aug", b"Sep",
                                      b"Oct", b"Nov", b"Dec"), 1)}


def _sls_line_kind(line: bytes) -> str | None:
    if not line.strip(b" \x00"):
        return "blank"
    if _SLS_DATA.fullmatch(line):
        return "data"
    if _SLS_TIME.fullmatch(line) or _SLS_TOTAL.fullmatch(line) or line.startswith(_SLS_BANNER):
        return "other"
    return None


def _sniff_slsnif(head: bytes) -> bool:
    # Past the banner, the first line is a stamp or a read. Bytes above 0x7F are written raw, so a
    # pipe's head may stop inside the first read: that line only has to start like one.
    text = head[len(_BOM):] if head.startswith(_BOM) else head
    for ln in text.split(b"\n"):
        ln = ln.rstrip(b"\r")
        if not ln.strip(b" \x00") or ln.startswith(_SLS_BANNER):
            continue
        return ln.startswith((b"Host   --> ", b"Device --> ")) or _SLS_TIME.fullmatch(ln) is not None
    return False


def _sls_bytes(body: bytes) -> bytes | None:
    """The bytes of a data line's ``c (xx) `` items (hex with -x, three decimal digits without), else None."""
    out = bytearray()
    pos = 0
    width = None
    if not body.endswith(b" "):
        body += b" "  # each item ends with a space; an editor may have taken the last one
    for m in _SLS_BYTE.finditer(body):
        if m.start() != pos:
            return None
        pos = m.end()
        digits = m.group(2)
        if width is None:
            width = len(digits)
        elif len(digits) != width:
            return None
        b = int(digits, 16) if width == 2 else int(digits)
        shown = m.group(1)
        if b > 255 or shown != (_SLS_NAMES[b] if b < 33 else b"<DEL>" if b == 127 else bytes((b,))):
            return None
        out.append(b)
    if not out or pos < len(body.rstrip(b" ")):
        return None
    return bytes(out)


def _read_slsnif(stream: BinaryIO, ctx: ReadContext) -> Iterator[Chunk]:
    path = ctx.path
    sides = _Sides(ctx, b"Host   ")
    last_n: int | None = None
    for lineno, line in _lines(stream, path):
        kind = _sls_line_kind(line)
        if kind is None:
            raise _error(path, lineno, "not a slsnif line ('Host   --> ' or 'Device --> ' and bytes)", line)
        if kind == "data":
            m = cast("re.Match[bytes]", _SLS_DATA.fullmatch(line))  # _sls_line_kind matched it: "data"
            data = _sls_bytes(m.group(2))
            if data is None:
                raise _error(path, lineno, "not slsnif bytes ('c (xx) ' with -x, 'c (ddd) ' without)", line)
            last_n = len(data)
            # slsnif's stamps are good to the second only (module docstring): no times.
            yield from sides.push(m.group(1), data, None)
            continue
        total = _SLS_TOTAL.fullmatch(line)
        if total is not None:
            if last_n is None or int(total.group(1)) != last_n:
                raise _error(path, lineno, "the byte total does not match the line before it", line)
            last_n = None
            continue
        stamp = _SLS_TIME.fullmatch(line)
        if stamp is not None and "start_time" not in ctx.found:
            mon, d, h, mi, s, y = stamp.groups()
            if mon not in _MONTHS or _wall(int(y), _MONTHS[mon], int(d), int(h), int(mi), int(s)) is None:
                raise _error(path, lineno, "not a valid date and time", line)
            _start(ctx, int(y), _MONTHS[mon], int(d), int(h), int(mi), int(s), 0, path, lineno)
    yield from sides.finish()


# ---- the rate the stamps show ----------------------------------------------------------------------
_PROBE_CHUNKS = 512


def _prober(read: Callable[[BinaryIO, ReadContext], Iterator[Chunk]]) -> Callable[[str, dict], dict]:
    """A ``probe`` giving the baud rate a log's stamps show, as our own timestamped hex gets it: stamped
    at arrival, chunks that follow each other back to back are a byte time apart per byte of the later."""

    def probe(path: str, options: dict) -> dict:
        from ..protocol.baud import estimate_from_spacings

        try:
            with open(path, "rb") as f:
                chunks = []
                for c in read(f, ReadContext(path, dict(options))):
                    if c[1] is not None and c[0]:
                        chunks.append(c)
                        if len(chunks) >= _PROBE_CHUNKS:
                            break
        except (OSError, CaptureError):
            return {}  # the reading command says why, with the line
        est = estimate_from_spacings(((t2 - t1) / len(d2), len(d1))
                                     for (d1, t1), (d2, t2) in zip(chunks, chunks[1:]) if t2 > t1)
        if est.baud is None:
            return {}
        return {"baud": est.baud, "baud_note": f"its timestamps: {est.evidence}"}

    return probe


# ---- registration --------------------------------------------------------------------------------
def _register(name: str, description: str, sniff: Callable[[bytes], bool],
              read: Callable[[BinaryIO, ReadContext], Iterator[Chunk]], probe=None) -> None:
    register(ForeignFormat(name, description, sniff, read, ARRIVAL, probe=probe))


# spy's millisecond stamps are too coarse to show a byte time at most rates; slsnif's have none.
_register("spy", "pyserial spy:// log: TX (host) and RX hex dumps, seconds since the port opened",
          _sniff_spy, _read_spy)
_register("socat", "socat -x (-v) dump: '>'/'<' blocks with wall-clock stamps", _sniff_socat, _read_socat,
          _prober(_read_socat))
_register("interceptty", "interceptty log: '< 0xNN' from the program, '>\\t0xNN' from the device",
          _sniff_interceptty, _read_interceptty, _prober(_read_interceptty))
# Probed unsplit: the split of a group lays its rest at an assumed rate, which must not vote for itself.
_register("jpnevulator", "jpnevulator --read --timing-print: timed groups of hex bytes", _sniff_jpnevulator,
          _read_jpnevulator, _prober(lambda f, ctx: _read_jpnevulator(f, ctx, split=False)))
_register("slsnif", "slsnif log: 'Host   --> ' and 'Device --> ' lines of 'c (xx)' bytes", _sniff_slsnif,
          _read_slsnif)
