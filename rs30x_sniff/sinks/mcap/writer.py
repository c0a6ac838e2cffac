"""MCAP writer adapter: raw bytes, decoded packets, servo state, transactions and findings as JSON channels."""

from __future__ import annotations

import base64
import errno
import heapq
import json
import struct
from operator import itemgetter, le
from typing import IO, Any
from collections.abc import Iterable

import foxglove
from foxglove.mcap import MCAPCompression, MCAPWriteOptions

from ...version import __version__
from ...protocol.events import Garbage
from ...protocol.mcap_names import (DIAGNOSTICS_TOPIC, GAP_METADATA_NAME, GAPS_METADATA_NAME, LOG_SCHEMA,
                                    MCAP_MAGIC, METADATA_NAME, MODELS_METADATA_NAME, PACKET_SCHEMA, PACKETS_TOPIC,
                                    RAW_SCHEMA, RAW_TOPIC,
                                    SERVO_STATE_SCHEMA, STATE_TOPIC, STATS_METADATA_NAME, TIME_BASES, TOPICS_RAW,
                                    TRANSACTION_SCHEMA, TRANSACTIONS_TOPIC, log_time_ns)
from ...render.block_json import record_json_line
from ...schemas import schema_bytes
from ...decode.blocks import Block
from ...decode.decoder import Sink, Step
from ...decode.pairing import Record
from .blocks import block_messages
from .servo_states import ServoStates
from .transactions import transaction_json
from ..stats import CaptureStats
from ...protocol.wire import byte_time

# foxglove.LogLevel values (Foxglove's published schema).
_LOG_LEVEL = {"info": 2, "warning": 3, "error": 4}
# Bytes a message record adds to a chunk besides its data (opcode, length, channel, sequence, two times).
_MESSAGE_OVERHEAD = 31

RAW_SPLIT = 4096  # largest /rs30x/raw message for a capture without timestamps

_encode = json.JSONEncoder(separators=(",", ":"), check_circular=False).encode


_log_time = itemgetter(0)  # a held message's (log_time, channel, data)


def _merged(held: list[tuple[int, Any, bytes]], made: list[tuple[int, Any, bytes]]) -> list[tuple[int, Any, bytes]]:
    """``held`` and ``made`` interleaved by log time, each in its own order, ``held`` first on a tie: what
    heapq.merge makes of them. Where both are in time order already (a clock that never went back) a
    stable sort of the two runs one after the other is the same list, made at C speed."""
    if not held:
        return made
    for side in (held, made):
        times = list(map(_log_time, side))
        if not all(map(le, times, times[1:])):
            return list(heapq.merge(held, made, key=_log_time))
    return sorted(held + made, key=_log_time)


