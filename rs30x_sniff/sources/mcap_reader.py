"""Read the /rs30x/raw channel of any writer's MCAP back as (bytes, t) chunks, surviving a killed writer and damage."""

from __future__ import annotations

import base64
import binascii
import json
import math
import os
import stat
import struct
import zlib
from typing import Any, BinaryIO
from collections.abc import Callable, Iterator

import zstandard
from mcap.opcode import Opcode

from ..protocol.chunks import SENDERS, UART_ERRORS, Marked, SourceGap
from ..protocol.mcap_names import (GAP_METADATA_NAME, GAPS_METADATA_NAME, MCAP_MAGIC, METADATA_NAME,
                                   MODELS_METADATA_NAME, RAW_ENCODING, RAW_SCHEMA, RAW_TOPIC)
from .base import CaptureError, CaptureWarning, open_capture, stderr_warning

_RECORD_HEAD = struct.Struct("<BQ")
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_MESSAGE_HEAD = struct.Struct("<HIQQ")       # channel, sequence, log time, publish time
_CHUNK_HEAD = struct.Struct("<QQQI")         # start and end time, uncompressed size and CRC
_TOOL = "rs30x-sniff"
# Our writer cuts chunks at a few MiB: a record or chunk claiming more is damage, and is not
# given the memory it asks for.
_MAX_RECORD = 1 << 30
_MAX_CHUNK = 256 << 20
# Record types that belong to the summary section, never between the header and Data End.
_SUMMARY_ONLY = {Opcode.FOOTER, Opcode.CHUNK_INDEX, Opcode.ATTACHMENT_INDEX, Opcode.STATISTICS,
                 Opcode.METADATA_INDEX, Opcode.SUMMARY_OFFSET}
_KNOWN = {int(op) for op in Opcode}
# Raw messages that arrive ahead of a gap in the capture bytes (another writer's chunk order, a copy
# sorted by log time where the capture's clock went back) wait for it up to this much capture data;
# a gap still open then, or at the end of the file, is a hole: reading stops before it.
_MAX_PENDING = 64 << 20
# The largest capture time an MCAP log time (nanoseconds in 64 bits) can hold, about year 2554.
MAX_TIME = (2 ** 64 - 1) / 1e9

_stderr_warning = stderr_warning  # kept: the name other modules knew

# (bytes, capture time, log time ns, marks): marks is None, or (sender, error) as the capture recorded
# them (rs30x_sniff.protocol.chunks), for a log converted from another tool's capture.
Raw = tuple[bytes, float | None, int, "tuple[str | None, str | None] | None"]


class _Damage(Exception):
    """The bytes at ``pos`` are not what an rs30x-sniff MCAP holds there."""

    def __init__(self, pos: int, what: str, chunks: int | None = None) -> None:
        super().__init__(what)
        self.pos = pos
        self.what = what
        self.chunks = chunks  # the chunks before it, where that is not the count read so far


class _Bad(Exception):
    """A record body that does not parse (the caller knows where it is)."""


class _Body:
    """Strict little-endian reads from one record body: reading past its end is damage, not a short read."""

    __slots__ = ("data", "pos")

    def __init__(self, data: bytes, pos: int = 0) -> None:
        self.data = data
        self.pos = pos

    def take(self, n: int) -> bytes:
        end = self.pos + n
        if n < 0 or end > len(self.data):
            raise _Bad(f"a field runs past the end of its record ({n} bytes)")
        out = self.data[self.pos:end]
        self.pos = end
        return out

    def u16(self) -> int:
        return _U16.unpack(self.take(2))[0]

    def u32(self) -> int:
        return _U32.unpack(self.take(4))[0]

    def u64(self) -> int:
        return _U64.unpack(self.take(8))[0]

    def string(self) -> str:
        try:
            return str(self.take(self.u32()), "utf-8")
        except UnicodeDecodeError:
            raise _Bad("a string that is not UTF-8") from None

    def string_map(self) -> dict[str, str]:
        inner = _Body(self.take(self.u32()))
        out: dict[str, str] = {}
        while inner.pos < len(inner.data):
            k = inner.string()
            out[k] = inner.string()
        return out

    def done(self) -> None:
        if self.pos != len(self.data):
            raise _Bad(f"{len(self.data) - self.pos} bytes left over in the record")


