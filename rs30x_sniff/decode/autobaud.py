"""Which baud rate is the bus at, as the decode stage tells it: a scan of table 4.7 (valid frames counted
at each rate) and, fed by the drive loop as sinks, the streaming estimate from timestamps and a watch for
a rate that stops working. The arithmetic on timestamps alone is rs30x_sniff.protocol.baud."""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any
from collections.abc import Callable, Iterable

from .decoder import Sink, Step
from .framing import FrameDecoder
from ..protocol.baud import NO_ESTIMATE, BaudEstimate, estimate_from_spacings
from ..protocol.events import RAW, T_END, T_START
from ..protocol.memmap import bus_rates
from ..protocol.wire import BAUD_RATES

from .pairing import Record

if TYPE_CHECKING:  # names for the checker; no import at run time
    from ..protocol.events import AnyEvent

# Table 4.7's rates, most likely first: the factory default 115200 (chapter 4, No. 6), then the
# rates hosts commonly pick, then the rest. A scan stops at the first rate that decodes cleanly.
SCAN_ORDER: tuple[int, ...] = (115200, 57600, 230400, 9600, 38400, 19200, 153600, 76800, 28800, 14400)


def scan_order() -> tuple[int, ...]:
    """SCAN_ORDER, then the rates only some models have (460800: RS301CR, RS302CD, RS405CB code 0x0A)."""
    return SCAN_ORDER + tuple(r for r in bus_rates() if r not in SCAN_ORDER)


SCAN_DWELL = 0.3  # seconds read at each rate: several frames even at 9600 on a busy bus

_VALID_KINDS = frozenset(("short", "long", "return", "ack", "nack"))


def is_valid(rec: Record | AnyEvent) -> bool:
    """Whether a record (or event) is a checksum-valid frame, or an ACK/NACK byte (which only follows one)."""
    ev = rec.event if type(rec) is Record else rec
    return ev.kind in _VALID_KINDS and ev.checksum_ok


# ---- the rate from timestamps, streamed -----------------------------------------------------
class BaudFromTimes(Sink[Record]):
    """The streaming :func:`rs30x_sniff.protocol.baud.estimate_baud`: a pipeline Sink; read :attr:`estimate`
    at any time.

    Keeps the last ``keep`` spacings, so memory stays bounded on a live port.
    """

    def __init__(self, rates: Iterable[int] = BAUD_RATES, keep: int = 4096) -> None:
        self.rates = tuple(rates)
        self._samples: deque[tuple[float, int]] = deque(maxlen=keep)
        self._prev: tuple[int, float] | None = None
        self._cached: BaudEstimate | None = None

    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        if not data:
            return
        if t is None:
            self._prev = None
            return
        p = self._prev
        if p is not None and t > p[1]:
            self._samples.append(((t - p[1]) / p[0], p[0]))
            self._cached = None
        self._prev = (len(data), t)

    def chunks(self, lengths: Any, times: Any) -> None:
        """:meth:`chunk` for many timed chunks at once, in order: their byte counts and start times (numpy
        arrays, every count above 0, every time known), as the linter's column form feeds F007."""
        import numpy as np

        n = len(lengths)
        if not n:
            return
        prev_len = np.empty(n, dtype=np.int64)
        prev_t = np.empty(n)
        prev_len[1:], prev_t[1:] = lengths[:-1], times[:-1]
        p = self._prev
        keep = np.ones(n, dtype=bool)
        if p is None:
            keep[0] = False
            prev_len[0], prev_t[0] = 1, 0.0
        else:
            prev_len[0], prev_t[0] = p[0], p[1]
        keep &= times > prev_t
        rows = np.flatnonzero(keep)
        if self._samples.maxlen:
            rows = rows[-self._samples.maxlen:]  # the deque keeps the last ones only: make those alone
        if len(rows):
            lens_kept = prev_len[rows]
            self._samples.extend(zip(((times[rows] - prev_t[rows]) / lens_kept).tolist(), lens_kept.tolist()))
            self._cached = None
        self._prev = (int(lengths[-1]), float(times[-1]))

    @property
    def spacings(self) -> tuple[tuple[float, int], ...]:
        """The spacings kept: (seconds per byte, byte count) of each pair of timed neighbours, oldest first."""
        return tuple(self._samples)

    @property
    def last(self) -> tuple[int, float] | None:
        """The byte count and time of the last timed chunk (None before one, or after an untimed one)."""
        return self._prev

    @property
    def estimate(self) -> BaudEstimate:
        if self._cached is None:
            self._cached = estimate_from_spacings(self._samples, self.rates) if self._samples else NO_ESTIMATE
        return self._cached


