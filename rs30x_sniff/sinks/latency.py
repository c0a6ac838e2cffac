"""Reply latencies in a bounded histogram: their count, percentiles and maximum."""

from __future__ import annotations

from array import array
from collections import Counter
from typing import Any

import numpy as np

# Latencies are counted in 1 us bins: exact enough for percentiles of a bus whose return delay steps by 50 us
# (table 4.6 No. 7). The bins up to DENSE_US are an array of counts (8 bytes a bin), grown to the largest
# latency seen: it holds every latency a servo can give (its return delay is at most 100 us + 255 x 50 us =
# 12.85 ms, table 4.6 No. 7). Later ones (a reader's stall, a long --reply-timeout) go to a Counter, in bins of
# COARSE_BITS significant bits (under 0.013 % wide). So memory is bounded by the spread of the latencies, never
# by the capture's length: a Counter of every 1 us bin grew 140 bytes a bin, and a live pty's jitter gave
# thousands of bins an hour (bench/live.py's RSS over an hour).
LATENCY_BIN = 1e-6
DENSE_US = 1 << 14
COARSE_BITS = 14
_FIRST_DENSE = 256  # bins the array starts with when it is first needed (2 KB)


def _coarse(k: int) -> int:
    """Bin ``k`` (>= DENSE_US) with its bits below COARSE_BITS significant ones cleared."""
    shift = k.bit_length() - COARSE_BITS
    return k >> shift << shift


