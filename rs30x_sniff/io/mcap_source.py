"""Read the /rs30x/raw channel of an MCAP file back as (bytes, t) chunks, surviving a writer that was killed."""

from __future__ import annotations

import base64
import io
import json
import os
import struct
import sys
from typing import Callable, Iterator

import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Header, Message, Metadata
from mcap.stream_reader import breakup_chunk

from .captures import MCAP_MAGIC, CaptureError, open_capture
from .mcap_sink import METADATA_NAME, MODELS_METADATA_NAME, RAW_TOPIC

_RECORD_HEAD = struct.Struct("<BQ")
_TOOL = "rs30x-sniff"


def _stderr_warning(text: str) -> None:
    print(f"rs30x-sniff: warning: {text}", file=sys.stderr)


class McapRawReader:
    """Iterates ``(data, t, log_time_ns)`` of every /rs30x/raw message in file order.

    Reads the data section record by record, so a file cut anywhere (no summary, no footer, half a
    chunk) is read up to its last complete chunk and ``warn`` is called once with what was lost.
    ``t`` is None where the capture had no timestamps (``log_time_ns`` is then synthetic).
    ``metadata`` fills in as the file is read (it sits at the start of files we write).
    """

    def __init__(self, path: str, warn: Callable[[str], None] | None = _stderr_warning) -> None:
        self.path = path
        self.warn = warn
        self.metadata: dict[str, dict[str, str]] = {}
        self.complete: bool | None = None  # known once iterated: False if the file was cut short
        self.lost_bytes = 0
        self.chunks = 0

    def __iter__(self) -> Iterator[tuple[bytes, float | None, int]]:
        path = self.path
        with open_capture(path) as f:
            size = os.fstat(f.fileno()).st_size
            if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                raise CaptureError(f"{path}: not an MCAP file (bad magic)")
            yield from self._records(f, size)

    def _records(self, f: io.BufferedReader, size: int) -> Iterator[tuple[bytes, float | None, int]]:
        path = self.path
        raw_channel: int | None = None
        first = True
        while True:
            pos = f.tell()
            head = f.read(_RECORD_HEAD.size)
            if len(head) < _RECORD_HEAD.size:
                self._cut(pos, size)
                break
            opcode, length = _RECORD_HEAD.unpack(head)
            if length > size - pos - _RECORD_HEAD.size:
                self._cut(pos, size)
                break
            body = f.read(length)
            try:
                if first:
                    if opcode != Opcode.HEADER:
                        raise CaptureError(f"{path}: not an MCAP file (no header record)")
                    header = Header.read(ReadDataStream(io.BytesIO(body)))
                    if not header.library.startswith(_TOOL):
                        raise CaptureError(f"{path}: not an rs30x-sniff MCAP (written by "
                                           f"{header.library or 'an unnamed tool'}; it has no {RAW_TOPIC} channel)")
                    first = False
                    continue
                if opcode == Opcode.DATA_END:
                    self.complete = True
                    break
                if opcode == Opcode.METADATA:
                    md = Metadata.read(ReadDataStream(io.BytesIO(body)))
                    self.metadata[md.name] = dict(md.metadata)
                    continue
                if opcode == Opcode.CHUNK:
                    records = breakup_chunk(Chunk.read(ReadDataStream(io.BytesIO(body))), validate_crc=True)
                    self.chunks += 1
                elif opcode in (Opcode.CHANNEL, Opcode.MESSAGE):
                    stream = ReadDataStream(io.BytesIO(body))
                    records = [Channel.read(stream) if opcode == Opcode.CHANNEL else Message.read(stream, length)]
                else:
                    continue  # schemas, indexes and anything newer: not needed to get the bytes back
            except CaptureError:
                raise
            except (McapError, zstandard.ZstdError, ValueError, KeyError, struct.error, EOFError) as e:
                raise CaptureError(f"{path}: corrupt MCAP record at byte {pos}: {type(e).__name__}") from None
            for r in records:
                if type(r) is Message:
                    if r.channel_id == raw_channel:
                        yield self._decode_raw(r, pos)
                elif type(r) is Channel and r.topic == RAW_TOPIC:
                    raw_channel = r.id
        if raw_channel is None and self.chunks:
            raise CaptureError(f"{path}: an MCAP without a {RAW_TOPIC} channel: nothing to decode")

    def _decode_raw(self, msg: Message, pos: int) -> tuple[bytes, float | None, int]:
        try:
            obj = json.loads(msg.data)
            data = base64.b64decode(obj["data"], validate=True)
            t = obj["t"]
        except (ValueError, KeyError, TypeError):
            raise CaptureError(f"{self.path}: corrupt {RAW_TOPIC} message in the chunk at byte {pos}") from None
        return data, (float(t) if t is not None else None), msg.log_time

    def _cut(self, pos: int, size: int) -> None:
        # The writer stopped before the end of the data section: everything up to ``pos`` is whole.
        self.complete = False
        self.lost_bytes = size - pos
        if self.warn is not None:
            if self.lost_bytes:
                self.warn(f"{self.path}: the file ends mid-record (was its writer stopped?): read "
                          f"{self.chunks} complete chunks, lost the last {self.lost_bytes} bytes")
            else:
                self.warn(f"{self.path}: the file has no summary or footer (was its writer stopped?): "
                          f"read all {self.chunks} chunks")

    # ---- metadata ------------------------------------------------------------------------------
    def read_metadata(self) -> dict[str, dict[str, str]]:
        """Read only the metadata at the start of the file (before its first chunk) and return it."""
        try:
            with open(self.path, "rb") as f:
                if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                    raise CaptureError(f"{self.path}: not an MCAP file (bad magic)")
                while True:
                    head = f.read(_RECORD_HEAD.size)
                    if len(head) < _RECORD_HEAD.size:
                        break
                    opcode, length = _RECORD_HEAD.unpack(head)
                    if opcode == Opcode.METADATA:
                        try:
                            md = Metadata.read(ReadDataStream(io.BytesIO(f.read(length))))
                        except (McapError, ValueError, struct.error):
                            break
                        self.metadata[md.name] = dict(md.metadata)
                    elif opcode == Opcode.HEADER:
                        f.seek(length, io.SEEK_CUR)
                    else:
                        break
        except OSError as e:
            raise CaptureError(f"{self.path}: cannot read: {e.strerror}") from None
        return self.metadata

    @property
    def baud(self) -> int | None:
        v = self.metadata.get(METADATA_NAME, {}).get("baud")
        return int(v) if v and v.isdigit() else None

    @property
    def models(self) -> dict[int, str]:
        """Per-ID models: what the writer was told, then what the bus taught it (if it finished)."""
        out: dict[int, str] = {}
        for name in (METADATA_NAME, MODELS_METADATA_NAME):
            for item in self.metadata.get(name, {}).get("models", "").split(","):
                k, sep, v = item.partition("=")
                if sep and k.isdigit():
                    out[int(k)] = v
        return out


def read_mcap_raw(path: str) -> Iterator[tuple[bytes, float | None]]:
    """The capture an rs30x-sniff MCAP holds: its /rs30x/raw chunks with their original timestamps."""
    for data, t, _ in McapRawReader(path):
        yield data, t