# ---- stretches without a valid frame (F007, BaudWatch) ---------------------------------------
STRETCH_BYTES = 64      # garbage bytes with no valid frame: a healthy bus has a frame every few dozen
STRETCH_TIME = 0.5      # ... or this long (timed captures), with at least STRETCH_TIME_BYTES of garbage
STRETCH_TIME_BYTES = 16


class NoFrameStretch:
    """Counts garbage since the last valid frame; :meth:`garbage` says True once per stretch, when it
    first holds ``min_bytes`` bytes (or ``min_time`` seconds and ``min_time_bytes`` bytes)."""

    def __init__(self, min_bytes: int = STRETCH_BYTES, min_time: float = STRETCH_TIME,
                 min_time_bytes: int = STRETCH_TIME_BYTES) -> None:
        self.min_bytes = min_bytes
        self.min_time = min_time
        self.min_time_bytes = min_time_bytes
        self.reset()

    def reset(self) -> None:
        """A valid frame: the stretch is over."""
        self.bytes = 0
        self.t0: float | None = None
        self.t1: float | None = None
        self.fired = False

    @property
    def span(self) -> float | None:
        return None if self.t0 is None or self.t1 is None else self.t1 - self.t0

    def garbage(self, n: int, t0: float | None = None, t1: float | None = None) -> bool:
        self.bytes += n
        if t0 is not None and self.t0 is None:
            self.t0 = t0
        if t1 is not None:
            self.t1 = t1
        if self.fired:
            return False
        span = self.span
        if self.bytes >= self.min_bytes or (span is not None and span >= self.min_time
                                            and self.bytes >= self.min_time_bytes):
            self.fired = True
            return True
        return False


