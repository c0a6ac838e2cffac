"""What the monitor shows, without Textual: a bounded record history, counts, servo rows, findings, filter, plot."""

from __future__ import annotations

import sys
from array import array
from bisect import bisect_left, bisect_right
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np

from ..decode.blocks import Block
from ..decode.pairing import BusTracker, Record
from ..protocol.events import LongPacket, ReturnPacket, ShortPacket
from ..decode.frame_runs import LONG, RETURN, SHORT, FrameRun
from ..decode.framing import SEAM_BACK_S, SEAM_GAP_S
from ..sinks.stats import RecentLoad
from ..filters import SEVERITY_RANK, Filter

DEFAULT_HISTORY = 1_000_000
PLOT_POINTS = 4096  # samples kept per plotted servo (drawn binned by time, so a long capture stays readable)
LOAD_WINDOW = 1.0  # seconds of capture time the bus load is measured over
# Registers the plot can show, in the order `p` cycles through them.
PLOT_REGISTERS = ("present_position", "present_speed", "present_current", "present_temperature",
                  "present_voltage", "goal_position")
# Registers the servos pane shows.
SERVO_COLUMNS = ("torque_enable", "goal_position", "present_position", "present_speed", "present_current",
                 "present_temperature", "present_voltage")
LATENCY_SAMPLES = 1000  # percentiles over the most recent replies
CHUNK_RECORDS = 1 << 16  # Records held per list of the history (eviction trims the first list only)

# Python object sizes on this interpreter, for the memory estimate (measured once, not guessed).
_EMPTY_LIST = sys.getsizeof([])
_RECORD_BASE = sys.getsizeof(Record.__new__(Record)) + _EMPTY_LIST


_SIZES: dict[tuple, int] = {}  # events of one type and shape all weigh the same


def record_size(rec: Record) -> int:
    """Approximate bytes a record holds on to: the record, its event, and the event's byte strings."""
    ev = rec.event
    t = type(ev)
    key = (t, len(ev.raw), ev.count if t is LongPacket else 0)
    size = _SIZES.get(key)
    if size is None:
        size = _RECORD_BASE + sys.getsizeof(ev) + sys.getsizeof(ev.raw) + 8  # + the history list's slot
        if t is ShortPacket or t is ReturnPacket:
            size += sys.getsizeof(ev.data)
        elif t is LongPacket:
            recs = ev.records
            size += sys.getsizeof(recs) + sum(sys.getsizeof(r) + sys.getsizeof(r.data) for r in recs)
        if len(_SIZES) < 4096:
            _SIZES[key] = size
    return size


@dataclass
class ServoRow:
    """One servo as the servos pane shows it (a snapshot made on the decoding thread)."""

    id: int
    model: str
    values: dict[str, Any]
    units: dict[str, str | None]
    requests: int
    returns: int
    latency_p50: float | None
    latency_p95: float | None
    last_t: float | None


def _percentile(sorted_values: list[float], q: float) -> float | None:
    if not sorted_values:
        return None
    k = min(len(sorted_values) - 1, max(0, round(q * (len(sorted_values) - 1))))
    return sorted_values[k]


def servo_snapshot(bus: BusTracker) -> dict[int, ServoRow]:
    """Rows for every servo the bus tracker knows; called on the thread that feeds the tracker."""
    rows: dict[int, ServoRow] = {}
    for sid, st in list(bus.servos.items()):
        values, units = {}, {}
        for name in SERVO_COLUMNS:
            try:
                reg = st.model.register(name)
            except KeyError:
                continue
            values[name] = st.get(name)
            units[name] = reg.unit
        lat = sorted(list(st.latencies)[-LATENCY_SAMPLES:])
        rows[sid] = ServoRow(sid, st.model.name, values, units, st.requests, st.returns,
                             _percentile(lat, 0.5), _percentile(lat, 0.95), st.last_t)
    return rows


def register_value(rec: Record, servo_id: int, name: str) -> Any:
    """The value of register ``name`` of ``servo_id`` that a record carries, if it carries all of it."""
    ev = rec.event
    t = type(ev)
    model = rec.model
    if model is None or not ev.checksum_ok:
        return None
    if t is ReturnPacket or t is ShortPacket:
        if ev.id != servo_id or not ev.data:
            return None
        address, data = ev.address, ev.data
    elif t is LongPacket:
        for r in ev.records:
            if r.vid == servo_id:
                # rec.model is the bus default here; the register addresses the plot offers are the
                # same in every model's map (tables 4.5 and 4.6), so it finds the right bytes.
                address, data = ev.address, r.data
                break
        else:
            return None
    else:
        return None
    try:
        return model.register(name).value_in(address, data)
    except KeyError:
        return None


