"""Capture statistics (traffic, per-servo polls, latencies, bus load, health, what happened); pure, no I/O.

The one definition of these figures: ``info``, the MCAP metadata and the monitor all read them here.
"""

from __future__ import annotations

import itertools
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np

from ..decode.blocks import Block
from ..protocol.events import Ack, Garbage, LongPacket, ReturnPacket, ShortPacket
from ..decode.frame_runs import LONG, RETURN, SHORT
from .health import FLUSH_ROWS, Frames, HealthRecorder, servo_health, timer, what_happened
from .pipeline import Sink
from ..decode.decoder import Step
from ..decode.framing import SEAM_BACK_S
from ..protocol.wire import BITS_PER_BYTE, BROADCAST_ID, RETURN_FLAG_BITS, byte_time

# Latencies are counted in 1 us bins: exact enough for percentiles of a bus whose return delay
# steps by 50 us (table 4.6 No. 7), with memory bounded by the spread, not by the capture length.
_LATENCY_BIN = 1e-6
# The peak bus load is the busiest of these windows from the capture start: long enough to hold many
# poll cycles, short enough that a burst is not averaged away over a long capture.
_LOAD_WINDOW = 1.0
# (flag, carries data) -> (op word, asks for a return): both follow from those two alone (table 4.2, 4.3).
_OPS: dict[tuple[int, bool], tuple[str, bool]] = {}
_NO_SEAM = 1 << 62  # a stream offset no capture reaches


@dataclass
class ServoStats:
    """Traffic to and from one servo ID."""

    id: int
    requests: int = 0          # short packets addressed to this ID
    reads: int = 0             # requests that ask for a return
    long_writes: int = 0       # long packets carrying data for this ID
    returns: int = 0
    acks: int = 0
    nacks: int = 0
    missing: int = 0           # requests whose reply never came
    answered: int = 0          # requests whose reply came
    first_read_t: float | None = None  # ... in the current time segment
    last_read_t: float | None = None
    first_missing: tuple[float | None, int] | None = None  # (t, offset) of the first unanswered request
    segment_reads: int = 0     # reads in the current time segment
    read_gaps: int = 0         # intervals between reads in segments already closed ...
    read_span: float = 0.0     # ... and the seconds they cover

    @property
    def poll_rate(self) -> float | None:
        """Reads per second between this servo's first and last read, within each time segment (None
        with fewer than two reads in one segment)."""
        gaps, span = self.read_gaps, self.read_span
        if self.segment_reads >= 2 and self.first_read_t is not None and self.last_read_t is not None:
            gaps += self.segment_reads - 1
            span += self.last_read_t - self.first_read_t
        return gaps / span if gaps and span > 0 else None

    def end_segment(self) -> None:
        """A seam of the capture's clock: the reads so far are one segment's."""
        if self.segment_reads >= 2 and self.first_read_t is not None and self.last_read_t is not None:
            self.read_gaps += self.segment_reads - 1
            self.read_span += self.last_read_t - self.first_read_t
        self.segment_reads = 0
        self.first_read_t = self.last_read_t = None


