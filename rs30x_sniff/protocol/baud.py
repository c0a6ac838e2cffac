"""What a capture's timestamps say of the line rate (table 4.7): pure arithmetic on ``(bytes, t)`` chunks.

Sources (a serial logger's or an analyzer's times), the commands (a timestamped capture's rate, a rate
the times contradict) and the decode stage's streaming estimate (rs30x_sniff.decode.autobaud.BaudFromTimes)
all use these; nothing here decodes a frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Iterable, Iterator

from .wire import BAUD_RATES, byte_time


# ---- the rate from timestamps ----------------------------------------------------------------
@dataclass(frozen=True)
class BaudEstimate:
    """A line rate read off timestamps: ``baud`` (None: the timestamps do not say), ``score`` in [0, 1]."""

    baud: int | None
    score: float
    evidence: str
    per_byte: float | None = None  # seconds per byte where chunks follow each other back to back
    samples: int = 0

    def __bool__(self) -> bool:
        return self.baud is not None


NO_ESTIMATE = BaudEstimate(None, 0.0, "no timestamps")

# A back-to-back spacing within this factor of a rate's byte time names that rate. Neighbours in
# table 4.7 are at least 4/3 apart, so 10 % never fits two rates.
MATCH_TOLERANCE = 0.10
# Spacings within this factor of the byte time count as back to back (a cluster, not chance).
CLUSTER_TOLERANCE = 0.05
PERCENTILE = 0.05     # of bytes: a low percentile, so one odd timestamp does not decide
MIN_SAMPLES = 8       # spacings needed before saying anything
MIN_CLUSTER = 0.10    # share of bytes that must sit back to back at the estimated rate
FULL_CLUSTER_BYTES = 256  # back-to-back bytes for full confidence


def _neighbours(chunks: Iterable[tuple[bytes, float | None]]) -> Iterator[tuple[float, int, int]]:
    """``(seconds between, bytes of the first, bytes of the second)`` of each two timed chunks in a row
    whose times increase (a clock that went back, or equal stamps, say nothing of the rate)."""
    prev: tuple[int, float] | None = None
    for data, t in chunks:
        if not data:
            continue
        if t is None:
            prev = None
            continue
        if prev is not None and t > prev[1]:
            yield t - prev[1], prev[0], len(data)
        prev = (len(data), t)


def _spacings(chunks: Iterable[tuple[bytes, float | None]]) -> list[tuple[float, int]]:
    return [(gap / n, n) for gap, n, _ in _neighbours(chunks)]


def estimate_from_spacings(samples: Iterable[tuple[float, int]], rates: Iterable[int] = BAUD_RATES) -> BaudEstimate:
    """:func:`estimate_baud` on (seconds per byte, bytes) spacings already taken."""
    samples = sorted(samples)
    if len(samples) < MIN_SAMPLES:
        return BaudEstimate(None, 0.0, f"{len(samples)} timestamp spacing(s): too few to tell the rate",
                            samples=len(samples))
    total = sum(w for _, w in samples)
    # Weighted by bytes: a long packet followed at once by the next frame is the best evidence.
    goal, acc, per_byte = PERCENTILE * total, 0, samples[-1][0]
    for s, w in samples:
        acc += w
        if acc >= goal:
            per_byte = s
            break
    best = min(rates, key=lambda r: abs(math.log(per_byte / byte_time(r))))
    bt = byte_time(best)
    off = per_byte / bt - 1
    cluster = sum(w for s, w in samples if abs(s / bt - 1) <= CLUSTER_TOLERANCE)
    share = cluster / total
    what = (f"{len(samples)} spacings; {PERCENTILE:.0%} of bytes come {per_byte * 1e6:.1f} us apart or closer "
            f"(a byte at {best} bit/s takes {bt * 1e6:.1f} us); {share:.0%} of bytes back to back")
    if abs(off) > MATCH_TOLERANCE or share < MIN_CLUSTER:
        return BaudEstimate(None, 0.0, what + ": no rate of table 4.7 fits", per_byte, len(samples))
    score = min(1.0, cluster / FULL_CLUSTER_BYTES) * (1 - abs(off) / MATCH_TOLERANCE)
    return BaudEstimate(best, round(score, 3), what, per_byte, len(samples))


def estimate_baud(chunks: Iterable[tuple[bytes, float | None]], rates: Iterable[int] = BAUD_RATES) -> BaudEstimate:
    """The line rate where chunks follow each other back to back (``t`` = the chunk's first byte).

    The spacing from one chunk's start to the next, per byte of the first, is at least the byte time
    (10 bits, 8N1) and equals it where the line never went idle. A low percentile of those spacings
    is matched to the nearest rate of table 4.7; None when nothing is within 10 % or too few bytes
    sit back to back (sparse timestamps: a logger stamping every second, chunks far apart).
    460800 (code 0x0A of some models) is left out of the candidates on purpose: arrival-stamped chunks at
    115200 would then read as back to back at 460800. A capture at 460800 is decoded with --baud 460800,
    and until then its rate-bound figures are absent, with the reason.
    """
    return estimate_from_spacings(_spacings(chunks), rates)


def contradicts(estimate: BaudEstimate | None, baud: int, min_score: float = 0.2) -> bool:
    """Whether a confident estimate names another rate than ``baud`` (the one the capture is decoded at)."""
    return estimate is not None and bool(estimate) and estimate.baud != baud and estimate.score >= min_score


# ---- rates the timestamps rule out ------------------------------------------------------------
# Bytes cannot overlap on the wire: at a rate too slow, chunks would start before the previous one
# ended. Jitter aside (OVERLAP_TOLERANCE of the chunk's line time), a right rate has next to no such
# pairs; a rate with more than OVERLAP_SHARE of them is contradicted by the timestamps.
OVERLAP_TOLERANCE = 0.10
OVERLAP_SHARE = 0.10


@dataclass(frozen=True)
class RateFit:
    """Which rates a capture's timestamps allow: ``spans`` holds, for each pair of timed neighbours,
    the seconds from one's time to the next's and the byte count of the shorter of the two.

    Whatever the times mark (a chunk's first byte or its arrival), the later chunk cannot begin
    within the line time of the shorter one, so a rate is tested without knowing the time reference.
    """

    spans: tuple[tuple[float, int], ...] = ()

    def overlaps(self, baud: int) -> int:
        """Pairs that would overlap at ``baud``."""
        bt = byte_time(baud) * (1 - OVERLAP_TOLERANCE)
        return sum(1 for d, n in self.spans if d < n * bt)

    def rules_out(self, baud: int) -> bool:
        """Whether the timestamps contradict ``baud`` (never on fewer than MIN_SAMPLES pairs)."""
        return len(self.spans) >= MIN_SAMPLES and self.overlaps(baud) > OVERLAP_SHARE * len(self.spans)

    def slowest(self, rates: Iterable[int] = BAUD_RATES) -> int | None:
        """The slowest of ``rates`` the timestamps allow (on a busy bus, the rate: close neighbours pin
        the byte time from above), or None when they rule out all of them or are too few to tell."""
        if len(self.spans) < MIN_SAMPLES:
            return None
        return next((r for r in sorted(rates) if not self.rules_out(r)), None)

    def evidence(self, baud: int) -> str:
        return (f"at {baud} bit/s, {self.overlaps(baud)} of {len(self.spans)} chunks would start before the previous "
                "one ended")


def rate_fit(chunks: Iterable[tuple[bytes, float | None]]) -> RateFit:
    """The :class:`RateFit` of timed chunks (``t`` in seconds). Neighbours whose times do not increase
    (a clock that went back, or equal stamps) are left out: they say nothing of the rate."""
    return RateFit(tuple((gap, min(n, m)) for gap, n, m in _neighbours(chunks)))


def contradiction(estimate: BaudEstimate | None, fit: RateFit | None, baud: int) -> tuple[int | None, str] | None:
    """How a capture's timestamps contradict decoding it at ``baud``: (the rate they show, or None when they
    fit no rate of table 4.7; the evidence), or None when they do not. Chunks that would overlap at ``baud``
    come first; else back-to-back bytes that name another rate with confidence."""
    if fit is not None and fit.rules_out(baud):
        shown = estimate.baud if estimate and estimate.baud is not None and not fit.rules_out(estimate.baud) \
            else fit.slowest()
        return shown, fit.evidence(baud)
    if estimate is not None and contradicts(estimate, baud):
        return estimate.baud, estimate.evidence
    return None
