"""What the monitor shows, without Textual: its history, figures, servo rows, findings, filtered view and plot."""

from __future__ import annotations

from array import array
from collections import Counter, deque
from typing import Any
from collections.abc import Iterable

from ..decode.blocks import Block
from ..decode.pairing import Record
from ..filters import Filter
from ..sinks.stats import RecentLoad
from .figures import LOAD_WINDOW, Stats, load_arrays
from .history import History, Segment
from .memory import HeldBytes
from .plot_series import NOT_READ, PLOT_POINTS, PlottedSeries
from .servos import ServoRow
from .view import FilteredView

DEFAULT_HISTORY = 1_000_000


class Store:
    """The monitor's model. Records are numbered by ``seq`` (0 for the first one since the last clear);
    only the newest ``history`` are held, so a seq below :attr:`first_seq` has been dropped.

    It puts together: :attr:`held` (the rows, rs30x_sniff.tui.history: lists of Records and Blocks, a
    Block's row made a Record only when asked for), :attr:`stats` and the bus load (tui.figures, from a
    Block's columns too), :attr:`held_bytes` (what the rows weigh, tui.memory), :attr:`shown` (the filtered
    view, tui.view) and :attr:`plotted` (the plot's series, tui.plot_series).
    """

    def __init__(self, history: int = DEFAULT_HISTORY, *, baud: int = 115200, plot_points: int = PLOT_POINTS) -> None:
        if history < 1:
            raise ValueError("history must hold at least one record")
        self.history = history
        self.baud = baud
        self.plotted = PlottedSeries(baud, plot_points)
        self.bytes_in = 0
        self.servos: dict[int, ServoRow] = {}
        self.clear()

    # ---- contents --------------------------------------------------------------------------------
    def clear(self) -> None:
        """Forget every record, finding and count (the source keeps running)."""
        self.held = History()
        self.held_bytes = HeldBytes()  # what the held Records, Blocks and runs weigh, and what Blocks build
        self.stats = Stats()
        self.findings: deque = deque(maxlen=self.history)
        self.findings_total = 0
        self.findings_by_id: Counter = Counter()
        self.bytes_base = self.bytes_in  # bytes counted from here on
        self.servos = {}
        self.capture_stats: dict[str, Any] = {}  # the feeder's screen_figures: info's figures the screen shows
        self.recent_load = RecentLoad(self.baud, LOAD_WINDOW)
        self.plotted.refill(self.held, self.servos)
        self.shown = FilteredView(self.held)
        self.generation = getattr(self, "generation", -1) + 1  # bumps on clear, so views can tell

    def __len__(self) -> int:
        return len(self.held)

    @property
    def first_seq(self) -> int:
        return self.held.first_seq

    @property
    def end_seq(self) -> int:
        return self.held.end_seq

    @property
    def memory(self) -> int:
        """Bytes of the held Records, Blocks and runs (not of Records Blocks build later)."""
        return self.held_bytes.total

    def get(self, seq: int) -> Record | None:
        return self.held.get(seq)

    def add(self, records: Iterable[Record | Block], findings: Iterable = (), servos: dict[int, ServoRow] | None = None,
            bytes_in: int | None = None, capture_stats: dict[str, Any] | None = None) -> None:
        """Take a batch from the decoding thread: records (and Blocks) in wire order, new findings, servo rows."""
        stats = self.stats
        run: list[Record] = []
        loads: list = []  # (t, bytes) tuples of Records, and (t0, sizes) arrays of Blocks, in order
        blocks = False
        if type(records) is not list:
            records = list(records)
        points = self.plotted.newest_points(records) if self.plotted.series else {}
        for x in records:
            if type(x) is Block:
                if run:
                    self._add_records(run, loads)
                    run = []
                self._add_block(x, loads, points.get(x, NOT_READ))
                blocks = True
            else:
                run.append(x)
        if run:
            self._add_records(run, loads)
        stats.records = self.end_seq
        if blocks and loads:
            self.recent_load.extend_arrays(*load_arrays(loads))
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
        self.stats.count_records(records, loads)
        self.held_bytes.add_records(records)
        if self.plotted.series:
            self.plotted.add_records(records)
        if self.shown.matching_new_rows:
            self.shown.add(self.end_seq, records)
        self.held.append_records(records)

    def _add_block(self, blk: Block, loads: list, points: Any = NOT_READ) -> None:
        """A Block into the history: a few array operations, whatever its length."""
        if not len(blk):
            return
        self.stats.count_block(blk, loads)
        if self.plotted.series:
            self.plotted.add_block(blk, points)
        if self.shown.matching_new_rows:
            self.shown.add(self.end_seq, blk.rows(0, len(blk)))
        self.held.append_block(blk)
        self.held_bytes.add_block(blk)

    def _drop(self, seg: Segment) -> None:
        """The memory figure without rows that leave the history (a segment, or Records cut from one)."""
        if isinstance(seg, list):  # Records cut from a segment (a Block is no list)
            self.held_bytes.drop_records(seg)
        else:
            self.held_bytes.drop_block(seg)

    def _evict(self) -> None:
        excess = len(self) - self.history
        if excess <= 0:
            return
        self.held.trim(self.first_seq + excess, self._drop)
        self.shown.trim()

    # ---- figures for the header --------------------------------------------------------------------
    @property
    def bytes_seen(self) -> int:
        return self.bytes_in - self.bytes_base

    @property
    def span(self) -> float | None:
        """Capture time from the first to the last timed record, added up over the time segments, if
        the source has timestamps."""
        return self.stats.span

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
        return (self.held_bytes.total + self.held.list_nbytes() + self.held_bytes.built(self.held.blocks())
                + self.shown.nbytes)

    def poll_rate(self, row: ServoRow) -> float | None:
        """Reads per second to one servo since the start (or the last clear), as `info` computes it."""
        servo = self.capture_stats.get("servos", {}).get(str(row.id))
        return None if servo is None else servo["poll_rate_hz"]

    # ---- the filtered view (tui.view) ----------------------------------------------------------------
    @property
    def filter(self) -> Filter | None:
        return self.shown.filter

    @property
    def view(self) -> array | None:
        """The seqs that pass the filter (an array), or None when there is no filter."""
        return self.shown.seqs

    def set_filter(self, flt: Filter | None) -> None:
        """Apply a filter to the whole history at once (see :meth:`begin_filter` for the stepwise way)."""
        self.begin_filter(flt)
        while not self.filter_step(1 << 30):
            pass

    def begin_filter(self, flt: Filter | None) -> None:
        self.shown.begin(flt)

    def filter_step(self, budget: int = 20_000) -> bool:
        """Scan up to ``budget`` more records against the filter; True when the scan is complete."""
        return self.shown.step(budget)

    @property
    def filter_progress(self) -> float | None:
        """How far a filter scan has got (0..1), or None when no scan is running."""
        return self.shown.progress

    def view_len(self, before: int | None = None) -> int:
        """Rows in the view (those with seq < ``before`` if given)."""
        return self.shown.count(before)

    def view_seq(self, index: int) -> int | None:
        """The seq of the view's row ``index``."""
        return self.shown.seq(index)

    def view_index(self, seq: int) -> int | None:
        """The row of ``seq`` in the view, or None if it is filtered out or gone."""
        return self.shown.index(seq)

    def view_nearest(self, seq: int) -> int:
        """The view row at ``seq`` or the first one after it (clamped to the last row)."""
        return self.shown.nearest(seq)

    # ---- lookups ---------------------------------------------------------------------------------
    def seq_of_offset(self, offset: int) -> int | None:
        """The record that starts at byte ``offset`` of the stream (records are in wire order)."""
        return self.held.seq_of_offset(offset)

    def seq_of(self, rec: Record) -> int | None:
        seq = self.seq_of_offset(rec.event.offset)
        return seq if seq is not None and self.get(seq) is rec else None

    def finding_seq(self, after: int | None, forward: bool = True, min_severity: str = "info") -> int | None:
        """The next (or previous) record after seq ``after`` that has a finding, in the view."""
        return self.held.finding_seq(after, forward, min_severity, self.shown.shows)

    # ---- plot (tui.plot_series) ----------------------------------------------------------------------
    @property
    def plot(self) -> deque[float]:
        """The plotted servo's values, oldest first."""
        return self.plotted.values

    @property
    def plot_series(self) -> dict[int, tuple[deque[float], deque[float]]]:
        """servo -> (times, values) of the plotted register."""
        return self.plotted.series

    @property
    def plot_id(self) -> int | None:
        return self.plotted.servo_id

    @property
    def plot_register(self) -> str:
        return self.plotted.register

    @property
    def plot_all(self) -> bool:
        return self.plotted.all_servos

    @property
    def plot_points(self) -> int:
        return self.plotted.points

    @plot_points.setter
    def plot_points(self, points: int) -> None:
        self.plotted.points = points

    def set_plot(self, servo_id: int | None, register: str | None = None, *, all_servos: bool | None = None) -> None:
        """Plot another servo or register (``all_servos``: every servo's series beside the selected one):
        refill the series from the held history."""
        plotted = self.plotted
        if register is not None:
            plotted.register = register
        if all_servos is not None:
            plotted.all_servos = all_servos
        plotted.servo_id = servo_id
        plotted.refill(self.held, self.servos)
