"""Reply latencies in a bounded histogram: their count, percentiles and maximum."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

# Latencies are counted in 1 us bins: exact enough for percentiles of a bus whose return delay
# steps by 50 us (table 4.6 No. 7), with memory bounded by the spread, not by the capture length.
LATENCY_BIN = 1e-6


@dataclass
class LatencyHistogram:
    """Reply latencies in 1 us bins: percentiles and maximum in bounded memory; ``unmeasured`` counts
    the paired replies whose times give no latency (pairing.reply_latency: stamped before their request
    ended, or closer to it than a servo can answer)."""

    bins: Counter = field(default_factory=Counter)
    count: int = 0
    max: float | None = None
    unmeasured: int = 0

    # ---- the record form -------------------------------------------------------------------------
    def add(self, latency: float) -> None:
        self.bins[round(latency / LATENCY_BIN)] += 1
        self.count += 1
        if self.max is None or latency > self.max:
            self.max = latency

    def add_paired(self, latency: float | None, timed: bool) -> None:
        """A paired reply's latency; None from a timed reply is one its times cannot measure (reply_latency)."""
        if latency is not None:  # add(), inlined: once a reply
            self.bins[round(latency / LATENCY_BIN)] += 1
            self.count += 1
            if self.max is None or latency > self.max:
                self.max = latency
        elif timed:
            self.unmeasured += 1

    # ---- the column form -------------------------------------------------------------------------
    def add_array(self, lat: np.ndarray) -> None:
        """Paired replies' latencies (at least one): :meth:`add` of each."""
        bins = self.bins
        keys = np.rint(lat / LATENCY_BIN).astype(np.int64)
        k0 = int(keys.min())
        cnt = np.bincount(keys - k0)
        for k in np.flatnonzero(cnt).tolist():
            bins[k + k0] += int(cnt[k])
        self.count += len(lat)
        top = float(lat.max())
        if self.max is None or top > self.max:
            self.max = top

    # ---- figures ---------------------------------------------------------------------------------
    def percentile(self, p: float) -> float | None:
        """The smallest bin value at or below which ``p`` percent of the latencies fall."""
        if not self.count:
            return None
        rank = max(1, -(-self.count * p // 100))  # ceil, nearest-rank method
        seen = 0
        for k in sorted(self.bins):
            seen += self.bins[k]
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