class McapRawReader:
    """Iterates ``(data, t, log_time_ns, marks)`` of every /rs30x/raw message in capture order.

    Reads the data section record by record, so a file cut anywhere (no summary, no footer, half a
    chunk) is read up to its last complete chunk, and a damaged one up to the last whole chunk before
    the damage; either way ``warn`` is called once with a line saying where reading stopped (the byte
    offset) and what was lost, and the same is kept in ``warnings`` as a
    :class:`~rs30x_sniff.sources.captures.CaptureWarning`. Every chunk is checked (lengths, CRC, and the
    stream offsets of its raw messages following on from the last), so what is returned is always
    the start of the capture, never a capture with a hole.

    The file is known by its content, not by who wrote it: the channel with topic /rs30x/raw, schema
    rs30x.Raw and JSON bodies, whatever the header's library, the record order (chunked or not, raw
    messages put back in stream order), the summary (none needed) or the metadata (defaults, said
    once, where it has none). A copy that starts later in the stream (trimmed by time) is read from its first byte,
    and says so (such notes go to ``warn`` only: nothing was lost). A file with no readable rs30x data (not an MCAP,
    another tool's MCAP, damage before the first chunk), another encoding on /rs30x/raw, or a time that is not a
    finite number an MCAP log time can hold, is a CaptureError.
    ``t`` is None where the capture had no timestamps (``log_time_ns`` is then synthetic).
    ``metadata`` fills in as the file is read (it sits at the start of files we write).
    An MCAP needs a seekable file: a pipe is refused with a CaptureError.

    With ``gaps``, where the recording's port was lost and found again (the writer's ``rs30x.gap`` records, or
    an older file's ``rs30x.gaps`` list placed by time) comes out as a
    :class:`~rs30x_sniff.protocol.chunks.SourceGap` before the first byte after it, as the live source gave
    it: the decoder makes it the same seam (F010, nothing paired across it), and a file written from this
    reading keeps it.
    """

    def __init__(self, path: str, warn: Callable[[str], None] | None = stderr_warning, *, gaps: bool = False) -> None:
        self.path = path
        self.warn = warn
        self.with_gaps = gaps
        self.gaps: list[SourceGap] = []  # the recording's gaps, once iterated with ``gaps``
        self._order_start = 0  # the stream offset the first raw message released starts at (not 0: a trimmed copy)
        self.warnings: list[CaptureWarning] = []
        self.metadata: dict[str, dict[str, str]] = {}
        self.complete: bool | None = None  # known once iterated: False if the file was cut short or damaged
        self.damaged_at: int | None = None  # file offset of the damage that stopped reading
        self.lost_bytes = 0
        self.chunks = 0
        self.raw_bytes = 0  # capture bytes returned so far

    def _open(self) -> tuple[BinaryIO, int]:
        path = self.path
        f = open_capture(path)  # "-": stdin, which must be a regular file (decode - < x.mcap)
        try:
            st = os.fstat(f.fileno())
            if not stat.S_ISREG(st.st_mode) or not f.seekable():
                raise CaptureError(f"{path}: an MCAP capture needs a seekable file, not a pipe "
                                   "(save it to a file first)")
        except BaseException:
            f.close()
            raise
        return f, st.st_size

    def __iter__(self) -> Iterator[Raw]:
        f, size = self._open()
        with f:
            try:
                if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                    raise CaptureError(f"{self.path}: not an MCAP file (bad magic)")
                if not self.with_gaps:
                    yield from self._records(f, size)
                    return
                placed = _gaps_of(_scan_metadata(f, size, (GAP_METADATA_NAME, GAPS_METADATA_NAME)))
                self.gaps = [g for _, g in placed]
                f.seek(len(MCAP_MAGIC))
                yield from _placed(self._records(f, size), placed, lambda: self._order_start)
            except OSError as e:
                raise CaptureError(f"{self.path}: cannot read: {e.strerror or e}") from None

    # ---- the data section ------------------------------------------------------------------------
    def _records(self, f: BinaryIO, size: int) -> Iterator[Raw]:
        path = self.path
        state = _State()
        pos = len(MCAP_MAGIC)
        try:
            while True:
                head = f.read(_RECORD_HEAD.size)
                if len(head) < _RECORD_HEAD.size:
                    self._cut(pos, size, state)
                    break
                opcode, length = _RECORD_HEAD.unpack(head)
                if opcode not in _KNOWN:
                    raise _Damage(pos, f"an unknown record type 0x{opcode:02x}")
                if pos == len(MCAP_MAGIC) and opcode != Opcode.HEADER:
                    raise CaptureError(f"{path}: not an MCAP file (no header record)")
                if length > _MAX_RECORD:
                    raise _Damage(pos, f"a record length of {length} bytes")
                body_pos = pos + _RECORD_HEAD.size
                if length > size - body_pos:
                    # The record runs past the end of the file: a writer stopped mid-record, unless
                    # what there is of the record already contradicts its length.
                    _check_prefix(opcode, length, f.read(min(64, size - body_pos)), pos)
                    self._cut(pos, size, state)
                    break
                body = f.read(length)
                if len(body) != length:
                    self._cut(pos, size, state)
                    break
                try:
                    if opcode == Opcode.DATA_END:
                        if length != 4:
                            raise _Bad("a Data End record that is not 4 bytes")
                        self.complete = True
                        break
                    yield from self._record(opcode, body, pos, state)
                except _Bad as e:
                    raise _Damage(pos, f"a damaged {_name(opcode)} record ({e})") from None
                pos = body_pos + length
            # The data section ends (whole or cut): raw messages still waiting for a gap are past a hole.
            yield from self._released(state.order.finish(), state)
            state.order.check()
        except _Damage as d:
            self._damaged(d, size, state)
        finally:
            if self.complete is None:
                self.complete = False
        if state.raw_channel is None:
            if state.header and not state.ours():
                # Another tool's MCAP: say who wrote it. The name is the file's text: shown quoted if it
                # is not plain, so the error stays one line.
                library = state.library or ""
                shown = library if library.isprintable() and len(library) <= 60 else repr(library[:60])
                raise CaptureError(f"{path}: not an rs30x-sniff MCAP (written by "
                                   f"{shown or 'an unnamed tool'}; it has no {RAW_TOPIC} channel)")
            if self.chunks:
                raise CaptureError(f"{path}: an MCAP without a {RAW_TOPIC} channel: nothing to decode")
        elif METADATA_NAME not in self.metadata and state.raw_messages:
            # Another writer's copy without our metadata: what the capture's settings were is not known.
            self._note(f"{path}: no {METADATA_NAME!r} metadata in this MCAP: its baud rate, time base and "
                       "servo models are not recorded (the defaults, or --baud and --model, apply)")

    def _record(self, opcode: int, body: bytes, pos: int, state: _State) -> Iterator[Raw]:
        b = _Body(body)
        if opcode == Opcode.HEADER:
            if state.header:
                raise _Bad("a second header")
            b.string()
            library = b.string()
            b.done()
            # Who wrote the file decides nothing (its channels do): kept for what is said about it.
            state.library = library
            state.header = True
            return
        if opcode == Opcode.METADATA:
            try:
                name = b.string()
                values = b.string_map()
                b.done()
            except _Bad as e:
                # Only descriptive text: the data can still be read (if the record's length was the
                # damaged part, the next record says so).
                self._warn(f"{self.path}: ignored a damaged metadata record at byte {pos} ({e})", pos, 0)
                return
            self.metadata[name] = values
            state.metadata.add(name)
            return
        if opcode == Opcode.CHUNK:
            messages = self._chunk(b, pos, state)
            self.chunks += 1
            yield from self._released(state.order.add(messages, pos, self.chunks - 1), state)
            state.order.check()
            return
        if opcode in (Opcode.CHANNEL, Opcode.MESSAGE, Opcode.SCHEMA):
            out = self._inner(opcode, b, pos, state)
            if out is not None:
                yield from self._released(state.order.add([out], pos, self.chunks), state)
                state.order.check()
            return
        if opcode == Opcode.MESSAGE_INDEX:
            b.u16()
            n = b.u32()
            if n % 16:
                raise _Bad("a message index of a partial entry")
            b.take(n)
            b.done()
            return
        if opcode in _SUMMARY_ONLY:
            raise _Bad("a summary record before Data End")
        # Attachments and anything else a reader may skip: not needed to get the bytes back.

    def _chunk(self, b: _Body, pos: int, state: _State) -> list[tuple[int | None, Raw]]:
        _, _, size, crc = _CHUNK_HEAD.unpack(b.take(_CHUNK_HEAD.size))
        compression = b.string()
        data = b.take(b.u64())
        b.done()
        if size > _MAX_CHUNK:
            raise _Bad(f"an uncompressed size of {size} bytes")
        if compression == "zstd":
            try:
                # The frame says how much it holds: checked first, so damage cannot ask for gigabytes.
                content = zstandard.frame_content_size(data)
                if content != size and content != -1:
                    raise _Bad("its size does not match its compressed data")
                raw = zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
            except zstandard.ZstdError as e:
                raise _Bad(f"zstd: {e}") from None
        elif compression == "lz4":
            try:
                import lz4.frame
            except ImportError:
                raise CaptureError(f"{self.path}: the chunk at byte {pos} is lz4-compressed: "
                                   "install the lz4 package to read it") from None
            try:
                raw = lz4.frame.decompress(bytes(data))
            except Exception as e:  # lz4 raises RuntimeError and friends
                raise _Bad(f"lz4: {e}") from None
        elif compression == "":
            raw = bytes(data)
        else:
            raise _Bad(f"an unknown compression {compression[:20]!r}")
        if len(raw) != size:
            raise _Bad("its size does not match its data")
        if crc and zlib.crc32(raw) != crc:
            raise _Bad("its CRC does not match its data")
        # Decode the whole chunk before returning any of it: a chunk is returned whole or not at all.
        out: list[tuple[int | None, Raw]] = []
        inner = _Body(raw)
        while inner.pos < len(raw):
            opcode = inner.take(1)[0]
            rec = _Body(inner.take(inner.u64()))
            if opcode in (Opcode.CHANNEL, Opcode.MESSAGE, Opcode.SCHEMA):
                m = self._inner(opcode, rec, pos, state)
                if m is not None:
                    out.append(m)
        return out

    def _inner(self, opcode: int, b: _Body, pos: int, state: _State) -> tuple[int | None, Raw] | None:
        """A schema, channel or message record (in a chunk, or not): the raw message it is, if one,
        with the stream offset it says it starts at (None from a writer that did not say)."""
        if opcode == Opcode.SCHEMA:
            sid = b.u16()
            name = b.string()
            b.string()
            b.take(b.u32())
            b.done()
            state.schemas[sid] = name
            return None
        if opcode == Opcode.CHANNEL:
            cid = b.u16()
            sid = b.u16()
            topic = b.string()
            encoding = b.string()
            b.string_map()
            b.done()
            if topic == RAW_TOPIC:
                self._raw_channel(cid, sid, encoding, state)
            return None
        channel, _, log_time, _ = _MESSAGE_HEAD.unpack(b.take(_MESSAGE_HEAD.size))
        if channel != state.raw_channel:
            return None
        state.raw_messages += 1
        try:
            obj = json.loads(b.take(len(b.data) - b.pos))
            data = base64.b64decode(obj["data"], validate=True)
            t = obj["t"]
            offset = obj.get("offset")
            length = obj.get("length")
            sender, error = obj.get("sender"), obj.get("error")
            if (sender is not None and sender not in SENDERS) or (error is not None and error not in UART_ERRORS):
                raise ValueError("a mark we do not write")
            if not (t is None or type(t) in (int, float)) or not all(
                    v is None or (type(v) is int and v >= 0) for v in (offset, length)):
                raise ValueError("a value of the wrong type")
        except (ValueError, KeyError, TypeError, AttributeError, binascii.Error):
            raise _Bad(f"a {RAW_TOPIC} message that is not what we write") from None
        if t is not None:
            # JSON as Python reads it takes NaN and Infinity, and numbers no clock reaches: an input
            # error where it is, not a traceback (or NaN in JSON output) further on.
            if not (isinstance(t, float) and math.isfinite(t) or isinstance(t, int)) or abs(t) > MAX_TIME:
                shown = json.dumps(t) if isinstance(t, float) else f"{t:.6g}" if abs(t) < 10 ** 300 else "(huge)"
                raise CaptureError(f"{self.path}: {RAW_TOPIC} message {state.raw_messages} (log time {log_time} ns, "
                                   f"in the record at byte {pos}): time {shown} is not a finite number of "
                                   f"seconds an MCAP log time can hold (|t| <= {MAX_TIME:.3g} s)")
            t = float(t)
        if length is not None and length != len(data):
            raise _Bad(f"a {RAW_TOPIC} message of {len(data)} bytes that says {length}")
        return offset, (data, t, log_time, (None if sender is None and error is None else (sender, error)))

    def _raw_channel(self, cid: int, sid: int, encoding: str, state: _State) -> None:
        """A channel on /rs30x/raw: the one to read, if its schema and encoding are ours."""
        schema = state.schemas.get(sid)
        if sid and schema is not None and schema != RAW_SCHEMA:
            shown = schema if schema.isprintable() and len(schema) <= 60 else repr(schema[:60])
            raise CaptureError(f"{self.path}: not an rs30x-sniff capture: its {RAW_TOPIC} channel has the "
                               f"schema {shown or '(unnamed)'}, not {RAW_SCHEMA}")
        if encoding != RAW_ENCODING:
            shown = encoding if encoding.isprintable() and len(encoding) <= 40 else repr(encoding[:40])
            raise CaptureError(f"{self.path}: unsupported encoding {shown or '(none)'} on {RAW_TOPIC} "
                               f"(rs30x-sniff reads {RAW_SCHEMA} messages in {RAW_ENCODING})")
        if state.raw_channel not in (None, cid):
            raise _Bad(f"a second {RAW_TOPIC} channel")
        state.raw_channel = cid

    def _released(self, raws: list[Raw], state: _State) -> list[Raw]:
        """Raw messages now in stream order: counted, and a late start said once."""
        order = state.order
        self._order_start = order.start
        if order.start and not state.said_start:
            state.said_start = True
            self._note(f"{self.path}: the capture starts at byte {order.start} of the recorded stream "
                       "(a copy trimmed by time?): offsets here count from there")
        for r in raws:
            self.raw_bytes += len(r[0])
        return raws

    # ---- what reading lost ---------------------------------------------------------------------
    def _warn(self, text: str, offset: int | None, lost: int) -> None:
        self.warnings.append(CaptureWarning(self.path, text, offset, lost))
        if self.warn is not None:
            self.warn(text)

    def _note(self, text: str) -> None:
        # Said (to ``warn``), but not one of ``warnings``: nothing was lost, the file is read whole.
        if self.warn is not None:
            self.warn(text)

    def _cut(self, pos: int, size: int, state: _State) -> None:
        # The writer stopped before the end of the data section: everything up to ``pos`` is whole.
        self.complete = False
        self.lost_bytes = size - pos
        if self.lost_bytes:
            text = (f"{self.path}: the file ends mid-record (was its writer stopped?): read "
                    f"{self.chunks} complete chunks, lost the last {self.lost_bytes} bytes (from byte {pos})")
        else:
            text = (f"{self.path}: the file has no summary or footer (was its writer stopped?): "
                    f"read all {self.chunks} chunks")
        self._warn(text, pos, self.lost_bytes)

    def _damaged(self, d: _Damage, size: int, state: _State) -> None:
        self.complete = False
        self.damaged_at = d.pos
        self.lost_bytes = size - d.pos
        if not state.header:
            raise CaptureError(f"{self.path}: corrupt MCAP at byte {d.pos}, in its header ({d.what}): "
                               "not a readable rs30x-sniff MCAP")
        if d.chunks is not None:
            self.chunks = d.chunks  # a hole found later: the chunks after it were read but not returned
        if not self.chunks and self.raw_bytes == 0:
            raise CaptureError(f"{self.path}: corrupt MCAP at byte {d.pos} ({d.what}), "
                               "before any capture data could be read")
        self._warn(f"{self.path}: corrupt MCAP at byte {d.pos} ({d.what}): read the {_n(self.chunks, 'chunk')} "
                   f"before it ({self.raw_bytes} capture bytes), skipped the last {self.lost_bytes} bytes",
                   d.pos, self.lost_bytes)

    # ---- metadata ------------------------------------------------------------------------------
    def read_metadata(self) -> dict[str, dict[str, str]]:
        """Read the metadata up to our own (``rs30x``) and return it, without decompressing a chunk.

        Our writer puts it first; another writer may put it after chunks (the record headers are read
        and the chunks seeked over to find it). Stops quietly at anything it does not expect: damage
        is for the full read to report.
        """
        try:
            f, size = self._open()
        except CaptureError:
            return self.metadata
        try:
            with f:
                if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                    raise CaptureError(f"{self.path}: not an MCAP file (bad magic)")
                for name, values in _scan_metadata(f, size, None):
                    self.metadata[name] = values
                    if name == METADATA_NAME:
                        break
        except OSError as e:
            raise CaptureError(f"{self.path}: cannot read: {e.strerror}") from None
        return self.metadata

    @property
    def baud(self) -> int | None:
        v = self.metadata.get(METADATA_NAME, {}).get("baud")
        return int(v) if v and v.isdigit() and len(v) < 10 else None

    @property
    def models(self) -> dict[int, str]:
        """Per-ID models: what the writer was told, then what the bus taught it (if it finished)."""
        out: dict[int, str] = {}
        for name in (METADATA_NAME, MODELS_METADATA_NAME):
            for item in self.metadata.get(name, {}).get("models", "").split(","):
                k, sep, v = item.partition("=")
                if sep and k.isdigit() and len(k) < 4:
                    out[int(k)] = v
        return out


