"""Capture files: detect the format, read them as (bytes, t) chunks, and write them back."""

from __future__ import annotations


import codecs
import io
import math
import os
import re
import select
import stat
import sys
import time
from array import array
from bisect import bisect_right
from collections import Counter
from itertools import repeat
from operator import itemgetter
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO
from collections.abc import Callable, Iterable, Iterator

from . import timeunit
from ..protocol.chunks import Marked, SourceGap
from ..protocol.mcap_names import MCAP_MAGIC
from ..protocol.wire import REQUEST_HEADER, RETURN_HEADER
from .timeunit import TimeUnit
from . import foreign
from .base import CaptureError, CaptureWarning, open_capture, stderr_warning

Chunk = tuple[bytes, float | None]

BINARY, HEX, TIMESTAMPED, MCAP = "bin", "hex", "timestamped", "mcap"
FORMATS = (BINARY, HEX, TIMESTAMPED, MCAP)
_EXTENSIONS = {".bin": BINARY, ".raw": BINARY, ".mcap": MCAP}
_TEXT_EXTENSIONS = {".hex", ".txt", ".log", ".thex"}
_READ_SIZE = 1 << 16
_BLOCK_SIZE = 1 << 18        # a text file's plain lines are read this many bytes at a time (_plain_lines)
_HEAD_SIZE = 4096           # bytes the format is sniffed from
_MAX_LINE = 64 << 20        # a longer "line" is not a text capture (and would have to sit in memory whole)
_BOM = b"\xef\xbb\xbf"
# Byte-order marks a text capture may start with, the longest first (UTF-32 LE's begins with UTF-16 LE's).
# UTF-16 is read (PowerShell's `>` writes UTF-16 LE with CRLF); UTF-32 is named and refused.
_BOMS = ((b"\xff\xfe\x00\x00", "utf-32-le"), (b"\x00\x00\xfe\xff", "utf-32-be"),
         (b"\xff\xfe", "utf-16-le"), (b"\xfe\xff", "utf-16-be"), (_BOM, "utf-8"))
_READ_ENCODINGS = ("utf-16-le", "utf-16-be")
_ENCODING_NAMES = {"utf-32-le": "UTF-32 LE", "utf-32-be": "UTF-32 BE", "utf-16-le": "UTF-16 LE",
                   "utf-16-be": "UTF-16 BE"}
_LONE_CR = re.compile(rb"\r(?!\n)")
# A live pipe that sends nothing for this long has its pending lines handed on (a hex line, the lines
# held to tell the unit of their times); SAMPLE_PATIENCE bounds how long the unit waits for more lines.
IDLE_WAIT = 0.1
SAMPLE_PATIENCE = 1.0
_HEX_TOKEN = re.compile(rb"^(?:[0-9a-fA-F]{2})+$")
_HEX_PAIR = re.compile(rb"[0-9a-fA-F]{2}")
_TOKEN = re.compile(rb"\S+")
# Anything float() reads as a decimal number, and the words it reads as nan/inf (so a bad time is
# reported as a bad time rather than as a bad hex byte); underscores and hex floats are not times.
_NUMBER = re.compile(rb"^[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$|^[+-]?(?:nan|inf|infinity)$", re.I)
# Control bytes no text capture holds: a head with one of them is binary, and on a pipe the sniffer
# can stop waiting for more (the bytes of a frame header, FA and FD, are not valid UTF-8 either).
_NOT_TEXT = re.compile(rb"[\x00-\x08\x0e-\x1f\x7f\xf8-\xff]")


# ---- opening: every input is opened once --------------------------------------------------------
class _Chain(io.RawIOBase):
    """The head already read from a stream that cannot seek back, then the rest of that stream."""

    def __init__(self, head: bytes, f: BinaryIO, owns: bool) -> None:
        super().__init__()
        self._head = memoryview(head)
        self._f = f
        self._owns = owns

    def readable(self) -> bool:
        return True

    def readinto(self, b) -> int:
        if len(self._head):
            n = min(len(b), len(self._head))
            b[:n] = self._head[:n]
            self._head = self._head[n:]
            return n
        # read1: what the pipe has now (at most one read), so a live stream is not held back.
        read1 = getattr(self._f, "read1", None)
        data = read1(len(b)) if read1 is not None else self._f.read(len(b))
        n = len(data)
        b[:n] = data
        return n

    def close(self) -> None:
        if not self.closed and self._owns:
            self._f.close()
        super().close()


@dataclass
class _Opened:
    stream: BinaryIO  # reads the capture from its first byte
    head: bytes       # its first bytes, for sniffing
    complete: bool    # the head is the whole capture
    seekable: bool
    fmt: str | None = None
    taken: bool = False
    fd: int | None = None     # a stream's descriptor, read directly (after the head) by a text reader
    note: str | None = None   # what was assumed of the format, said once by the reader

    @property
    def encoding(self) -> str | None:
        """The encoding a byte-order mark names (None: no mark, read as ASCII/UTF-8)."""
        return _bom_of(self.head)

    @property
    def text(self) -> bytes:
        """The head as UTF-8 with LF line ends, for sniffing a text capture (a cut last line stays cut)."""
        return _as_utf8_lf(self.head, self.encoding, self.complete)


def _as_utf8_lf(head: bytes, encoding: str | None, complete: bool) -> bytes:
    if encoding in _ENCODING_NAMES:  # UTF-16 or UTF-32: decoded to sniff (UTF-32 is then named and refused)
        head = codecs.getincrementaldecoder(encoding)("replace").decode(head, final=complete).encode("utf-8")
        head = head.removeprefix(_BOM)  # the decoded mark
    elif head.startswith(_BOM):
        head = head[len(_BOM):]
    return _LONE_CR.sub(b"\n", head.replace(b"\r\n", b"\n")) if b"\r" in head else head


