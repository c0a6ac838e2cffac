"""Request/reply pairing, latencies, and per-servo shadow state (sans-IO, fed with frame events)."""

from __future__ import annotations

from collections import deque
from functools import lru_cache
from typing import Any, Protocol, TypeVar, cast, final
from collections.abc import Callable, Collection, Iterable, Mapping
from weakref import ref

import numpy as np

from .frame_runs import LONG, RETURN, SHORT
from ..protocol.events import (
    ADDRESS, CAPTURE_START, CHECKSUM_OK, DATA, FLAG, ID, LONG_ADDRESS, LONG_CHECKSUM_OK, LONG_FLAG, LONG_LENGTH,
    LONG_RECORDS, REASON, T_END, T_START, Ack, AnyEvent, Garbage, LongPacket, Nack, Packet, ReturnPacket, ShortPacket)
from ..protocol.memmap import Field, Model, ModelRegistry, default_registry
from ..protocol.wire import (
    AT_DATA, BROADCAST_ID, FLAG_MODE_UNDEFINED, FLAG_WANTS_REPLY, LONG_PACKET_ID, NO_AREAS, RETURN_MODE_MASK, SUM_SIZE)

# Reply status of a record.
ANSWERED = "answered"        # a request whose reply came
MISSING = "missing"          # a request whose reply never came
PAIRED = "paired"            # a reply to the request before it
UNSOLICITED = "unsolicited"  # a reply nobody asked for
# A second reply to one request within its reply window, from the ID asked or the ID whose reply came first
# (or an ACK/NACK to a request for one, or any reply to a broadcast): two servos answer to one ID.
EXTRA = "extra"
# The edges of a capture (or of a time segment), not faults: a request whose reply time had not run out
# when the capture ended, and the first reply of a capture whose request came before the capture began.
UNKNOWN = "unknown"
UNSEEN = "request-unseen"

# A return comes 100 us + 50 us x return_delay (at most 12.85 ms, table 4.6 No. 7) after the request;
# allow for the reply's own transmission and USB jitter before calling it missing.
DEFAULT_REPLY_TIMEOUT = 0.050
# A servo's shadow of its memory map: addresses 0 to 255 (data past the end is clipped).
MAP_SIZE = 256
# A return of addresses 0-1 carries the model number (table 4.5): 0x3030 RS303MR, 0x3040 RS304MD.
MODEL_NUMBER_ADDRESS, MODEL_NUMBER_SIZE = 0, 2

# ---- the special cases: frames the tracker follows one by one ----------------------------------------
# What a checksum-valid frame does to the tracker is plain when it only counts a request or a return for
# its servo (by ID, or each VID of a long packet) and stores its data in that servo's shadow, inside the
# map: the columnar path (rs30x_sniff.decode.blocks) does that for a whole run of frames at once. A frame
# of these cases does more, which only BusTracker.feed_into follows (a case is a bit; a frame may be two):
PLAIN = 0
BROADCAST_WRITE = 1  # data to ID 255: every servo's shadow
SERVO_ID_WRITE = 2   # data over servo_id (table 4.6 No. 4): the servo answers to its new ID at once
PAST_MAP = 4         # data past address 255: clipped
MODEL_NUMBER = 8     # a return of the model number from a servo of no configured model: its model is learned
# A request whose return mode table 4.3 leaves undefined and some model's map defines (return_areas: RS204MD's
# and RS405CB's 0x0D reads 60-127): whether a return is due depends on its servo's model, which the tracker
# knows at that frame, learned ones included (a model number earlier in the same run).
MODEL_RETURN_MODE = 16