class _State:
    __slots__ = ("header", "library", "metadata", "schemas", "raw_channel", "raw_messages", "order", "said_start")

    def __init__(self) -> None:
        self.header = False
        self.library: str | None = None
        self.metadata: set[str] = set()         # names of the metadata records read
        self.schemas: dict[int, str] = {}       # schema id -> name
        self.raw_channel: int | None = None
        self.raw_messages = 0                   # /rs30x/raw messages seen, for where an error is
        self.order = _StreamOrder()
        self.said_start = False

    def ours(self) -> bool:
        """Whether the file says it is an rs30x-sniff log (its header or metadata), channels or not."""
        return (self.library or "").startswith(_TOOL) or METADATA_NAME in self.metadata


class _StreamOrder:
    """Puts raw messages back in stream order by the offsets they carry, and finds holes.

    Our writer numbers every raw byte, so a message that does not start where the last one ended is
    either early (another writer's order: it waits, within _MAX_PENDING) or past a hole (a lost
    chunk: reading stops at the first chunk a message waiting for it came in). Where the stream starts
    is the offset 0, or, in a copy trimmed by time, the lowest offset seen once the waiting messages
    can tell no more (the end of the data section, or the limit).
    """

    __slots__ = ("next", "start", "pending", "pending_bytes", "hole")

    def __init__(self) -> None:
        self.next: int | None = None   # stream offset of the next raw byte, once the start is known
        self.start = 0
        self.pending: dict[int, tuple[Raw, int, int]] = {}  # offset -> (message, record position, chunks before)
        self.pending_bytes = 0
        self.hole = False

    def add(self, items: list[tuple[int | None, Raw]], pos: int, chunks: int) -> list[Raw]:
        """The messages of one record (a chunk's, whole), and those they release, in stream order."""
        out: list[Raw] = []
        for offset, raw in items:
            if offset is None:
                # A writer that did not number its bytes: its messages are taken in file order.
                if self.pending:
                    raise _Bad(f"a {RAW_TOPIC} message without an offset among numbered ones")
                self.next = (self.next or 0) + len(raw[0])
                out.append(raw)
                continue
            if self.next is None and offset == 0:
                self.next = 0
            if offset == self.next:
                out.append(raw)
                self.next += len(raw[0])
                self._drain(out)
                continue
            if (self.next is not None and offset < self.next) or offset in self.pending:
                raise _Bad(f"capture bytes from {offset} come twice")
            self.pending[offset] = (raw, pos, chunks)
            self.pending_bytes += len(raw[0])
        if self.pending_bytes > _MAX_PENDING:
            self._settle(out)
            self.hole = self.pending_bytes > _MAX_PENDING
        return out

    def finish(self) -> list[Raw]:
        """At the end of the data section: what waited for the start; what still waits is past a hole."""
        out: list[Raw] = []
        self._settle(out)
        self.hole = bool(self.pending)
        return out

    def check(self) -> None:
        """Damage at the first chunk whose messages wait for bytes that will not come."""
        if self.hole:
            _, pos, chunks = min(self.pending.values(), key=lambda p: p[1])
            raise _Damage(pos, f"capture bytes {self.next}..{min(self.pending)} are missing", chunks)

    def _settle(self, out: list[Raw]) -> None:
        if self.next is None and self.pending:
            self.next = self.start = min(self.pending)  # a stream that starts later: a trimmed copy
            self._drain(out)

    def _drain(self, out: list[Raw]) -> None:
        pending = self.pending
        while self.next in pending:
            raw = pending.pop(self.next)[0]
            self.pending_bytes -= len(raw[0])
            out.append(raw)
            self.next += len(raw[0])