# A pipe, FIFO or stdin can be read only once, but callers may ask for its format and then read it
# (convert and info do): the one open stream waits here, with its format, until it is closed.
_PIPES: dict[str, _Opened] = {}


def _open(path: str) -> _Opened:
    """Open ``path`` (``-`` is stdin) and read its head: a file seeks back, a pipe (or stdin) is chained.

    Stdin redirected from a regular file (``decode - < x.mcap``) is that file: opened anew, it seeks.
    """
    if path == "-" and not stdin_is_file():
        f = getattr(sys.stdin, "buffer", None)
        if f is None:
            raise CaptureError("-: there is no standard input to read")
        owns = False
        seekable = False  # a pipe or terminal on stdin is read as a stream, and never closed
    else:
        f = open_capture(path)
        owns = True
        try:
            seekable = f.seekable()
        except OSError:
            seekable = False
    try:
        if seekable:
            start = f.tell()
            head = f.read(_HEAD_SIZE)
            f.seek(start)
            return _Opened(f, head, len(head) < _HEAD_SIZE, True)
        fd = _fileno(f)
        read = (lambda n: os.read(fd, n)) if fd is not None else (getattr(f, "read1", None) or f.read)
        head, ended = _read_head(read, fd)
    except OSError as e:
        if owns:
            f.close()
        raise CaptureError(f"{path}: cannot read: {e.strerror or e}") from None
    stream = io.BufferedReader(_Chain(head, f, owns), buffer_size=_READ_SIZE)
    return _Opened(stream, head, ended, False, fd=fd)


def _fileno(f: BinaryIO) -> int | None:
    try:
        return f.fileno()
    except (OSError, ValueError, AttributeError, io.UnsupportedOperation):
        return None


def stdin_is_file() -> bool:
    """Whether standard input is a regular file (``< x.mcap``), which can be read like one."""
    try:
        return stat.S_ISREG(os.fstat(sys.stdin.fileno()).st_mode)
    except (OSError, ValueError, AttributeError, io.UnsupportedOperation):
        return False


def regular_file(path: str) -> bool:
    """Whether ``path`` (``-``: stdin) is a regular file: one that can be read ahead and read again."""
    return stdin_is_file() if path == "-" else os.path.isfile(path)


def _read_head(read: Callable[[int], bytes], fd: int | None) -> tuple[bytes, bool]:
    """The head of a pipe and whether the pipe ended within it.

    Takes what arrives until the head is full, the pipe ends, a byte says "binary", or a first data line
    says which text it is: a live stream of a few bytes a second must not wait for 4 KiB before it is
    decoded. A first line that leaves hex or times open waits for more, at most SAMPLE_PATIENCE of silence.
    """
    head = bytearray()
    while len(head) < _HEAD_SIZE:
        # A first line that leaves the format open (no whole line yet, or ``10 FA AF``) waits for more.
        if fd is not None and head and not _ready(fd, SAMPLE_PATIENCE):
            if _data_lines(_as_utf8_lf(bytes(head), _bom_of(head), False), False):
                break  # a whole data line, then silence: judge by what came
        block = read(_HEAD_SIZE - len(head))
        if not block:
            return bytes(head), True
        head += block
        if _NOT_TEXT.search(block) and _bom_of(head) is None:
            break
        if _first_line_kind(_as_utf8_lf(bytes(head), _bom_of(head), False), definite=True) is not None:
            break
    return bytes(head), False


def _bom_of(head: bytes | bytearray) -> str | None:
    return next((enc for bom, enc in _BOMS if head.startswith(bom)), None)


def _ready(fd: int, timeout: float) -> bool:
    """Whether ``fd`` has something to read (or its end) within ``timeout`` seconds; True if it cannot be asked."""
    try:
        return bool(select.select([fd], [], [], timeout)[0])
    except (OSError, ValueError):
        return True


def _sniffed(path: str, fmt: str | None) -> _Opened:
    """The open input of ``path`` with its format (``fmt`` if given, else detected)."""
    pending = _PIPES.get(path)
    if pending is not None and pending.stream.closed:
        del _PIPES[path]
        pending = None
    if pending is None:
        pending = _open(path)
        if not pending.seekable:
            _PIPES[path] = pending
    if pending.fmt is None or fmt is not None:
        try:
            pending.fmt = fmt or _detect(path, pending)
        except CaptureError:
            pending.stream.close()
            raise
    return pending


def detect_format(path: str) -> str:
    """The format of a capture file: by extension, else by content (``-`` is stdin, sniffed too).

    A pipe or FIFO is opened once: it stays open, so that :func:`read_capture` reads it from its first byte.
    """
    opened = _sniffed(path, None)
    if opened.seekable:
        opened.stream.close()
    return opened.fmt  # type: ignore[return-value]


