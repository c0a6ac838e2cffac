"""What unit a capture's plain-number times count in (s, ms, us, ns; from the epoch or not), told by their spacing."""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime, UTC
from decimal import Decimal, InvalidOperation
from collections.abc import Iterable

from ..protocol.wire import BAUD_RATES, byte_time

SECONDS = "s"
EXPONENTS = {"s": 0, "ms": 3, "us": 6, "ns": 9}  # a unit is 10**-exponent seconds
UNITS = tuple(EXPONENTS)
NAMES = {"s": "seconds", "ms": "milliseconds", "us": "microseconds", "ns": "nanoseconds"}

# A first time that falls between these, read in some unit, is a wall-clock stamp in that unit; no
# capture time, counted from the epoch or from the capture's start, is later than EPOCH_MAX. Nor is a
# stamp more than AHEAD past the wall clock now (a clock set a little fast aside): 3456789012.5 us since
# a device booted is no second of 2079. ``now`` is the caller's: this module reads no clock.
EPOCH_MIN = 946_684_800.0    # 2000-01-01T00:00:00Z
EPOCH_MAX = 4_102_444_800.0  # 2100-01-01T00:00:00Z
AHEAD = 86_400.0             # a day
# Neighbours further apart than this are separate time segments for the decoder (rs30x_sniff.decode.framing's
# SEAM_GAP_S): a unit that makes most of a capture's neighbours so is not its unit.
SEAM_GAP = 10.0
MAX_SEAM_SHARE = 0.5     # more of the capture's span than this in gaps a segment long: not the unit
MAX_SPARSE_OVERLAP = 0.10  # read in the unit, no more of the neighbours than this may overlap at every rate

# How a unit was known (TimeUnit.how).
SPACING, SIZE, GIVEN, ASSUMED = "spacing", "size", "given", "assumed"

MIN_PAIRS = 8            # timed neighbours needed before the spacing says anything
# A chunk "follows closely" when it starts within this much idle line of the previous one's end (or,
# stamped at arrival, ends that soon after it): a servo's return delay, a host's turnaround. Far
# below what a wrong unit makes of it (at least 39 ms a byte read 1000x too coarse).
CLOSE_GAP = 0.002
CLOSE_BYTES = 2          # ... or this many byte times, at the slow rates
OVERLAP_TOLERANCE = 0.10  # a spacing this far below n byte times is impossible at that rate (jitter aside)
MIN_CLOSE = 4            # closely following pairs a unit needs, of at least two lengths ...
MIN_CLOSE_SHARE = 0.10   # ... and this share of all pairs
MAX_OVERLAP_SHARE = 0.5  # more pairs than this impossible at every rate: not the unit
MAX_STEP = 0.005         # times written more coarsely than this (s) cannot show bytes following each other


@dataclass(frozen=True)
class TimeUnit:
    """How to read a capture's plain-number times.

    ``unit`` is s, ms, us or ns (``scale`` seconds each); ``epoch`` says they count from 1970-01-01
    UTC, so that ``start``, the first time in seconds, is the capture's wall-clock anchor. ``how``
    says how the unit was known: ``spacing`` (the chunks' spacing fits the wire only in this unit),
    ``size`` (only this unit puts the first time between 2000 and 2100), ``given`` (--time-unit)
    or ``assumed`` (seconds: the sample could not tell); ``evidence`` says it in words.
    """

    unit: str = SECONDS
    epoch: bool = False
    how: str = ASSUMED
    evidence: str = ""
    start: float | None = None

    @property
    def exponent(self) -> int:
        return EXPONENTS[self.unit]

    @property
    def scale(self) -> float:
        """Seconds per unit."""
        return 10.0 ** -self.exponent

    @property
    def told(self) -> bool:
        """Whether the content told the unit (rather than an option, or the default)."""
        return self.how in (SPACING, SIZE)

    def describe(self) -> str:
        """``times in milliseconds since the epoch``."""
        return f"times in {NAMES[self.unit]}" + (" since the epoch" if self.epoch else "")

    @property
    def said(self) -> bool:
        """Whether a reader says this reading on stderr: any but plain seconds since the capture began
        (our own captures' times), epoch seconds too, and a unit other than seconds assumed."""
        return (self.told or self.how == ASSUMED) and (self.unit != SECONDS or self.epoch)

    def how_known(self) -> str:
        """``told by the content`` or ``assumed: ...``, for the line that says the reading."""
        if self.told:
            return "told by the content"
        return self.evidence if self.evidence.startswith("assumed") else f"assumed: {self.evidence}"