def _n(count: int, noun: str) -> str:
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def _name(opcode: int) -> str:
    try:
        return Opcode(opcode).name.lower().replace("_", " ")
    except ValueError:
        return f"0x{opcode:02x}"


def _check_prefix(opcode: int, length: int, prefix: bytes, pos: int) -> None:
    """Damage if the first bytes of a record cut by the end of the file already contradict its length.

    A header or chunk says, inside, how long its parts are; a killed writer leaves them consistent.
    """
    b = _Body(prefix)
    try:
        if opcode == Opcode.HEADER:
            b.take(b.u32())
            expected = b.pos + 4 + b.u32()
        elif opcode == Opcode.CHUNK:
            b.take(_CHUNK_HEAD.size)
            compression = b.string()
            if compression not in ("zstd", "lz4", ""):
                raise _Damage(pos, f"a chunk with an unknown compression {compression[:20]!r}")
            expected = b.pos + 8 + b.u64()
        elif opcode == Opcode.METADATA:
            b.take(b.u32())
            expected = b.pos + 4 + b.u32()
        elif opcode == Opcode.DATA_END:
            expected = 4
        else:
            return
    except _Bad:
        return  # too little left to tell: a cut
    if expected != length:
        raise _Damage(pos, f"a {_name(opcode)} record whose length ({length}) contradicts its content ({expected})")