# frame_case and frame_cases are twins, one frame and a column of frames: change one, change the other.
# The tracker decides each event by frame_case; BusTracker.rows_needing_tracker hands frame_cases to the
# columnar path. tests/decode/test_pairing_twins.py holds them equal on random runs.
def frame_case(kind: int, sid: int, address: int, size: int, id_address: int, configured: Collection[int],
               flag: int, area_modes: Collection[int]) -> int:
    """The special cases of one checksum-valid frame (PLAIN: none): ``kind`` SHORT, LONG or RETURN
    (rs30x_sniff.decode.frame_runs), ``size`` its data bytes (a long packet's: each record's, after its VID),
    ``id_address`` where servo_id lives, ``configured`` the IDs given a model (none is learned), ``flag`` its
    flag byte, ``area_modes`` the return modes beyond table 4.3 some model may define (MODEL_RETURN_MODE)."""
    mode_case = MODEL_RETURN_MODE if kind == SHORT and flag & RETURN_MODE_MASK in area_modes else PLAIN
    if size <= 0:
        return mode_case
    end = address + size
    case = PAST_MAP if end > MAP_SIZE else PLAIN
    if kind == RETURN:
        if address == MODEL_NUMBER_ADDRESS and size >= MODEL_NUMBER_SIZE and sid not in configured:
            case |= MODEL_NUMBER
    elif kind == SHORT and sid == BROADCAST_ID:
        case |= BROADCAST_WRITE
    elif address <= id_address < end:
        case |= SERVO_ID_WRITE
    return case | mode_case


def frame_cases(columns: Mapping[str, np.ndarray], id_address: int, configured: Collection[int],
                area_modes: Collection[int]) -> np.ndarray:
    """:func:`frame_case` of every frame of a run, from its header columns (rs30x_sniff.decode.frame_runs
    FrameRun.header: kind, id, flag, address, length, data_len): one uint8 of case bits per row."""
    kind, sid = columns["kind"], columns["id"]
    address = columns["address"].astype(np.int64)
    size = np.where(kind == LONG, columns["length"].astype(np.int64) - 1, columns["data_len"])
    end = address + size
    data = size > 0
    case = np.where(data & (end > MAP_SIZE), PAST_MAP, PLAIN).astype(np.uint8)
    is_return = kind == RETURN
    request = data & ~is_return
    broadcast = request & (kind == SHORT) & (sid == BROADCAST_ID)
    case[broadcast] |= BROADCAST_WRITE
    case[request & ~broadcast & (address <= id_address) & (id_address < end)] |= SERVO_ID_WRITE
    learns = is_return & (address == MODEL_NUMBER_ADDRESS) & (size >= MODEL_NUMBER_SIZE)
    if configured:
        known = np.zeros(256, dtype=bool)  # by ID: every value of the ID byte
        known[list(configured)] = True
        learns &= ~known[sid]
    case[learns] |= MODEL_NUMBER
    if area_modes:
        case[(kind == SHORT) & _flags_of_modes(frozenset(area_modes))[columns["flag"]]] |= MODEL_RETURN_MODE
    return case


@lru_cache(maxsize=8)
def _flags_of_modes(area_modes: frozenset[int]) -> np.ndarray:
    """By flag byte: whether its return mode is one of ``area_modes`` (made once, not for every run)."""
    modes = np.zeros(256, dtype=bool)
    modes[[f for f in range(256) if f & RETURN_MODE_MASK in area_modes]] = True
    return modes


# A servo answers no sooner than 100 us after a request's last byte (table 4.6 No. 7, return delay 0). A reply
# the times put closer than half that was not timed by the clock but laid out by it: the bytes of one read (a
# USB adapter's packet, a pty's write) placed back to back at the line rate, so the return delay between them
# is lost and would read as 0. Half, not all of it: a real reply's stamps may put it a little early (a
# logger's clock, times rounded to the us, a line a few % off its nominal rate) and keep their latency.
# README and docs/live-capture.md give this number (tests/e2e/test_time_units.py holds them equal).
MIN_REPLY_LATENCY = 50e-6


def reply_latency(request: AnyEvent, reply: AnyEvent) -> float | None:
    """Seconds from the end of ``request`` to the start of ``reply`` (None without times).

    None also where the clock cannot support one. A reply cannot start before its request ended, so stamps
    that say otherwise (a logger's arrival times read as first-byte times, a wrong baud) give no latency
    rather than a false 0; F005/F006 report them. Nor can it start sooner than MIN_REPLY_LATENCY after it:
    closer times were computed for bytes that came in one read, not measured. A Block
    (rs30x_sniff.decode.blocks) pairs such replies too; ``Block.reply_latencies`` gives only those with one.
    """
    t0, t1 = reply[T_START], request[T_END]
    if t0 is None or t1 is None:
        return None
    latency = t0 - t1
    return latency if latency >= MIN_REPLY_LATENCY else None