# ---- Blocks (rs30x_sniff.decode.blocks): rows kept as columns ---------------------------------------------------
_BLOCK_BASE = sys.getsizeof(Block.__new__(Block)) + sys.getsizeof({}) + 8 * 112  # the object, cols, views


def run_nbytes(run: FrameRun) -> int:
    """Bytes a FrameRun holds: its bytes and its columns (shared by the Blocks cut from it)."""
    n = sys.getsizeof(run.blob) + 256
    for a in (run.starts, run.ends, run.t0, run.t1):
        if a is not None:
            n += a.nbytes + 112
    for a in (run.header_made or {}).values():
        if a.base is None:
            n += a.nbytes + 112
    return n


def built_nbytes(blk: Block) -> int:
    """Bytes of the Records a Block has built and keeps (a row shown, or every row the linter read)."""
    made = blk.made_rows
    if not made:
        return 0
    return sum(record_size(r) for r in made.values()) + sys.getsizeof(made)


_NOT_READ = object()  # a Block whose plot points Store.add has not read ahead


def _values_of(reg: Any, raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For a 1- or 2-byte register's raw bytes (as an unsigned little-endian number): the value
    register_value gives, as a float, and whether it is a number (an enum's label is not). Each raw
    value is converted once, when first seen: (values, is a number, worked out) by raw bytes, kept in
    the register's cache."""
    lut = reg.cache.get("plot values")
    if lut is None:
        size = 1 << 8 * reg.size
        lut = reg.cache["plot values"] = (np.zeros(size), np.zeros(size, dtype=bool), np.zeros(size, dtype=bool))
    values, ok, known = lut
    new = raw[~known[raw]]
    if new.size:
        bits = 8 * reg.size
        convert = reg.convert
        for u in np.unique(new).tolist():
            v = convert(u - (1 << bits) if reg.signed and u >= 1 << (bits - 1) else u)
            if isinstance(v, (int, float)):
                values[u] = float(v)
                ok[u] = True
            known[u] = True
    return values[raw], ok[raw]


def _register_of(model: Any, name: str) -> Any:
    if model is None:
        return None
    try:
        return model.register(name)
    except KeyError:
        return None


def _values_at(blob_array: np.ndarray, blob: bytes, at: np.ndarray, reg: Any) -> tuple[np.ndarray, np.ndarray]:
    """(values, is a number) of ``reg`` whose bytes start at ``at`` in the blob."""
    if reg.size <= 2:
        raw = blob_array[at].astype(np.intp)
        if reg.size == 2:
            raw |= blob_array[at + 1].astype(np.intp) << 8
        return _values_of(reg, raw)
    vals, oks = [], []
    for p in at.tolist():  # a wider register: as Register.value_in reads it
        v = reg.convert(int.from_bytes(blob[p:p + reg.size], "little", signed=reg.signed))
        good = isinstance(v, (int, float))
        vals.append(float(v) if good else 0.0)
        oks.append(good)
    return np.array(vals, dtype=float), np.array(oks, dtype=bool)


def block_points(blk: Block, ids: Iterable[int], name: str, byte_seconds: float,
                 a: int = 0) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """For each servo of ``ids``: (times, values) of register ``name`` in rows ``a``.. of a Block, as
    register_value reads it from each row's record (a servo's returns and the writes to it, and its
    record of each long packet), in row order."""
    cols, run = blk.cols, blk.run
    kind, sid = cols["kind"][a:], cols["id"][a:]
    dlen = cols["data_len"][a:].astype(np.int64)
    address = cols["address"][a:].astype(np.int64)
    starts = run.starts[blk.lo + a:blk.hi]
    t0 = None if run.t0 is None else run.t0[blk.lo + a:blk.hi]
    arr, blob = run.bytes_array, run.blob
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    own = (kind != LONG) & (dlen > 0)
    long_rows = np.flatnonzero((kind == LONG) & (cols["length"][a:] > 0) & (dlen > 0))
    long_reg = _register_of(blk.default, name) if long_rows.size else None
    if long_reg is not None:
        # Long packets whose records hold the register: most write other registers (goal positions
        # while present_position is plotted), and then none is read.
        ln = cols["length"][a:][long_rows].astype(np.int64)
        reach = long_reg.address - address[long_rows]
        covers = (reach >= 0) & (reach + long_reg.size <= ln - 1)
        if not covers.all():
            long_rows, ln = long_rows[covers], ln[covers]
        if not long_rows.size:
            long_reg = None
    for servo in ids:
        rows_parts, at_parts, regs = [], [], []
        rows = np.flatnonzero(own & (sid == servo))
        reg = _register_of(blk.models.get(servo), name) if rows.size else None
        if reg is not None:
            start = reg.address - address[rows]
            fits = (start >= 0) & (start + reg.size <= dlen[rows])
            rows_parts.append(rows[fits])
            at_parts.append(starts[rows[fits]] + 7 + start[fits])
            regs.append(reg)
        if long_reg is not None:
            dl = dlen[long_rows]
            nrec = -(-dl // ln)
            width = int(nrec.max())
            j = np.arange(width)
            vid_at = starts[long_rows][:, None] + 7 + j * ln[:, None]
            valid = j < nrec[:, None]
            hit = valid & (arr[np.minimum(vid_at, len(arr) - 1)] == servo)
            has = hit.any(axis=1)
            if has.any():
                first = hit.argmax(axis=1)[has]  # the first record for the servo, as register_value takes
                r = long_rows[has]
                lnr, dlr = ln[has], dl[has]
                data_len = np.minimum(lnr - 1, dlr - first * lnr - 1)
                start = long_reg.address - address[r]
                fits = (start >= 0) & (start + long_reg.size <= data_len)
                rows_parts.append(r[fits])
                at_parts.append(starts[r[fits]] + 7 + first[fits] * lnr[fits] + 1 + start[fits])
                regs.append(long_reg)
        if not rows_parts:
            continue
        got_rows, got_vals = [], []
        for rws, at, reg in zip(rows_parts, at_parts, regs):
            if rws.size:
                vals, ok = _values_at(arr, blob, at, reg)
                got_rows.append(rws[ok])
                got_vals.append(vals[ok])
        if not got_rows:
            continue
        rws = np.concatenate(got_rows)
        vals = np.concatenate(got_vals)
        if len(got_rows) > 1:
            order = np.argsort(rws, kind="stable")
            rws, vals = rws[order], vals[order]
        if not rws.size:
            continue
        times = t0[rws] if t0 is not None else (run.base + starts[rws]) * byte_seconds
        out[servo] = (times, vals)
    return out


@dataclass
class Stats:
    """Running counts since the last clear."""

    records: int = 0
    missing: int = 0       # requests whose reply never came
    kinds: Counter = field(default_factory=Counter)
    severities: Counter = field(default_factory=Counter)
    first_t: float | None = None
    last_t: float | None = None
    segment_t: float | None = None  # first time of the current time segment (rs30x_sniff.decode.framing.Seam)
    closed_span: float = 0.0        # seconds of the segments before it

    @property
    def packets(self) -> int:
        """Requests and returns (not ACK/NACK bytes or garbage)."""
        k = self.kinds
        return k["short"] + k["long"] + k["return"]

    @property
    def replies(self) -> int:
        """Returns, ACKs and NACKs."""
        k = self.kinds
        return k["return"] + k["ack"] + k["nack"]

    @property
    def garbage(self) -> int:
        return self.kinds["garbage"]


class Store:
    """The monitor's model. Records are numbered by ``seq`` (0 for the first one since the last clear);
    only the newest ``history`` are held, so a seq below :attr:`first_seq` has been dropped.

    The history is a list of segments in wire order: lists of Records, and Blocks (rs30x_sniff.decode.blocks:
    a file's clean stretches, kept as columns). A Block's row becomes a Record only when it is asked
    for (:meth:`get`, and the Block keeps it); counts, load, plot series and the memory figure come
    from its columns, and a filter scan makes its rows' Records for the moment and lets them go.
    """

    def __init__(self, history: int = DEFAULT_HISTORY, *, baud: int = 115200, plot_points: int = PLOT_POINTS) -> None:
        if history < 1:
            raise ValueError("history must hold at least one record")
        self.history = history
        self.baud = baud
        self.plot_points = plot_points
        self.plot_id: int | None = None
        self.plot_register = PLOT_REGISTERS[0]
        self.plot_all = False
        self.bytes_in = 0
        self.servos: dict[int, ServoRow] = {}
        self.clear()

    # ---- contents --------------------------------------------------------------------------------
    def clear(self) -> None:
        """Forget every record, finding and count (the source keeps running)."""
        self._segs: list[list[Record] | Block] = []  # the history: lists of Records and Blocks
        self._starts: list[int] = []  # the seq of each segment's first row (a Block's may be dropped)
        self._runs: dict[int, list] = {}  # id of a FrameRun -> [run, Blocks held of it, its bytes]
        self._built: dict[int, tuple] = {}  # id of a Block -> (it, what it keeps, bytes of that)
        self.first_seq = 0
        self.end_seq = 0
        self.stats = Stats()
        self.findings: deque = deque(maxlen=self.history)
        self.findings_total = 0
        self.findings_by_id: Counter = Counter()
        self.memory = 0  # bytes of the held Records, Blocks and runs (not of Records Blocks build later)
        self.bytes_base = self.bytes_in  # bytes counted from here on
        self.servos = {}
        self.capture_stats: dict[str, Any] = {}  # the feeder's CaptureStats.as_dict(): info's figures
        self.recent_load = RecentLoad(self.baud, LOAD_WINDOW)
        self.plot_series: dict[int, tuple[deque[float], deque[float]]] = {}  # servo -> (times, values)
        if self.plot_id is not None:
            self.set_plot(self.plot_id)
        self.filter: Filter | None = None
        self.view: array | None = None  # seqs that pass the filter; None when there is no filter
        self._scan_seq: int | None = None  # where a filter scan resumes; None when it is complete
        self.generation = getattr(self, "generation", -1) + 1  # bumps on clear, so views can tell

    def __len__(self) -> int:
        return self.end_seq - self.first_seq

    def _segment(self, seq: int) -> int:
        """The index of the segment holding ``seq`` (which must be held)."""
        return bisect_right(self._starts, seq) - 1

    def get(self, seq: int) -> Record | None:
        if not self.first_seq <= seq < self.end_seq:
            return None
        j = self._segment(seq)
        seg = self._segs[j]
        k = seq - self._starts[j]
        return seg[k] if type(seg) is list else seg.record(k)

    def add(self, records: Iterable[Record | Block], findings: Iterable = (), servos: dict[int, ServoRow] | None = None,
            bytes_in: int | None = None, capture_stats: dict[str, Any] | None = None) -> None:
        """Take a batch from the decoding thread: records (and Blocks) in wire order, new findings, servo rows."""
        stats = self.stats
        run: list[Record] = []
        loads: list = []  # (t, bytes) tuples of Records, and (t0, sizes) arrays of Blocks, in order
        blocks = False
        if type(records) is not list:
            records = list(records)
        points = self._newest_points(records) if self.plot_series else {}
        for x in records:
            if type(x) is Block:
                if run:
                    self._add_records(run, loads)
                    run = []
                self._add_block(x, loads, points.get(id(x), _NOT_READ))
                blocks = True
            else:
                run.append(x)
        if run:
            self._add_records(run, loads)
        stats.records = self.end_seq
        if blocks and loads:
            self.recent_load.extend_arrays(*_load_arrays(loads))
        elif loads:
            self.recent_load.extend(loads[0] if len(loads) == 1 else [x for part in loads for x in part])
        for f in findings:
            self.findings.append(f)
            self.findings_total += 1
            stats.severities[f.severity] += 1
            if f.id is not None:
                self.findings_by_id[f.id] += 1
        if servos is not None:
            self.servos = servos
        if capture_stats is not None:
            self.capture_stats = capture_stats
        if bytes_in is not None:
            self.bytes_in = bytes_in
        self._evict()

    def _add_records(self, records: list[Record], loads: list) -> None:
        segs, starts = self._segs, self._starts
        stats = self.stats
        kinds = stats.kinds
        flt = self.filter if self._scan_seq is None else None
        view = self.view
        seq = self.end_seq
        memory = 0
        timed: list[tuple[float, int]] = []
        load = timed.append
        series, plot_reg = self.plot_series, self.plot_register
        byte_seconds = 10 / self.baud  # a capture without times is plotted against line time
        # This loop runs on the screen's thread for every record: keep it lean.
        missing = 0
        first_t = stats.first_t
        last_t = None
        seg_t, closed, prev_t = stats.segment_t, stats.closed_span, stats.last_t
        for rec in records:
            ev = rec.event
            kinds[ev.kind] += 1
            memory += record_size(rec)
            if rec.status == "missing":
                missing += 1
            t = ev.t_start
            if t is not None:
                if first_t is None:
                    first_t = seg_t = t
                elif t < prev_t - SEAM_BACK_S or t - prev_t > SEAM_GAP_S:
                    closed += max(0.0, prev_t - seg_t)  # a seam of the clock: spans add up, never run back
                    seg_t = t
                last_t = prev_t = t
                load((t, len(ev.raw)))
            if series:
                if type(ev) is LongPacket:
                    for sid, (ts, vs) in series.items():
                        v = register_value(rec, sid, plot_reg)
                        if isinstance(v, (int, float)):
                            ts.append(ev.offset * byte_seconds if t is None else t)
                            vs.append(float(v))
                else:
                    sid = getattr(ev, "id", None)
                    if sid in series:
                        v = register_value(rec, sid, plot_reg)
                        if isinstance(v, (int, float)):
                            ts, vs = series[sid]
                            ts.append(ev.offset * byte_seconds if t is None else t)
                            vs.append(float(v))
            if flt is not None and flt.matches(rec):
                view.append(seq)
            seq += 1
        # Into the history: the last list filled up to CHUNK_RECORDS, then new lists.
        i = 0
        if segs and type(segs[-1]) is list and len(segs[-1]) < CHUNK_RECORDS:
            i = CHUNK_RECORDS - len(segs[-1])
            segs[-1] += records[:i]
        at = self.end_seq + i
        while i < len(records):
            segs.append(records[i:i + CHUNK_RECORDS])
            starts.append(at)
            at += len(segs[-1])
            i += CHUNK_RECORDS
        self.end_seq = seq
        stats.missing += missing
        stats.first_t = first_t
        stats.segment_t, stats.closed_span = seg_t, closed
        if last_t is not None:
            stats.last_t = last_t
        self.memory += memory
        if timed:
            loads.append(timed)

    def _newest_points(self, items: list) -> dict[int, Any]:
        """The plot points of a batch's last Blocks, newest first, as far back as the plot keeps
        (plot_points a servo): {id of a Block: its points, or None where none of them is kept}. A
        long load has far more points than the plot holds; Blocks before the newest run of Records
        are not looked at here (_add_block reads them)."""
        want = {sid: self.plot_points for sid in self.plot_series}
        byte_seconds = 10 / self.baud
        out: dict[int, Any] = {}
        for x in reversed(items):
            if type(x) is not Block:
                break
            if not want:
                out[id(x)] = None  # older than every point the plot keeps
                continue
            got = out[id(x)] = block_points(x, list(want), self.plot_register, byte_seconds)
            for sid, (_, vs) in got.items():
                want[sid] -= len(vs)
                if want[sid] <= 0:
                    del want[sid]
        return out

    def _add_block(self, blk: Block, loads: list, points: Any = _NOT_READ) -> None:
        """A Block into the history: a few array operations, whatever its length."""
        n = len(blk)
        if not n:
            return
        seq = self.end_seq
        stats = self.stats
        kinds = stats.kinds
        counts = np.bincount(blk.cols["kind"], minlength=3).tolist()
        for code, name in ((SHORT, "short"), (LONG, "long"), (RETURN, "return")):
            if counts[code]:
                kinds[name] += counts[code]
        t0 = blk.t0
        if t0 is not None:
            t = float(t0[0])
            if stats.first_t is None:
                stats.first_t = stats.segment_t = t
            elif t < stats.last_t - SEAM_BACK_S or t - stats.last_t > SEAM_GAP_S:  # a Block never spans a seam
                stats.closed_span += max(0.0, stats.last_t - stats.segment_t)
                stats.segment_t = t
            stats.last_t = float(t0[-1])
            run = blk.run
            loads.append((t0, run.ends[blk.lo:blk.hi] - run.starts[blk.lo:blk.hi]))
        if self.plot_series and points is not None:
            if points is _NOT_READ:
                points = block_points(blk, list(self.plot_series), self.plot_register, 10 / self.baud)
            for sid, (ts, vs) in points.items():
                pts = self.plot_series[sid]
                pts[0].extend(ts[-self.plot_points:].tolist())
                pts[1].extend(vs[-self.plot_points:].tolist())
        if self.filter is not None and self._scan_seq is None:
            matches = self.filter.matches
            view = self.view
            for k, rec in enumerate(blk.rows(0, n)):
                if matches(rec):
                    view.append(seq + k)
        self._segs.append(blk)
        self._starts.append(seq)
        self.end_seq = seq + n
        self.memory += _BLOCK_BASE + blk.answered.nbytes
        held = self._runs.get(id(blk.run))
        if held is None:
            size = run_nbytes(blk.run)
            self._runs[id(blk.run)] = [blk.run, 1, size]
            self.memory += size
        else:
            held[1] += 1

    def _drop(self, seg: list[Record] | Block) -> None:
        """The memory figure without a segment that leaves the history."""
        if type(seg) is list:
            self.memory -= sum(record_size(r) for r in seg)
            return
        self.memory -= _BLOCK_BASE + seg.answered.nbytes
        self._built.pop(id(seg), None)
        held = self._runs[id(seg.run)]
        held[1] -= 1
        if not held[1]:
            del self._runs[id(seg.run)]
            self.memory -= held[2]

    def _evict(self) -> None:
        excess = len(self) - self.history
        if excess <= 0:
            return
        first = self.first_seq + excess
        segs, starts = self._segs, self._starts
        drop = 0
        while drop < len(segs) and starts[drop] + len(segs[drop]) <= first:
            self._drop(segs[drop])
            drop += 1
        del segs[:drop], starts[:drop]
        if segs and starts[0] < first:
            seg, cut = segs[0], first - starts[0]
            if type(seg) is list:
                self.memory -= sum(record_size(r) for r in seg[:cut])
                del seg[:cut]
                starts[0] = first
            else:
                # The Block stays whole, its first rows hidden; Records built of those one by one go.
                seg.forget_before(cut)
        self.first_seq = first
        if self.view is not None:
            del self.view[:bisect_left(self.view, self.first_seq)]
        if self._scan_seq is not None:
            self._scan_seq = max(self._scan_seq, self.first_seq)

    def _rows(self, start: int, stop: int) -> Iterable[tuple[int, list[Record]]]:
        """(seq of the first, Records) of the held rows from ``start`` to ``stop``, segment by segment
        (a Block's made for the moment)."""
        if start >= stop:
            return
        segs, starts = self._segs, self._starts
        j = self._segment(start)
        while j < len(segs) and starts[j] < stop:
            seg, s0 = segs[j], starts[j]
            a, b = max(start, s0) - s0, min(stop, s0 + len(seg)) - s0
            yield s0 + a, seg[a:b] if type(seg) is list else seg.rows(a, b)
            j += 1

    # ---- figures for the header --------------------------------------------------------------------
    @property
    def bytes_seen(self) -> int:
        return self.bytes_in - self.bytes_base

    @property
    def span(self) -> float | None:
        """Capture time from the first to the last timed record, added up over the time segments, if
        the source has timestamps."""
        s = self.stats
        if s.first_t is None or s.last_t is None or s.segment_t is None:
            return None
        return s.closed_span + max(0.0, s.last_t - s.segment_t)

    @property
    def bus_load(self) -> float | None:
        """Fraction of the last second of capture time the wire was busy (8N1: 10 bits a byte)."""
        return self.recent_load.value

    @property
    def average_load(self) -> float | None:
        """Bus load since the start (or the last clear), as `info` computes it."""
        return self.capture_stats.get("bus_load")

    def memory_estimate(self) -> int:
        """Bytes the held history costs, roughly (records, events, byte strings, Blocks and their runs,
        the Records Blocks have built, the lists themselves)."""
        total = self.memory + sys.getsizeof(self._segs) + 2 * sys.getsizeof(self._starts)
        built = self._built
        for seg in self._segs:
            if type(seg) is list:
                total += sys.getsizeof(seg)
                continue
            made = seg.made_rows
            if made:
                key = (seg.linted_by_rows, len(made))
                hit = built.get(id(seg))
                if hit is None or hit[0] is not seg or hit[1] != key:  # what it holds changed: weigh it again
                    hit = built[id(seg)] = (seg, key, built_nbytes(seg))
                total += hit[2]
        return total + (self.view.itemsize * len(self.view) if self.view else 0)

    def poll_rate(self, row: ServoRow) -> float | None:
        """Reads per second to one servo since the start (or the last clear), as `info` computes it."""
        servo = self.capture_stats.get("servos", {}).get(str(row.id))
        return None if servo is None else servo["poll_rate_hz"]

    # ---- the filtered view -----------------------------------------------------------------------
    def set_filter(self, flt: Filter | None) -> None:
        """Apply a filter to the whole history at once (see :meth:`begin_filter` for the stepwise way)."""
        self.begin_filter(flt)
        while not self.filter_step(1 << 30):
            pass

    def begin_filter(self, flt: Filter | None) -> None:
        self.filter = flt
        if flt is None:
            self.view = None
            self._scan_seq = None
        else:
            self.view = array("q")
            self._scan_seq = self.first_seq

    def filter_step(self, budget: int = 20_000) -> bool:
        """Scan up to ``budget`` more records against the filter; True when the scan is complete."""
        if self._scan_seq is None:
            return True
        start = max(self._scan_seq, self.first_seq)
        stop = min(self.end_seq, start + budget)
        matches, view = self.filter.matches, self.view
        for seq, recs in self._rows(start, stop):
            for k, rec in enumerate(recs):
                if matches(rec):
                    view.append(seq + k)
        if stop >= self.end_seq:
            self._scan_seq = None
            return True
        self._scan_seq = stop
        return False

    @property
    def filter_progress(self) -> float | None:
        """How far a filter scan has got (0..1), or None when no scan is running."""
        if self._scan_seq is None:
            return None
        n = len(self)
        return (self._scan_seq - self.first_seq) / n if n else 1.0

    def view_len(self, before: int | None = None) -> int:
        """Rows in the view (those with seq < ``before`` if given)."""
        if self.view is None:
            end = self.end_seq if before is None else min(before, self.end_seq)
            return max(0, end - self.first_seq)
        if before is None:
            return len(self.view)
        return bisect_left(self.view, before)

    def view_seq(self, index: int) -> int | None:
        """The seq of the view's row ``index``."""
        if index < 0:
            return None
        if self.view is None:
            seq = self.first_seq + index
            return seq if seq < self.end_seq else None
        return self.view[index] if index < len(self.view) else None

    def view_index(self, seq: int) -> int | None:
        """The row of ``seq`` in the view, or None if it is filtered out or gone."""
        if seq < self.first_seq or seq >= self.end_seq:
            return None
        if self.view is None:
            return seq - self.first_seq
        i = bisect_left(self.view, seq)
        return i if i < len(self.view) and self.view[i] == seq else None

    def view_nearest(self, seq: int) -> int:
        """The view row at ``seq`` or the first one after it (clamped to the last row)."""
        n = self.view_len()
        if self.view is None:
            return max(0, min(seq - self.first_seq, n - 1))
        return max(0, min(bisect_left(self.view, seq), n - 1))

    # ---- lookups ---------------------------------------------------------------------------------
    def seq_of_offset(self, offset: int) -> int | None:
        """The record that starts at byte ``offset`` of the stream (records are in wire order)."""
        segs = self._segs
        j = bisect_right(range(len(segs)), offset, key=lambda j: _first_offset(segs[j])) - 1
        if j < 0:
            return None
        seg = segs[j]
        if type(seg) is list:
            i = bisect_left(seg, offset, key=lambda r: r.event.offset)
            found = i < len(seg) and seg[i].event.offset == offset
        else:
            offsets = seg.offsets
            i = int(np.searchsorted(offsets, offset))
            found = i < len(offsets) and int(offsets[i]) == offset
        seq = self._starts[j] + i
        return seq if found and seq >= self.first_seq else None

    def seq_of(self, rec: Record) -> int | None:
        seq = self.seq_of_offset(rec.event.offset)
        return seq if seq is not None and self.get(seq) is rec else None

    def finding_seq(self, after: int | None, forward: bool = True, min_severity: str = "info") -> int | None:
        """The next (or previous) record after seq ``after`` that has a finding, in the view."""
        rank = SEVERITY_RANK[min_severity]
        base, end = self.first_seq, self.end_seq
        if base == end:
            return None
        if after is None:
            after = base - 1 if forward else end
        segs, starts = self._segs, self._starts
        if forward:
            lo, hi = max(after + 1, base), end
            if lo >= hi:
                return None
            order = range(self._segment(lo), len(segs))
        else:
            lo, hi = base, min(after, end)
            if lo >= hi:
                return None
            order = range(self._segment(hi - 1), -1, -1)
        for j in order:
            seg, s0 = segs[j], starts[j]
            if s0 >= hi or s0 + len(seg) <= lo:
                break
            a, b = max(lo, s0) - s0, min(hi, s0 + len(seg)) - s0
            if type(seg) is list or seg.linted_by_rows:
                recs = seg if type(seg) is list else seg.records()
                ks = range(a, b) if forward else range(b - 1, a - 1, -1)
            elif seg.made_rows:
                # A Block the linter passed whole has no finding of its own; one of the Records it keeps may
                # have got one later.
                recs = seg.made_rows
                ks = sorted((k for k in recs if a <= k < b and recs[k].findings), reverse=not forward)
            else:
                continue
            for k in ks:
                rec = recs[k]
                if rec.findings and any(SEVERITY_RANK.get(f.severity, 0) >= rank for f in rec.findings):
                    seq = s0 + k
                    if self.view is None or self.view_index(seq) is not None:
                        return seq
        return None

    # ---- plot ------------------------------------------------------------------------------------
    @property
    def plot(self) -> deque[float]:
        """The plotted servo's values, oldest first."""
        pair = self.plot_series.get(self.plot_id) if self.plot_id is not None else None
        return pair[1] if pair is not None else deque()

    def set_plot(self, servo_id: int | None, register: str | None = None, *, all_servos: bool | None = None) -> None:
        """Plot another servo or register (``all_servos``: every servo's series beside the selected one):
        refill the series from the held history."""
        if register is not None:
            self.plot_register = register
        if all_servos is not None:
            self.plot_all = all_servos
        self.plot_id = servo_id
        self.plot_series = {}
        if servo_id is None:
            return
        ids = [servo_id] + ([i for i in sorted(self.servos) if i != servo_id] if self.plot_all else [])
        found: dict[int, tuple[list[float], list[float]]] = {i: ([], []) for i in ids}  # newest first
        full: set[int] = set()
        byte_seconds = 10 / self.baud
        points = self.plot_points
        for j in range(len(self._segs) - 1, -1, -1):
            seg = self._segs[j]
            if type(seg) is not list:
                hidden = max(0, self.first_seq - self._starts[j])
                wanted = [i for i in ids if i not in full]
                for sid, (ts, vs) in block_points(seg, wanted, self.plot_register, byte_seconds, hidden).items():
                    fts, fvs = found[sid]
                    need = points - len(fvs)
                    fts += ts[::-1][:need].tolist()
                    fvs += vs[::-1][:need].tolist()
                    if len(fvs) >= points:
                        full.add(sid)
                if len(full) == len(ids):
                    break
                continue
            for rec in reversed(seg):
                ev = rec.event
                for sid in ids if type(ev) is LongPacket else ((ev.id,) if getattr(ev, "id", None) in found else ()):
                    if sid in full:
                        continue
                    v = register_value(rec, sid, self.plot_register)
                    if isinstance(v, (int, float)):
                        ts, vs = found[sid]
                        ts.append(ev.offset * byte_seconds if ev.t_start is None else ev.t_start)
                        vs.append(float(v))
                        if len(vs) >= points:
                            full.add(sid)
                if len(full) == len(ids):
                    break
            if len(full) == len(ids):
                break
        for sid, (ts, vs) in found.items():
            self.plot_series[sid] = (deque(reversed(ts), maxlen=points), deque(reversed(vs), maxlen=points))


def _first_offset(seg: list[Record] | Block) -> int:
    if type(seg) is list:
        return seg[0].event.offset
    return seg.run.base + int(seg.run.starts[seg.lo])


def _load_arrays(loads: list) -> tuple[np.ndarray, np.ndarray]:
    """The (t, bytes) of a batch's Records and Blocks, in order, as two arrays."""
    ts, ns = [], []
    for part in loads:
        if type(part) is list:
            ts.append(np.array([t for t, _ in part], dtype=float))
            ns.append(np.array([n for _, n in part], dtype=np.int64))
        else:
            ts.append(part[0])
            ns.append(part[1])
    if len(ts) == 1:
        return ts[0], ns[0]
    return np.concatenate(ts), np.concatenate(ns)