@dataclass
class LatencyHistogram:
    """Reply latencies in 1 us bins: percentiles and maximum in bounded memory."""

    bins: Counter = field(default_factory=Counter)
    count: int = 0
    max: float | None = None

    def add(self, latency: float) -> None:
        self.bins[round(latency / _LATENCY_BIN)] += 1
        self.count += 1
        if self.max is None or latency > self.max:
            self.max = latency

    def percentile(self, p: float) -> float | None:
        """The smallest bin value at or below which ``p`` percent of the latencies fall."""
        if not self.count:
            return None
        rank = max(1, -(-self.count * p // 100))  # ceil, nearest-rank method
        seen = 0
        for k in sorted(self.bins):
            seen += self.bins[k]
            if seen >= rank:
                return k * _LATENCY_BIN
        return self.max


class CaptureStats(Sink):
    """Feed every record (and the findings), then read the figures or :meth:`as_dict`; as a sink of
    the drive loop it counts the bytes, records and findings that pass through.

    Times come from the records; a capture without timestamps is measured in line time: its
    byte count at the configured baud rate, as if the bus had never been idle. Where the capture's
    clock has seams (rs30x_sniff.decode.framing.Seam, handed over on the steps), durations add up over the
    time segments and rates and loads are taken within them. ``timing_unsupported`` (a reason) leaves
    out the figures that need the byte time to be right (latency, bus load): set when the timestamps
    contradict the baud rate.
    """

    takes_blocks = True  # a Block's rows are counted on its columns (add_block), as add() counts each

    def __init__(self, baud: int) -> None:
        self.baud = baud
        self.bytes = 0
        self.bytes_in = 0  # bytes fed through chunk()
        self.records = 0
        self.by_kind: Counter = Counter()
        self.by_op: Counter = Counter()
        self.bad_checksums = 0
        self.garbage_bytes = 0
        self.servos: dict[int, ServoStats] = {}
        self._known = np.zeros(256, dtype=bool)  # IDs in self.servos, for add_block
        self._op_table = np.zeros(512, dtype=bool)  # flag * 2 + carries data -> reads (of _OPS seen)
        self.latency = LatencyHistogram()
        self.findings: Counter = Counter()
        self.finding_codes: Counter = Counter()
        self.first_t: float | None = None  # the capture's first time
        self.last_t: float | None = None   # the current time segment's last
        self.segment_t: float | None = None  # the current time segment's first
        self.closed_span = 0.0  # seconds of the time segments before it
        self.seams: list = []   # every seam so far
        self._next_seam = _NO_SEAM  # stream offset where the next seam takes effect
        self._pending_seams: list = []
        self.timing_unsupported: str | None = None
        self.wall_anchor: float | None = None  # epoch seconds of capture time 0, where the source says
        self.unmeasured = 0  # paired replies whose times give no latency (stamped before their request ended)
        self.timed = False
        self.health = HealthRecorder()          # per-servo register ranges, status flags, findings
        self.bad_by: Counter = Counter()        # (kind, the ID it claims) of packets with a bad Sum
        self.first_bad: tuple[float | None, int] | None = None
        self.first_garbage: tuple[float | None, int] | None = None
        self._win_start: float | None = None    # the current bus-load window (see _LOAD_WINDOW)
        self._win_end = float("-inf")
        self._win_bytes = 0
        self._windows: list[tuple[float, float]] = []  # (load, start) of every closed window, in time order
        # Where a live reader fell behind: (t, seconds, bytes) of bytes timed at the line rate, not as
        # they came (rs30x_sniff.sources.serial_tap); no load is measured over them. The source's own list.
        self.stalls: list[tuple[float, float, int]] = []

    # ---- as a sink ---------------------------------------------------------------------------------
    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        self.bytes_in += len(data)

    def batch(self, step: Step) -> None:
        if step.seams:
            self._pending_seams += step.seams
            self._next_seam = self._pending_seams[0].offset
        add = self.add
        for rec in step:
            if type(rec) is Block:
                self.add_block(rec)
            else:
                add(rec)
        if step.findings:
            self.add_findings(step.findings)

    def close(self) -> None:
        self.set_bytes(self.bytes_in)

    def servo(self, sid: int) -> ServoStats:
        st = self.servos.get(sid)
        if st is None:
            st = self.servos[sid] = ServoStats(sid)
            self._known[sid] = True
        return st

    def add(self, rec: Any) -> None:
        # Per record on captures of millions of frames: events are read by index, not by property.
        ev = rec.event
        if ev[0] >= self._next_seam:
            self._end_segment(ev[0])
        self.records += 1
        t = type(ev)
        kind = t.kind
        self.by_kind[kind] += 1
        raw = ev[1]
        end_offset = ev[0] + len(raw)
        if end_offset > self.bytes:
            self.bytes = end_offset
        ts = ev[2]
        if ts is not None:
            self.timed = True
            if self.first_t is None:
                self.first_t = ts
            if self.segment_t is None:
                self.segment_t = ts
            end = ev[3]
            if end is None:
                end = ts
            if self.last_t is None or end > self.last_t:
                self.last_t = end
            if ts >= self._win_end:
                self._roll(ts)
            self._win_bytes += len(raw)
        if t is Garbage:
            self.garbage_bytes += len(raw)
            if self.first_garbage is None:
                self.first_garbage = (ts, ev[0])
            return
        if not ev.checksum_ok:
            # Its ID, VIDs and op cannot be trusted: a bad checksum, not traffic of the servos it names.
            # The ID it claims is kept apart, as a hint for the summary ("bad returns from ID 3").
            self.bad_checksums += 1
            self.bad_by[kind, getattr(ev, "id", None)] += 1
            if self.first_bad is None:
                self.first_bad = (ts, ev[0])
            return
        if t is ShortPacket:
            data = ev[9]
            key = (ev[5], bool(data))
            op = _OPS.get(key)
            if op is None:  # the op and whether it reads depend on the flag and on data being there
                op = _OPS[key] = (ev.op, ev.read_range is not None)
            self.by_op[op[0]] += 1
            sid = ev[4]
            if sid != BROADCAST_ID:
                st = self.servos.get(sid) or self.servo(sid)
                st.requests += 1
                if st.requests == 1:  # the model it is decoded as, even if it never answers
                    self.health.servo(sid).model = rec.model
                if rec.status == "answered":
                    st.answered += 1
                if op[1]:
                    st.reads += 1
                    st.segment_reads += 1
                    if ts is not None:
                        if st.first_read_t is None:
                            st.first_read_t = ts
                        st.last_read_t = ts
                if rec.status == "missing":
                    st.missing += 1
                    if st.first_missing is None:
                        st.first_missing = (ts, ev[0])
                if data:
                    self.health.written(rec, ev, sid)
        elif t is LongPacket:
            self.by_op["long-write"] += 1
            servos = self.servos
            for r in ev[8]:
                st = servos.get(r[0]) or self.servo(r[0])
                st.long_writes += 1
            self.health.long_written(rec, ev)
        else:  # a reply: return, ACK or NACK
            sid = ev[4] if t is ReturnPacket else rec.id
            if sid is not None:
                st = self.servos.get(sid) or self.servo(sid)
                if t is ReturnPacket:
                    st.returns += 1
                    self.health.returned(rec, ev, sid)
                elif t is Ack:
                    st.acks += 1
                else:
                    st.nacks += 1
            lat = rec.latency
            if rec.status == "paired":
                if lat is not None:
                    self.latency.add(lat)
                elif ts is not None:
                    self.unmeasured += 1

    def add_block(self, blk: Block) -> None:
        """Count a Block's rows (rs30x_sniff.decode.blocks) on its columns: the same figures as :meth:`add` of
        each of its records, in order. Every row is an intact short, long or return packet, and each
        request asking for a reply is followed by its (paired) return."""
        n = len(blk)
        if not n:
            return
        cols = blk.cols
        kind, sid, flag, dlen = cols["kind"], cols["id"], cols["flag"], cols["data_len"]
        run, lo, hi = blk.run, blk.lo, blk.hi
        starts, ends = run.starts[lo:hi], run.ends[lo:hi]
        if run.base + int(starts[0]) >= self._next_seam:  # a Block never spans a seam (framing)
            self._end_segment(run.base + int(starts[0]))
        self.records += n
        counts = np.bincount(kind, minlength=3).tolist()
        by_kind = self.by_kind
        for code, name in ((SHORT, "short"), (LONG, "long"), (RETURN, "return")):
            if counts[code]:
                by_kind[name] += counts[code]
        end_offset = run.base + int(ends[-1])  # rows are in wire order
        if end_offset > self.bytes:
            self.bytes = end_offset
        t0 = blk.t0
        if t0 is not None:
            self.timed = True
            if self.first_t is None:
                self.first_t = float(t0[0])
            if self.segment_t is None:
                self.segment_t = float(t0[0])
            last = float(blk.t1.max())
            if self.last_t is None or last > self.last_t:
                self.last_t = last
            self._load_rows(t0, ends - starts)
        is_short = kind == SHORT
        to_servo = is_short & (sid != BROADCAST_ID)
        is_return = kind == RETURN
        # Long packets by shape: (rows, VID of each of their records).
        long_rows = np.flatnonzero(kind == LONG) if counts[LONG] else None
        longs = _long_vids(blk, long_rows) if counts[LONG] else []
        named = sid[to_servo | is_return]
        known = self._known
        if not known[named].all() or not all(known[v].all() for _, v in longs):
            self._new_servos(blk, to_servo | is_return, longs)
        servos, health = self.servos, self.health
        models = blk.models
        if counts[SHORT]:
            keys = flag.astype(np.intp) * 2 + (dlen > 0)
            by_key = np.bincount(keys[is_short], minlength=512)
            table = self._op_table
            for key in np.flatnonzero(by_key).tolist():
                op = _OPS.get((key >> 1, bool(key & 1)))
                if op is None:  # the op and whether it reads depend on the flag and on data being there
                    ev = run.event(lo + int(np.flatnonzero(is_short & (keys == key))[0]))
                    op = _OPS[key >> 1, bool(key & 1)] = (ev.op, ev.read_range is not None)
                table[key] = op[1]
                self.by_op[op[0]] += int(by_key[key])
            req_counts = np.bincount(sid[to_servo], minlength=256)
            for i in np.flatnonzero(req_counts).tolist():
                st = servos[i]
                if st.requests == 0:  # the model it is decoded as, even if it never answers
                    health.servo(i).model = models[i]
                st.requests += int(req_counts[i])
            answered = np.bincount(sid[to_servo & blk.answered], minlength=256)
            for i in np.flatnonzero(answered).tolist():
                servos[i].answered += int(answered[i])
            read_rows = np.flatnonzero(to_servo & table[keys])
            if read_rows.size:
                rs = sid[read_rows]
                read_counts = np.bincount(rs, minlength=256)
                if t0 is None:
                    for i in np.flatnonzero(read_counts).tolist():
                        servos[i].reads += int(read_counts[i])
                        servos[i].segment_reads += int(read_counts[i])
                else:
                    tr = t0[read_rows]
                    ids, first = np.unique(rs, return_index=True)
                    _, last = np.unique(rs[::-1], return_index=True)
                    firsts, lasts = tr[first].tolist(), tr[len(rs) - 1 - last].tolist()
                    for i, c, f, la in zip(ids.tolist(), read_counts[ids].tolist(), firsts, lasts):
                        st = servos[i]
                        st.reads += c
                        st.segment_reads += c
                        if st.first_read_t is None:
                            st.first_read_t = f
                        st.last_read_t = la
            writes = np.flatnonzero(to_servo & (dlen > 0))
            if writes.size:
                self._health_rows(blk, writes, health.writes, False)
        if counts[LONG]:
            self.by_op["long-write"] += counts[LONG]
            for _, vids in longs:
                vc = np.bincount(vids.ravel(), minlength=256)
                for i in np.flatnonzero(vc).tolist():
                    servos[i].long_writes += int(vc[i])
            if blk.vid_models is None:
                self._health_rows(blk, long_rows, health.long_writes, None)
            else:  # servos of mixed models: each packet on its own, as the record path does
                made = blk.made_rows
                for k in long_rows.tolist():
                    rec = made.get(k) or blk.fresh_record(k)
                    health.long_written(rec, rec.event)
        if counts[RETURN]:
            rc = np.bincount(sid[is_return], minlength=256)
            for i in np.flatnonzero(rc).tolist():
                servos[i].returns += int(rc[i])
            with_data = np.flatnonzero(is_return & (dlen > 0))
            if with_data.size:
                self._health_rows(blk, with_data, health.returns, True)
            flagged = np.flatnonzero(is_return & (flag != 0))
            if flagged.size:
                self._flags(blk, flagged)
            got = blk.reply_latencies()
            if got is not None and got[0].size:
                self._latencies(got[1])

    def _new_servos(self, blk: Block, named: np.ndarray, longs: list) -> None:
        """Create the ServoStats of the IDs the Block names first, in the order add() would."""
        sid = blk.cols["id"]
        first: dict[int, tuple[int, int]] = {}  # ID -> (row, place in the row) of its first mention
        rows = np.flatnonzero(named)
        for i, k in zip(*np.unique(sid[rows], return_index=True)):
            first[int(i)] = (int(rows[k]), 0)
        for rws, vids in longs:
            flat = vids.ravel()
            for i, k in zip(*np.unique(flat, return_index=True)):
                at = (int(rws[k // vids.shape[1]]), int(k % vids.shape[1]) + 1)
                i = int(i)
                if i not in first or at < first[i]:
                    first[i] = at
        for i in sorted((i for i in first if i not in self.servos), key=first.__getitem__):
            self.servo(i)

    def _load_rows(self, t0: np.ndarray, sizes: np.ndarray) -> None:
        """The bus-load windows over rows starting at ``t0`` of ``sizes`` bytes (as add() rolls them)."""
        n = len(t0)
        if n > 1 and not (t0[1:] >= t0[:-1]).all():
            for ts, size in zip(t0.tolist(), sizes.tolist()):  # a clock that steps back: row by row
                if ts >= self._win_end:
                    self._roll(ts)
                self._win_bytes += size
            return
        if float(t0[-1]) < self._win_end:  # the usual: the whole Block within the current window
            self._win_bytes += int(sizes.sum())
            return
        cum = np.concatenate(([0], np.cumsum(sizes))).tolist()
        pos = 0
        while pos < n:
            ts = float(t0[pos])
            if ts >= self._win_end:
                self._roll(ts)
            stop = pos + 1 + int(np.searchsorted(t0[pos + 1:], self._win_end, "left"))
            self._win_bytes += cum[stop] - cum[pos]
            pos = stop

    def _health_rows(self, blk: Block, rows: np.ndarray, bufs: dict, present: bool | None) -> None:
        """Rows of the Block into the health recorder's buffers, as returned() / written() /
        long_written() put them (``present`` True, False, None): by shape, each shape in the order
        its first row came, flushed every FLUSH_ROWS rows of a shape as they are."""
        cols, run = blk.cols, blk.run
        address = cols["address"][rows].astype(np.int64)
        if present is None:  # long packets: (address, length, records)
            length = cols["length"][rows].astype(np.int64)
            dl = cols["data_len"][rows].astype(np.int64)
            nrec = np.where(length > 0, -(-dl // np.maximum(length, 1)), 0)
            keys = (address * 256 + length) * (1 << 20) + nrec
        else:  # returns and short writes: (servo, address, data length)
            keys = (cols["id"][rows].astype(np.int64) * 256 + address) * (1 << 20) + cols["data_len"][rows]
        order = np.argsort(keys, kind="stable")
        sk = keys[order]
        cut = np.flatnonzero(sk[1:] != sk[:-1]) + 1
        bounds = [0, *cut.tolist(), len(sk)]
        heads = bounds[:-1]
        groups = sorted(zip(order[heads].tolist(), heads, bounds[1:], sk[heads].tolist()))  # by first row
        health = self.health
        grouped = rows[order] + blk.lo  # rows of the run, shape by shape
        models = blk.models
        for _, g0, g1, key in groups:
            rest, third = divmod(key, 1 << 20)
            key_t = (rest >> 8, rest & 255, third)
            model = blk.default if present is None else models[key_t[0]]
            b = bufs.get(key_t)
            if b is None or b[0] is not model:
                b = health.open_buffer(bufs, key_t, model)
            i = g0
            while True:
                room = FLUSH_ROWS - len(b[1])
                if g1 - i < room:  # the rest waits in the buffer, as raw frames
                    b[1] += _buffered(run, grouped[i:g1], _frame_size(key_t, present))
                    break
                # These rows fill the buffer: the record path's flush, their bytes read in place.
                if present is None:
                    health.flush_long(key_t, b, run, grouped[i:i + room])
                else:
                    health.flush_short(key_t, b, present, run, grouped[i:i + room])
                i += room
                if i == g1:
                    break

    def _flags(self, blk: Block, rows: np.ndarray) -> None:
        """Status flags of a Block's returns (rows), counted per servo and flag with the first seen."""
        cols = blk.cols
        flags, ids = cols["flag"][rows], cols["id"][rows]
        t0 = blk.t0
        offsets = blk.offsets[rows]
        health = self.health
        for i in np.unique(ids).tolist():
            mine = ids == i
            h = health.servos.get(i) or health.servo(i)
            for bit, name in RETURN_FLAG_BITS.items():
                hit = np.flatnonzero(mine & ((flags & bit) != 0))
                if not hit.size:
                    continue
                seen = h.flags.get(name)
                if seen is None:
                    k = int(hit[0])
                    h.flags[name] = [len(hit), None if t0 is None else float(t0[rows[k]]), int(offsets[k])]
                else:
                    seen[0] += len(hit)

    def _latencies(self, lat: np.ndarray) -> None:
        """Paired replies' latencies into the histogram, as LatencyHistogram.add of each."""
        hist = self.latency
        bins = hist.bins
        keys = np.rint(lat / _LATENCY_BIN).astype(np.int64)
        k0 = int(keys.min())
        cnt = np.bincount(keys - k0)
        for k in np.flatnonzero(cnt).tolist():
            bins[k + k0] += int(cnt[k])
        hist.count += len(lat)
        top = float(lat.max())
        if hist.max is None or top > hist.max:
            hist.max = top

    def add_findings(self, findings: Iterable[Any]) -> None:
        findings = list(findings)
        for f in findings:
            self.findings[f.severity] += 1
            self.finding_codes[f"{f.code} {f.name}"] += 1
        self.health.findings(findings)

    def _end_segment(self, offset: int) -> None:
        """Close the time segment before the seam(s) at or before stream ``offset``: its span is added
        up, its last bus-load window and each servo's reads are closed, and the clock starts afresh."""
        while self._pending_seams and self._pending_seams[0].offset <= offset:
            self.seams.append(self._pending_seams.pop(0))
        self._next_seam = self._pending_seams[0].offset if self._pending_seams else _NO_SEAM
        if self.segment_t is None:
            return
        if self.last_t is not None:
            self.closed_span += max(0.0, self.last_t - self.segment_t)
            self._close_window(self.last_t)
        self.segment_t = self.last_t = None
        self._win_start, self._win_end, self._win_bytes = None, float("-inf"), 0
        for st in self.servos.values():
            st.end_segment()

    def _close_window(self, last: float) -> None:
        """A segment's last window, closed at its last byte ``last``."""
        load = self._open_window_load(last)
        if load is not None:
            self._windows.append((load, self._win_start))

    def _open_window_load(self, last: float | None) -> float | None:
        """The load of the window still open, up to ``last``: counted over its own span once that is half
        a window (shorter, one packet would look like a full bus); None before that."""
        if self._win_start is None:
            return None
        span = (last or self._win_start) - self._win_start
        if span < _LOAD_WINDOW / 2:
            return None
        return min(1.0, self._win_bytes * byte_time(self.baud) / min(span, _LOAD_WINDOW))

    def _roll(self, ts: float) -> None:
        """Close the bus-load window(s) before ``ts`` and open the one holding it."""
        if self._win_start is None:
            self._win_start = ts
        else:
            load = min(1.0, self._win_bytes * byte_time(self.baud) / _LOAD_WINDOW)
            self._windows.append((load, self._win_start))
            self._win_start += (ts - self._win_start) // _LOAD_WINDOW * _LOAD_WINDOW
        self._win_end = self._win_start + _LOAD_WINDOW
        self._win_bytes = 0

    def set_bytes(self, n: int) -> None:
        """The input's total byte count (the records may end before trailing bytes of a cut frame)."""
        self.bytes = max(self.bytes, n)

    # ---- figures ------------------------------------------------------------------------------
    @property
    def line_time(self) -> float:
        """Seconds the captured bytes occupy the line at the baud rate (10 bits a byte)."""
        return self.bytes * byte_time(self.baud)

    @property
    def duration(self) -> float:
        """Seconds from the first to the last byte, added up over the time segments (line time for a
        capture without timestamps)."""
        if self.timed and self.first_t is not None:
            current = 0.0
            if self.segment_t is not None and self.last_t is not None:
                current = max(0.0, self.last_t - self.segment_t)
            return self.closed_span + current
        return self.line_time

    @property
    def bus_load(self) -> float | None:
        """Fraction of the capture's time the line was busy (None for an instant or untimed capture,
        or where the timestamps contradict the baud rate)."""
        if not self.timed or self.timing_unsupported:
            return None
        d = self.duration
        return min(1.0, self.line_time / d) if d > 0 else None

    @property
    def load_peak(self) -> tuple[float, float] | None:
        """(load, start time) of the busiest second of a timed capture (None for a shorter one).

        The last window counts over its own span once that is half a window (shorter, one packet
        would look like a full bus); and no second is quieter than the whole capture's average says
        the busiest must be.
        """
        if not self.timed or self.timing_unsupported or self.duration < _LOAD_WINDOW:
            return None
        # The first of the busiest windows, none measured over a reader's stall.
        best = max((w for w in self._windows if not (self.stalls and self._stalled(w[1]))),
                   key=lambda w: w[0], default=None)
        load = self._open_window_load(self.last_t)
        if load is not None and not self._stalled(self._win_start) and (best is None or load > best[0]):
            best = (load, self._win_start)
        avg = self.bus_load
        if avg is not None and self.first_t is not None and (best is None or avg > best[0]):
            best = (avg, self.first_t)
        return best

    def latency_dict(self) -> dict[str, Any]:
        """Reply latencies: count and percentiles, or none with the reason they cannot be given."""
        lat = self.latency
        if self.timing_unsupported:
            return {"count": 0, "p50": None, "p95": None, "max": None, "unmeasured": lat.count + self.unmeasured,
                    "absent": self.timing_unsupported}
        out = {"count": lat.count, "p50": lat.percentile(50), "p95": lat.percentile(95), "max": lat.max,
               "unmeasured": self.unmeasured}
        if self.unmeasured:
            out["absent"] = (f"{self.unmeasured} repl{'y' if self.unmeasured == 1 else 'ies'} stamped before "
                             f"{'its' if self.unmeasured == 1 else 'their'} request ended (F005/F006): no latency")
        return out

    def _stalled(self, start: float) -> bool:
        """Whether the load window from ``start`` holds bytes a live reader timed at the line rate."""
        end = start + _LOAD_WINDOW
        return any(t < end and t + seconds > start for t, seconds, _ in self.stalls)

    @property
    def packets(self) -> int:
        return self.records - self.by_kind["garbage"]

    def as_dict(self) -> dict[str, Any]:
        """Every figure as plain JSON-ready data (``info --format json``)."""
        lat = self.latency
        return {
            "duration_s": self.duration,
            "timed": self.timed,
            "bytes": self.bytes,
            "baud": self.baud,
            "bus_load": self.bus_load,
            "records": self.records,
            "packets": self.packets,
            "by_type": dict(sorted(self.by_kind.items())),
            "by_op": dict(sorted(self.by_op.items())),
            "bad_checksums": self.bad_checksums,
            "garbage_bytes": self.garbage_bytes,
            "latency_s": self.latency_dict(),
            "segments": len(self.seams) + 1 if self.timed else 1,
            "reader_stalls": [{"t": t, "seconds": sec, "bytes": n} for t, sec, n in self.stalls],
            "timing_unsupported": self.timing_unsupported,
            "servos": {
                str(sid): {"requests": s.requests, "reads": s.reads, "long_writes": s.long_writes,
                           "returns": s.returns, "acks": s.acks, "nacks": s.nacks, "missing": s.missing,
                           "poll_rate_hz": s.poll_rate}
                for sid, s in sorted(self.servos.items())
            },
            "findings": {sev: self.findings.get(sev, 0) for sev in ("error", "warning", "info")},
            "findings_by_rule": dict(self.finding_codes.most_common()),
            **self.health_dict(),
        }

    def health_dict(self) -> dict[str, Any]:
        """Per-servo health, the busiest second and the "what happened" lines (keys of :meth:`as_dict`)."""
        self.health.flush()
        when = timer(self.first_t, self.timed, byte_time(self.baud), self.wall_anchor)
        hs = self.health.servos
        # The servos of the traffic table, and any whose registers were seen; not IDs only a finding
        # named (a damaged packet's ID is no servo).
        ids = set(self.servos) | {sid for sid, h in hs.items() if h.lo or h.flags}
        health = {str(sid): servo_health(hs.get(sid), when) for sid in sorted(ids)}
        peak = self.load_peak
        t, wall = when(peak[1], 0) if peak else (None, None)
        return {
            "health": health,
            "bus_load_peak": None if peak is None else {"load": peak[0], "t": t, "wall": wall,
                                                        "window_s": _LOAD_WINDOW},
            "what_happened": what_happened(self, health, when),
        }


def _long_vids(blk: Block, rows: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The long packets among ``rows`` of a Block, by shape: (their rows, the VID of each of their
    records, one row of VIDs per packet); packets that carry no record are left out."""
    cols = blk.cols
    length = cols["length"][rows].astype(np.int64)
    dlen = cols["data_len"][rows].astype(np.int64)
    keep = (length > 0) & (dlen > 0)
    rows, length, dlen = rows[keep], length[keep], dlen[keep]
    if not rows.size:
        return []
    a, starts = blk.run.bytes_array, blk.run.starts[blk.lo:blk.hi]
    keys = length * (1 << 20) + dlen
    shapes = [int(keys[0])] if (keys == keys[0]).all() else np.unique(keys).tolist()
    out = []
    for key in shapes:
        ln, dl = divmod(key, 1 << 20)
        rws = rows if len(shapes) == 1 else rows[keys == key]
        nrec = -(-dl // ln)  # the last record of a ragged packet is cut short
        out.append((rws, a[(starts[rws] + 7)[:, None] + np.arange(nrec) * ln]))
    return out


def _frame_size(key: tuple, present: bool | None) -> int:
    """The frame size a health buffer's key describes: (servo, address, data length) of a short
    packet or return, (address, length, records) of a long packet."""
    return 8 + (key[1] * key[2] if present is None else key[2])


def _buffered(run: Any, rows: np.ndarray, size: int) -> list[bytes]:
    """Buffer items for ``rows`` of ``run``: the frames of ``size`` bytes as one Frames, and the
    others (left out at the flush, counted until then) as their own bytes, one item a row."""
    starts, ends = run.starts[rows], run.ends[rows]
    fits = ends - starts == size
    items = Frames.rows(run.bytes_array[starts[fits][:, None] + np.arange(size)].tobytes(), size)
    if not fits.all():
        blob = run.blob
        items += [blob[s:e] for s, e in zip(starts[~fits].tolist(), ends[~fits].tolist())]
    return items


class RecentLoad:
    """Bus load over the last ``window`` seconds of capture time: what a live display shows.

    Fed ``(t, nbytes)`` per record or chunk start; the newest item's own bytes end after its start
    time, so the busy time counts the items before it, over the window up to its start.
    """

    def __init__(self, baud: int, window: float = 1.0) -> None:
        self.bits = BITS_PER_BYTE / baud
        self.window = window
        self._items: deque[tuple[float, int]] = deque()
        self._bytes = 0
        self._last_t: float | None = None

    def add(self, t: float, nbytes: int) -> None:
        self.extend(((t, nbytes),))

    def extend(self, timed_sizes: Iterable[tuple[float, int]]) -> None:
        """Add ``(t, nbytes)`` items in time order (one call per batch: the window is trimmed once)."""
        new = list(timed_sizes)
        prev = self._last_t
        restart = None
        for k, (t, _) in enumerate(new):
            if prev is not None and t < prev - SEAM_BACK_S:
                restart = k  # the clock restarted (a seam, rs30x_sniff.decode.framing): nothing is measured across it
            prev = t
        if restart is not None:
            self._start_over()
            new = new[restart:]
        self._append(new)

    def _start_over(self) -> None:
        self._items.clear()
        self._bytes = 0
        self._last_t = None

    def _append(self, new: list[tuple[float, int]]) -> None:
        if not new:
            return
        items = self._items
        items.extend(new)
        self._bytes += sum(n for _, n in new)
        last = items[-1][0]
        if self._last_t is None or last > self._last_t:
            self._last_t = last
        horizon = self._last_t - self.window
        while items and items[0][0] < horizon:
            self._bytes -= items.popleft()[1]

    def extend_arrays(self, ts: np.ndarray, sizes: np.ndarray) -> None:
        """:meth:`extend` with ``zip(ts, sizes)`` (a Block's rows): the items the window would drop at
        once (older than it, once all held before them are dropped too) are not made at all."""
        n = len(ts)
        if not n:
            return
        if self._last_t is not None and float(ts[0]) < self._last_t - SEAM_BACK_S:
            self._start_over()  # a restarted clock (a seam): nothing is measured across it
        drops = np.flatnonzero(np.diff(ts) < -SEAM_BACK_S)  # Blocks joined across a seam
        if drops.size:
            self._start_over()
            k = int(drops[-1]) + 1
            ts, sizes, n = ts[k:], sizes[k:], n - k
        last = float(ts[-1])
        horizon = (last if self._last_t is None or last > self._last_t else self._last_t) - self.window
        p = 0
        items = self._items
        if not items or max(t for t, _ in items) < horizon:
            old = ts[:-1] < horizon  # the last item is always handed over: _append settles the window on it
            p = n - 1 if old.all() else int(np.argmin(old))
        self._append(list(zip(ts[p:].tolist(), sizes[p:].tolist())))

    @property
    def value(self) -> float | None:
        """Fraction of the window the wire was busy, 0..1 (None until there is a span to measure)."""
        items = self._items
        if not items or self._last_t is None:
            return None
        span = min(self.window, max(self._last_t - items[0][0], 0.0))
        if span <= 0:
            return None
        busy = (self._bytes - items[-1][1]) * self.bits
        return min(1.0, busy / span)