def seconds(text: str, unit: str = SECONDS) -> float:
    """A time written as ``text`` in ``unit``, in seconds: shifted as a decimal, so ``500.794`` ms is
    exactly the float ``0.500794`` s is (a capture reads the same whatever unit it was written in)."""
    exp = EXPONENTS[unit]
    if not exp:
        return float(text)
    try:
        return float(Decimal(text).scaleb(-exp))
    except InvalidOperation:
        return float(text)  # float() takes spellings Decimal does not ("infinity" aside, none in practice)


def resolution(text: str) -> float:
    """The step of the last digit of a time written as ``text`` (``0.000123`` -> 1e-6, ``500`` -> 1),
    in its own unit; 0 when it has none (nan, inf)."""
    try:
        exp = Decimal(text).as_tuple().exponent
    except InvalidOperation:
        return 0.0
    return 10.0 ** exp if isinstance(exp, int) else 0.0


def problem(t: float) -> str | None:
    """Why ``t`` (seconds, from the capture start or the epoch) cannot be a capture time, or None."""
    if not math.isfinite(t):
        return "is not a finite number"
    if t < 0:
        return "is negative"
    if t > EPOCH_MAX:
        return "is after the year 2100"
    return None


def epoch_unit(first: float, now: float | None = None) -> str | None:
    """The unit in which ``first`` falls between 2000 and 2100, and no more than a day after ``now`` (the
    wall clock, seconds since the epoch, when known), as a time since the epoch, or None."""
    for unit in EXPONENTS:
        if _is_epoch(first, unit, now):
            return unit
    return None


def given(unit: str, first: float | None = None, now: float | None = None) -> TimeUnit:
    """The unit an option names (``--time-unit``); ``first``, the first time as written, says whether
    the times count from the epoch (not when more than a day after ``now``)."""
    epoch = first is not None and _is_epoch(first, unit, now)
    start = None if first is None else first * 10.0 ** -EXPONENTS[unit]
    return TimeUnit(unit, epoch, GIVEN, "given by --time-unit", start)


def _is_epoch(first: float, unit: str, now: float | None = None) -> bool:
    latest = EPOCH_MAX if now is None else min(EPOCH_MAX, now + AHEAD)
    return EPOCH_MIN <= first * 10.0 ** -EXPONENTS[unit] < latest