def _detect(path: str, opened: _Opened) -> str:
    ext = Path(path).suffix.lower() if path != "-" else ""
    head = opened.head
    if head.startswith(MCAP_MAGIC) and not opened.seekable:
        raise CaptureError(f"{path}: an MCAP capture needs a seekable file, not a pipe (save it to a file first)")
    if ext in _EXTENSIONS:
        return _EXTENSIONS[ext]
    if head.startswith(MCAP_MAGIC):
        return MCAP
    other = foreign.by_extension(ext) or foreign.sniff(head)
    if other is not None:
        return other.name
    if not head and ext not in _TEXT_EXTENSIONS:
        return BINARY  # nothing to read either way
    text = opened.text
    text_kind = _sniff_text(text, opened.complete)
    named = _other_encoding(head)
    if named is not None and (text_kind or ext in _TEXT_EXTENSIONS):
        raise _encoding_error(path, named)
    if text_kind:
        if text_kind == TIMESTAMPED and ext != ".thex":  # a .thex says it holds times
            opened.note = _times_assumed(text, opened.complete)
        return text_kind
    if ext in _TEXT_EXTENSIONS or (not _NOT_TEXT.search(text) and _first_line_kind(text)):
        # A text capture with a bad token: read it as its first data line says, so the error names the line.
        return _first_line_kind(text) or HEX
    if REQUEST_HEADER in head or RETURN_HEADER in head or not opened.seekable:
        # stdin was always raw bytes, and a pipe's head may be one short read: not text is binary.
        return BINARY
    raise CaptureError(f"{path}: unknown capture format (use --input-format {'|'.join(input_formats())})")


def _other_encoding(head: bytes) -> str | None:
    """The name of an encoding a text capture is not read in, when ``head`` shows one: a UTF-32 byte-order
    mark, or UTF-16 without one (every other byte NUL, the rest ASCII)."""
    enc = _bom_of(head)
    if enc in _ENCODING_NAMES and enc not in _READ_ENCODINGS:
        return _ENCODING_NAMES[enc]
    if enc is None and len(head) >= 8:
        sample = head[:len(head) & ~1][:512]
        even, odd = sample[0::2], sample[1::2]
        for zeros, chars, order in ((odd, even, "LE"), (even, odd, "BE")):
            if not zeros.strip(b"\x00") and chars.isascii() and not _NOT_TEXT.search(chars):
                return f"UTF-16 {order} without a byte-order mark"
    return None


def _encoding_error(path: str, named: str) -> CaptureError:
    code = named.split(" without")[0].replace(" ", "")
    # Line 1: the file's first bytes (a byte-order mark, or the NULs beside its first characters) tell the encoding.
    return CaptureError(f"{path}: a text capture in {named}, which is not read (ASCII, UTF-8 and UTF-16 with a "
                        f"byte-order mark are): save it as UTF-8 (iconv -f {code} -t UTF-8)", line=1)


def _data_lines(head: bytes, complete: bool) -> list[list[bytes]]:
    """The tokens of each line of ``head`` (UTF-8, LF: see _Opened.text) that has any outside its comment."""
    if head.startswith(_BOM):
        head = head[len(_BOM):]
    raw = head.splitlines()
    if not complete and raw and not head.endswith((b"\n", b"\r")):
        raw = raw[:-1]  # the last line may be cut by the 4 KiB window
    return [toks for toks in (ln.partition(b"#")[0].split() for ln in raw) if toks]


def _time_not_bytes(line: list[bytes]) -> bool:
    """Whether a line's first token is a whole number written unlike the hex bytes after it: several bytes'
    worth of decimal digits run together (``1767225600``) before bytes written one by one (``FA AF``).
    A dump writes a line's bytes alike, so that token is a time, not a packet's bytes."""
    first = line[0]
    return len(line) > 1 and first.isdigit() and len(first) >= 4 and all(len(t) == 2 for t in line[1:])


def _sniff_text(head: bytes, complete: bool = True) -> str | None:
    """HEX or TIMESTAMPED when the data lines of ``head`` are all one or the other.

    ``head`` is UTF-8 with LF line ends (_Opened.text). Comments (``#`` to the end of the line) may hold
    any text, UTF-8 or not; a UTF-8 BOM is skipped.
    The rule for times: a file is timestamped when the first token of every data line is a decimal
    number (``0.5``, ``12``, ``1e-3``; ``nan``/``-1`` too, so the reader can say the time is bad)
    followed by hex bytes, and that first column cannot be hex data: some first token is not a whole
    number of hex bytes (it has a ``.``, a sign or an exponent, or an odd number of digits), or every
    first token is an integer of three or more digits and they never decrease (clock ticks), or every
    line's first token is digits run together before bytes written apart (``1767225600 FA AF``, even on
    one line: _time_not_bytes). A file whose first tokens are all two-digit numbers (``10 FA AF``) is
    ambiguous and read as plain hex, unless the caller asks for ``timestamped``. Where the first column
    could have been hex bytes, the reader says that it read times (_times_assumed).
    """
    if _NOT_TEXT.search(head):
        return None
    lines = _data_lines(head, complete)
    if not lines:
        return HEX  # blank or comments only (so far)
    if all(_NUMBER.match(ln[0]) and all(_HEX_TOKEN.match(t) for t in ln[1:]) for ln in lines):
        firsts = [ln[0] for ln in lines]
        if any(not _HEX_TOKEN.match(f) for f in firsts):
            return TIMESTAMPED
        if len(firsts) > 1 and all(f.isdigit() and len(f) > 2 for f in firsts) and \
                all(int(a) <= int(b) for a, b in zip(firsts, firsts[1:])):
            return TIMESTAMPED
        if all(_time_not_bytes(ln) for ln in lines):
            return TIMESTAMPED
    if all(all(_HEX_TOKEN.match(t) for t in ln) for ln in lines):
        return HEX
    return None