# ---- scanning a port ------------------------------------------------------------------------
@dataclass(frozen=True)
class RateScore:
    """What one rate of a scan gave: bytes read, checksum-valid frames and their bytes."""

    baud: int
    seconds: float
    bytes: int
    frames: int
    frame_bytes: int

    @property
    def frames_per_s(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    @property
    def valid_share(self) -> float:
        """Share of the bytes read that are in valid frames."""
        return self.frame_bytes / self.bytes if self.bytes else 0.0

    def as_json(self) -> dict[str, Any]:
        return {"baud": self.baud, "seconds": self.seconds, "bytes": self.bytes, "frames": self.frames,
                "frames_per_s": round(self.frames_per_s, 2), "valid_share": round(self.valid_share, 3)}


@dataclass(frozen=True)
class ScanResult:
    """The rate a scan chose (None: no rate gave valid frames), its frames per second, every rate's score."""

    baud: int | None
    score: float
    table: list[RateScore] = field(default_factory=list)
    seconds: float = 0.0  # time spent reading (simulated or real)
    wall: float = 0.0     # wall-clock time the scan took

    def __bool__(self) -> bool:
        return self.baud is not None

    def describe(self) -> str:
        rows = "; ".join(f"{s.baud}: {s.frames} frames in {s.bytes} bytes" for s in self.table)
        head = f"--baud auto: {self.baud} bit/s ({self.score:.1f} frames/s)" if self.baud else \
            "--baud auto: no rate of table 4.7 gave a valid frame (is the bus quiet?)"
        return f"{head} [{rows}]"


def score_bytes(data: bytes, baud: int, seconds: float) -> RateScore:
    """Decode ``data`` read at ``baud`` and count its checksum-valid frames."""
    dec = FrameDecoder(baud, gap_bytes=None)
    events = dec.feed(data) + dec.close()
    frames = [e for e in events if is_valid(e)]
    return RateScore(baud, seconds, len(data), len(frames), sum(len(e.raw) for e in frames))


ACCEPT_SHARE = 0.5  # a rate whose bytes are mostly valid frames ends the scan at once
MIN_FRAMES = 2      # fewer valid frames than this at the best rate: no answer


def scan(read_for: Callable[[int, float], bytes], rates: Iterable[int] | None = None, dwell: float = SCAN_DWELL,
         *, accept_share: float = ACCEPT_SHARE, min_frames: int = MIN_FRAMES,
         clock: Callable[[], float] = time.monotonic) -> ScanResult:
    """Try each rate with ``read_for(baud, seconds) -> bytes`` and pick the one with most valid frames per second.

    ``read_for`` only listens (a port reopened at each rate, or a simulated wire): a scan never
    writes to the bus. It stops early at a rate whose bytes are at least ``accept_share`` valid
    frames (with ``min_frames`` of them): at a wrong rate nearly nothing decodes.
    """
    start = clock()
    table: list[RateScore] = []
    for baud in scan_order() if rates is None else rates:
        s = score_bytes(read_for(baud, dwell), baud, dwell)
        table.append(s)
        if s.frames >= min_frames and s.valid_share >= accept_share:
            break
    best = max(table, key=lambda s: (s.frames_per_s, s.valid_share), default=None)
    seconds = sum(s.seconds for s in table)
    if best is None or best.frames < min_frames:
        return ScanResult(None, 0.0, table, seconds, clock() - start)
    return ScanResult(best.baud, best.frames_per_s, table, seconds, clock() - start)


class BaudWatch(Sink[Record]):
    """Watches a live pipeline at ``baud``: :attr:`rescan_due` turns True when the rate stops giving
    valid frames (a baud change written to the servos, flashed and rebooted, is common during setup).

    Fed by the drive loop as a Sink: ``chunk`` counts the bytes read, ``batch`` the valid frames.
    A rescan is due when ``garbage_bytes`` of garbage came without a valid frame, or when
    ``min_bytes`` bytes arrived over ``min_time`` seconds without one (so it also works while the
    decoder still holds the garbage back). Call :meth:`reset` after switching rates.
    """

    def __init__(self, baud: int, *, offset: int = 0, garbage_bytes: int = STRETCH_BYTES, min_bytes: int = 256,
                 min_time: float = STRETCH_TIME) -> None:
        self.garbage_bytes = garbage_bytes
        self.min_bytes = min_bytes
        self.min_time = min_time
        self.reset(baud, offset)

    def reset(self, baud: int | None = None, offset: int = 0) -> None:
        """Start watching afresh (after a rescan: the new rate, and the new decoder's offset, 0)."""
        if baud is not None:
            self.baud = baud
        self.fed = offset        # decoder stream offset of the next byte (``offset``: bytes it had before this watch)
        self.valid_end = offset  # stream offset where the last valid frame ended
        self.valid_t: float | None = None
        self.first_t: float | None = None
        self.now: float | None = None
        self.frames = 0
        self._stretch = NoFrameStretch(self.garbage_bytes)
        self.rescan_due = False
        self.reason = ""

    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        if not data:
            return
        self.fed += len(data)
        if t is not None:
            if self.first_t is None:
                self.first_t = t
            self.now = t
        self._check()

    def batch(self, step: Step) -> None:
        for rec in step:
            ev = rec.event
            if is_valid(ev):
                self.frames += 1
                self.valid_end = ev.end_offset
                self.valid_t = ev[T_END] if ev[T_END] is not None else self.now
                self._stretch.reset()
            elif ev.kind == "garbage":
                if self._stretch.garbage(len(ev[RAW]), ev[T_START], ev[T_END]):
                    self._due(f"{self._stretch.bytes} bytes of garbage without a valid frame")
        self._check()

    def _check(self) -> None:
        if self.rescan_due:
            return
        since = self.fed - self.valid_end
        if since < self.min_bytes:
            return
        ref = self.valid_t if self.valid_t is not None else self.first_t
        if self.now is not None and ref is not None and self.now - ref < self.min_time:
            return
        self._due(f"{since} bytes without a valid frame")

    def _due(self, why: str) -> None:
        self.rescan_due = True
        before = f" (after {self.frames} valid frames)" if self.frames else ""
        self.reason = f"{why} at {self.baud} bit/s{before}: the bus may have changed rate; rescan"
