"""The monitor's held rows in wire order, numbered by seq: lists of Records and Blocks, trimmed from the front."""

from __future__ import annotations

import sys
from bisect import bisect_left, bisect_right
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence

import numpy as np

from ..decode.blocks import Block
from ..decode.pairing import Record
from ..filters import SEVERITY_RANK

CHUNK_RECORDS = 1 << 16  # Records held per list of the history (trimming cuts the first list only)

Segment = list[Record] | Block  # (told apart by type(seg) is Block: Block is final)


class History:
    """Rows numbered by ``seq`` from :attr:`first_seq` (the oldest held) to :attr:`end_seq` (one past
    the newest), as segments in wire order: lists of Records, and Blocks (rs30x_sniff.decode.blocks: a
    file's clean stretches, kept as columns). A Block's row becomes a Record only when it is asked for
    (:meth:`get`, and the Block keeps it); :meth:`rows` makes its Records for the moment."""

    def __init__(self) -> None:
        self.segments: list[Segment] = []
        self.starts: list[int] = []  # the seq of each segment's first row (a Block's may be trimmed)
        self.first_seq = 0
        self.end_seq = 0

    def __len__(self) -> int:
        return self.end_seq - self.first_seq

    def segment_index(self, seq: int) -> int:
        """The index of the segment holding ``seq`` (which must be held)."""
        return bisect_right(self.starts, seq) - 1

    def get(self, seq: int) -> Record | None:
        if not self.first_seq <= seq < self.end_seq:
            return None
        j = self.segment_index(seq)
        seg = self.segments[j]
        k = seq - self.starts[j]
        return seg[k] if type(seg) is not Block else seg.record(k)

    def blocks(self) -> Iterator[Block]:
        return (seg for seg in self.segments if type(seg) is Block)

    def newest_first(self) -> Iterator[tuple[Segment, int]]:
        """(segment, seq of its first row) from the newest segment back."""
        segs, starts = self.segments, self.starts
        for j in range(len(segs) - 1, -1, -1):
            yield segs[j], starts[j]

    # ---- growing and trimming --------------------------------------------------------------------
    def append_records(self, records: list[Record]) -> None:
        """Records after the newest row: the last list filled up to CHUNK_RECORDS, then new lists."""
        segs, starts = self.segments, self.starts
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
        self.end_seq += len(records)

    def append_block(self, blk: Block) -> None:
        self.segments.append(blk)
        self.starts.append(self.end_seq)
        self.end_seq += len(blk)

    def trim(self, first: int, drop: Callable[[Segment], None]) -> None:
        """Hold the rows from seq ``first`` on: ``drop`` is told of each segment as it leaves, and of the
        Records cut from the front of a list (as a list); a Block stays whole, its first rows hidden
        (the Records it built of those one by one go)."""
        segs, starts = self.segments, self.starts
        n = 0
        while n < len(segs) and starts[n] + len(segs[n]) <= first:
            drop(segs[n])
            n += 1
        del segs[:n], starts[:n]
        if segs and starts[0] < first:
            seg, cut = segs[0], first - starts[0]
            if type(seg) is not Block:
                drop(seg[:cut])
                del seg[:cut]
                starts[0] = first
            else:
                seg.forget_before(cut)
        self.first_seq = first

    # ---- reading ---------------------------------------------------------------------------------
    def rows(self, start: int, stop: int) -> Iterable[tuple[int, list[Record]]]:
        """(seq of the first, Records) of the held rows from ``start`` to ``stop``, segment by segment
        (a Block's made for the moment)."""
        if start >= stop:
            return
        segs, starts = self.segments, self.starts
        j = self.segment_index(start)
        while j < len(segs) and starts[j] < stop:
            seg, s0 = segs[j], starts[j]
            a, b = max(start, s0) - s0, min(stop, s0 + len(seg)) - s0
            yield s0 + a, seg[a:b] if type(seg) is not Block else seg.rows(a, b)
            j += 1

    def seq_of_offset(self, offset: int) -> int | None:
        """The row that starts at byte ``offset`` of the stream (rows are in wire order)."""
        segs = self.segments
        j = bisect_right(range(len(segs)), offset, key=lambda j: _first_offset(segs[j])) - 1
        if j < 0:
            return None
        seg = segs[j]
        if type(seg) is not Block:
            i = bisect_left(seg, offset, key=lambda r: r.event.offset)
            found = i < len(seg) and seg[i].event.offset == offset
        else:
            offsets = seg.offsets
            i = int(np.searchsorted(offsets, offset))
            found = i < len(offsets) and int(offsets[i]) == offset
        seq = self.starts[j] + i
        return seq if found and seq >= self.first_seq else None

    def finding_seq(self, after: int | None, forward: bool, min_severity: str,
                    shown: Callable[[int], bool]) -> int | None:
        """The next (or previous) row after seq ``after`` with a finding of ``min_severity`` or worse that
        ``shown`` lets through."""
        rank = SEVERITY_RANK[min_severity]
        base, end = self.first_seq, self.end_seq
        if base == end:
            return None
        if after is None:
            after = base - 1 if forward else end
        segs, starts = self.segments, self.starts
        if forward:
            lo, hi = max(after + 1, base), end
            if lo >= hi:
                return None
            order = range(self.segment_index(lo), len(segs))
        else:
            lo, hi = base, min(after, end)
            if lo >= hi:
                return None
            order = range(self.segment_index(hi - 1), -1, -1)
        for j in order:
            seg, s0 = segs[j], starts[j]
            if s0 >= hi or s0 + len(seg) <= lo:
                break
            a, b = max(lo, s0) - s0, min(hi, s0 + len(seg)) - s0
            recs: Sequence[Record] | Mapping[int, Record]
            ks: Iterable[int]
            if type(seg) is not Block or seg.linted_by_rows:
                recs = seg if type(seg) is not Block else seg.records()
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
                    if shown(seq):
                        return seq
        return None

    def list_nbytes(self) -> int:
        """Bytes of the history's own lists (the segment lists and the lists of Records)."""
        return (sys.getsizeof(self.segments) + 2 * sys.getsizeof(self.starts)
                + sum(sys.getsizeof(seg) for seg in self.segments if type(seg) is not Block))


def _first_offset(seg: Segment) -> int:
    if type(seg) is not Block:
        return seg[0].event.offset
    return seg.run.base + int(seg.run.starts[seg.lo])
