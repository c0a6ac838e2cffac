"""MCAP writer adapter: raw bytes, decoded packets, servo state, transactions and findings as JSON channels."""

from __future__ import annotations

import base64
import json
from typing import IO, Any, Iterable

from mcap.writer import CompressionType, Writer

from .. import __version__
from ..events import Garbage, ShortPacket
from ..render import record_json
from ..schemas import schema_bytes
from .servo_states import ServoStates
from ..stats import CaptureStats
from ..wire import byte_time

RAW_TOPIC = "/rs30x/raw"
PACKETS_TOPIC = "/rs30x/packets"
TRANSACTIONS_TOPIC = "/rs30x/transactions"
DIAGNOSTICS_TOPIC = "/rs30x/diagnostics"
STATE_TOPIC = "/rs30x/servo/{id}/state"
METADATA_NAME = "rs30x"               # written first: a killed writer still leaves it
MODELS_METADATA_NAME = "rs30x.models"  # written by finish(): what the bus taught us
STATS_METADATA_NAME = "rs30x.stats"    # written by finish(): `info`'s figures for the whole log, as JSON

# capture: the capture's own times; synthetic: byte positions at the baud rate (no timestamps);
# wall: a live port, in wall-clock time; monotonic: older live logs, seconds since the port opened.
TIME_BASES = ("capture", "synthetic", "wall", "monotonic")
# foxglove.LogLevel values (Foxglove's published schema).
_LOG_LEVEL = {"info": 2, "warning": 3, "error": 4}
# The mcap Writer also cuts chunks by size; ours does it first (so every cut is flushed to the OS),
# this only keeps the library's own check out of the way.
_WRITER_CHUNK_FACTOR = 4
# Bytes a message record adds to a chunk besides its data (opcode, length, channel, sequence, two times).
_MESSAGE_OVERHEAD = 31

RAW_SPLIT = 4096  # largest /rs30x/raw message for a capture without timestamps

_encode = json.JSONEncoder(separators=(",", ":"), check_circular=False).encode


def _ns(t: float) -> int:
    return int(round(t * 1e9)) if t > 0 else 0


