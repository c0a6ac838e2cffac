"""What the monitor's history weighs: Records, Blocks, the FrameRuns Blocks share and the Records they build."""

from __future__ import annotations

import sys
from collections.abc import Iterable

from ..decode.blocks import Block
from ..decode.frame_runs import FrameRun
from ..decode.pairing import Record
from ..protocol.events import LongPacket, ReturnPacket, ShortPacket

# Python object sizes on this interpreter, for the memory estimate (measured once, not guessed).
_EMPTY_LIST = sys.getsizeof([])
_RECORD_BASE = sys.getsizeof(Record.__new__(Record)) + _EMPTY_LIST
BLOCK_BASE = sys.getsizeof(Block.__new__(Block)) + sys.getsizeof({}) + 8 * 112  # the object, cols, views

_SIZES: dict[tuple, int] = {}  # events of one type and shape all weigh the same


def record_size(rec: Record) -> int:
    """Approximate bytes a record holds on to: the record, its event, and the event's byte strings."""
    ev = rec.event
    t = type(ev)
    key = (t, len(ev.raw), ev.count if t is LongPacket else 0)
    size = _SIZES.get(key)
    if size is None:
        size = _RECORD_BASE + sys.getsizeof(ev) + sys.getsizeof(ev.raw) + 8  # + the history list's slot
        if type(ev) is ShortPacket or type(ev) is ReturnPacket:  # (a new size: once per shape)
            size += sys.getsizeof(ev.data)
        elif type(ev) is LongPacket:
            recs = ev.records
            size += sys.getsizeof(recs) + sum(sys.getsizeof(r) + sys.getsizeof(r.data) for r in recs)
        if len(_SIZES) < 4096:
            _SIZES[key] = size
    return size


def block_nbytes(blk: Block) -> int:
    """Bytes a Block holds of its own (its columns are views of its run's)."""
    return BLOCK_BASE + blk.answered.nbytes


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


class HeldBytes:
    """Bytes of the held Records, Blocks and runs, added as they come and taken off as they go; a run
    counts once however many held Blocks share it. The Records Blocks build later are weighed when
    asked (:meth:`built`), as they come at any time (a row shown, a finding's sample)."""

    def __init__(self) -> None:
        self.total = 0  # bytes of the held Records, Blocks and runs
        self._runs: dict[FrameRun, list] = {}  # a run -> [held Blocks of it, its bytes]
        self._built: dict[Block, tuple] = {}   # a Block -> (what it keeps, bytes of that)

    def add_records(self, records: Iterable[Record]) -> None:
        self.total += sum(map(record_size, records))

    def drop_records(self, records: Iterable[Record]) -> None:
        self.total -= sum(map(record_size, records))

    def add_block(self, blk: Block) -> None:
        self.total += block_nbytes(blk)
        held = self._runs.get(blk.run)
        if held is None:
            size = run_nbytes(blk.run)
            self._runs[blk.run] = [1, size]
            self.total += size
        else:
            held[0] += 1

    def drop_block(self, blk: Block) -> None:
        self.total -= block_nbytes(blk)
        self._built.pop(blk, None)
        held = self._runs[blk.run]
        held[0] -= 1
        if not held[0]:
            del self._runs[blk.run]
            self.total -= held[1]

    def built(self, blocks: Iterable[Block]) -> int:
        """Bytes of the Records the held ``blocks`` keep, each Block weighed again only when what it
        keeps has changed."""
        total = 0
        built = self._built
        for blk in blocks:
            made = blk.made_rows
            if made:
                key = (blk.linted_by_rows, len(made))
                hit = built.get(blk)
                if hit is None or hit[0] != key:  # what it holds changed: weigh it again
                    hit = built[blk] = (key, built_nbytes(blk))
                total += hit[1]
        return total