@final  # the checker narrows by `type(x) is Record` both ways
class Record:
    """An event as the rest of the program sees it: decoded fields, its pair, its servo's model."""

    __slots__ = ("event", "index", "model", "vid_models", "request", "_reply", "latency", "status", "findings",
                 "_fields", "__weakref__", "_values", "resolved_by")

    def __init__(self, event: AnyEvent, index: int, model: Model | None) -> None:
        self.event = event
        self.index = index
        self.model = model
        # For a long packet: each record's servo model, parallel to ``event.records``, settled when the
        # tracker built this record; None while every servo on the bus has ``model`` (the common case).
        self.vid_models: tuple[Model, ...] | None = None
        self.request: Record | None = None
        self._reply: Callable[[], Record | None] | None = None
        self.latency: float | None = None
        self.status: str | None = None
        self.findings: list = []
        self._fields: list[Field] | None = None
        self._values: tuple | None = None
        # For a MISSING request: the record whose arrival settled that no reply would come (None at end
        # of input). The linter tells a missing reply from a host that did not wait by it.
        self.resolved_by: Record | None = None

    @property
    def reply(self) -> Record | None:
        """For a request: the reply that answered it.

        Held by a weak reference: with a strong link both ways every transaction would be a reference
        cycle, and the cyclic garbage collector would cost a third of the decoding time. The reply
        always leaves the tracker in the same batch as its request, so whoever keeps the request and
        its batch keeps both.
        """
        r = self._reply
        return None if r is None else r()

    @reply.setter
    def reply(self, rec: Record | None) -> None:
        self._reply = None if rec is None else ref(rec)

    # Convenience views of the event.
    @property
    def kind(self) -> str:
        return self.event.kind

    @property
    def offset(self) -> int:
        return self.event.offset

    @property
    def t(self) -> float | None:
        return self.event.t_start

    @property
    def id(self) -> int | None:
        return getattr(self.event, "id", None) if not isinstance(self.event, (Ack, Nack)) else (
            self.request.id if self.request is not None else None)

    @property
    def is_request(self) -> bool:
        return isinstance(self.event, (ShortPacket, LongPacket))

    @property
    def is_reply(self) -> bool:
        return isinstance(self.event, (ReturnPacket, Ack, Nack))

    @property
    def expects(self) -> str | None:
        """What reply a request asks for: "ack", "return", or None. A return mode table 4.3 does not define
        asks for a return where the servo's model defines it (its map's return_areas: RS204MD's 0x0D)."""
        ev = self.event
        if type(ev) is ShortPacket:
            kind = (ev.expects_in(self.return_areas) if FLAG_MODE_UNDEFINED[ev[FLAG]] else ev.expects).kind
            if kind != "none":
                return kind
        return None

    @property
    def return_areas(self) -> Mapping[int, tuple[int, int]]:
        """The return modes beyond table 4.3 this record's servo model defines (none without a model)."""
        m = self.model
        return NO_AREAS if m is None else m.behaviour.return_areas

    @property
    def read_range(self) -> tuple[int, int] | None:
        """For a short request: (first address, byte count) of the return it asks for, by table 4.3 or by its
        servo model's return_areas; None for any other record."""
        ev = self.event
        if type(ev) is ShortPacket:
            return ev.read_range_in(self.return_areas) if FLAG_MODE_UNDEFINED[ev[FLAG]] else ev.read_range
        return None

    @property
    def op(self) -> str | None:
        """What a short request does, as one word (ShortPacket.op), reading the range :attr:`read_range`
        says; None for any other record."""
        ev = self.event
        if type(ev) is ShortPacket:
            return ev.op_in(self.return_areas) if FLAG_MODE_UNDEFINED[ev[FLAG]] else ev.op
        return None

    @property
    def values(self) -> tuple:
        """Engineering values of the fields the packet carries, in field order (decoded once, on first use)."""
        v = self._values
        if v is None:
            v = self._values = self._decode_values()
        return v

    @property
    def fields(self) -> list[Field]:
        """Named, scaled fields the packet carries, with their raw bytes (built on first use, then kept)."""
        f = self._fields
        if f is None:
            f = self._fields = self._build_fields(self.values)
        return f

    def peek_fields(self) -> list[Field]:
        """The fields, without keeping them (or their values) on the record: for views that glance at
        many records once, such as a timeline or a search through a long history."""
        if self._fields is not None:
            return self._fields
        return self._build_fields(self._values)

    def _build_fields(self, values: tuple | None) -> list[Field]:
        lay, data = self.data_layout()
        if lay is None:
            return []
        if isinstance(lay, list):
            return [x for (sub, d, vid) in lay for x in sub.fields(d, sub.values(d), vid)]
        # a layout comes only with a packet's data, and every packet names a servo (LongPacket's id is 0)
        return lay.fields(data, lay.values(data) if values is None else values, cast(Packet, self.event).id)

    def data_layout(self):
        """(layout, data) for the packet's data; for a long packet to servos of mixed models, a list."""
        ev = self.event
        t = type(ev)
        if t is ReturnPacket or t is ShortPacket:
            if not ev.data:
                return None, b""
            return self.model.layout(ev.address, len(ev.data)), ev.data
        if t is LongPacket and ev.length and ev.records:
            data = ev.raw[AT_DATA:-SUM_SIZE]
            vm = self.vid_models
            first = self.model if vm is None else vm[0]
            if len(data) == ev.length * ev.count and (vm is None or all(m is first for m in vm)):
                return first.long_layout(ev.address, ev.length, ev.count), data
            return [(m.layout(ev.address, len(r.data)), r.data, r.vid)
                    for m, r in zip(vm or (first,) * len(ev.records), ev.records)], data
        return None, b""

    def _decode_values(self) -> tuple:
        lay, data = self.data_layout()
        if lay is None:
            return ()
        if isinstance(lay, list):
            return tuple(v for sub, d, _ in lay for v in sub.values(d))
        return lay.values(data)

    def named_values(self) -> list[tuple[Any, str, Any]]:
        """``(servo id, register name, value)`` of each whole, named register the packet carries, in
        field order (Layout.named_values): the fields' content without the Field objects."""
        lay, data = self.data_layout()
        if lay is None:
            return []
        if isinstance(lay, list):
            return [x for sub, d, vid in lay for x in sub.named_values(d, sub.values(d), vid)]
        return lay.named_values(data, self.values, cast(Packet, self.event).id)  # a layout means a packet

    @property
    def read_names(self) -> list[str]:
        """For a read request: the registers it asks for."""
        ev = self.event
        if type(ev) is ShortPacket:
            rr = self.read_range
            if rr is not None:
                assert self.model is not None, "a short packet's record carries its servo's model (feed_into)"
                return self.model.names_in(*rr)
        return []

    def __repr__(self) -> str:
        return f"<Record {self.index} {self.kind}@{self.offset} status={self.status}>"