class JsonChannels:
    """The channels' messages, built once for every sink that publishes them (an MCAP file, a Foxglove
    WebSocket server): a subclass says how a channel is opened (``_channel``) and a message written
    (``_write``), so both carry the same bodies with the same log times.
    """

    def __init__(self, *, source: str, baud: int, models: dict[int, str] | None = None,
                 start_time: float | None = None) -> None:
        self.source = source
        self.baud = baud
        self._byte_time = byte_time(baud)
        self._origin = start_time or 0.0
        self._raw_offset = 0                   # stream offset of the next raw byte
        self._servos = ServoStates(models)
        self._models = self._servos.models     # servo -> model name, for the metadata too
        self._states: dict[int, dict[str, str]] = {}  # servo -> register name -> '"name":value'
        self._state_channels: dict[int, Any] = {}

    def _channel(self, topic: str, schema_name: str) -> Any:
        """The handle ``_write`` takes for ``topic`` (registered on first use)."""
        raise NotImplementedError

    def _write(self, cid: Any, log_time: int, data: bytes) -> None:
        raise NotImplementedError

    def _time(self, t: float | None, offset: int) -> float:
        # A capture without timestamps: the time the byte would have reached the wire at full line rate.
        # --start-time anchors either kind to the wall clock (``start_time`` seconds since the epoch).
        return self._origin + (t if t is not None else offset * self._byte_time)

    # ---- messages -----------------------------------------------------------------------------
    def raw(self, data: bytes, t: float | None) -> None:
        """One /rs30x/raw message: bytes as they arrived (``t``: capture time of the first byte, or None)."""
        if not data:
            return
        if t is None and len(data) > RAW_SPLIT:
            # An untimed capture arrives in big blocks; smaller messages keep each one's (synthetic)
            # log time close to its bytes and chunks within their time bound.
            for i in range(0, len(data), RAW_SPLIT):
                self.raw(data[i:i + RAW_SPLIT], None)
            return
        offset = self._raw_offset
        self._raw_offset += len(data)
        ts = "null" if t is None else repr(float(t))
        body = (f'{{"offset":{offset},"t":{ts},"length":{len(data)},"data":"'
                f'{base64.b64encode(data).decode("ascii")}"}}').encode()
        self._write(self._channel(RAW_TOPIC, "rs30x.Raw"), _ns(self._time(t, offset)), body)

    def record(self, rec: Any) -> None:
        """A decoded record: its /rs30x/packets message, the state of every servo it changes, and
        its /rs30x/transactions message if it is a request that asked for a reply."""
        ev = rec.event
        log_time = _ns(self._time(ev.t_start, ev.offset))
        self._write(self._channel(PACKETS_TOPIC, "rs30x.Packet"), log_time, _encode(record_json(rec)).encode())
        if type(ev) is Garbage:
            return
        changed = self._servos.changes(rec)
        if changed:
            self._update_state(rec, changed, log_time)
        if rec.expects is not None:
            self._write(self._channel(TRANSACTIONS_TOPIC, "rs30x.Transaction"), log_time,
                        _encode(transaction_json(rec)).encode())

    def _update_state(self, rec: Any, changed: dict[int, list[tuple[str, Any]]], log_time: int) -> None:
        # Each servo's state is kept as its JSON fragments ('"name":value'), so a packet that changes
        # two registers re-encodes two values, not the whole object (a long packet changes 18 servos).
        states = self._states
        for tid, pairs in changed.items():
            st = states.get(tid)
            if st is None:
                st = states[tid] = {}
            for name, value in pairs:
                st[name] = _fragment(name, value)
        ev = rec.event
        tail = f',"t":{"null" if ev.t_start is None else repr(ev.t_start)},"offset":{ev.offset},'
        fallback = rec.model.name if rec.model is not None else ""
        models = self._models
        channels = self._state_channels
        for tid in changed:
            st = states[tid]
            cid = channels.get(tid)
            if cid is None:
                cid = channels[tid] = self._channel(STATE_TOPIC.format(id=tid), "rs30x.ServoState")
            body = f'{{"id":{tid},"model":"{models.get(tid) or fallback}"{tail}{",".join(st.values())}}}'
            self._write(cid, log_time, body.encode())

    def findings(self, findings: Iterable[Any]) -> None:
        """Lint findings as foxglove.Log messages on /rs30x/diagnostics."""
        for f in findings:
            t = self._time(f.t, f.offset)
            ns = _ns(t)
            msg = {"timestamp": {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000},
                   "level": _LOG_LEVEL.get(f.severity, 0),
                   "message": f.message if f.id is None else f"id {f.id}: {f.message}",
                   "name": f"{f.code} {f.name}", "file": self.source, "line": f.offset}
            self._write(self._channel(DIAGNOSTICS_TOPIC, "foxglove.Log"), ns, _encode(msg).encode())

    # ---- as a sink of the drive loop (rs30x_sniff.pipeline) ----------------------------------------
    def chunk(self, data: bytes, t: float | None) -> None:
        self.raw(data, t)

    def batch(self, step: Any) -> None:
        record = self.record
        for rec in step:
            record(rec)
        if step.findings:
            self.findings(step.findings)

    def idle(self) -> None:
        pass


