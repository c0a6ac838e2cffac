"""Read the /rs30x/raw channel of an MCAP file back as (bytes, t) chunks, surviving a killed writer and damage."""

from __future__ import annotations

import base64
import binascii
import json
import os
import stat
import struct
import zlib
from typing import BinaryIO, Callable, Iterator

import zstandard
from mcap.opcode import Opcode

from ..chunks import SENDERS, UART_ERRORS, Marked
from .captures import MCAP_MAGIC, CaptureError, CaptureWarning, open_capture, stderr_warning
from .mcap_sink import METADATA_NAME, MODELS_METADATA_NAME, RAW_TOPIC

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

_stderr_warning = stderr_warning  # kept: the name other modules knew

# (bytes, capture time, log time ns, marks): marks is None, or (sender, error) as the capture recorded
# them (rs30x_sniff.chunks), for a log converted from another tool's capture.
Raw = tuple[bytes, float | None, int, "tuple[str | None, str | None] | None"]


class _Damage(Exception):
    """The bytes at ``pos`` are not what an rs30x-sniff MCAP holds there."""

    def __init__(self, pos: int, what: str) -> None:
        super().__init__(what)
        self.pos = pos
        self.what = what


class _Bad(Exception):
    """A record body that does not parse (the caller knows where it is)."""