class TakesRecords(Protocol):
    """Where the tracker appends the Records it releases: a list of them, or a decoder's Step (which may hold
    Blocks too, rs30x_sniff.decode.decoder)."""

    def append(self, rec: Record, /) -> None: ...

    def __iadd__(self, recs: list[Record], /) -> Any: ...


TakesT = TypeVar("TakesT", bound=TakesRecords)


class ServoState:
    """What the bus has told us about one servo: a shadow of its memory map."""

    __slots__ = ("id", "model", "image", "known", "requests", "returns", "latencies", "last_t")

    def __init__(self, servo_id: int, model: Model) -> None:
        self.id = servo_id
        self.model = model
        self.image = bytearray(MAP_SIZE)
        self.known = 0  # bit a set once address a of image holds a value seen on the bus
        self.requests = 0
        self.returns = 0
        self.latencies: deque[float] = deque(maxlen=1024)  # recent reply latencies (bounded for live use)
        self.last_t: float | None = None

    def store(self, address: int, data: bytes, t: float | None = None) -> None:
        n = len(data)
        if address + n > MAP_SIZE:
            n = MAP_SIZE - address
            data = data[:n]
        self.image[address:address + n] = data
        self.known |= ((1 << n) - 1) << address
        self.last_t = t

    def is_known(self, address: int, size: int = 1) -> bool:
        mask = ((1 << size) - 1) << address
        return self.known & mask == mask

    def get(self, name: str) -> Any:
        """Latest known engineering value of a register, or None if never seen."""
        reg = self.model.register(name)
        return reg.value_in(0, self.image) if self.is_known(reg.address, reg.size) else None

    def values(self) -> dict[str, Any]:
        """Every named register whose value is known."""
        image = self.image
        return {reg.name: reg.value_in(0, image) for reg in self.model.registers
                if reg.name and self.is_known(reg.address, reg.size)}