class McapSink(JsonChannels):
    """Writes one MCAP file: register each schema and channel once (lazily), chunks cut by size and
    by log time so a writer killed mid-way loses at most ``chunk_seconds`` of traffic.

    Use as a context manager, or call :meth:`finish` (safe to call twice).
    """

    def __init__(self, path: str | IO[bytes], *, source: str, baud: int, time_base: str,
                 models: dict[int, str] | None = None, extra_metadata: dict[str, str] | None = None,
                 chunk_seconds: float = 1.0, chunk_size: int = 256 * 1024, start_time: float | None = None) -> None:
        if time_base not in TIME_BASES:
            raise ValueError(f"time_base must be one of {TIME_BASES}, not {time_base!r}")
        if isinstance(path, (str, bytes)) or hasattr(path, "__fspath__"):
            self._file: IO[bytes] = open(path, "wb")
            self._owns_file = True
        else:
            self._file = path
            self._owns_file = False
        super().__init__(source=source, baud=baud, models=models, start_time=start_time)
        self.path = path
        self.time_base = time_base
        self._chunk_ns = int(chunk_seconds * 1e9)
        self._chunk_size = chunk_size
        self._writer = Writer(self._file, chunk_size=chunk_size * _WRITER_CHUNK_FACTOR,
                              compression=CompressionType.ZSTD)
        self._writer.start(profile="", library=f"rs30x-sniff {__version__}")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._chunk_start: int | None = None   # log time of the first message in the open chunk
        self._chunk_bytes = 0
        self._finished = False
        self._size = 0
        self.messages = 0
        self.chunks = 0
        self.stats = CaptureStats(baud)  # what passes through the drive loop, summed as `info` sums it
        meta = {"source": source, "baud": str(baud), "time_base": time_base, "tool": "rs30x-sniff",
                "start_time": "" if start_time is None else repr(start_time),
                "tool_version": __version__, "models": _models_text(self._models)}
        meta.update(extra_metadata or {})
        self._writer.add_metadata(METADATA_NAME, meta)

    # ---- context manager -----------------------------------------------------------------------
    def __enter__(self) -> McapSink:
        return self

    def __exit__(self, *exc: object) -> None:
        # Finish even on an error: what was captured so far stays a complete, indexed file.
        self.finish()

    @property
    def bytes_written(self) -> int:
        """Bytes in the file so far (what has reached the file object)."""
        return self._size if self._finished else self._file.tell()

    # ---- channels -----------------------------------------------------------------------------
    def _channel(self, topic: str, schema_name: str) -> int:
        cid = self._channels.get(topic)
        if cid is None:
            sid = self._schemas.get(schema_name)
            if sid is None:
                data = schema_bytes(schema_name)
                sid = self._schemas[schema_name] = self._writer.register_schema(schema_name, "jsonschema", data)
                self._chunk_bytes += len(data) + len(schema_name) + 32  # the schema record goes in the chunk
            cid = self._channels[topic] = self._writer.register_channel(topic, "json", sid)
            self._chunk_bytes += len(topic) + 32
        return cid

    def _write(self, cid: int, log_time: int, data: bytes) -> None:
        start = self._chunk_start
        if start is None:
            self._chunk_start = log_time
        elif (log_time - start > self._chunk_ns or start - log_time > self._chunk_ns
              or self._chunk_bytes >= self._chunk_size):
            self.flush()
            self._chunk_start = log_time
        self._writer.add_message(cid, log_time, data, log_time)
        self._chunk_bytes += len(data) + _MESSAGE_OVERHEAD
        self.messages += 1

    def flush(self) -> None:
        """Close the open chunk and hand it to the OS (a live recorder calls this when the bus is idle)."""
        if self._finished:
            return
        if self._chunk_start is not None:
            self.chunks += 1
        self._writer.flush()
        self._chunk_start = None
        self._chunk_bytes = 0

    # ---- as a sink: JsonChannels' protocol, and the statistics of what passed through ------------
    def chunk(self, data: bytes, t: float | None) -> None:
        super().chunk(data, t)
        self.stats.chunk(data, t)

    def batch(self, step: Any) -> None:
        super().batch(step)
        self.stats.batch(step)

    def close(self) -> None:
        self.finish()

    def finish(self) -> None:
        """Write the last chunk, the models metadata, the summary and the footer; idempotent."""
        if self._finished:
            return
        self.flush()
        self._finished = True
        try:
            self._writer.add_metadata(MODELS_METADATA_NAME, {"models": _models_text(self._models)})
            if self.stats.bytes_in:
                self.stats.close()
                self._writer.add_metadata(STATS_METADATA_NAME, {"stats": json.dumps(self.stats.as_dict())})
            self._writer.finish()
        finally:
            self._size = self._file.tell()
            if self._owns_file:
                self._file.close()
            else:
                self._file.flush()


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


def transaction_json(rec: Any) -> dict[str, Any]:
    """A request that expects a reply, with its reply and latency (the /rs30x/transactions object)."""
    ev = rec.event
    reply = rec.reply
    rev = reply.event if reply is not None else None
    return {
        "id": ev.id, "op": ev.op if type(ev) is ShortPacket else "write", "expects": rec.expects,
        "status": rec.status or "missing", "request_offset": ev.offset, "t_request": ev.t_start,
        "request_raw": ev.raw.hex(), "read": rec.read_names,
        "reply_type": rev.kind if rev is not None else None,
        "reply_offset": rev.offset if rev is not None else None,
        "t_reply": rev.t_start if rev is not None else None,
        "reply_raw": rev.raw.hex() if rev is not None else None,
        "reply_checksum_ok": rev.checksum_ok if rev is not None else None,
        "latency_s": reply.latency if reply is not None else None,
    }
