"""Request/reply pairing, latencies, and per-servo shadow state (sans-IO, fed with frame events)."""

from __future__ import annotations

from collections import deque
from typing import Any, Callable, Iterable
from weakref import ref

from ..protocol.events import CAPTURE_START, Ack, AnyEvent, Garbage, LongPacket, Nack, ReturnPacket, ShortPacket
from ..protocol.memmap import Field, Model, ModelRegistry, default_registry
from ..protocol.wire import BROADCAST_ID, FLAG_WANTS_REPLY

# Reply status of a record.
ANSWERED = "answered"        # a request whose reply came
MISSING = "missing"          # a request whose reply never came
PAIRED = "paired"            # a reply to the request before it
UNSOLICITED = "unsolicited"  # a reply nobody asked for
EXTRA = "extra"              # a second reply to one request (two servos share an ID)
# The edges of a capture (or of a time segment), not faults: a request whose reply time had not run out
# when the capture ended, and the first reply of a capture whose request came before the capture began.
UNKNOWN = "unknown"
UNSEEN = "request-unseen"

# A return comes 100 us + 50 us x return_delay (at most 12.85 ms, table 4.6 No. 7) after the request;
# allow for the reply's own transmission and USB jitter before calling it missing.
DEFAULT_REPLY_TIMEOUT = 0.050


def reply_latency(request: AnyEvent, reply: AnyEvent) -> float | None:
    """Seconds from the end of ``request`` to the start of ``reply`` (None without times).

    None also where the clock cannot support one: a reply cannot start before its request ended, so stamps that say otherwise (a logger's arrival times read as first-byte times, a wrong
    baud, a held clock) give no latency rather than a false 0; F005/F006 report them. Blocks
    (rs30x_sniff.decode.blocks) hold only replies with a latency of zero or more: ``Block.reply_latencies``.
    """
    t0, t1 = reply[2], request[3]
    if t0 is None or t1 is None:
        return None
    latency = t0 - t1
    return latency if latency >= 0.0 else None


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
        """What reply a request asks for: "ack", "return", or None."""
        ev = self.event
        if type(ev) is ShortPacket:
            kind = ev.expects.kind
            if kind != "none":
                return kind
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
        return lay.fields(data, lay.values(data) if values is None else values, self.event.id)

    def data_layout(self):
        """(layout, data) for the packet's data; for a long packet to servos of mixed models, a list."""
        ev = self.event
        t = type(ev)
        if t is ReturnPacket or t is ShortPacket:
            if not ev.data:
                return None, b""
            return self.model.layout(ev.address, len(ev.data)), ev.data
        if t is LongPacket and ev.length and ev.records:
            data = ev.raw[7:-1]
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
        return lay.named_values(data, self.values, self.event.id)

    def fields_json(self, only: set[int] | None = None, compact: bool = False) -> str:
        """The JSON text of the fields' objects (``render.field_json``), without the brackets, written
        from per-layout templates: no Field objects or dicts are built (``only``: those servo IDs)."""
        lay, data = self.data_layout()
        if lay is None:
            return ""
        if isinstance(lay, list):
            parts = [sub.fields_json(d, sub.values(d), vid, only, compact) for sub, d, vid in lay]
            return ("," if compact else ", ").join(p for p in parts if p)
        return lay.fields_json(data, self.values, self.event.id, only, compact)

    @property
    def read_names(self) -> list[str]:
        """For a read request: the registers it asks for."""
        ev = self.event
        if type(ev) is ShortPacket:
            rr = ev.read_range
            if rr is not None:
                return self.model.names_in(*rr)
        return []

    def __repr__(self) -> str:
        return f"<Record {self.index} {self.kind}@{self.offset} status={self.status}>"