def _scan_metadata(f: BinaryIO, size: int, names: tuple[str, ...] | None) -> Iterator[tuple[str, dict[str, str]]]:
    """``(name, values)`` of the data section's metadata records (those named ``names``, or all), read from
    just past the magic with the other records seeked over; stops quietly at anything unexpected (a cut, damage:
    the full read reports it) and at Data End."""
    pos = len(MCAP_MAGIC)
    while True:
        head = f.read(_RECORD_HEAD.size)
        if len(head) < _RECORD_HEAD.size:
            return
        opcode, length = _RECORD_HEAD.unpack(head)
        pos += _RECORD_HEAD.size
        if length > size - pos or opcode not in _KNOWN or opcode in _SUMMARY_ONLY or \
                opcode == Opcode.DATA_END or (pos == len(MCAP_MAGIC) + _RECORD_HEAD.size
                                              and opcode != Opcode.HEADER):
            return
        if opcode != Opcode.METADATA:
            f.seek(length, os.SEEK_CUR)
            pos += length
            continue
        body = _Body(f.read(length))
        pos += length
        try:
            name = body.string()
            if names is None or name in names:
                yield name, body.string_map()
        except _Bad:
            return


def _gaps_of(records: Iterator[tuple[str, dict[str, str]]]) -> list[tuple[int | None, SourceGap]]:
    """The recording's gaps: ``(offset, SourceGap)``, the stream offset it comes before (None: an older file's,
    placed by its time), in stream order. The per-gap records are taken where the file has them (a cut file has
    no list at the end); else the list; an entry that does not read is left out."""
    one: list[dict] = []
    listed: list[dict] = []
    for name, values in records:
        try:
            if name == GAP_METADATA_NAME:
                one.append({k: json.loads(v) for k, v in values.items()})
            else:
                listed = [g for g in json.loads(values.get("gaps", "[]")) if isinstance(g, dict)]
        except ValueError:
            continue
    out = []
    for g in one or listed:
        back: Any = g.get("back_at")  # a JSON value, of any type until checked
        lost: Any = g.get("lost_at")
        why, offset = g.get("why"), g.get("offset")
        if not (type(back) in (int, float) and math.isfinite(back)):  # (a JSON true is no time)
            continue
        lost = float(lost) if type(lost) in (int, float) and math.isfinite(lost) else None
        gap = SourceGap(float(back), lost, why if isinstance(why, str) else "the source lost the line")
        out.append((offset if type(offset) is int and offset >= 0 else None, gap))
    return sorted(out, key=lambda g: (g[0] is None, g[0] or 0, g[1][1]))