class LatencyHistogram:
    """Reply latencies in 1 us bins: percentiles and maximum in bounded memory; ``unmeasured`` counts
    the paired replies whose times give no latency (pairing.reply_latency: stamped before their request
    ended, or closer to it than a servo can answer)."""

    def __init__(self) -> None:
        self._dense = array("q")         # _dense[k]: latencies of k us (k < DENSE_US)
        self._late: Counter = Counter()  # _coarse(k) -> latencies of k us, k >= DENSE_US
        self.count = 0
        self.max: float | None = None
        self.unmeasured = 0

    # ---- the record form -------------------------------------------------------------------------
    def add(self, latency: float) -> None:
        k = round(latency / LATENCY_BIN)
        if 0 <= k < len(self._dense):
            self._dense[k] += 1
        else:
            self.add_bin(k, 1)
        self.count += 1
        if self.max is None or latency > self.max:
            self.max = latency

    def add_paired(self, latency: float | None, timed: bool) -> None:
        """A paired reply's latency; None from a timed reply is one its times cannot measure (reply_latency)."""
        if latency is not None:  # add(), inlined: once a reply
            k = round(latency / LATENCY_BIN)
            if 0 <= k < len(self._dense):
                self._dense[k] += 1
            else:
                self.add_bin(k, 1)
            self.count += 1
            if self.max is None or latency > self.max:
                self.max = latency
        elif timed:
            self.unmeasured += 1

    def add_bin(self, k: int, n: int) -> None:
        """``n`` latencies of ``k`` us: in the array, grown to hold bin ``k`` if need be (to a power of two, at
        most DENSE_US), or past it in their coarse bin. (A latency is never negative: pairing.reply_latency gives
        none for a reply stamped before its request ended; bin 0 would hold one.)"""
        k = max(k, 0)
        if k >= DENSE_US:
            self._late[_coarse(k)] += n
            return
        self._grow_to(k)
        self._dense[k] += n

    def _grow_to(self, k: int) -> None:
        """The array long enough to hold bin ``k`` (< DENSE_US): grown to a power of two, at least _FIRST_DENSE."""
        size = len(self._dense)
        if k >= size:
            self._dense.frombytes(bytes(8 * (min(DENSE_US, max(_FIRST_DENSE, 1 << k.bit_length())) - size)))

    # ---- the column form -------------------------------------------------------------------------
    def add_array(self, lat: np.ndarray) -> None:
        """Paired replies' latencies (at least one): :meth:`add` of each."""
        keys = np.maximum(np.rint(lat / LATENCY_BIN).astype(np.int64), 0)
        top = int(keys.max())
        if top >= DENSE_US:
            late = keys >= DENSE_US
            for k in keys[late].tolist():
                self._late[_coarse(k)] += 1
            keys = keys[~late]
            top = int(keys.max()) if len(keys) else -1
        if top >= 0:
            self._grow_to(top)
            k0 = int(keys.min())
            cnt = np.bincount(keys - k0)
            dense = np.frombuffer(self._dense, np.int64)  # a view: the counts are added in place
            dense[k0:k0 + len(cnt)] += cnt
            del dense  # (the array cannot grow while a view of it is held)
        self.count += len(lat)
        top_s = float(lat.max())
        if self.max is None or top_s > self.max:
            self.max = top_s

    # ---- figures ---------------------------------------------------------------------------------
    @property
    def bins(self) -> dict[int, int]:
        """Every bin that holds a latency: its lower edge in us -> its count."""
        out = {k: int(n) for k, n in enumerate(self._dense) if n}
        out.update(sorted(self._late.items()))
        return out

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, LatencyHistogram):
            return NotImplemented
        return (self.count, self.max, self.unmeasured, self.bins) == (other.count, other.max, other.unmeasured,
                                                                       other.bins)

    def __add__(self, other: LatencyHistogram) -> LatencyHistogram:
        """The latencies of both (two parts of a capture)."""
        out = LatencyHistogram()
        for h in (self, other):
            for k, n in h.bins.items():
                out.add_bin(k, n)
            out.count += h.count
            out.unmeasured += h.unmeasured
            if h.max is not None and (out.max is None or h.max > out.max):
                out.max = h.max
        return out

    def percentile(self, p: float) -> float | None:
        """The smallest bin value at or below which ``p`` percent of the latencies fall."""
        if not self.count:
            return None
        rank = max(1, -(-self.count * p // 100))  # ceil, nearest-rank method
        seen = 0
        if self._dense:
            cum = np.cumsum(np.frombuffer(self._dense, np.int64))
            if cum[-1] >= rank:
                return int(np.searchsorted(cum, rank)) * LATENCY_BIN  # the first bin whose sum reaches it
            seen = int(cum[-1])
        for k in sorted(self._late):
            seen += self._late[k]
            if seen >= rank:
                return k * LATENCY_BIN
        return self.max

    def as_dict(self, unsupported: str | None = None) -> dict[str, Any]:
        """Count and percentiles, or none with the reason they cannot be given (``unsupported``: the
        timestamps contradict the baud rate)."""
        unmeasured = self.unmeasured
        if unsupported:
            return {"count": 0, "p50": None, "p95": None, "max": None, "unmeasured": self.count + unmeasured,
                    "absent": unsupported}
        out: dict[str, Any] = {"count": self.count, "p50": self.percentile(50), "p95": self.percentile(95),
                               "max": self.max, "unmeasured": unmeasured}
        if unmeasured:
            one = unmeasured == 1
            out["absent"] = (f"{unmeasured} repl{'y' if one else 'ies'} timed sooner after {'its' if one else 'their'} "
                             f"request than a servo answers (stamped before it ended, F005/F006, or laid out with it "
                             f"at the line rate, read in one piece): no latency")
        return out


# Replies a column form's latencies are held for before they are split by servo: a split costs a pass per
# servo, so it is paid once per this many replies, not once per Block.
SPLIT_EVERY = 1 << 16


class ServoLatencies:
    """Reply latencies per servo, a LatencyHistogram each (``by_id``): the record form adds one reply, the
    column form a Block's replies at once (held, then split by servo every SPLIT_EVERY replies)."""

    def __init__(self) -> None:
        self.by_id: dict[int, LatencyHistogram] = {}
        self._held: list[tuple[np.ndarray, np.ndarray]] = []
        self._held_count = 0

    def add(self, sid: int, latency: float) -> None:
        h = self.by_id.get(sid)
        if h is None:
            h = self.by_id[sid] = LatencyHistogram()
        h.add(latency)

    def add_arrays(self, ids: np.ndarray, lat: np.ndarray) -> None:
        """Replies of servos ``ids`` with latencies ``lat`` (same length)."""
        if len(lat):
            self._held.append((ids, lat))
            self._held_count += len(lat)
            if self._held_count >= SPLIT_EVERY:
                self.split()

    def split(self) -> None:
        """Put the held replies into their servos' histograms (before any figure is read)."""
        if not self._held:
            return
        ids = np.concatenate([i for i, _ in self._held])
        lat = np.concatenate([x for _, x in self._held])
        self._held, self._held_count = [], 0
        for sid in np.unique(ids).tolist():
            h = self.by_id.get(sid)
            if h is None:
                h = self.by_id[sid] = LatencyHistogram()
            h.add_array(lat[ids == sid])

    def as_dict(self, sid: int, unsupported: str | None = None) -> dict[str, Any] | None:
        """Servo ``sid``'s count and percentiles (LatencyHistogram.as_dict); None when no reply of it had one."""
        self.split()
        h = self.by_id.get(sid)
        return None if h is None else h.as_dict(unsupported)