def _times_assumed(head: bytes, complete: bool) -> str | None:
    """What a timestamped capture's reader says when its first column could also have been hex bytes."""
    lines = _data_lines(head, complete)
    firsts = [ln[0] for ln in lines]
    if not lines or not all(_HEX_TOKEN.match(f) for f in firsts):
        return None
    if len(firsts) > 1 and all(f.isdigit() and len(f) > 2 for f in firsts) and \
            all(int(a) <= int(b) for a, b in zip(firsts, firsts[1:])):
        return None  # clock ticks: a column of whole numbers that never decrease says it well enough
    return (f"its first column ({firsts[0].decode('ascii')}{', ...' if len(firsts) > 1 else ''}) is read as "
            "times, not hex bytes: digits run together before bytes written apart "
            "(--input-format hex to read it as bytes)")


def _first_line_kind(head: bytes, definite: bool = False) -> str | None:
    """The format the first data line of ``head`` reads as on its own (None if neither). With ``definite``,
    only a line no later line can make the other format: a time with a point, sign or exponent, digits
    written unlike their bytes, or a first byte with a letter (None for ``10 FA AF``, or no whole line)."""
    lines = _data_lines(head, not definite)[:1]
    if not lines:
        return None
    first = lines[0]
    if _NUMBER.match(first[0]) and not _HEX_TOKEN.match(first[0]):
        return TIMESTAMPED
    if definite:
        if _time_not_bytes(first) and all(_HEX_TOKEN.match(t) for t in first):
            return TIMESTAMPED
        if _NUMBER.match(first[0]):
            return None
    return HEX if all(_HEX_TOKEN.match(t) for t in first) else None


# ---- reading -------------------------------------------------------------------------------------
def input_formats() -> tuple[str, ...]:
    """Every format name ``--input-format`` takes: ours, then other tools' (rs30x_sniff.sources.foreign)."""
    return (*FORMATS, *foreign.formats())


def read_capture(path: str, fmt: str | None = None, *,
                 warn: Callable[[str], None] | None = stderr_warning,
                 options: dict | None = None) -> CaptureReader:
    """Stream a capture as (bytes, t) chunks; ``t`` is the capture time of the chunk's first byte.

    ``path`` may be a file, a pipe or FIFO (``/dev/fd/N``), or ``-`` for stdin: each is opened once and
    sniffed from its first 4 KiB (an MCAP needs a seekable file). Without ``fmt`` the format is
    detected now, so an unreadable or unknown file fails here; with it, at the first chunk. Problems
    the reader works around (a damaged MCAP) go to ``warn`` as one line each, and stay in the
    returned reader's ``warnings`` as :class:`CaptureWarning` objects.
    """
    if fmt is not None and fmt not in input_formats():
        raise CaptureError(f"{path}: unknown input format {fmt!r} (use one of {', '.join(input_formats())})")
    reader = CaptureReader(path, fmt, warn, options)
    if fmt is None:
        reader._start()
    return reader


class CaptureReader:
    """An iterator over the (bytes, t) chunks of one capture, which can say where a byte came from.

    ``locate(offset)`` maps a stream byte offset (the position of a byte in the concatenated chunks,
    as events report it) to ``(line, column)`` in a hex or timestamped-hex file, both 1-based, the
    column being that of the byte's first hex digit; None for binary and MCAP captures, for a reader
    opened with the option ``"locate": False`` (it keeps no index), and for offsets not read yet.
    The reader keeps a few integers per line with data (and a column per byte only for lines whose
    bytes are not evenly spaced), not the text.
    ``warnings`` lists the :class:`CaptureWarning` objects of the problems worked around so far.
    ``streamed`` is True when the capture is not a regular file (a pipe, a FIFO, a terminal, a device):
    its bytes may still be arriving as they are read (`socat ... | rs30x-sniff decode -`); stdin
    redirected from a file is a file. ``live`` is False: a capture is not a port (rs30x_sniff.sources.serial_tap).
    ``time_unit`` says how a timestamped hex capture's times were read (rs30x_sniff.sources.timeunit): in the
    unit of the option ``"time_unit"``, else in the one the content tells; they come out in seconds
    (epoch times as seconds since the epoch). The option ``"say_time_unit"`` says a told unit other
    than seconds on stderr.
    """

    live = False
    batched = False

    def __init__(self, path: str, fmt: str | None, warn: Callable[[str], None] | None,
                 options: dict | None = None) -> None:
        self.path = path
        self.format = fmt
        self.streamed: bool = _streamed(path)
        # What another tool's reader was given (--channel, --baud) and learned (a found baud rate).
        self.context = foreign.ReadContext(path, dict(options or {}), warn)
        self.warnings: list[CaptureWarning] = []
        # How a timestamped hex capture's times were read (None until its first times are in).
        self.time_unit: TimeUnit | None = None
        self._warn = warn
        # The wall clock now, for "no epoch time is more than a day ahead" (timeunit.detect_unit): read here,
        # at the edge, unless the caller gives it (option "now", seconds since the epoch).
        now = self.context.options.get("now")
        self._now: float = time.time() if now is None else now
        self._gen: Iterator[Chunk] | None = None
        self._lines: _LineIndex | None = None

    def _start(self) -> Iterator[Chunk]:
        if self._gen is None:
            path = self.path
            opened = _sniffed(path, self.format)
            if opened.taken:
                raise CaptureError(f"{path}: is a pipe already being read (a pipe can be read only once)")
            self.format = fmt = opened.fmt
            opened.taken = True
            if fmt == MCAP:
                opened.stream.close()  # the MCAP reader seeks by itself
                self._gen = self._mcap(opened.seekable)
            elif fmt == BINARY:
                self._gen = _read_binary(opened.stream)
            elif fmt not in FORMATS:
                other = foreign.get(fmt)
                assert other is not None  # _sniffed gives a registered format
                if other.needs_seek and not opened.seekable:
                    opened.stream.close()
                    raise CaptureError(f"{path}: a {fmt} capture needs a seekable file, not a pipe "
                                       "(save it to a file first)")
                self._gen = _closing(_sane_times(other.read(opened.stream, self.context), path), opened.stream)
            else:
                # 16 bytes a line, for findings' FILE:LINE:COL: a reader nobody will ask (options
                # "locate": False, as convert's) keeps none (locate() is None), and a long capture's
                # memory stays flat.
                self._lines = _LineIndex() if self.context.options.get("locate", True) else None
                named = _other_encoding(opened.head)
                if named is not None:
                    opened.stream.close()
                    raise _encoding_error(path, named)
                if opened.note and self._warn is not None:
                    self._say(f"{path}: {opened.note}")
                self._gen = _read_text(_Lines(opened), path, fmt == TIMESTAMPED, self._lines,
                                       self.context.options.get("time_unit"), self._unit_decided, self._now)
        return self._gen

    def _say(self, text: str) -> None:
        self.warnings.append(CaptureWarning(self.path, text))
        if self._warn is not None:
            self._warn(text)

    def _unit_decided(self, unit: TimeUnit) -> None:
        self.time_unit = self.context.found["time_unit"] = unit
        if unit.said and self.context.options.get("say_time_unit"):
            # Seconds since the capture began are what our captures hold: every other reading is said,
            # epoch seconds too (info says every unit, plain seconds included).
            print(f"rs30x-sniff: {self.path}: {unit.describe()}, {unit.how_known()} (--time-unit to say otherwise)",
                  file=sys.stderr)

    def _mcap(self, seekable: bool) -> Iterator[Chunk]:
        from .mcap_reader import McapRawReader

        if not seekable:
            raise CaptureError(f"{self.path}: an MCAP capture needs a seekable file, not a pipe "
                               "(save it to a file first)")
        reader = McapRawReader(self.path, warn=self._warn, gaps=True)
        reader.warnings = self.warnings
        for item in reader:
            if type(item) is SourceGap:  # the recording's port was lost here: the same seam again
                yield item
                continue
            data, t, _, marks = item
            yield (data, t) if marks is None else Marked(data, t, sender=marks[0], error=marks[1])

    def __iter__(self) -> Iterator[Chunk]:
        return self._start()

    def __next__(self) -> Chunk:
        return next(self._start())

    def close(self) -> None:
        """Stop reading and close the file (also done when the chunks run out)."""
        gen = self._gen
        if gen is not None:
            gen.close()  # type: ignore[attr-defined]

    def locate(self, offset: int) -> tuple[int, int] | None:
        """``(line, column)`` of the stream byte at ``offset`` in a text capture, else None."""
        lines = self._lines
        return lines.locate(offset) if lines is not None else None


