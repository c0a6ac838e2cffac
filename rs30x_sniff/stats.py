"""Capture statistics (duration, traffic by type, per-servo polls and latencies, bus load); pure, no I/O.

The one definition of these figures: ``info``, the MCAP metadata and the monitor all read them here.
"""

from __future__ import annotations

import itertools
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any, Iterable

from .events import LongPacket, ShortPacket
from .pipeline import Sink, Step
from .wire import BITS_PER_BYTE, byte_time

# Latencies are counted in 1 us bins: exact enough for percentiles of a bus whose return delay
# steps by 50 us (table 4.6 No. 7), with memory bounded by the spread, not by the capture length.
_LATENCY_BIN = 1e-6


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
    first_read_t: float | None = None
    last_read_t: float | None = None

    @property
    def poll_rate(self) -> float | None:
        """Reads per second between this servo's first and last read (None with fewer than two)."""
        if self.reads < 2 or self.first_read_t is None or self.last_read_t is None:
            return None
        span = self.last_read_t - self.first_read_t
        return (self.reads - 1) / span if span > 0 else None


@dataclass
class LatencyHistogram:
    """Reply latencies in 1 us bins: percentiles and maximum in bounded memory."""

    bins: Counter = field(default_factory=Counter)
    count: int = 0
    max: float | None = None

    def add(self, latency: float) -> None:
        self.bins[round(latency / _LATENCY_BIN)] += 1
        self.count += 1
        if self.max is None or latency > self.max:
            self.max = latency

    def percentile(self, p: float) -> float | None:
        """The smallest bin value at or below which ``p`` percent of the latencies fall."""
        if not self.count:
            return None
        rank = max(1, -(-self.count * p // 100))  # ceil, nearest-rank method
        seen = 0
        for k in sorted(self.bins):
            seen += self.bins[k]
            if seen >= rank:
                return k * _LATENCY_BIN
        return self.max


class CaptureStats(Sink):
    """Feed every record (and the findings), then read the figures or :meth:`as_dict`; as a sink of
    the drive loop it counts the bytes, records and findings that pass through.

    Times come from the records; a capture without timestamps is measured in line time: its
    byte count at the configured baud rate, as if the bus had never been idle.
    """

    def __init__(self, baud: int) -> None:
        self.baud = baud
        self.bytes = 0
        self.bytes_in = 0  # bytes fed through chunk()
        self.records = 0
        self.by_kind: Counter = Counter()
        self.by_op: Counter = Counter()
        self.bad_checksums = 0
        self.garbage_bytes = 0
        self.servos: dict[int, ServoStats] = {}
        self.latency = LatencyHistogram()
        self.findings: Counter = Counter()
        self.finding_codes: Counter = Counter()
        self.first_t: float | None = None
        self.last_t: float | None = None
        self.timed = False

    # ---- as a sink ---------------------------------------------------------------------------------
    def chunk(self, data: bytes, t: float | None) -> None:
        self.bytes_in += len(data)

    def batch(self, step: Step) -> None:
        add = self.add
        for rec in step:
            add(rec)
        if step.findings:
            self.add_findings(step.findings)

    def close(self) -> None:
        self.set_bytes(self.bytes_in)

    def servo(self, sid: int) -> ServoStats:
        st = self.servos.get(sid)
        if st is None:
            st = self.servos[sid] = ServoStats(sid)
        return st

    def add(self, rec: Any) -> None:
        ev = rec.event
        self.records += 1
        kind = ev.kind
        self.by_kind[kind] += 1
        self.bytes = max(self.bytes, ev.offset + len(ev.raw))
        if ev.t_start is not None:
            self.timed = True
            if self.first_t is None:
                self.first_t = ev.t_start
            end = ev.t_end if ev.t_end is not None else ev.t_start
            if self.last_t is None or end > self.last_t:
                self.last_t = end
        if kind == "garbage":
            self.garbage_bytes += len(ev.raw)
            return
        if not ev.checksum_ok:
            # Its ID, VIDs and op cannot be trusted: a bad checksum, not traffic of the servos it names.
            self.bad_checksums += 1
            return
        t = type(ev)
        if t is ShortPacket:
            self.by_op[ev.op] += 1
            if ev.id != 0xFF:
                st = self.servo(ev.id)
                st.requests += 1
                if ev.read_range is not None:
                    st.reads += 1
                    if ev.t_start is not None:
                        if st.first_read_t is None:
                            st.first_read_t = ev.t_start
                        st.last_read_t = ev.t_start
                if rec.status == "missing":
                    st.missing += 1
        elif t is LongPacket:
            self.by_op["long-write"] += 1
            for r in ev.records:
                self.servo(r.vid).long_writes += 1
        elif rec.is_reply:
            sid = rec.id
            if sid is not None:
                st = self.servo(sid)
                if kind == "return":
                    st.returns += 1
                elif kind == "ack":
                    st.acks += 1
                else:
                    st.nacks += 1
            if rec.latency is not None and rec.status == "paired":
                self.latency.add(rec.latency)

    def add_findings(self, findings: Iterable[Any]) -> None:
        for f in findings:
            self.findings[f.severity] += 1
            self.finding_codes[f"{f.code} {f.name}"] += 1

    def set_bytes(self, n: int) -> None:
        """The input's total byte count (the records may end before trailing bytes of a cut frame)."""
        self.bytes = max(self.bytes, n)

    # ---- figures ------------------------------------------------------------------------------
    @property
    def line_time(self) -> float:
        """Seconds the captured bytes occupy the line at the baud rate (10 bits a byte)."""
        return self.bytes * byte_time(self.baud)

    @property
    def duration(self) -> float:
        """Seconds from the first to the last byte (line time for a capture without timestamps)."""
        if self.timed and self.first_t is not None and self.last_t is not None:
            return max(0.0, self.last_t - self.first_t)
        return self.line_time

    @property
    def bus_load(self) -> float | None:
        """Fraction of the capture's time the line was busy (None for an instant or untimed capture)."""
        if not self.timed:
            return None
        d = self.duration
        return min(1.0, self.line_time / d) if d > 0 else None

    @property
    def packets(self) -> int:
        return self.records - self.by_kind["garbage"]

    def as_dict(self) -> dict[str, Any]:
        """Every figure as plain JSON-ready data (``info --format json``)."""
        lat = self.latency
        return {
            "duration_s": self.duration,
            "timed": self.timed,
            "bytes": self.bytes,
            "baud": self.baud,
            "bus_load": self.bus_load,
            "records": self.records,
            "packets": self.packets,
            "by_type": dict(sorted(self.by_kind.items())),
            "by_op": dict(sorted(self.by_op.items())),
            "bad_checksums": self.bad_checksums,
            "garbage_bytes": self.garbage_bytes,
            "latency_s": {"count": lat.count, "p50": lat.percentile(50), "p95": lat.percentile(95), "max": lat.max},
            "servos": {
                str(sid): {"requests": s.requests, "reads": s.reads, "long_writes": s.long_writes,
                           "returns": s.returns, "acks": s.acks, "nacks": s.nacks, "missing": s.missing,
                           "poll_rate_hz": s.poll_rate}
                for sid, s in sorted(self.servos.items())
            },
            "findings": {sev: self.findings.get(sev, 0) for sev in ("error", "warning", "info")},
            "findings_by_rule": dict(self.finding_codes.most_common()),
        }


class RecentLoad:
    """Bus load over the last ``window`` seconds of capture time: what a live display shows.

    Fed ``(t, nbytes)`` per record or chunk start; the newest item's own bytes end after its start
    time, so the busy time counts the items before it, over the window up to its start.
    """

    def __init__(self, baud: int, window: float = 1.0) -> None:
        self.bits = BITS_PER_BYTE / baud
        self.window = window
        self._items: deque[tuple[float, int]] = deque()
        self._bytes = 0
        self._last_t: float | None = None

    def add(self, t: float, nbytes: int) -> None:
        self.extend(((t, nbytes),))

    def extend(self, timed_sizes: Iterable[tuple[float, int]]) -> None:
        """Add ``(t, nbytes)`` items in time order (one call per batch: the window is trimmed once)."""
        items = self._items
        n0 = len(items)
        items.extend(timed_sizes)
        if len(items) == n0:
            return
        self._bytes += sum(n for _, n in itertools.islice(items, n0, None))
        last = items[-1][0]
        if self._last_t is None or last > self._last_t:
            self._last_t = last
        horizon = self._last_t - self.window
        while items and items[0][0] < horizon:
            self._bytes -= items.popleft()[1]

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
