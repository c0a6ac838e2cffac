"""What the monitor shows, without Textual: a bounded record history, counts, servo rows, findings, filter, plot."""

from __future__ import annotations

import sys
from array import array
from bisect import bisect_left
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any, Iterable

from ..bus import BusTracker, Record
from ..events import LongPacket, ReturnPacket, ShortPacket
from ..stats import RecentLoad
from .filter import SEVERITY_RANK, Filter

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


@dataclass
class Stats:
    """Running counts since the last clear."""

    records: int = 0
    missing: int = 0       # requests whose reply never came
    kinds: Counter = field(default_factory=Counter)
    severities: Counter = field(default_factory=Counter)
    first_t: float | None = None
    last_t: float | None = None

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
    only the newest ``history`` are held, so a seq below :attr:`first_seq` has been dropped."""

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
        self.rows: list[Record] = []
        self.first_seq = 0
        self.stats = Stats()
        self.findings: deque = deque(maxlen=self.history)
        self.findings_total = 0
        self.findings_by_id: Counter = Counter()
        self.memory = 0
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

    @property
    def end_seq(self) -> int:
        return self.first_seq + len(self.rows)

    def __len__(self) -> int:
        return len(self.rows)

    def get(self, seq: int) -> Record | None:
        i = seq - self.first_seq
        if 0 <= i < len(self.rows):
            return self.rows[i]
        return None

    def add(self, records: Iterable[Record], findings: Iterable = (), servos: dict[int, ServoRow] | None = None,
            bytes_in: int | None = None, capture_stats: dict[str, Any] | None = None) -> None:
        """Take a batch from the decoding thread: records in wire order, new findings, servo rows."""
        rows = self.rows
        stats = self.stats
        kinds = stats.kinds
        flt = self.filter if self._scan_seq is None else None
        view = self.view
        seq = self.end_seq
        memory = 0
        loads: list[tuple[float, int]] = []
        load = loads.append
        series, plot_reg = self.plot_series, self.plot_register
        byte_seconds = 10 / self.baud  # a capture without times is plotted against line time
        # This loop runs on the screen's thread for every record: keep it lean.
        missing = 0
        first_t = stats.first_t
        last_t = None
        for rec in records:
            rows.append(rec)
            ev = rec.event
            kinds[ev.kind] += 1
            memory += record_size(rec)
            if rec.status == "missing":
                missing += 1
            t = ev.t_start
            if t is not None:
                if first_t is None:
                    first_t = t
                last_t = t
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
        stats.missing += missing
        stats.first_t = first_t
        if last_t is not None:
            stats.last_t = last_t
        stats.records = seq
        self.memory += memory
        self.recent_load.extend(loads)
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

    def _evict(self) -> None:
        excess = len(self.rows) - self.history
        if excess <= 0:
            return
        dropped = self.rows[:excess]
        self.memory -= sum(record_size(r) for r in dropped)
        del self.rows[:excess]
        self.first_seq += excess
        if self.view is not None:
            del self.view[:bisect_left(self.view, self.first_seq)]
        if self._scan_seq is not None:
            self._scan_seq = max(self._scan_seq, self.first_seq)

    # ---- figures for the header --------------------------------------------------------------------
    @property
    def bytes_seen(self) -> int:
        return self.bytes_in - self.bytes_base

    @property
    def span(self) -> float | None:
        """Capture time from the first to the last timed record, if the source has timestamps."""
        s = self.stats
        if s.first_t is None or s.last_t is None:
            return None
        return s.last_t - s.first_t

    @property
    def bus_load(self) -> float | None:
        """Fraction of the last second of capture time the wire was busy (8N1: 10 bits a byte)."""
        return self.recent_load.value

    @property
    def average_load(self) -> float | None:
        """Bus load since the start (or the last clear), as `info` computes it."""
        return self.capture_stats.get("bus_load")

    def memory_estimate(self) -> int:
        """Bytes the held history costs, roughly (records, events, byte strings, the list itself)."""
        return self.memory + sys.getsizeof(self.rows) + (self.view.itemsize * len(self.view) if self.view else 0)

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
        flt, view, rows, base = self.filter, self.view, self.rows, self.first_seq
        for seq in range(start, stop):
            if flt.matches(rows[seq - base]):
                view.append(seq)
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
        n = len(self.rows)
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
        i = bisect_left(self.rows, offset, key=lambda r: r.event.offset)
        if i < len(self.rows) and self.rows[i].event.offset == offset:
            return self.first_seq + i
        return None

    def seq_of(self, rec: Record) -> int | None:
        seq = self.seq_of_offset(rec.event.offset)
        return seq if seq is not None and self.get(seq) is rec else None

    def finding_seq(self, after: int | None, forward: bool = True, min_severity: str = "info") -> int | None:
        """The next (or previous) record after seq ``after`` that has a finding, in the view."""
        rank = SEVERITY_RANK[min_severity]
        rows, base = self.rows, self.first_seq
        if not rows:
            return None
        if after is None:
            after = base - 1 if forward else self.end_seq
        if forward:
            rng = range(max(after + 1, base), self.end_seq)
        else:
            rng = range(min(after, self.end_seq) - 1, base - 1, -1)
        for seq in rng:
            rec = rows[seq - base]
            if rec.findings and any(SEVERITY_RANK.get(f.severity, 0) >= rank for f in rec.findings):
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
        found: dict[int, tuple[list[float], list[float]]] = {i: ([], []) for i in ids}
        full: set[int] = set()
        byte_seconds = 10 / self.baud
        for rec in reversed(self.rows):
            ev = rec.event
            for sid in ids if type(ev) is LongPacket else ((ev.id,) if getattr(ev, "id", None) in found else ()):
                if sid in full:
                    continue
                v = register_value(rec, sid, self.plot_register)
                if isinstance(v, (int, float)):
                    ts, vs = found[sid]
                    ts.append(ev.offset * byte_seconds if ev.t_start is None else ev.t_start)
                    vs.append(float(v))
                    if len(vs) >= self.plot_points:
                        full.add(sid)
            if len(full) == len(ids):
                break
        for sid, (ts, vs) in found.items():
            self.plot_series[sid] = (deque(reversed(ts), maxlen=self.plot_points),
                                     deque(reversed(vs), maxlen=self.plot_points))