def _streamed(path: str) -> bool:
    """Whether ``path`` (``-``: stdin) is anything but a regular file, or cannot be looked at."""
    try:
        mode = os.stat(sys.stdin.fileno() if path == "-" else path).st_mode  # os.stat takes a descriptor too
    except (OSError, ValueError, AttributeError):
        return True
    return not stat.S_ISREG(mode)


class _LineIndex:
    """Where each line's bytes start in the stream, and how to find a byte's column in the line.

    Two integers per line with data: the stream offset of its first byte, and its line number,
    first column and spacing packed in one (the text reader appends them itself, inline).
    """

    def __init__(self) -> None:
        self.starts = array("q")   # stream offset of the line's first byte (increasing)
        self.where = array("q")    # line << 32 | first column << 2 | spacing (3 "FA AF", 2 "FAAF", 0 uneven)
        self.uneven: dict[int, array] = {}  # index -> the column of every byte, for uneven lines
        self.end = 0               # stream offset after the last byte indexed

    def locate(self, offset: int) -> tuple[int, int] | None:
        if offset < 0 or offset >= self.end:
            return None
        i = bisect_right(self.starts, offset) - 1
        k = offset - self.starts[i]
        w = self.where[i]
        step = w & 3
        col = ((w >> 2) & 0x3FFFFFFF) + step * k if step else self.uneven[i][k]
        return w >> 32, col


def _sane_times(chunks: Iterator[Chunk], path: str) -> Iterator[Chunk]:
    """Another tool's chunks, each time checked: one that is not finite, after the year 2100, or more
    than 130 years before the capture's start is an input error naming the byte (a reader that knows
    the line checks its times first; this catches what it lets through)."""
    offset = 0
    try:
        for chunk in chunks:
            t = chunk[1]
            if t is not None and not -timeunit.EPOCH_MAX <= t <= timeunit.EPOCH_MAX:
                why = (timeunit.problem(t) if not math.isfinite(t) or t > 0
                       else "is more than 130 years before its start")
                raise CaptureError(f"{path}: the time {t:g} s of the byte at stream offset {offset} {why}")
            offset += len(chunk[0])
            yield chunk
    finally:
        close = getattr(chunks, "close", None)
        if close is not None:
            close()  # the reader's own cleanup, while its file is still open


def _closing(chunks: Iterator[Chunk], f: BinaryIO) -> Iterator[Chunk]:
    """A foreign reader's chunks, closing the file when they end or the reader is closed."""
    try:
        yield from chunks
    finally:
        f.close()


def _read_binary(f: BinaryIO) -> Iterator[Chunk]:
    read = getattr(f, "read1", None) or f.read
    try:
        while True:
            block = read(_READ_SIZE)
            if not block:
                return
            yield bytes(block), None
    finally:
        f.close()


