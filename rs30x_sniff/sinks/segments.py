"""Time segments of a capture (its clock split at seams) and the seconds they add up to."""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # names for the checker; no import at run time
    from ..decode.framing import Seam

NO_SEAM = 1 << 62  # a stream offset no capture reaches


class TimeSegments:
    """Where the capture's clock restarts or resumes (rs30x_sniff.decode.framing.Seam, handed over on the
    steps) and the times of the segment it splits: the capture's first time, the current segment's
    first and last, and the span of the segments before it."""

    def __init__(self) -> None:
        self.timed = False
        self.first_t: float | None = None    # the capture's first time
        self.segment_t: float | None = None  # the current time segment's first
        self.last_t: float | None = None     # the current time segment's last
        self.closed_span = 0.0  # seconds of the time segments before it
        self.seams: list[Seam] = []   # every seam passed so far
        self.next_seam = NO_SEAM  # stream offset where the next seam takes effect
        self._pending: list[Seam] = []

    def expect(self, seams: Iterable[Seam]) -> None:
        """Seams a step announces: each takes effect at the first record at or after its offset."""
        self._pending += seams
        self.next_seam = self._pending[0].offset

    # ---- the record form -------------------------------------------------------------------------
    def add(self, ts: float, end: float | None) -> None:
        """A record on the wire from ``ts`` to ``end`` (None: ``ts``)."""
        if end is None:
            end = ts
        last = self.last_t
        if last is None:  # its first record (a segment's first and last times are set together)
            self._start(ts, end)
        elif end > last:
            self.last_t = end

    def _start(self, ts: float, end: float) -> None:
        """A time segment's first record, on the wire from ``ts`` to ``end``."""
        self.timed = True
        if self.first_t is None:
            self.first_t = ts
        self.segment_t, self.last_t = ts, end

    # ---- the column form -------------------------------------------------------------------------
    def add_rows(self, t0: np.ndarray, t1: np.ndarray) -> None:
        """Rows on the wire from ``t0`` to ``t1``, in wire order: :meth:`add` of each."""
        self.timed = True
        if self.first_t is None:
            self.first_t = float(t0[0])
        if self.segment_t is None:
            self.segment_t = float(t0[0])
        last = float(t1.max())
        if self.last_t is None or last > self.last_t:
            self.last_t = last

    # ---- seams -----------------------------------------------------------------------------------
    def end_segment(self, offset: int) -> float | None:
        """Pass the seam(s) at or before stream ``offset`` and close the time segment before them: its
        span is added up and the clock starts afresh. The closed segment's last time, None if no timed
        segment was open (a segment's first and last times are set together)."""
        pending = self._pending
        while pending and pending[0].offset <= offset:
            self.seams.append(pending.pop(0))
        self.next_seam = pending[0].offset if pending else NO_SEAM
        if self.segment_t is None:
            return None
        last = self.last_t
        if last is not None:
            self.closed_span += max(0.0, last - self.segment_t)
        self.segment_t = self.last_t = None
        return last

    def span(self) -> float | None:
        """Seconds from the first to the last time, added up over the segments (None when untimed)."""
        if not (self.timed and self.first_t is not None):
            return None
        current = 0.0
        if self.segment_t is not None and self.last_t is not None:
            current = max(0.0, self.last_t - self.segment_t)
        return self.closed_span + current

    def count(self) -> int:
        """How many time segments (one for an untimed capture)."""
        return len(self.seams) + 1 if self.timed else 1
