"""Per-servo traffic: requests, reads, long writes and replies of each ID, and its poll rate by time segment."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..protocol.wire import AT_DATA

if TYPE_CHECKING:  # names for the checker; no import at run time
    from ..decode.blocks import Block


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

    def as_dict(self) -> dict[str, Any]:
        return {"requests": self.requests, "reads": self.reads, "long_writes": self.long_writes,
                "returns": self.returns, "acks": self.acks, "nacks": self.nacks, "missing": self.missing,
                "poll_rate_hz": self.poll_rate}


class ServoTraffic:
    """The ServoStats of every ID the traffic names (``by_id``, in the order they were first named), fed
    per record or per Block."""

    def __init__(self) -> None:
        self.by_id: dict[int, ServoStats] = {}
        self.known = np.zeros(256, dtype=bool)  # IDs in by_id, for the column form

    def servo(self, sid: int) -> ServoStats:
        st = self.by_id.get(sid)
        if st is None:
            st = self.by_id[sid] = ServoStats(sid)
            self.known[sid] = True
        return st

    # ---- the record form -------------------------------------------------------------------------
    def request(self, sid: int, reads: bool, status: str | None, ts: float | None, offset: int) -> bool:
        """An intact short packet to ``sid`` (asking for a return if ``reads``), its pairing ``status``;
        whether it is the servo's first request."""
        st = self.by_id.get(sid) or self.servo(sid)
        st.requests += 1
        if status == "answered":
            st.answered += 1
        if reads:
            st.reads += 1
            st.segment_reads += 1
            if ts is not None:
                if st.first_read_t is None:
                    st.first_read_t = ts
                st.last_read_t = ts
        if status == "missing":
            st.missing += 1
            if st.first_missing is None:
                st.first_missing = (ts, offset)
        return st.requests == 1

    def long_write(self, records: tuple) -> None:
        """An intact long packet's records, (VID, data) each."""
        by_id = self.by_id
        for r in records:
            st = by_id.get(r[0]) or self.servo(r[0])
            st.long_writes += 1

    def returned(self, sid: int) -> None:
        (self.by_id.get(sid) or self.servo(sid)).returns += 1

    def acked(self, sid: int) -> None:
        (self.by_id.get(sid) or self.servo(sid)).acks += 1

    def nacked(self, sid: int) -> None:
        (self.by_id.get(sid) or self.servo(sid)).nacks += 1

    # ---- the column form -------------------------------------------------------------------------
    def add_block(self, blk: Block, to_servo: np.ndarray, reads: np.ndarray, is_return: np.ndarray,
                  long_rows: np.ndarray | None) -> list[int]:
        """A Block's rows (rs30x_sniff.decode.blocks): ``to_servo`` the short packets to one servo,
        ``reads`` those asking for a return, ``is_return`` the returns, ``long_rows`` the long packets
        (None without any): the same figures as the record form of each row, in order. The IDs whose
        first request is in the Block, in ID order."""
        sid = blk.cols["id"]
        longs = long_vids(blk, long_rows) if long_rows is not None else []
        named = sid[to_servo | is_return]
        known = self.known
        if not known[named].all() or not all(known[v].all() for _, v in longs):
            self._new_servos(blk, to_servo | is_return, longs)
        by_id = self.by_id
        first = []
        if to_servo.any():
            req_counts = np.bincount(sid[to_servo], minlength=256)
            for i in np.flatnonzero(req_counts).tolist():
                st = by_id[i]
                if st.requests == 0:
                    first.append(i)
                st.requests += int(req_counts[i])
            answered = np.bincount(sid[to_servo & blk.answered], minlength=256)
            for i in np.flatnonzero(answered).tolist():
                by_id[i].answered += int(answered[i])
            self._reads(blk, np.flatnonzero(reads))
        for _, vids in longs:
            vc = np.bincount(vids.ravel(), minlength=256)
            for i in np.flatnonzero(vc).tolist():
                by_id[i].long_writes += int(vc[i])
        if is_return.any():
            rc = np.bincount(sid[is_return], minlength=256)
            for i in np.flatnonzero(rc).tolist():
                by_id[i].returns += int(rc[i])
        return first

    def _reads(self, blk: Block, read_rows: np.ndarray) -> None:
        """Reads (the rows of requests asking for a return) counted, with each servo's first and last time."""
        if not read_rows.size:
            return
        by_id = self.by_id
        rs = blk.cols["id"][read_rows]
        read_counts = np.bincount(rs, minlength=256)
        t0 = blk.t0
        if t0 is None:
            for i in np.flatnonzero(read_counts).tolist():
                by_id[i].reads += int(read_counts[i])
                by_id[i].segment_reads += int(read_counts[i])
            return
        tr = t0[read_rows]
        ids, first = np.unique(rs, return_index=True)
        _, last = np.unique(rs[::-1], return_index=True)
        firsts, lasts = tr[first].tolist(), tr[len(rs) - 1 - last].tolist()
        for i, c, f, la in zip(ids.tolist(), read_counts[ids].tolist(), firsts, lasts):
            st = by_id[i]
            st.reads += c
            st.segment_reads += c
            if st.first_read_t is None:
                st.first_read_t = f
            st.last_read_t = la

    def _new_servos(self, blk: Block, named: np.ndarray, longs: list) -> None:
        """Create the ServoStats of the IDs the Block names first, in the order the record form would."""
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
        for i in sorted((i for i in first if i not in self.by_id), key=first.__getitem__):
            self.servo(i)

    # ---- time segments -----------------------------------------------------------------------------
    def end_segment(self) -> None:
        for st in self.by_id.values():
            st.end_segment()

    def as_dict(self) -> dict[str, Any]:
        return {str(sid): s.as_dict() for sid, s in sorted(self.by_id.items())}


def long_vids(blk: Block, rows: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
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
        out.append((rws, a[(starts[rws] + AT_DATA)[:, None] + np.arange(nrec) * ln]))  # each record's VID
    return out