# A timestamped capture's first chunks are held back until their spacing tells the unit of their times
# (rs30x_sniff.sources.timeunit): at most _UNIT_SAMPLE, fewer when the spacing is clear sooner (at a checkpoint),
# so a live pipe of timestamped lines waits only for its first few dozen.
_UNIT_SAMPLE = 512
_UNIT_CHECKPOINTS = frozenset((32, 128))
_SampledLine = tuple  # (data, time as written, its token, line number, its column)
_EPOCH_MAX = timeunit.EPOCH_MAX


class _Lines:
    """A text capture's lines as UTF-8 bytes with LF line ends, whatever its encoding (a UTF-16 or UTF-8
    byte-order mark) and line ends (LF, CRLF, CR alone: old Mac tools). ``readline()`` gives one line
    (at most _MAX_LINE bytes), b"" at the end, and None when a stream has sent nothing for IDLE_WAIT
    (so what is pending can be handed on: a pipe streams line by line)."""

    readline: Callable[[], bytes | None]  # set by __init__ for the kind of stream

    def __init__(self, opened: _Opened) -> None:
        self.opened = opened
        enc = opened.encoding
        f = opened.stream
        if not opened.seekable and opened.fd is not None:
            self._stream(opened, enc)
        elif enc in _READ_ENCODINGS or _LONE_CR.search(opened.head[:-1] if not opened.complete else opened.head):
            # Decoded with universal newlines; a comment's bytes that are not UTF-8 pass through as they were.
            text = io.TextIOWrapper(f, encoding="utf-16" if enc in _READ_ENCODINGS else "utf-8-sig",
                                    errors="replace" if enc in _READ_ENCODINGS else "surrogateescape", newline=None)
            self.readline = lambda: text.readline(_MAX_LINE).encode("utf-8", "surrogateescape")
            self._close = text.close
        else:
            self.readline = lambda: f.readline(_MAX_LINE)
            self._close = f.close
            if opened.seekable:
                self.whole_lines = self._whole_lines

    # Many lines at a time (_read_text's plain lines): a file read as it is, LF line ends (else None).
    whole_lines: Callable[[], bytes | None] | None = None

    def _whole_lines(self) -> bytes | None:
        """Up to _BLOCK_SIZE bytes of whole lines, each ending in LF; b"" at the end; None when not even one
        line ends within them (a last line without its LF, a longer line): readline() takes the next line."""
        f = self.opened.stream
        block = f.read(_BLOCK_SIZE)
        if not block:
            return b""
        cut = block.rfind(b"\n") + 1
        if cut < len(block):
            f.seek(cut - len(block), io.SEEK_CUR)  # the cut line is read with the next block
            if not cut:
                return None
            block = block[:cut]
        return block

    def _stream(self, opened: _Opened, enc: str | None) -> None:
        fd = opened.fd
        self._fd = fd
        self._buf = bytearray()
        self._raw = [opened.head]  # the head, then what os.read gives
        self._dec = codecs.getincrementaldecoder(enc)("replace") if enc in _READ_ENCODINGS else None
        self._cr = False  # the last byte taken was a CR, whose LF may come in the next read
        self._eof = False
        self._close = opened.stream.close
        self.readline = self._stream_line

    def _feed(self, data: bytes, final: bool = False) -> None:
        if self._dec is not None:
            data = self._dec.decode(data, final).encode("utf-8")
        if self._cr and data.startswith(b"\n"):
            data = data[1:]
        if data:
            self._cr = data.endswith(b"\r")
            if b"\r" in data:
                data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
            self._buf += data

    def _stream_line(self) -> bytes | None:
        buf = self._buf
        while True:
            end = buf.find(b"\n")
            if end >= 0 or len(buf) >= _MAX_LINE:
                n = end + 1 if 0 <= end < _MAX_LINE else _MAX_LINE
                line = bytes(buf[:n])
                del buf[:n]
                return line
            if self._eof:
                line = bytes(buf)
                buf.clear()
                return line
            if self._raw:
                data = self._raw.pop()
            elif not _ready(self._fd, IDLE_WAIT):  # type: ignore[arg-type]
                return None
            else:
                data = os.read(self._fd, _READ_SIZE)  # type: ignore[arg-type]
            if not data:
                self._eof = True
                self._feed(b"", final=True)
            else:
                self._feed(data)

    def close(self) -> None:
        self._close()


