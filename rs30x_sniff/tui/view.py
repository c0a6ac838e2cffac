"""The filtered view: the seqs of the held rows a filter lets through, scanned a budget at a time."""

from __future__ import annotations

from array import array
from bisect import bisect_left
from collections.abc import Iterable

from ..decode.pairing import Record
from ..filters import Filter
from .history import History


class FilteredView:
    """Which rows of ``history`` the screen lists. Without a filter every held row; with one, the
    seqs in :attr:`seqs` (ascending): new rows are matched as they come, the held ones by a scan
    that resumes at :attr:`scan_seq` (:meth:`step`) so a long history never stalls the screen."""

    def __init__(self, history: History) -> None:
        self.history = history
        self.filter: Filter | None = None
        self.seqs: array | None = None  # seqs that pass the filter; None when there is no filter
        self.scan_seq: int | None = None  # where a filter scan resumes; None when it is complete

    def begin(self, flt: Filter | None) -> None:
        """Show what ``flt`` lets through (None: every row), the held rows once :meth:`step` has read them."""
        self.filter = flt
        if flt is None:
            self.seqs = None
            self.scan_seq = None
        else:
            self.seqs = array("q")
            self.scan_seq = self.history.first_seq

    def step(self, budget: int) -> bool:
        """Scan up to ``budget`` more rows against the filter; True when the scan is complete."""
        if self.scan_seq is None:
            return True
        history = self.history
        start = max(self.scan_seq, history.first_seq)
        stop = min(history.end_seq, start + budget)
        flt, seqs = self.filter, self.seqs
        assert flt is not None and seqs is not None, "a scan runs only under a filter (begin)"
        matches = flt.matches
        for seq, recs in history.rows(start, stop):
            for k, rec in enumerate(recs):
                if matches(rec):
                    seqs.append(seq + k)
        if stop >= history.end_seq:
            self.scan_seq = None
            return True
        self.scan_seq = stop
        return False

    @property
    def matching_new_rows(self) -> bool:
        """Whether rows being added are matched as they come (a filter is set and its scan is done)."""
        return self.filter is not None and self.scan_seq is None

    def add(self, seq: int, records: Iterable[Record]) -> None:
        """New rows from ``seq`` on (the scan, when running, reaches them later)."""
        flt, seqs = self.filter, self.seqs
        assert flt is not None and seqs is not None, "called only when matching_new_rows (a filter is set)"
        matches = flt.matches
        for k, rec in enumerate(records):
            if matches(rec):
                seqs.append(seq + k)

    def trim(self) -> None:
        """Forget the seqs the history no longer holds."""
        first = self.history.first_seq
        if self.seqs is not None:
            del self.seqs[:bisect_left(self.seqs, first)]
        if self.scan_seq is not None:
            self.scan_seq = max(self.scan_seq, first)

    @property
    def progress(self) -> float | None:
        """How far a filter scan has got (0..1), or None when no scan is running."""
        if self.scan_seq is None:
            return None
        n = len(self.history)
        return (self.scan_seq - self.history.first_seq) / n if n else 1.0

    @property
    def nbytes(self) -> int:
        return self.seqs.itemsize * len(self.seqs) if self.seqs else 0

    def count(self, before: int | None = None) -> int:
        """Rows in the view (those with seq < ``before`` if given)."""
        if self.seqs is None:
            history = self.history
            end = history.end_seq if before is None else min(before, history.end_seq)
            return max(0, end - history.first_seq)
        if before is None:
            return len(self.seqs)
        return bisect_left(self.seqs, before)

    def seq(self, index: int) -> int | None:
        """The seq of the view's row ``index``."""
        if index < 0:
            return None
        if self.seqs is None:
            seq = self.history.first_seq + index
            return seq if seq < self.history.end_seq else None
        return self.seqs[index] if index < len(self.seqs) else None

    def index(self, seq: int) -> int | None:
        """The row of ``seq`` in the view, or None if it is filtered out or gone."""
        history = self.history
        if seq < history.first_seq or seq >= history.end_seq:
            return None
        if self.seqs is None:
            return seq - history.first_seq
        i = bisect_left(self.seqs, seq)
        return i if i < len(self.seqs) and self.seqs[i] == seq else None

    def shows(self, seq: int) -> bool:
        """Whether held row ``seq`` is in the view."""
        return self.seqs is None or self.index(seq) is not None

    def nearest(self, seq: int) -> int:
        """The view row at ``seq`` or the first one after it (clamped to the last row)."""
        n = self.count()
        if self.seqs is None:
            return max(0, min(seq - self.history.first_seq, n - 1))
        return max(0, min(bisect_left(self.seqs, seq), n - 1))