class JsonChannels(Sink[Record | Block]):
    """The channels' messages, built once for every sink that publishes them (an MCAP file, a Foxglove
    WebSocket server): a subclass says how a channel is opened (``channel``) and a message written
    (``_write``), so both carry the same bodies with the same log times.

    A file takes every message. A live server sets ``_every_message`` to False and answers ``_live``:
    a message on a channel nobody is subscribed to is then never encoded, so a server with no client
    costs the decoding and little more. What a later message depends on (the stream offset of the raw
    bytes, each servo's registers) is kept either way, so a client that subscribes late gets the same
    bodies a file holds from then on.

    The column form (sinks/mcap/blocks.py) writes the same messages through the public names:
    ``channel``, ``time_of``, ``servos`` (ServoStates), ``model_names`` and ``state_slot``.
    """

    _every_message = True

    def __init__(self, *, source: str, baud: int, models: dict[int, str] | None = None,
                 start_time: float | None = None) -> None:
        self.source = source
        self.baud = baud
        self._byte_time = byte_time(baud)
        self._origin = start_time or 0.0
        self._raw_offset = 0                   # stream offset of the next raw byte
        self.servos = ServoStates(models)
        self.model_names = self.servos.models     # servo -> model name, for the metadata too
        self._states: dict[int, dict[str, str]] = {}  # servo -> register name -> '"name":value'
        self._held: dict[int, dict[str, Any]] = {}    # servo -> register values not yet in _states
        self._state_channels: dict[int, Any] = {}
        # A columnar group's raw messages (chunk_group), held until its step's messages are made, then
        # written with them in log-time order; None: every message is written as it is made.
        self._raw_held: list[tuple[int, Any, bytes]] | None = None
        self._made: list[tuple[int, Any, bytes]] | None = None

    def _emit(self, cid: Any, log_time: int, data: bytes) -> None:
        made = self._made
        if made is None:
            self._write(cid, log_time, data)
        else:
            made.append((log_time, cid, data))

    def _emit_held(self, message: tuple[int, Any, bytes]) -> None:
        """``_emit`` of a (log_time, channel, data) message, as block_messages gives them."""
        self._emit(message[1], message[0], message[2])

    def channel(self, topic: str, schema_name: str) -> Any:
        """The handle ``_write`` takes for ``topic`` (registered on first use)."""
        raise NotImplementedError

    def _write(self, cid: Any, log_time: int, data: bytes) -> None:
        raise NotImplementedError

    def _write_all(self, messages: Iterable[tuple[int, Any, bytes]]) -> None:
        """``_write`` of each (log_time, channel, data) message in turn (a file does it in one loop)."""
        write = self._write
        for lt, cid, data in messages:
            write(cid, lt, data)

    def _live(self, cid: Any) -> bool:
        """Whether a message on ``cid`` would reach anyone (asked only when not ``_every_message``)."""
        return True

    @property
    def origin(self) -> float:
        """What time_of adds to every time: --start-time's seconds since the epoch, or 0."""
        return self._origin

    @property
    def byte_time(self) -> float:
        """Seconds a byte takes on the wire at the baud rate (time_of's time of an untimed offset)."""
        return self._byte_time

    def time_of(self, t: float | None, offset: int) -> float:
        """A message's time in seconds (log_time_ns makes its log time) from capture time ``t`` or, without
        one, the stream ``offset``."""
        # A capture without timestamps: the time the byte would have reached the wire at full line rate.
        # --start-time anchors either kind to the wall clock (``start_time`` seconds since the epoch).
        return self._origin + (t if t is not None else offset * self._byte_time)

    # ---- messages -----------------------------------------------------------------------------
    def raw(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        """One /rs30x/raw message: bytes as they arrived (``t``: capture time of the first byte, or None),
        with who sent them and the UART error flagged on them where the capture says (``sender``,
        ``error``: written only when set, so they survive a conversion of another tool's capture)."""
        if not data:
            return
        if t is None and len(data) > RAW_SPLIT:
            # An untimed capture arrives in big blocks; smaller messages keep each one's (synthetic)
            # log time close to its bytes and chunks within their time bound.
            for i in range(0, len(data), RAW_SPLIT):
                self.raw(data[i:i + RAW_SPLIT], None, sender, error)
            return
        offset = self._raw_offset
        self._raw_offset += len(data)
        cid = self.channel(RAW_TOPIC, RAW_SCHEMA)
        if not (self._every_message or self._live(cid)):
            return
        ts = "null" if t is None else repr(float(t))
        marks = (f',"sender":"{sender}"' if sender else "") + (f',"error":"{error}"' if error else "")
        body = (f'{{"offset":{offset},"t":{ts},"length":{len(data)},"data":"'
                f'{base64.b64encode(data).decode("ascii")}"{marks}}}').encode()
        self._emit(cid, log_time_ns(self.time_of(t, offset)), body)

    def record(self, rec: Record) -> None:
        """A decoded record: its /rs30x/packets message, the state of every servo it changes, and
        its /rs30x/transactions message if it is a request that asked for a reply."""
        ev = rec.event
        log_time = log_time_ns(self.time_of(ev.t_start, ev.offset))
        every = self._every_message
        cid = self.channel(PACKETS_TOPIC, PACKET_SCHEMA)
        if every or self._live(cid):
            self._emit(cid, log_time, record_json_line(rec, compact=True).encode())
        if type(ev) is Garbage:
            return
        changed = self.servos.changes(rec)
        if changed:
            self._update_state(rec, changed, log_time)
        if rec.expects is not None:
            cid = self.channel(TRANSACTIONS_TOPIC, TRANSACTION_SCHEMA)
            if every or self._live(cid):
                self._emit(cid, log_time, _encode(transaction_json(rec)).encode())

    def state_slot(self, tid: int) -> tuple[Any, dict[str, str]]:
        """Servo ``tid``'s state channel and its fragments ('"name":value' by name), made on first use."""
        cid = self._state_channels.get(tid)
        if cid is None:
            cid = self._state_channels[tid] = self.channel(STATE_TOPIC.format(id=tid), SERVO_STATE_SCHEMA)
        st = self._states.get(tid)
        if st is None:
            st = self._states[tid] = {}
        return cid, st

    def _update_state(self, rec: Record, changed: dict[int, list[tuple[str, Any]]], log_time: int) -> None:
        # Each servo's state is kept as its JSON fragments ('"name":value'), so a packet that changes
        # two registers re-encodes two values, not the whole object (a long packet changes 18 servos).
        # A servo whose channel nobody watches keeps its new values as they are (``_held``), encoded
        # when someone does: its state stays whole without a value encoded for nobody.
        every = self._every_message
        live = []
        slot = self.state_slot
        for tid, pairs in changed.items():
            cid, st = slot(tid)
            if every or self._live(cid):
                held = self._held.pop(tid, None)
                if held:
                    for name, value in held.items():
                        st[name] = _fragment(name, value)
                for name, value in pairs:
                    st[name] = _fragment(name, value)
                live.append((tid, cid, st))
            else:
                held = self._held.get(tid)
                if held is None:
                    held = self._held[tid] = {}
                held.update(pairs)
        if not live:
            return
        ev = rec.event
        tail = f',"t":{"null" if ev.t_start is None else repr(ev.t_start)},"offset":{ev.offset},'
        fallback = rec.model.name if rec.model is not None else ""
        models = self.model_names
        for tid, cid, st in live:
            body = f'{{"id":{tid},"model":"{models.get(tid) or fallback}"{tail}{",".join(st.values())}}}'
            self._emit(cid, log_time, body.encode())

    def findings(self, findings: Iterable[Any]) -> None:
        """Lint findings as foxglove.Log messages on /rs30x/diagnostics."""
        cid = self.channel(DIAGNOSTICS_TOPIC, LOG_SCHEMA)
        if not (self._every_message or self._live(cid)):
            return
        for f in findings:
            t = self.time_of(f.t, f.offset)
            ns = log_time_ns(t)
            msg = {"timestamp": {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000},
                   "level": _LOG_LEVEL.get(f.severity, 0),
                   "message": f.message if f.id is None else f"id {f.id}: {f.message}",
                   "name": f"{f.code} {f.name}", "file": self.source, "line": f.offset}
            self._emit(cid, ns, _encode(msg).encode())

    # ---- as a sink of the drive loop (rs30x_sniff.sinks.pipeline) ----------------------------------------
    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        self.raw(data, t, sender, error)

    def chunk_group(self, chunks: list[tuple[bytes, float | None]]) -> None:
        """A columnar Pipeline's group of plain chunks (Pipeline.feed_many): their raw messages wait for
        the step they decode to, so the file gets both in log-time order (the record path interleaves
        them chunk by chunk; a group's records come after all its chunks)."""
        made = self._made = self._raw_held if self._raw_held is not None else []
        try:
            if self._every_message:
                self._raw_many(chunks, made.append)
            else:
                for data, t in chunks:
                    self.raw(data, t)
        finally:
            self._raw_held, self._made = self._made, None

    def _raw_many(self, chunks: list[tuple[bytes, float | None]], append: Any) -> None:
        """``raw`` of each plain chunk, every message taken: the same bodies and log times with the
        per-message calls (time_of, log_time_ns, channel) made inline (a file's every chunk comes here)."""
        offset = self._raw_offset
        origin, byte_t = self._origin, self._byte_time
        b64 = base64.b64encode
        cid = None
        try:
            for data, t in chunks:
                n = len(data)
                if not n:
                    continue
                if t is None and n > RAW_SPLIT:
                    self._raw_offset = offset
                    self.raw(data, None)  # split into RAW_SPLIT messages (it appends through _emit to the same list)
                    offset = self._raw_offset
                    continue
                if cid is None:
                    cid = self.channel(RAW_TOPIC, RAW_SCHEMA)  # on first use, as raw() registers it
                if t is None:
                    x = origin + offset * byte_t
                    ts = "null"
                else:
                    x = origin + t
                    ts = repr(float(t))
                append((int(round(x * 1e9)) if x > 0 else 0, cid,  # log_time_ns(time_of(t, offset))
                        f'{{"offset":{offset},"t":{ts},"length":{n},"data":"{b64(data).decode("ascii")}"}}'.encode()))
                offset += n
        finally:
            self._raw_offset = offset

    def batch(self, step: Step) -> None:
        held = self._raw_held
        if held is None and not step.blocks:
            self._records(step)
        else:
            self._raw_held = None
            made = self._made = []
            try:
                self._records(step)
            finally:
                self._made = None
                # Interleaved by log time, each side kept in its own order (the raw bytes in stream order
                # even where a capture's clock went back); raw first where times tie, as the record path
                # writes a chunk before its records.
                self._write_all(_merged(held or [], made))
        if step.findings:  # after the step's records, in the order found, as the record path writes them
            self.findings(step.findings)

    def _records(self, step: Step) -> None:
        record = self.record
        for rec in step:
            if type(rec) is Block:
                made = self._made
                block_messages(self, rec, made.append if made is not None else self._emit_held)
            else:
                record(rec)

    def flush_held(self) -> None:
        """Write raw messages still held (a group that decoded to nothing yet)."""
        held, self._raw_held = self._raw_held, None
        if held:
            self._write_all(held)

    def idle(self) -> None:
        self.flush_held()


class McapSink(JsonChannels):
    """Writes one MCAP file: register each schema and channel once (lazily), chunks cut by size and
    by log time so a writer killed mid-way loses at most ``chunk_seconds`` of traffic.

    The file is written by the Foxglove SDK's MCAP writer (Rust: 3 to 4 times the messages/s of the
    mcap package's Writer, see bench/foxglove_sdk.py) through :class:`_SdkFile`, so that the file
    stays what the mcap Writer made of it: our name in the header, whole chunks only.

    Use as a context manager, or call :meth:`finish` (safe to call twice).
    """

    def __init__(self, path: str | IO[bytes], *, source: str, baud: int, time_base: str,
                 models: dict[int, str] | None = None, extra_metadata: dict[str, str] | None = None,
                 chunk_seconds: float = 1.0, chunk_size: int = 256 * 1024, start_time: float | None = None,
                 decoded: bool = True) -> None:
        if time_base not in TIME_BASES:
            raise ValueError(f"time_base must be one of {TIME_BASES}, not {time_base!r}")
        if isinstance(path, (str, bytes)) or hasattr(path, "__fspath__"):
            # Unbuffered: the SDK hands over whole chunks, and no bytes wait in a buffer that a failed
            # write would leave to be written later, past the footer of a salvaged file.
            self._file: IO[bytes] = open(path, "wb", buffering=0)
            self._owns_file = True
        else:
            self._file = path
            self._owns_file = False
        super().__init__(source=source, baud=baud, models=models, start_time=start_time)
        # decoded=False: the bytes (/rs30x/raw), the findings and the figures only, as a dumpcap keeps a capture
        # to decode later: every reader of the file decodes the raw bytes again, and `convert` writes the
        # decoded topics from them. A black box left running costs far less so (record's default).
        self.decoded = decoded
        self.path = path
        self.time_base = time_base
        self.gaps: list[dict] = []  # where the source lost the line (gap()): the rs30x.gaps metadata
        self._chunk_ns = int(chunk_seconds * 1e9)
        self._chunk_size = chunk_size
        self._out = _SdkFile(self._file, library=f"rs30x-sniff {__version__}")
        # A context of its own: these channels reach this file only, never a live server in the same
        # process (record --foxglove) nor another file (the next part of record --split-size).
        self._context = foxglove.Context()
        options = MCAPWriteOptions(
            compression=MCAPCompression.Zstd, profile="",
            # Chunks are cut here only (by size and time, each cut flushed to the OS): a cut the SDK
            # made inside log() would report a write error on stderr instead of raising it.
            chunk_size=None,
            # Appending only: each chunk is built in memory and written whole, so a killed recorder
            # leaves whole chunks and at most one cut record (a seeking writer streams a chunk under
            # a placeholder length that is only filled in when it ends).
            disable_seeking=True,
            calculate_data_section_crc=False,  # 0, "not computed", as the mcap Writer left it
            compression_threads=0)             # no faster with a thread pool (measured), and a recorder needs none
        try:
            self._writer = self._sdk(foxglove.open_mcap, self._out, context=self._context, writer_options=options)
        except BaseException:
            if self._owns_file:
                self._file.close()
            raise
        self._schemas: set[str] = set()
        self._channels: dict[str, Any] = {}
        self._chunk_start: int | None = None   # log time of the first message in the open chunk
        self._chunk_bytes = 0
        self._finished = False
        self._finalized = False
        self.messages = 0
        self.chunks = 0
        self.stats = CaptureStats(baud)  # what passes through the drive loop, summed as `info` sums it
        meta = {"source": source, "baud": str(baud), "time_base": time_base, "tool": "rs30x-sniff",
                "start_time": "" if start_time is None else repr(start_time),
                "tool_version": __version__, "models": _models_text(self.model_names)}
        if not decoded:
            meta["topics"] = TOPICS_RAW  # absent: every topic (all files before this key)
        meta.update(extra_metadata or {})
        self._sdk(self._writer.write_metadata, METADATA_NAME, meta)

    def _sdk(self, call: Any, *args: Any, **kwargs: Any) -> Any:
        """A call into the SDK's writer that may write to the file. A failed write (a full disk, a
        closed pipe) is kept from the SDK (:class:`_SdkFile` takes the bytes and drops them), so the
        SDK never prints its own complaint when it is closed or dropped; the OSError is raised here,
        once, for the command to report in one line. Ctrl-C while Python code wrote a chunk comes back
        from the SDK as a RuntimeError with the cause left out: it is raised as itself."""
        try:
            result = call(*args, **kwargs)
        except Exception:
            error, self._out.error = self._out.error, None
            if error is not None:
                raise error from None
            raise
        error, self._out.error = self._out.error, None
        if error is not None:
            raise error
        return result

    # ---- context manager -----------------------------------------------------------------------
    def __enter__(self) -> McapSink:
        return self

    def __exit__(self, *exc: object) -> None:
        # Finish even on an error: what was captured so far stays a complete, indexed file.
        self.finish()

    @property
    def bytes_written(self) -> int:
        """Bytes in the file so far (what has reached the file object)."""
        return self._out.position

    @property
    def failed(self) -> OSError | None:
        """The write error that stopped the file, if one did (nothing was written after it)."""
        return self._out.failed

    @property
    def readable_bytes(self) -> int:
        """How much of the file a reader gets: all of it once finished, else the whole chunks before
        the last flush that reached the OS (a failed write may have left a cut chunk after them)."""
        return self._out.readable

    @property
    def finalized(self) -> bool:
        """Whether the file ends with an MCAP footer (finished, or salvaged after a failed write)."""
        return self._finalized

    # ---- channels -----------------------------------------------------------------------------
    def channel(self, topic: str, schema_name: str) -> Any:
        ch = self._channels.get(topic)
        if ch is None:
            data = schema_bytes(schema_name)
            if schema_name not in self._schemas:
                # One schema record per name (the SDK shares it between channels), in the chunk.
                self._schemas.add(schema_name)
                self._chunk_bytes += len(data) + len(schema_name) + 32
            schema = foxglove.Schema(name=schema_name, encoding="jsonschema", data=data)
            # The SDK's channel object, for its log(data, log_time): the wrapper's log() checks the
            # message's type on every call, which about doubles the cost of a write (measured).
            ch = self._channels[topic] = foxglove.Channel(topic, schema=schema, message_encoding="json",
                                                          context=self._context).base
            self._chunk_bytes += len(topic) + 32
        return ch

    def _write(self, cid: Any, log_time: int, data: bytes) -> None:
        start = self._chunk_start
        if start is None:
            self._chunk_start = log_time
        elif (log_time - start > self._chunk_ns or start - log_time > self._chunk_ns
              or self._chunk_bytes >= self._chunk_size):
            self.flush()
            self._chunk_start = log_time
        # The publish time is the log time, as before: the SDK writes log_time for both.
        cid.log(data, log_time)
        self._chunk_bytes += len(data) + _MESSAGE_OVERHEAD
        self.messages += 1

    def _write_all(self, messages: Iterable[tuple[int, Any, bytes]]) -> None:
        # _write's loop with its state in locals: a columnar step's hundreds of thousands of messages
        # pay one call each (the SDK's log), not three.
        start, size = self._chunk_start, self._chunk_bytes
        span, limit = self._chunk_ns, self._chunk_size
        n = 0
        try:
            for log_time, cid, data in messages:
                if start is None:
                    start = log_time
                elif log_time - start > span or start - log_time > span or size >= limit:
                    self._chunk_start, self._chunk_bytes = start, size
                    self.flush()
                    start, size = log_time, 0
                cid.log(data, log_time)
                size += len(data) + _MESSAGE_OVERHEAD
                n += 1
        finally:
            self._chunk_start, self._chunk_bytes = start, size
            self.messages += n

    def flush(self) -> None:
        """Close the open chunk and hand it to the OS (a live recorder calls this when the bus is idle)."""
        if self._finished:
            return
        if self._chunk_start is not None:
            self.chunks += 1
        self._sdk(self._writer.flush)
        self._chunk_start = None
        self._chunk_bytes = 0

    # ---- as a sink: JsonChannels' protocol, and the statistics of what passed through ------------
    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        super().chunk(data, t, sender, error)
        self.stats.chunk(data, t)

    takes_blocks = True  # a file: a Block's messages come from templates (io/mcap_blocks.py)

    def chunk_group(self, chunks: list[tuple[bytes, float | None]]) -> None:
        super().chunk_group(chunks)
        for data, t in chunks:
            self.stats.chunk(data, t)

    def batch(self, step: Step) -> None:
        if self.decoded:
            super().batch(step)
        else:
            self.flush_held()  # the raw bytes only (their group's records make no messages here)
            if step.findings:
                self.findings(step.findings)
        self.stats.batch(step)  # a CaptureStats: it takes Blocks as they are (takes_blocks)

    def gap(self, t: float, lost_at: float | None, note: str) -> None:
        """The source lost the line from ``lost_at`` to ``t`` (epoch seconds), before the stream byte it is at
        (``offset``): a GAP_METADATA_NAME record now, so a file cut later still says it, and all of them in
        GAPS_METADATA_NAME at the end. A reader makes each a seam again (sources/mcap_reader.py); the
        decoder's F010 finding marks the same place in the diagnostics."""
        gap = {"offset": self._raw_offset, "lost_at": lost_at, "back_at": t,
               "seconds": None if lost_at is None else round(t - lost_at, 6), "why": note}
        self.gaps.append(gap)
        if self._finished:
            return
        # The bytes before the gap go out first (raw messages held by a columnar group too), so the record
        # lies between the chunks it parts.
        self.flush_held()
        self.flush()
        self._sdk(self._writer.write_metadata, GAP_METADATA_NAME, {k: json.dumps(v) for k, v in gap.items()})

    def close(self) -> None:
        self.flush_held()
        self.finish()

    def finish(self) -> None:
        """Write the last chunk, the models metadata, the summary and the footer; idempotent.

        After a failed write the SDK's end goes nowhere (its bytes are dropped) and the file is
        salvaged instead: cut back to its last whole chunk and closed with a footer of its own, where
        the file allows it (a regular file with room for 50 bytes)."""
        if self._finished:
            return
        try:
            self.flush()
        finally:
            self._finished = True
            try:
                self._sdk(self._writer.write_metadata, MODELS_METADATA_NAME, {"models": _models_text(self.model_names)})
                if self.gaps:
                    self._sdk(self._writer.write_metadata, GAPS_METADATA_NAME, {"gaps": json.dumps(self.gaps)})
                if self.stats.bytes_in:
                    self.stats.close()
                    self._sdk(self._writer.write_metadata, STATS_METADATA_NAME,
                              {"stats": json.dumps(self.stats.as_dict())})
                self._sdk(self._writer.close)
                self._finalized = self._out.failed is None
            finally:
                for ch in self._channels.values():
                    ch.close()  # out of the context: nothing keeps this file's channels alive
                if self._out.failed is not None:
                    self._finalized = self._out.salvage()
                self._out.release()
                try:
                    if self._owns_file:
                        self._file.close()
                    elif self._out.failed is None:
                        self._file.flush()
                except OSError:
                    pass  # its write error was raised already; the same one again says nothing new


_HEADER = 0x01  # the header record's opcode
_U32, _U64 = struct.Struct("<I"), struct.Struct("<Q")
# A salvaged file's end: Data End (opcode 0x0F, data section CRC 0: not computed) and a Footer (opcode
# 0x02) that points at no summary section, then the closing magic.
_DATA_END = bytes([0x0F]) + _U64.pack(4) + _U32.pack(0)
_FOOTER = bytes([0x02]) + _U64.pack(20) + _U64.pack(0) + _U64.pack(0) + _U32.pack(0)


class _SdkFile:
    """The file object the SDK's MCAP writer writes: every byte goes on to ``file``, but the header
    names us (``library``): the SDK writes its own name there, and rs30x-sniff's reader
    (io/mcap_source) knows our files by that field.

    The writer appends only (disable_seeking) and asks for its position with seek(0, SEEK_CUR): it
    gets the position in this file, so every offset it writes into the summary stays right whatever
    the length of our header. (No data section CRC is written, as before: it would cover the SDK's
    header, not ours.)
    """

    def __init__(self, file: IO[bytes], library: str) -> None:
        self.file: IO[bytes] | None = file
        self.library = library.encode()
        self.position = 0
        self.readable = 0      # the position of the last flush that reached the OS: whole chunks before it
        self.error: BaseException | None = None  # the last exception a write or flush raised, not yet raised
        self.failed: OSError | None = None      # the write error after which nothing more reached the file

    def write(self, data: bytes) -> int:
        given = len(data)
        if self.failed is not None:
            return given  # the file stopped at its error: the rest goes nowhere, the SDK stays healthy
        try:
            if self.position == 0:
                data = self._own_header(bytes(data))
            view = memoryview(data)
            file = self.file
            assert file is not None  # the SDK writes before it closes (release)
            while view:  # an unbuffered file may take part of a write
                n = file.write(view)
                n = len(view) if n is None else n
                if n <= 0:
                    raise OSError(errno.EIO, "the file took none of the bytes written")
                self.position += n
                view = view[n:]
        except OSError as e:
            self._fail(e)
            return given
        except BaseException as e:
            self.error = e  # for McapSink._sdk: the SDK passes on only its own error
            raise
        return given  # what the writer gave, whatever reached the file

    def seek(self, offset: int, whence: int = 0) -> int:
        if (offset, whence) in ((0, 1), (0, 2), (self.position, 0)):
            return self.position
        raise OSError("the MCAP writer was expected to append only")

    def tell(self) -> int:
        return self.position

    def flush(self) -> None:
        if self.file is None or self.failed is not None:
            return
        try:
            self.file.flush()
        except OSError as e:
            self._fail(e)
            return
        except BaseException as e:
            self.error = e
            raise
        self.readable = self.position

    def _fail(self, e: OSError) -> None:
        name = getattr(self.file, "name", None)
        if e.filename is None and isinstance(name, str):
            e.filename = name  # the file's own name, so the error says which output it was
        self.failed = self.error = e

    def salvage(self) -> bool:
        """After a failed write: cut the file back to its last whole chunk and end it with a footer
        (no summary: a reader finds the chunks by scanning), so it reads as a finished file. Whether
        that worked; a pipe, a device or a disk without 50 bytes to spare keeps what it got."""
        f = self.file
        if f is None:
            return False
        try:
            f.seek(self.readable)
            f.truncate()
            f.write(_DATA_END + _FOOTER + MCAP_MAGIC)
            f.flush()
        except (OSError, ValueError, AttributeError):
            return False
        self.position = self.readable = self.readable + len(_DATA_END) + len(_FOOTER) + len(MCAP_MAGIC)
        return True

    def release(self) -> None:
        # The SDK may hold on to this object after closing; the file (or a BytesIO's buffer) need not.
        self.file = None

    def _own_header(self, data: bytes) -> bytes:
        n = len(MCAP_MAGIC)
        if data[:n] != MCAP_MAGIC or len(data) < n + 9 or data[n] != _HEADER:
            raise RuntimeError("the Foxglove SDK did not begin its MCAP with a header record")
        length = _U64.unpack_from(data, n + 1)[0]
        body_at = n + 9
        if len(data) < body_at + length:
            # This SDK writes the magic and the header in one call; one that does not needs this changed.
            raise RuntimeError("the Foxglove SDK wrote its MCAP header in pieces")
        profile_len = _U32.unpack_from(data, body_at)[0]
        profile = data[body_at:body_at + 4 + profile_len]
        body = profile + _U32.pack(len(self.library)) + self.library
        return data[:n] + bytes([_HEADER]) + _U64.pack(len(body)) + body + data[body_at + length:]


def _fragment(name: str, value: Any) -> str:
    """'"name":value' as JSON, the value as the packets channel shows it (floats to 6 decimals)."""
    t = type(value)
    if t is float:
        return f'"{name}":{round(value, 6)!r}'
    if t is int:
        return f'"{name}":{value}'
    return f'"{name}":{_encode(value)}'


def _models_text(models: dict[int, str]) -> str:
    """``{1: "RS303MR", 3: "RS304MD"}`` -> ``"1=RS303MR,3=RS304MD"`` (metadata values are strings)."""
    return ",".join(f"{i}={m}" for i, m in sorted(models.items()))