def _read_text(lines: _Lines, path: str, timestamped: bool, index: _LineIndex | None,
               time_unit: str | None = None, decided: Callable[[TimeUnit], None] | None = None,
               now: float | None = None) -> Iterator[Chunk]:
    """The chunks of a hex or timestamped-hex capture; each line with data is indexed in ``index``
    for locate(), unless it is None. An error names the line whether or not there is an index.

    A timestamped capture's times come out in seconds: read in ``time_unit`` (s, ms, us, ns) if
    given, else in the unit the spacing of the first chunks tells; ``decided`` hears the unit once.
    ``now`` (the wall clock, seconds since the epoch) rules out epoch times more than a day ahead.
    A stream's pending lines are handed on when it goes quiet (the unit decided by the lines so far
    if they tell it, else after SAMPLE_PATIENCE of quiet), so a pipe's lines come out as they come in.
    """
    pending = bytearray()  # untimed hex lines are merged into larger chunks
    readline = lines.readline
    quiet = 0.0  # seconds a stream has sent nothing, since the last line
    if index is not None:
        starts, where, uneven = index.starts.append, index.where.append, index.uneven
    offset = 0
    lineno = 0
    unit: TimeUnit | None = None
    exp = 0  # the unit's power of ten below a second, once known
    sample: list[_SampledLine] = []
    whole_lines = lines.whole_lines if timestamped else None
    backlog: list[bytes] = []  # lines of a block _plain_lines declined, last first, read one by one

    def settle(found: TimeUnit) -> Iterator[Chunk]:
        """The unit is known: said once, and the sampled lines handed on in it."""
        nonlocal unit, exp
        unit, exp = found, found.exponent
        if decided is not None:
            decided(unit)
        yield from _in_seconds(sample, unit, path)
        sample.clear()

    try:
        while True:
            line: bytes | None
            if backlog:
                line = backlog.pop()
            else:
                if whole_lines is not None and unit is not None and not exp:  # times in seconds, as written
                    block = whole_lines()
                    if block:
                        chunks = _plain_lines(block, offset, lineno, index)
                        if chunks is not None:
                            lineno += len(chunks[1])
                            offset = index.end if index is not None else offset + sum(map(len, chunks[0]))
                            yield from zip(*chunks)
                            continue
                        backlog = [ln + b"\n" for ln in block.split(b"\n")[-2::-1]]
                        line = backlog.pop()
                    else:
                        line = b"" if block == b"" else readline()
                else:
                    line = readline()
            if line is None:  # a stream gone quiet: hand on what is pending
                quiet += IDLE_WAIT
                if pending:
                    yield bytes(pending), None
                    pending.clear()
                if sample and unit is None and time_unit is None:
                    found = _sampled_unit(sample, now)
                    if found.how in (timeunit.SPACING, timeunit.SIZE) or quiet >= SAMPLE_PATIENCE:
                        yield from settle(found)
                continue
            if not line:
                break
            quiet = 0.0
            lineno += 1
            if len(line) == _MAX_LINE and not line.endswith(b"\n"):
                raise CaptureError(f"{path}:{lineno}: the line is longer than {_MAX_LINE >> 20} MiB: "
                                   "not a text capture", line=lineno)
            if lineno == 1 and line.startswith(_BOM):
                line = line[len(_BOM):]
            body = line.partition(b"#")[0]
            base = 0  # column of body[0] in the line, 0-based
            t = None
            if timestamped:
                parts = body.split(None, 1)
                if not parts:
                    continue
                head = parts[0]
                rest = parts[1] if len(parts) > 1 else b""
                if not _NUMBER.match(head):
                    raise CaptureError(f"{path}:{lineno}: expected a time in seconds, got {_show(head)}",
                                       line=lineno, column=len(body) - len(body.lstrip()) + 1)
                t = float(head)
                if not (t >= 0 and math.isfinite(t)):
                    raise CaptureError(f"{path}:{lineno}: time {_show(head)} is not a finite, non-negative number",
                                       line=lineno, column=len(body) - len(body.lstrip()) + 1)
                tbody = body
                base = len(body) - len(rest)
                body = rest
            try:
                # fromhex skips the whitespace between bytes: one C call per line.
                data = bytes.fromhex(body.decode("ascii"))
            except (ValueError, UnicodeDecodeError):
                bad, col = _bad_token(body)
                raise CaptureError(f"{path}:{lineno}: not a hex byte: {_show(bad)}",
                                   line=lineno, column=base + col) from None
            n = len(data)
            if not n:
                continue
            if index is not None:
                # Index the line for locate(): its bytes are evenly spaced unless the text says otherwise.
                stripped = body.lstrip()
                first = base + len(body) - len(stripped) + 1
                width = len(stripped.rstrip())
                if width == 3 * n - 1 and stripped[2:width:3] == b" " * (n - 1):
                    step = 3
                elif width == 2 * n:
                    step = 2
                else:
                    step = 0
                    uneven[len(index.starts)] = array(
                        "q", (base + m.start() + 1 for m in _HEX_PAIR.finditer(body)))
                starts(offset)
                where(lineno << 32 | first << 2 | step)
                index.end = offset + n
            offset += n
            if timestamped:
                if unit is None:
                    if time_unit is None:
                        sample.append((data, t, head, lineno, len(tbody) - len(tbody.lstrip()) + 1))
                        k = len(sample)
                        if k < _UNIT_SAMPLE and k not in _UNIT_CHECKPOINTS:
                            continue
                        found = _sampled_unit(sample, now)
                        if k < _UNIT_SAMPLE and found.how != timeunit.SPACING:
                            continue  # not clear yet: sample on
                        yield from settle(found)
                        continue
                    unit = timeunit.given(time_unit, t, now)
                    exp = unit.exponent
                    if decided is not None:
                        decided(unit)
                if exp or t > _EPOCH_MAX:  # type: ignore[operator]
                    t = _seconds(t, head, unit, path, lineno, len(tbody) - len(tbody.lstrip()) + 1)  # type: ignore[arg-type]
                yield data, t
            else:
                pending += data
                if len(pending) >= _READ_SIZE:
                    yield bytes(pending), None
                    pending.clear()
        if pending:
            yield bytes(pending), None
        if sample:
            yield from settle(_sampled_unit(sample, now))
    except CaptureError:
        if sample and unit is None:
            # A bad line within the sample: the lines before it are read (in the unit they tell) first.
            yield from settle(_sampled_unit(sample, now))
        raise
    finally:
        lines.close()


# The bytes of plain timestamped lines (_plain_lines): a time as written (digits and a point), hex digits,
# spaces and LF. Anything else (a comment, a sign, an exponent, nan, a tab, CR, an underscore float() would
# read) is for the line-by-line reader, which says what is wrong.
_PLAIN_BYTES = b"0123456789abcdefABCDEF. \n"


