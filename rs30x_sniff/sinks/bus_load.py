"""Bus load: the one-second windows of a capture whose busiest is its peak, and the live display's recent load."""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable

import numpy as np

from ..decode.framing import SEAM_BACK_S
from ..protocol.wire import byte_time

# The peak bus load is the busiest of these windows from the capture start: long enough to hold many
# poll cycles, short enough that a burst is not averaged away over a long capture.
LOAD_WINDOW = 1.0
# A live reader's stall (sources/serial_tap.py) is found as its bytes arrive, and reaches back over them: at
# most one read, 1 MiB (the reader's DRAIN_MAX), which at 9600 baud is 1092 s. So the last HELD_WINDOWS closed
# windows are kept as they are, for a stall found later to take out of the peak; older ones are folded into the
# busiest so far, and memory stays the same however long the capture (about 130 kB).
HELD_WINDOWS = 1200


def stalled(start: float, stalls: list[tuple[float, float, int]]) -> bool:
    """Whether the load window from ``start`` holds bytes a live reader timed at the line rate (``stalls``:
    (t, seconds, bytes) where it fell behind, rs30x_sniff.sources.serial_tap)."""
    end = start + LOAD_WINDOW
    return any(t < end and t + seconds > start for t, seconds, _ in stalls)


class LoadWindows:
    """The bus load of each LOAD_WINDOW of a time segment, from its first byte: the window still open
    (``start``, ``end``, the ``bytes`` begun in it) and every closed one."""

    def __init__(self, baud: int) -> None:
        self.byte_s = byte_time(baud)
        self.start: float | None = None  # the open window
        self.end = float("-inf")
        self.bytes = 0
        # (load, start) of the last HELD_WINDOWS closed windows, in the order closed; the busiest of those before
        # them (the first of equals), none of them over a stall known when they were folded.
        self.closed: deque[tuple[float, float]] = deque()
        self.folded: tuple[float, float] | None = None
        # Where a live reader fell behind, (t, seconds, bytes): no load is measured over it (CaptureStats.stalls).
        self.stalls: list[tuple[float, float, int]] = []

    # ---- the record form -------------------------------------------------------------------------
    def add(self, ts: float, nbytes: int) -> None:
        """A record of ``nbytes`` starting at ``ts``."""
        if ts >= self.end:
            self.roll(ts)
        self.bytes += nbytes

    # ---- the column form -------------------------------------------------------------------------
    def add_rows(self, t0: np.ndarray, sizes: np.ndarray) -> None:
        """Rows starting at ``t0`` of ``sizes`` bytes: :meth:`add` of each, in order."""
        n = len(t0)
        if n > 1 and not (t0[1:] >= t0[:-1]).all():
            for ts, size in zip(t0.tolist(), sizes.tolist()):  # a clock that steps back: row by row
                if ts >= self.end:
                    self.roll(ts)
                self.bytes += size
            return
        if float(t0[-1]) < self.end:  # the usual: the whole Block within the current window
            self.bytes += int(sizes.sum())
            return
        cum = np.concatenate(([0], np.cumsum(sizes))).tolist()
        pos = 0
        while pos < n:
            ts = float(t0[pos])
            if ts >= self.end:
                self.roll(ts)
            stop = pos + 1 + int(np.searchsorted(t0[pos + 1:], self.end, "left"))
            self.bytes += cum[stop] - cum[pos]
            pos = stop

    # ---- windows ---------------------------------------------------------------------------------
    def roll(self, ts: float) -> None:
        """Close the window(s) before ``ts`` and open the one holding it."""
        if self.start is None:
            self.start = ts
        else:
            self._close((min(1.0, self.bytes * self.byte_s / LOAD_WINDOW), self.start))
            self.start += (ts - self.start) // LOAD_WINDOW * LOAD_WINDOW
        self.end = self.start + LOAD_WINDOW
        self.bytes = 0

    def end_segment(self, last: float) -> None:
        """A seam of the capture's clock: the segment's last window closes at its last byte ``last``, and
        the next segment starts its own windows."""
        load, start = self.open_load(last), self.start
        if load is not None and start is not None:  # (a load is measured only in an open window)
            self._close((load, start))
        self.start, self.end, self.bytes = None, float("-inf"), 0

    def _close(self, window: tuple[float, float]) -> None:
        closed = self.closed
        closed.append(window)
        if len(closed) > HELD_WINDOWS:
            old = closed.popleft()
            if (self.folded is None or old[0] > self.folded[0]) and not (self.stalls and stalled(old[1], self.stalls)):
                self.folded = old

    def open_load(self, last: float | None) -> float | None:
        """The load of the window still open, up to ``last``: counted over its own span once that is half
        a window (shorter, one packet would look like a full bus); None before that."""
        if self.start is None:
            return None
        span = (last or self.start) - self.start
        if span < LOAD_WINDOW / 2:
            return None
        return min(1.0, self.bytes * self.byte_s / min(span, LOAD_WINDOW))

    def busiest(self, last: float | None,
                stalls: list[tuple[float, float, int]] | None = None) -> tuple[float, float] | None:
        """(load, start) of the first of the busiest windows, the open one counted up to ``last``; none
        measured over a reader's stall (``stalls``: :attr:`stalls` unless given)."""
        stalls = self.stalls if stalls is None else stalls
        best = self.folded
        for w in self.closed:
            if (best is None or w[0] > best[0]) and not (stalls and stalled(w[1], stalls)):
                best = w
        load, start = self.open_load(last), self.start
        if load is not None and start is not None and not stalled(start, stalls) and (best is None or load > best[0]):
            best = (load, start)
        return best


class RecentLoad:
    """Bus load over the last ``window`` seconds of capture time: what a live display shows.

    Fed ``(t, nbytes)`` per record or chunk start; the newest item's own bytes end after its start
    time, so the busy time counts the items before it, over the window up to its start.
    """

    def __init__(self, baud: int, window: float = 1.0) -> None:
        self.bits = byte_time(baud)
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