class _Body:
    """Strict little-endian reads from one record body: reading past its end is damage, not a short read."""

    __slots__ = ("data", "pos")

    def __init__(self, data: bytes | memoryview, pos: int = 0) -> None:
        self.data = data
        self.pos = pos

    def take(self, n: int) -> bytes | memoryview:
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
    """Iterates ``(data, t, log_time_ns)`` of every /rs30x/raw message in file order.

    Reads the data section record by record, so a file cut anywhere (no summary, no footer, half a
    chunk) is read up to its last complete chunk, and a damaged one up to the last whole chunk before
    the damage; either way ``warn`` is called once with a line saying where reading stopped (the byte
    offset) and what was lost, and the same is kept in ``warnings`` as a
    :class:`~rs30x_sniff.io.captures.CaptureWarning`. Every chunk is checked (lengths, CRC, and the
    stream offsets of its raw messages following on from the last), so what is returned is always
    the start of the capture, never a capture with a hole. A file with no readable rs30x data (not
    an MCAP, another tool's MCAP, damage before the first chunk) is a CaptureError.
    ``t`` is None where the capture had no timestamps (``log_time_ns`` is then synthetic).
    ``metadata`` fills in as the file is read (it sits at the start of files we write).
    An MCAP needs a seekable file: a pipe is refused with a CaptureError.
    """

    def __init__(self, path: str, warn: Callable[[str], None] | None = stderr_warning) -> None:
        self.path = path
        self.warn = warn
        self.warnings: list[CaptureWarning] = []
        self.metadata: dict[str, dict[str, str]] = {}
        self.complete: bool | None = None  # known once iterated: False if the file was cut short or damaged
        self.damaged_at: int | None = None  # file offset of the damage that stopped reading
        self.lost_bytes = 0
        self.chunks = 0
        self.raw_bytes = 0  # capture bytes returned so far

    def _open(self) -> tuple[BinaryIO, int]:
        path = self.path
        if path == "-":
            raise CaptureError("-: an MCAP capture needs a seekable file, not stdin (save it to a file first)")
        f = open_capture(path)
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
                yield from self._records(f, size)
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
        except _Damage as d:
            self._damaged(d, size, state)
        finally:
            if self.complete is None:
                self.complete = False
        if state.raw_channel is None and self.chunks:
            raise CaptureError(f"{path}: an MCAP without a {RAW_TOPIC} channel: nothing to decode")

    def _record(self, opcode: int, body: bytes, pos: int, state: _State) -> Iterator[Raw]:
        b = _Body(body)
        if opcode == Opcode.HEADER:
            if state.header:
                raise _Bad("a second header")
            b.string()
            library = b.string()
            b.done()
            if not library.startswith(_TOOL):
                # The name is the file's text: shown quoted if it is not plain, so the error stays one line.
                shown = library if library.isprintable() and len(library) <= 60 else repr(library[:60])
                raise CaptureError(f"{self.path}: not an rs30x-sniff MCAP (written by "
                                   f"{shown or 'an unnamed tool'}; it has no {RAW_TOPIC} channel)")
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
            return
        if opcode == Opcode.CHUNK:
            messages = self._chunk(b, pos, state)
            self.chunks += 1
            yield from messages
            return
        if opcode in (Opcode.CHANNEL, Opcode.MESSAGE, Opcode.SCHEMA):
            out = self._inner(opcode, b, pos, state)
            if out is not None:
                yield out
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

    def _chunk(self, b: _Body, pos: int, state: _State) -> list[Raw]:
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
                import lz4.frame  # type: ignore[import-not-found]
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
        out: list[Raw] = []
        inner = _Body(raw)
        mark = state.offset
        try:
            while inner.pos < len(raw):
                opcode = inner.take(1)[0]
                rec = _Body(inner.take(inner.u64()))
                if opcode in (Opcode.CHANNEL, Opcode.MESSAGE, Opcode.SCHEMA):
                    m = self._inner(opcode, rec, pos, state)
                    if m is not None:
                        out.append(m)
        except _Bad:
            state.offset = mark
            raise
        return out

    def _inner(self, opcode: int, b: _Body, pos: int, state: _State) -> Raw | None:
        """A schema, channel or message record (in a chunk, or not): the raw message it is, if one."""
        if opcode == Opcode.SCHEMA:
            return None
        if opcode == Opcode.CHANNEL:
            cid = b.u16()
            b.u16()
            topic = b.string()
            b.string()
            b.string_map()
            b.done()
            if topic == RAW_TOPIC:
                if state.raw_channel not in (None, cid):
                    raise _Bad(f"a second {RAW_TOPIC} channel")
                state.raw_channel = cid
            return None
        channel, _, log_time, _ = _MESSAGE_HEAD.unpack(b.take(_MESSAGE_HEAD.size))
        if channel != state.raw_channel:
            return None
        try:
            obj = json.loads(b.take(len(b.data) - b.pos))
            data = base64.b64decode(obj["data"], validate=True)
            t = obj["t"]
            t = float(t) if t is not None else None
            offset = obj.get("offset")
            length = obj.get("length")
            sender, error = obj.get("sender"), obj.get("error")
            if (sender is not None and sender not in SENDERS) or (error is not None and error not in UART_ERRORS):
                raise ValueError("a mark we do not write")
        except (ValueError, KeyError, TypeError, AttributeError, binascii.Error):
            raise _Bad(f"a {RAW_TOPIC} message that is not what we write") from None
        # The writer numbers every raw byte: a message that does not start where the last one ended
        # means a lost chunk (one whose record type was damaged, say), and a hole must not be read on.
        if offset is not None and offset != state.offset:
            raise _Bad(f"capture bytes {state.offset}..{offset} are missing")
        if length is not None and length != len(data):
            raise _Bad(f"a {RAW_TOPIC} message of {len(data)} bytes that says {length}")
        state.offset += len(data)
        return data, t, log_time, (None if sender is None and error is None else (sender, error))

    # ---- what reading lost ---------------------------------------------------------------------
    def _warn(self, text: str, offset: int | None, lost: int) -> None:
        self.warnings.append(CaptureWarning(self.path, text, offset, lost))
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
        if not self.chunks and state.offset == 0:
            raise CaptureError(f"{self.path}: corrupt MCAP at byte {d.pos} ({d.what}), "
                               "before any capture data could be read")
        self._warn(f"{self.path}: corrupt MCAP at byte {d.pos} ({d.what}): read the {_n(self.chunks, 'chunk')} "
                   f"before it ({state.offset} capture bytes), skipped the last {self.lost_bytes} bytes",
                   d.pos, self.lost_bytes)

    # ---- metadata ------------------------------------------------------------------------------
    def read_metadata(self) -> dict[str, dict[str, str]]:
        """Read only the metadata at the start of the file (before its first chunk) and return it.

        Stops quietly at anything it does not expect: damage is for the full read to report.
        """
        try:
            f, size = self._open()
        except CaptureError:
            return self.metadata
        try:
            with f:
                if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                    raise CaptureError(f"{self.path}: not an MCAP file (bad magic)")
                pos = len(MCAP_MAGIC)
                while True:
                    head = f.read(_RECORD_HEAD.size)
                    if len(head) < _RECORD_HEAD.size:
                        break
                    opcode, length = _RECORD_HEAD.unpack(head)
                    pos += _RECORD_HEAD.size
                    if length > size - pos or opcode not in (Opcode.HEADER, Opcode.METADATA):
                        break
                    body = _Body(f.read(length))
                    pos += length
                    if opcode == Opcode.METADATA:
                        try:
                            name = body.string()
                            self.metadata[name] = body.string_map()
                        except _Bad:
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
    __slots__ = ("header", "raw_channel", "offset")

    def __init__(self) -> None:
        self.header = False
        self.raw_channel: int | None = None
        self.offset = 0  # stream offset of the next raw byte


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


def read_mcap_raw(path: str, warn: Callable[[str], None] | None = stderr_warning
                  ) -> Iterator[tuple[bytes, float | None]]:
    """The capture an rs30x-sniff MCAP holds: its /rs30x/raw chunks with their original timestamps."""
    for data, t, _, marks in McapRawReader(path, warn=warn):
        yield (data, t) if marks is None else Marked(data, t, sender=marks[0], error=marks[1])