def _placed(raws: Iterator[Raw], gaps: list[tuple[int | None, SourceGap]],
            start: Callable[[], int]) -> Iterator[Raw | SourceGap]:
    """``raws`` with each gap before the first raw message at or past its stream offset (or, an older file's
    gap, its time); a gap with nothing after it in the file is not given (the live source gave none either)."""
    if not gaps:
        yield from raws
        return
    waiting = list(gaps)
    pos: int | None = None
    for raw in raws:
        if pos is None:
            pos = start()
        while waiting and (waiting[0][0] <= pos if waiting[0][0] is not None
                           else raw[1] is not None and raw[1] >= waiting[0][1][1]):
            yield waiting.pop(0)[1]
        yield raw
        pos += len(raw[0])


def read_mcap_raw(path: str, warn: Callable[[str], None] | None = stderr_warning
                  ) -> Iterator[tuple[bytes, float | None]]:
    """The capture an rs30x-sniff MCAP holds: its /rs30x/raw chunks with their original timestamps, and its
    gaps (SourceGap) where the recording's port was lost."""
    for item in McapRawReader(path, warn=warn, gaps=True):
        if type(item) is SourceGap:
            yield item
            continue
        data, t, _, marks = item
        yield (data, t) if marks is None else Marked(data, t, sender=marks[0], error=marks[1])