class ServoState:
    """What the bus has told us about one servo: a shadow of its memory map."""

    __slots__ = ("id", "model", "image", "known", "requests", "returns", "latencies", "last_t")

    def __init__(self, servo_id: int, model: Model) -> None:
        self.id = servo_id
        self.model = model
        self.image = bytearray(256)
        self.known = 0  # bit a set once address a of image holds a value seen on the bus
        self.requests = 0
        self.returns = 0
        self.latencies: deque[float] = deque(maxlen=1024)  # recent reply latencies (bounded for live use)
        self.last_t: float | None = None

    def store(self, address: int, data: bytes, t: float | None = None) -> None:
        n = len(data)
        if address + n > 256:
            n = 256 - address
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

    def _all_default(self) -> bool:
        d = self.default
        return all(m is d for m in self.configured.values()) and all(m is d for m in self.learned.values())

    # ---- what pairing outside the tracker reads and moves (a Block of rows: rs30x_sniff.decode.blocks) ----
    @property
    def uniform(self) -> bool:
        """True while every servo has the default model (the common case: one model on the bus)."""
        return self._uniform

    @property
    def id_address(self) -> int:
        """The address of servo_id (table 4.6 No. 4): a write there moves the servo to its new ID."""
        return self._id_address

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
        """The latest request, if it got its reply: another reply now is EXTRA to it; None once a later
        request comes (or at a seam). Set after requests paired outside the tracker (a Block) to the last
        of them, answered, or to None when it asked for no reply."""
        return self._last_request

    @last_answered.setter
    def last_answered(self, req: Record | None) -> None:
        self._last_request = req

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

    def feed_many(self, events: list[AnyEvent], out: list[Record]) -> list[Record]:
        """Append the records released by ``events`` to ``out`` (the batch form the decoder uses)."""
        step = self.feed_into
        for ev in events:
            step(ev, out)
        return out

    def feed_into(self, ev: AnyEvent, out: list[Record]) -> None:
        """Append the records released by one more event to ``out`` (the form the decoder's loops call)."""
        t = type(ev)
        if t is ShortPacket or t is ReturnPacket:
            model = self._model_cache.get(ev[4]) or self.model_of(ev[4])
        else:
            model = self.default
        rec = Record(ev, self._index, model)
        if self.fresh:
            if self._segment_t is None:
                self._segment_t = ev[2]
            if t is not Garbage or ev[4] != CAPTURE_START:  # bytes from before the capture keep it fresh
                self.fresh = False
                if t is ReturnPacket or t is Ack or t is Nack:
                    self._first_reply(rec)
        if t is LongPacket and not self._uniform:
            # Settle each VID's model now: what is learned later does not rewrite this packet.
            model_of = self.model_of
            rec.vid_models = tuple([model_of(r[0]) for r in ev.records])
        self._index += 1
        pending = self._pending
        if pending is not None:
            t0, t1 = ev[2], pending.event[3]
            if t0 is not None and t1 is not None and t0 - t1 > self.reply_timeout:
                self._resolve_missing(out, rec)
                pending = None
        if t is ReturnPacket or t is Ack or t is Nack:
            self._on_reply(rec, pending)
        elif t is ShortPacket or t is LongPacket:
            if pending is not None:
                self._resolve_missing(out, rec)
            self._last_request = None
            if t is LongPacket:
                self._on_long(ev)
            else:
                self._on_short(rec, ev)
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

    def _end_segment(self, out: list[Record], end_t: float | None) -> None:
        p = self._pending
        if p is None:
            return
        self._resolve_missing(out)
        t1 = p.event[3]
        if end_t is None or t1 is None or end_t - t1 <= self.reply_timeout:
            p.status = UNKNOWN  # its reply time had not run out: it may have come after the capture

    def _first_reply(self, rec: Record) -> None:
        """The segment's first packet is a reply: to a request before the capture, if it came in time."""
        t0, s = rec.event[2], self._segment_t
        if self._pending is None and (t0 is None or s is None or t0 - s <= self.reply_timeout):
            rec.status = UNSEEN

    # ---- pairing -----------------------------------------------------------------------------
    def _resolve_missing(self, out: list[Record], by: Record | None = None) -> None:
        self._pending.status = MISSING
        self._pending.resolved_by = by
        self._pending = None
        out += self._held
        self._held = []

    def _on_long(self, ev: LongPacket) -> None:
        if not ev.checksum_ok:
            return
        address, t = ev.address, ev.t_start
        n = ev.length - 1
        if n <= 0:
            return
        end = address + n
        if end > 256:
            for vid, data in ev.records:
                self.servo(vid).store(address, data, t)
        else:
            mask = ((1 << n) - 1) << address
            servos = self.servos
            for vid, data in ev.records:
                st = servos.get(vid)
                if st is None:
                    st = self.servo(vid)
                st.image[address:end] = data  # inlined ServoState.store: 18 of these per gait frame
                st.known |= mask
                st.last_t = t
        ida = self._id_address
        if address <= ida < end:
            k = ida - address
            self._renumber([(vid, data[k]) for vid, data in ev.records if len(data) > k])

    def _on_short(self, rec: Record, ev: ShortPacket) -> None:
        sid = ev.id
        # A packet whose Sum is wrong names no servo we can trust: it creates none and changes no shadow.
        if ev.checksum_ok:
            data = ev.data
            if sid == BROADCAST_ID:
                if data:
                    for st in list(self.servos.values()):
                        st.store(ev.address, data, ev.t_start)
            else:
                st = self.servos.get(sid) or self.servo(sid)
                st.requests += 1
                if data:
                    address = ev.address
                    st.store(address, data, ev.t_start)
                    ida = self._id_address
                    if address <= ida < address + len(data):
                        self._renumber([(sid, data[ida - address])])
        if FLAG_WANTS_REPLY[ev.flag]:  # an ACK/NACK or a return (table 4.3)
            self._pending = rec

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
        if pending is not None:
            req = pending
            rec.status = PAIRED
            req.status = ANSWERED
            req.reply = rec
            self._pending = None
            self._last_request = req
        elif self._last_request is not None:
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
            if ev.checksum_ok:
                st = self.servo(ev.id)
                st.returns += 1
                if rec.latency is not None and rec.status == PAIRED:
                    st.latencies.append(rec.latency)
                self._learn(ev, st)
                st.store(ev.address, ev.data, ev.t_start)
                rec.model = st.model
        elif req is not None:
            rec.model = req.model

    def _learn(self, ev: ReturnPacket, st: ServoState) -> None:
        # A return of addresses 0-1 carries the model number (table 4.5): 0x3030 RS303MR, 0x3040 RS304MD.
        if ev.address == 0 and len(ev.data) >= 2 and ev.id not in self.configured:
            m = self.registry.by_number.get(int.from_bytes(ev.data[:2], "little"))
            if m is not None and m is not st.model:
                self.learned[ev.id] = m
                self._model_cache.pop(ev.id, None)
                st.model = m
                self._uniform = self._all_default()