def _when(t: float) -> str:
    return datetime.fromtimestamp(t, UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


@dataclass(frozen=True)
class _Fit:
    """How a capture's spacing reads in one unit: closely following pairs at the best rate, impossible ones."""

    pairs: int
    close: int = 0
    lengths: int = 0
    rate: int | None = None
    overlaps: int = 0

    seams: int = 0
    seam_share: float = 0.0  # of the span between the first and last time, in gaps longer than SEAM_GAP
    near: int = 0      # pairs that could follow each other back to back at some rate, one length or more
    median: float = 0.0  # the median spacing, seconds

    @property
    def backs(self) -> bool:
        return (self.close >= MIN_CLOSE and self.lengths >= 2 and self.close >= MIN_CLOSE_SHARE * self.pairs
                and self.overlaps <= MAX_OVERLAP_SHARE * self.pairs)

    @property
    def possible(self) -> bool:
        """Whether the wire allows this reading, sparse traffic too: next to no neighbours starting before
        the previous one could have ended at any rate of table 4.7 (jitter aside), and not most of the
        capture's span in gaps a time segment long (every poll a segment of its own)."""
        return self.overlaps <= MAX_SPARSE_OVERLAP * self.pairs and self.seam_share <= MAX_SEAM_SHARE

    def against(self) -> str:
        """Why the reading is not possible, in words."""
        if self.overlaps > MAX_SPARSE_OVERLAP * self.pairs:
            return f"{self.overlaps} of {self.pairs} chunks would start before the previous one ended"
        return (f"{self.seams} of {self.pairs} chunks would come more than {SEAM_GAP:g} s after the previous one "
                f"({self.seam_share:.0%} of the span)")


def _fit(pairs: list[tuple[int, int, float]], scale: float, step: float, rates: tuple[int, ...]) -> _Fit:
    """``pairs`` are (bytes before, bytes after, raw spacing); ``step`` is the times' resolution in seconds."""
    fastest = byte_time(max(rates))
    overlaps = sum(1 for n1, n2, d in pairs
                   if d * scale + step < (1 - OVERLAP_TOLERANCE) * min(n1, n2) * fastest)
    far = [d for _, _, d in pairs if d * scale > SEAM_GAP]  # each a time segment of its own to the decoder
    span = sum(d for _, _, d in pairs)
    seams, seam_share = len(far), (sum(far) / span if span > 0 else 0.0)
    slowest = byte_time(min(rates))
    reach = max(CLOSE_GAP, CLOSE_BYTES * slowest) + step
    near = sum(1 for n1, n2, d in pairs if d * scale <= max(n1, n2) * slowest + reach)
    median = sorted(d for _, _, d in pairs)[len(pairs) // 2] * scale if pairs else 0.0
    best = _Fit(len(pairs), overlaps=overlaps, seams=seams, seam_share=seam_share, near=near, median=median)
    for rate in rates:
        bt = byte_time(rate)
        slack = max(CLOSE_GAP, CLOSE_BYTES * bt) + step
        # Stamped at the first byte, a chunk starts n byte times after the previous one did (n of the
        # previous chunk); stamped at arrival, it ends n byte times (n of its own) after the previous end.
        for side in (0, 1):
            close = 0
            lengths: set[int] = set()
            for n1, n2, d0 in pairs:
                n, d = (n2 if side else n1), d0 * scale
                gap = d - n * bt
                if -(OVERLAP_TOLERANCE * n * bt + step) <= gap <= slack:
                    close += 1
                    lengths.add(n)
            if close > best.close and len(lengths) >= 2:
                best = _Fit(len(pairs), close, len(lengths), rate, overlaps, seams, seam_share, near, median)
    return best


def detect_unit(chunks: Iterable[tuple[bytes, float | None]], *, step: float = 0.0,
                rates: Iterable[int] = BAUD_RATES, now: float | None = None) -> TimeUnit:
    """The unit of a sample of timed chunks ``(bytes, t)``, ``t`` as written (any unit).

    At the right unit, chunks that follow each other closely (a reply after its request, frames on a
    busy bus) are about n byte times apart at one rate of table 4.7, for chunks of several lengths,
    and few chunks start before the previous one could have ended; read 1000 times too fine, nearly
    all of them would, and read 1000 times too coarse none follows closely. When exactly one unit
    fits so, it is the unit. Else a first time that only one unit puts between 2000 and 2100, and no
    more than a day after ``now`` (the caller's wall clock, seconds since the epoch), names it (a
    wall-clock stamp), unless the spacing makes that reading impossible. Else, sparse traffic too
    is checked against the wire: a unit in which most chunks would overlap the one before at every
    rate, or come a time segment (SEAM_GAP) after it, is not the unit; when one unit is left, it is
    the unit (microseconds since boot, 3456789012.5 then 20000 more a poll). Else seconds are assumed
    (or, when seconds are ruled out, the coarsest unit left). ``step`` is the times' resolution as
    written (1 for whole numbers), so rounding is not taken for a gap or an overlap.
    """
    timed = [(len(d), t) for d, t in chunks if d and t is not None and math.isfinite(t) and t >= 0]
    if not timed:
        return TimeUnit(evidence="no times to tell the unit by: seconds assumed")
    first = timed[0][1]
    rates = tuple(rates)
    # Equal stamps (a coarse clock) and a clock that goes back say nothing about the unit.
    pairs = [(n1, n2, t2 - t1) for (n1, t1), (n2, t2) in zip(timed, timed[1:]) if t2 > t1]
    fits: dict[str, _Fit] = {}   # units the close spacing can speak for
    wire: dict[str, _Fit] = {}   # every unit that keeps the capture before 2100, sparse traffic too
    if len(pairs) >= MIN_PAIRS:
        for unit, exp in EXPONENTS.items():
            scale = 10.0 ** -exp
            # A unit that puts the capture after 2100 is not its unit; one in which the times are
            # written too coarsely to show a frame (whole seconds) has nothing to say of close spacing.
            if first * scale <= EPOCH_MAX:
                wire[unit] = f = _fit(pairs, scale, step * scale, rates)
                if step * scale <= MAX_STEP:
                    fits[unit] = f
    backed = [u for u, f in fits.items() if f.backs]
    by_size = epoch_unit(first, now)
    if by_size is not None and by_size in wire and wire[by_size].overlaps > MAX_OVERLAP_SHARE * len(pairs):
        by_size = None  # a wall-clock reading the wire rules out (a logger's arrival stamps bunch a little)
    left = [u for u, f in wire.items() if f.possible]
    if len(backed) == 1:
        unit, how = backed[0], SPACING
        f = fits[unit]
        evidence = (f"read in {NAMES[unit]}, {f.close} of {f.pairs} chunks follow the previous one as closely as "
                    f"{f.rate} bit/s allows")
        finer = UNITS.index(unit) + 1
        if finer < len(UNITS) and UNITS[finer] in fits:
            g = fits[UNITS[finer]]
            evidence += f"; read in {NAMES[UNITS[finer]]}, {g.overlaps} would start before the previous one ended"
    elif by_size is not None:
        unit, how = by_size, SIZE
        evidence = f"its first time, {_when(first * 10.0 ** -EXPONENTS[by_size])}, read in {NAMES[by_size]}"
        if backed:
            evidence += f" (the spacing fits {' and '.join(NAMES[u] for u in backed)} too)"
        elif len(pairs) < MIN_PAIRS:
            evidence += f" ({len(pairs)} spacings: too few to check closely)"
    elif not backed and (sparse := _sparse(wire, left)) is not None:
        unit, how, evidence = sparse
    else:
        why = (f"{len(pairs)} spacings: too few to tell" if len(pairs) < MIN_PAIRS else
               "the spacing fits no unit alone" if not backed else
               f"the spacing fits {' and '.join(NAMES[u] for u in backed)}")
        if first > EPOCH_MAX:
            why += " (read in seconds, the first time is after 2100)"
        return TimeUnit(evidence=f"{why}: seconds assumed{_ahead(first, now)}", start=first)
    scale = 10.0 ** -EXPONENTS[unit]
    return TimeUnit(unit, _is_epoch(first, unit, now), how, evidence + _ahead(first, now), first * scale)


def _ahead(first: float, now: float | None) -> str:
    """What the wall clock ruled out, in words ("" when nothing)."""
    unit = epoch_unit(first)
    if unit is None or epoch_unit(first, now) is not None:
        return ""
    return (f"; not {NAMES[unit]} since the epoch: {_when(first * 10.0 ** -EXPONENTS[unit])} is more than a day "
            "after now")


POLL_PERIOD = 0.010  # a controller's usual loop, for the last guess between units the wire allows


def _sparse(wire: dict[str, _Fit], left: list[str]) -> tuple[str, str, str] | None:
    """The unit sparse traffic's spacing tells (unit, how, evidence), or None to assume seconds.

    Only the units the wire allows are left (_Fit.possible); seconds among several are assumed. With
    seconds ruled out, the unit with the most neighbours close enough to follow each other on a slow line
    tells it (a reply after its request); failing that, the one that puts the median spacing nearest
    POLL_PERIOD is assumed."""
    if not wire or not left or (len(left) > 1 and SECONDS in left):
        return None  # seconds, as ever, unless the wire rules them out
    ruled = "; ".join(f"read in {NAMES[u]}, {f.against()}" for u, f in wire.items() if u not in left)
    if len(left) == 1:
        return left[0], SPACING, f"read in {NAMES[left[0]]}, the wire allows the spacing; {ruled}"
    nears = sorted(left, key=lambda u: wire[u].near, reverse=True)
    if wire[nears[0]].near > wire[nears[1]].near:
        u = nears[0]
        evidence = (f"read in {NAMES[u]}, {wire[u].near} of {wire[u].pairs} chunks follow the previous one as "
                    f"closely as a line of table 4.7 allows; read in {NAMES[nears[1]]}, {wire[nears[1]].near}")
        return u, SPACING, evidence + (f"; {ruled}" if ruled else "")
    u = min(left, key=lambda u: abs(math.log(max(wire[u].median, 1e-12) / POLL_PERIOD)))
    return u, ASSUMED, (f"assumed: read in {NAMES[u]}, chunks come {wire[u].median * 1e3:g} ms apart (a controller's "
                        f"loop), where the wire allows {' and '.join(NAMES[v] for v in left)}; {ruled}")