class BusTracker:
    """Pairs requests with replies and keeps the shadow state; yields records in wire order.

    A request that asks for a reply is held back (with everything after it) until its reply
    arrives, another request shows it will not, the reply timeout passes, or :meth:`close`;
    so every record leaves complete with its pairing.
    """

    def __init__(self, registry: ModelRegistry | None = None, models: dict[int, str] | None = None,
                 reply_timeout: float = DEFAULT_REPLY_TIMEOUT, default_model: str | None = None) -> None:
        self.registry = registry or default_registry()
        self.configured = {i: self.registry.get(m) for i, m in (models or {}).items()}
        self.default = self.registry.get(default_model) if default_model else self.registry.default
        self.learned: dict[int, Model] = {}
        self.reply_timeout = reply_timeout
        self.servos: dict[int, ServoState] = {}
        self._index = 0
        self._pending: Record | None = None   # request whose reply is due
        self._last_request: Record | None = None  # latest request that got its reply (for EXTRA)
        self._answer_ids: tuple = ()  # the IDs whose return is a second reply to it: asked, and answered
        self._held: list[Record] = []
        # True from the start of input (or of a time segment) until its first packet: a reply then
        # answers a request the capture did not see (UNSEEN), if it comes within the reply timeout.
        self.fresh = True
        self._segment_t: float | None = None  # the segment's first time, once an event has one
        self._model_cache: dict[int, Model] = {}
        self._uniform = self._all_default()  # kept up to date by _learn and _renumber: no model lookups
        # Where servo_id lives and what it may hold (table 4.6 No. 4: address 4, 1-127, the same in every
        # map): a write there moves the servo to its new ID at once.
        reg = self.default.register("servo_id")
        self._id_address = reg.address
        self._id_range = reg.range or (1, 127)
        # The return modes beyond table 4.3 any model here may define (MODEL_RETURN_MODE): those of every
        # model a servo could have or be learned as, whichever it turns out to have.
        self._area_modes = frozenset(
            mode for m in (*self.registry.models.values(), *self.configured.values(), self.default)
            for mode in m.behaviour.return_areas)

    def _all_default(self) -> bool:
        d = self.default
        return all(m is d for m in self.configured.values()) and all(m is d for m in self.learned.values())

    # ---- what pairing outside the tracker reads and moves (a Block of rows: rs30x_sniff.decode.blocks) ----
    def rows_needing_tracker(self, columns: Mapping[str, np.ndarray]) -> np.ndarray:
        """Per frame of a run of checksum-valid frames (its header columns, FrameRun.header): True where
        the frame is one of the special cases (:func:`frame_case`), which only :meth:`feed_into` follows."""
        return frame_cases(columns, self._id_address, self.configured, self._area_modes) != PLAIN

    @property
    def uniform(self) -> bool:
        """True while every servo has the default model (the common case: one model on the bus)."""
        return self._uniform

    @property
    def waiting(self) -> Record | None:
        """The request whose reply is due (the tracker holds it, and every record after it, until then)."""
        return self._pending

    @property
    def next_index(self) -> int:
        """The index the next record gets."""
        return self._index

    def advance(self, n: int) -> None:
        """``n`` records were paired outside the tracker (a Block), with no request left waiting: the next
        record's index is ``n`` further on, and the time segment has had its first packet."""
        self._index += n
        self.fresh = False

    @property
    def last_answered(self) -> Record | None:
        """The latest request, if it got its reply: a second reply to it within its reply window, from the
        ID asked or the ID that answered, is EXTRA; None once a later request comes (or at a seam). Set after
        requests paired outside the tracker (a Block) to the last of them, answered (with its reply still
        linked: the setter reads the ID that answered), or to None when it asked for no reply."""
        return self._last_request

    @last_answered.setter
    def last_answered(self, req: Record | None) -> None:
        self._answered(req, None if req is None else req.reply)

    def _answered(self, req: Record | None, reply: Record | None) -> None:
        """``req`` got ``reply``: a second reply to it is EXTRA if it comes from the ID asked or the ID that
        answered (an ACK/NACK names none: the ID asked), within the request's reply window."""
        self._last_request = req
        if req is None:
            self._answer_ids = ()
            return
        asked = req.event[ID]
        got = reply.event[ID] if reply is not None and type(reply.event) is ReturnPacket else asked
        self._answer_ids = (asked,) if got == asked else (asked, got)

    def _second_reply(self, rec: Record) -> bool:
        """Whether a reply with no request waiting is a second reply to the latest answered one (EXTRA)."""
        req = self._last_request
        if req is None:
            return False
        ev = rec.event
        t0, t1 = ev[T_START], req.event[T_END]
        if t0 is not None and t1 is not None and t0 - t1 > self.reply_timeout:
            return False  # past the request's reply window: no request asked for it (unsolicited)
        if req.event[ID] == BROADCAST_ID:
            return True  # every servo was asked
        if type(ev) is ReturnPacket:
            return ev[ID] in self._answer_ids  # another ID's return is unsolicited, not a second answer
        return req.expects == "ack"  # an ACK/NACK names no ID: a second one to a request that asked for one

    def model_of(self, servo_id: int) -> Model:
        m = self._model_cache.get(servo_id)
        if m is None:
            m = self._model_cache[servo_id] = (
                self.configured.get(servo_id) or self.learned.get(servo_id) or self.default)
        return m

    def servo(self, servo_id: int) -> ServoState:
        st = self.servos.get(servo_id)
        if st is None:
            st = self.servos[servo_id] = ServoState(servo_id, self.model_of(servo_id))
        return st

    def feed_all(self, events: Iterable[AnyEvent]) -> list[Record]:
        out: list[Record] = []
        for ev in events:
            out += self.feed(ev)
        return out

    def feed(self, ev: AnyEvent) -> list[Record]:
        """Records released by one more event (none while a reply is still due)."""
        out: list[Record] = []
        self.feed_into(ev, out)
        return out

    def feed_many(self, events: list[AnyEvent], out: TakesT) -> TakesT:
        """Append the records released by ``events`` to ``out`` (the batch form the decoder uses)."""
        step = self.feed_into
        for ev in events:
            step(ev, out)
        return out

    def feed_into(self, ev: AnyEvent, out: TakesRecords) -> None:
        """Append the records released by one more event to ``out`` (the form the decoder's loops call)."""
        t = type(ev)
        if t is ShortPacket or t is ReturnPacket:
            model = self._model_cache.get(ev[ID]) or self.model_of(ev[ID])
        else:
            model = self.default
        rec = Record(ev, self._index, model)
        if self.fresh:
            if self._segment_t is None:
                self._segment_t = ev[T_START]
            if t is not Garbage or ev[REASON] != CAPTURE_START:  # bytes from before the capture keep it fresh
                self.fresh = False
                if t is ReturnPacket or t is Ack or t is Nack:
                    self._first_reply(rec)
        if t is LongPacket and not self._uniform:
            # Settle each VID's model now: what is learned later does not rewrite this packet.
            model_of = self.model_of
            rec.vid_models = tuple([model_of(r[0]) for r in ev[LONG_RECORDS]])  # r[0]: the record's VID
        self._index += 1
        pending = self._pending
        if pending is not None:
            t0, t1 = ev[T_START], pending.event[T_END]
            if t0 is not None and t1 is not None and t0 - t1 > self.reply_timeout:
                self._resolve_missing(out, rec)
                pending = None
        if t is ReturnPacket or t is Ack or t is Nack:
            self._on_reply(rec, pending)
        elif t is ShortPacket or t is LongPacket:
            if pending is not None:
                self._resolve_missing(out, rec)
            self._last_request = None
            # t is type(ev), narrowed by hand: the checker cannot follow it, and the hot loop keeps it in a local.
            if t is LongPacket:
                self._on_long(ev)  # type: ignore[arg-type]
            else:
                self._on_short(rec, ev)  # type: ignore[arg-type]
        if self._pending is not None:
            self._held.append(rec)
            return
        if self._held:
            out += self._held
            self._held = []
        out.append(rec)

    def close(self, end_t: float | None = None) -> list[Record]:
        """End of input (its last byte ended at ``end_t``, if timed): a request still waiting is UNKNOWN,
        unless the capture ran on past its reply timeout (then MISSING)."""
        out: list[Record] = []
        self._end_segment(out, end_t)
        return out

    def seam(self, end_t: float | None = None) -> list[Record]:
        """A seam in the capture's clock (rs30x_sniff.decode.framing.Seam; the old segment ended at ``end_t``):
        nothing is paired across it, as if one capture ended and another began."""
        out: list[Record] = []
        self._end_segment(out, end_t)
        self._last_request = None
        self.fresh = True
        self._segment_t = None
        return out

    def _end_segment(self, out: TakesRecords, end_t: float | None) -> None:
        p = self._pending
        if p is None:
            return
        self._resolve_missing(out)
        t1 = p.event[T_END]
        if end_t is None or t1 is None or end_t - t1 <= self.reply_timeout:
            p.status = UNKNOWN  # its reply time had not run out: it may have come after the capture

    def _first_reply(self, rec: Record) -> None:
        """The segment's first packet is a reply: to a request before the capture, if it came in time."""
        t0, s = rec.event[T_START], self._segment_t
        if self._pending is None and (t0 is None or s is None or t0 - s <= self.reply_timeout):
            rec.status = UNSEEN

    # ---- pairing -----------------------------------------------------------------------------
    def _resolve_missing(self, out: TakesRecords, by: Record | None = None) -> None:
        pending = self._pending
        assert pending is not None  # called only while a request waits for its reply
        pending.status = MISSING
        pending.resolved_by = by
        self._pending = None
        out += self._held
        self._held = []

    def _on_long(self, ev: LongPacket) -> None:
        if not ev[LONG_CHECKSUM_OK]:
            return
        address, t = ev[LONG_ADDRESS], ev[T_START]
        n = ev[LONG_LENGTH] - 1  # each record's data bytes, after its VID
        if n <= 0:
            return
        ida = self._id_address
        case = frame_case(LONG, LONG_PACKET_ID, address, n, ida, self.configured, ev[LONG_FLAG], self._area_modes)
        records = ev[LONG_RECORDS]
        if case & PAST_MAP:
            for vid, data in records:
                self.servo(vid).store(address, data, t)  # clipped
        else:
            end = address + n
            mask = ((1 << n) - 1) << address
            servos = self.servos
            for vid, data in records:
                st = servos.get(vid)
                if st is None:
                    st = self.servo(vid)
                st.image[address:end] = data  # inlined ServoState.store: 18 of these per gait frame
                st.known |= mask
                st.last_t = t
        if case & SERVO_ID_WRITE:
            k = ida - address
            self._renumber([(vid, data[k]) for vid, data in records if len(data) > k])

    def _on_short(self, rec: Record, ev: ShortPacket) -> None:
        # A packet whose Sum is wrong names no servo we can trust: it creates none and changes no shadow.
        if ev[CHECKSUM_OK]:
            sid, address, data = ev[ID], ev[ADDRESS], ev[DATA]
            ida = self._id_address
            case = frame_case(SHORT, sid, address, len(data), ida, self.configured, ev[FLAG], self._area_modes)
            if case & BROADCAST_WRITE:
                for st in list(self.servos.values()):
                    st.store(address, data, ev[T_START])
            elif sid != BROADCAST_ID:  # a broadcast names no servo: none is made or counted for it
                st = self.servos.get(sid) or self.servo(sid)
                st.requests += 1
                if data:
                    st.store(address, data, ev[T_START])  # clipped if PAST_MAP
                    if case & SERVO_ID_WRITE:
                        self._renumber([(sid, data[ida - address])])
        flag = ev[FLAG]
        if FLAG_WANTS_REPLY[flag]:  # an ACK/NACK or a return (table 4.3)
            self._pending = rec
        elif FLAG_MODE_UNDEFINED[flag] and flag & RETURN_MODE_MASK in rec.return_areas:
            self._pending = rec  # a return its servo's model defines (MODEL_RETURN_MODE)

    def _renumber(self, moves: list[tuple[int, int]]) -> None:
        """Servos whose servo_id was written: each (old, new) servo answers to its new ID at once
        (table 4.6 No. 4), so its shadow, counters and learned model move there."""
        lo, hi = self._id_range
        moves = [(old, new) for old, new in moves if old != new and lo <= new <= hi]
        if not moves:
            return
        servos, learned, cache = self.servos, self.learned, self._model_cache
        # Take every moving servo out first: a long packet may swap two IDs.
        taken = [(new, servos.pop(old, None)) for old, new in moves]
        for old, _ in moves:
            learned.pop(old, None)
            cache.pop(old, None)
        for new, st in taken:
            cache.pop(new, None)
            if st is None:
                continue
            before = servos.get(new)
            if before is not None:  # traffic to the new ID before the change still counts there
                st.requests += before.requests
                st.returns += before.returns
            st.id = new
            model = self.configured.get(new) or st.model
            if model is self.default:
                learned.pop(new, None)
            else:
                learned[new] = model
            st.model = model
            servos[new] = st
        self._uniform = self._all_default()

    def _on_reply(self, rec: Record, pending: Record | None) -> None:
        ev = rec.event
        req: Record | None
        if pending is not None:
            req = pending
            rec.status = PAIRED
            req.status = ANSWERED
            req.reply = rec
            self._pending = None
            self._answered(req, rec)
        elif self._second_reply(rec):
            req = self._last_request
            rec.status = EXTRA
        else:
            if rec.status != UNSEEN:
                rec.status = UNSOLICITED
            req = None
        rec.request = req
        if req is not None:
            rec.latency = reply_latency(req.event, ev)
        if type(ev) is ReturnPacket:
            if ev[CHECKSUM_OK]:
                sid, address, data = ev[ID], ev[ADDRESS], ev[DATA]
                st = self.servo(sid)
                st.returns += 1
                if rec.latency is not None and rec.status == PAIRED:
                    st.latencies.append(rec.latency)
                if frame_case(RETURN, sid, address, len(data), self._id_address, self.configured, ev[FLAG],
                              self._area_modes) & MODEL_NUMBER:
                    self._learn(sid, data, st)
                st.store(address, data, ev[T_START])  # clipped if PAST_MAP
                rec.model = st.model
        elif req is not None:
            rec.model = req.model

    def _learn(self, sid: int, data: bytes, st: ServoState) -> None:
        """A return of the model number (MODEL_NUMBER) from servo ``sid``: its model, if the registry knows it."""
        m = self.registry.by_number.get(int.from_bytes(data[:MODEL_NUMBER_SIZE], "little"))
        if m is not None and m is not st.model:
            self.learned[sid] = m
            self._model_cache.pop(sid, None)
            st.model = m
            self._uniform = self._all_default()