def _plain_lines(block: bytes, offset: int, lineno: int, index: _LineIndex | None) -> tuple[list, list] | None:
    """The (bytes, times) of a block of whole lines that are each "TIME HH HH ..." or "TIME HHHH..." (a time in
    seconds as written, digits and a point, then the bytes one space apart or with none), each line indexed in
    ``index`` as _read_text indexes it (``offset``, ``lineno``: the stream offset and line number before the
    block); None, and nothing indexed, when any line is otherwise (_read_text then reads them one by one, and says
    what is wrong). The same chunks as line by line, with C loops over the block's lines for the Python of each."""
    if block.translate(None, _PLAIN_BYTES):
        return None
    import numpy as np  # a text capture's reader only (numpy is no start-up cost of every command)

    a = np.frombuffer(block, dtype=np.uint8)
    if (a[1:][a[:-1] == 32] <= 32).any():  # a space before a space or LF (a line starting with one has no time)
        return None
    rows = block.decode("ascii").split("\n")
    rows.pop()  # after the last LF
    parts = list(map(str.partition, rows, repeat(" ")))
    heads, rests = list(map(itemgetter(0), parts)), list(map(itemgetter(2), parts))
    try:
        times = list(map(float, heads))  # digits and points only: what _NUMBER reads, or a ValueError
        data = list(map(bytes.fromhex, rests))
    except ValueError:
        return None
    if min(times) < 0 or max(times) > _EPOCH_MAX:  # (a time after 2100 is the line reader's to refuse)
        return None
    n = np.fromiter(map(len, data), np.int64, len(data))
    width = np.fromiter(map(len, rests), np.int64, len(rests))
    # No space doubled, none at either end, the bytes pairs: one space between every two bytes, or none.
    step = np.where(width == 3 * n - 1, 3, np.where(width == 2 * n, 2, 0))
    if not ((step > 0) & (n > 0)).all():  # (a line of its own spacing: see _LineIndex)
        return None
    if index is not None:
        first = np.fromiter(map(len, heads), np.int64, len(heads)) + 2  # the column after "TIME "
        ends = np.cumsum(n) + offset
        lines = np.arange(lineno + 1, lineno + 1 + len(rows), dtype=np.int64)
        index.starts.frombytes((ends - n).tobytes())
        index.where.frombytes((lines << 32 | first << 2 | step).tobytes())
        index.end = int(ends[-1])
    return data, times


def _sampled_unit(sample: list[_SampledLine], now: float | None = None) -> TimeUnit:
    """The unit the sampled lines' times are in (their resolution as written keeps rounding from
    counting as gaps or overlaps). The resolution most lines are written in, the coarser on a tie: one
    odd line (the tail of a line cut by `tail -c`, whose first hex byte reads as a whole number) must
    not make the whole capture look written in whole seconds."""
    step = max(Counter(timeunit.resolution(line[2].decode("ascii")) for line in sample).most_common(),
               key=lambda kv: (kv[1], kv[0]))[0]
    return timeunit.detect_unit([(line[0], line[1]) for line in sample], step=step, now=now)


def _in_seconds(sample: list[_SampledLine], unit: TimeUnit, path: str) -> Iterator[Chunk]:
    for data, t, head, lineno, column in sample:
        yield data, _seconds(t, head, unit, path, lineno, column)


def _seconds(t: float, head: bytes, unit: TimeUnit, path: str, lineno: int, column: int) -> float:
    """A time as written (``t``, from the token ``head``) in seconds, or a CaptureError for a time after 2100."""
    if unit.exponent:
        t = timeunit.seconds(head.decode("ascii"), unit.unit)
    if t > timeunit.EPOCH_MAX:
        raise CaptureError(f"{path}:{lineno}: time {_show(head)} in {timeunit.NAMES[unit.unit]} is after the year "
                           f"2100 (--time-unit to read it in another unit)", line=lineno, column=column)
    return t


def _bad_token(body: bytes) -> tuple[bytes, int]:
    """The first token of ``body`` that is not hex bytes, and its 1-based column."""
    for m in _TOKEN.finditer(body):
        if not _HEX_TOKEN.match(m.group()):
            return m.group(), m.start() + 1
    found = _TOKEN.search(body)
    return (found.group(), found.start() + 1) if found else (body, 1)


def _show(token: bytes) -> str:
    return repr(token.decode("utf-8", "replace")[:20])


# ---- writers -------------------------------------------------------------------------------------
def write_capture(path: str | Path, chunks: Iterable[Chunk], fmt: str) -> int:
    """Write chunks as a capture of ``fmt`` (bin, hex or timestamped); returns the bytes written."""
    total = 0
    if fmt == BINARY:
        with open(path, "wb") as f:
            for data, _ in chunks:
                f.write(data)
                total += len(data)
        return total
    if fmt not in (HEX, TIMESTAMPED):
        raise CaptureError(f"{path}: cannot write format {fmt!r}")
    with open(path, "w", encoding="ascii") as f:
        for data, t in chunks:
            if not data:
                continue
            hexs = data.hex(" ").upper()
            if fmt == TIMESTAMPED:
                f.write(f"{(t or 0.0):.6f} {hexs}\n")
            else:
                f.write(hexs + "\n")
            total += len(data)
    return total


def format_for_output(path: str, fmt: str | None) -> str:
    """The capture format to write ``path`` in: the explicit one, else by extension."""
    if fmt:
        return fmt
    ext = Path(path).suffix.lower()
    if ext in (".bin", ".raw"):
        return BINARY
    if ext == ".mcap":
        return MCAP
    return TIMESTAMPED if ext in (".thex", ".log") else HEX
