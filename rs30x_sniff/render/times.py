"""The times a person reads on a text line (--time-format): since the capture's start, time of day, delta or epoch."""

from __future__ import annotations

import time
from typing import Any, cast
from collections.abc import Callable, Iterable

import numpy as np

from ..protocol.chunks import EPOCH_MIN

RELATIVE, ABSOLUTE, DELTA, EPOCH = "relative", "absolute", "delta", "epoch"
TIME_FORMATS = (RELATIVE, ABSOLUTE, DELTA, EPOCH)
DEFAULT_TIME_FORMAT = RELATIVE

WIDTH = 12                        # a time in seconds: f"{t:12.6f}", as decode has always written it
ABSOLUTE_WIDTH = 26               # 2026-11-27 14:32:05.123456
NO_TIME = f"{'-':>{WIDTH}}"       # an untimed event's time

HELP = ("how text lines show times (decode, record --print, the monitor, info's text): "
        "relative (default): seconds since the capture's start, as the capture's own clock counts them (a file timed "
        "from its start: its own times, the ones lint, info and t: filters use; a port or any wall-clock capture: "
        "from its first byte); one origin for the whole capture, so after a lost port the seconds go on and after a "
        "clock restart (F010) they go back as the clock did; "
        "absolute: local date and time of day, where the capture has wall-clock times (else relative, said once); "
        "delta: seconds since the previous event ('-' where the clock went back); "
        "epoch: seconds since 1970, wall-clock captures only (else relative, said once). "
        "JSON, MCAP and tables always keep the capture's own times")


def time_text(t: float | str | None) -> str:
    """A shown time as a line writes it: a number of seconds, a text already made (absolute, delta), or none."""
    if t is None:
        return NO_TIME
    if type(t) is str:
        return t
    return f"{t:{WIDTH}.6f}"


def wall_text(x: float, decimals: int = 6) -> str:
    """Local date and time of day of ``x`` seconds since 1970, to ``decimals`` places: the fraction is the epoch
    form's own digits, so ``absolute`` and ``epoch`` never disagree on a rounding."""
    s = f"{x:.{decimals}f}"
    whole, _, frac = s.partition(".")
    try:
        if x < 0:
            raise ValueError
        day = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(int(whole)))
    except (OverflowError, OSError, ValueError):
        return s  # no calendar date for it: the number itself, never an invented date
    return f"{day}.{frac}" if decimals else day


class TimeForm:
    """How one capture's times are shown. Told the capture's first timed time (:meth:`start`), it knows
    the origin (0 for a capture timed from its own start, the first byte for wall-clock times) and the
    wall clock (epoch times; ``anchor``: a log's own date for its time 0; else none). ``anchor`` may be a
    callable, asked at :meth:`start` (a reader finds a log's date as it reads)."""

    def __init__(self, mode: str = DEFAULT_TIME_FORMAT, anchor: float | None | Callable[[], float | None] = None,
                 say: Callable[[str], None] | None = None) -> None:
        if mode not in TIME_FORMATS:
            raise ValueError(f"time format {mode!r}: one of {', '.join(TIME_FORMATS)}")
        self.mode = mode
        self.anchor = anchor
        self.say = say                    # told once when the asked form cannot be shown (no wall clock)
        self.first: float | None = None   # the capture's first time
        self.origin: float | None = None  # capture time shown as 0 (relative)
        self.wall: float | None = None    # epoch seconds of capture time 0, where the capture has a wall clock
        self.shown = mode                 # what is shown: ``mode``, or relative where the capture has no wall clock
        self.note: str | None = None      # why, when ``shown`` is not ``mode``

    @property
    def started(self) -> bool:
        return self.origin is not None

    def start(self, t: float) -> None:
        """The capture's first timed time decides the origin and the wall clock (once)."""
        if self.origin is not None:
            return
        self.first = t
        if t > EPOCH_MIN:
            self.origin, self.wall = t, 0.0
        else:
            anchor = self.anchor() if callable(self.anchor) else self.anchor
            self.origin, self.wall = 0.0, anchor
        if self.mode in (ABSOLUTE, EPOCH) and self.wall is None:
            self.shown = RELATIVE
            self.note = (f"--time-format {self.mode}: the capture's times are not wall-clock times (they count "
                         f"from its start): shown as seconds since the start")
            if self.say is not None:
                self.say(self.note)

    def start_with(self, items: Iterable[Any]) -> None:
        """:meth:`start` at the first timed Record or Block of ``items`` (nothing if none is timed yet)."""
        if self.origin is None:
            t = first_time(items)
            if t is not None:
                self.start(t)

    @property
    def numeric(self) -> bool:
        """Shown times are numbers (written ``12.6f``), not texts (absolute, delta)."""
        return self.shown in (RELATIVE, EPOCH)

    @property
    def identity(self) -> bool:
        """Shown times are the capture's own (relative, on a capture timed from its start)."""
        return self.shown == RELATIVE and self.origin == 0.0

    @property
    def width(self) -> int:
        return ABSOLUTE_WIDTH if self.shown == ABSOLUTE else WIDTH

    def value(self, t: float | None, prev: float | None = None) -> float | str | None:
        """The shown time of an event at ``t`` (``prev``: the previous event's, for delta), as :func:`time_text`
        writes it. Call :meth:`start` first."""
        # After start, origin is set, and wall too where absolute or epoch is shown (start falls back to
        # relative without it): casts, not tests, on this per-line path.
        shown = self.shown
        if shown == RELATIVE:
            return None if t is None else t - cast(float, self.origin)
        if shown == EPOCH:
            return None if t is None else cast(float, self.wall) + t
        if shown == ABSOLUTE:
            return NO_TIME_WIDE if t is None else wall_text(cast(float, self.wall) + t)
        return delta_text(t, prev, self.first)

    def values(self, t0: np.ndarray, prev: float | None = None) -> list | None:
        """The shown times of a timed Block's rows (``t0``), as :meth:`value` gives each (``prev``: the time of
        the event before the first row); None where they are the rows' own times."""
        shown = self.shown
        if shown == RELATIVE:
            return None if self.origin == 0.0 else (t0 - self.origin).tolist()
        if shown == EPOCH:
            return (self.wall + t0).tolist()
        if shown == ABSOLUTE:
            wall = self.wall
            return [wall_text(wall + t) for t in t0.tolist()]
        ts = t0.tolist()
        first = self.first
        return [delta_text(t, p, first) for t, p in zip(ts, [prev, *ts[:-1]])]

    def seconds(self, t: float) -> str:
        """A summary's time (info: "at ...", "from ..."), to two places: seconds since the start, the date and
        time of day, or epoch seconds; delta is a line's form, so a summary shows seconds since the start."""
        shown, wall, origin = self.shown, self.wall, self.origin
        if shown == ABSOLUTE or shown == EPOCH:
            assert wall is not None, "start() shows absolute or epoch times only with a wall clock"
            return wall_text(wall + t, 2) if shown == ABSOLUTE else f"{wall + t:.2f} s"
        assert origin is not None, "seconds() is called after start()"
        return f"{t - origin:.2f} s"


NO_TIME_WIDE = f"{'-':>{ABSOLUTE_WIDTH}}"


def delta_text(t: float | None, prev: float | None, first: float | None = None) -> str:
    """Seconds since the previous event (``prev``): 0 for the capture's ``first``; '-' for none (no time, no
    previous event known, or the clock went back: a restart, F010, where no duration is known)."""
    if t is None:
        return NO_TIME
    if prev is None:
        return f"{0.0:{WIDTH}.6f}" if t == first else NO_TIME
    if t < prev:
        return NO_TIME
    return f"{t - prev:{WIDTH}.6f}"


def first_time(items: Iterable[Any]) -> float | None:
    """The time of the first timed Record or Block of ``items`` (a Step, a batch), or None."""
    for x in items:
        t0 = getattr(x, "t0", None)
        if t0 is not None:
            if len(t0):
                return float(t0[0])
            continue
        ev = getattr(x, "event", None)
        if ev is not None and ev.t_start is not None:
            return ev.t_start
    return None


class LineClock:
    """The shown time of each event of a stream, in wire order (a sink's lines): a :class:`TimeForm` and the
    previous event's time, for delta. Every event goes through it, the ones not written too (``--id``,
    ``--filter``), so a delta is to the previous event on the wire."""

    def __init__(self, form: TimeForm) -> None:
        self.form = form
        self.prev: float | None = None

    def record(self, t: float | None) -> float | str | None:
        form = self.form
        if t is not None and form.origin is None:
            form.start(t)
        if form.origin is None:
            return None if t is None else t  # untimed so far: nothing to shift
        v = form.value(t, self.prev)
        if t is not None:
            self.prev = t
        return v

    def block(self, t0: np.ndarray | None) -> list | None:
        """A Block's rows' shown times (None: their own, or untimed)."""
        if t0 is None or not len(t0):
            return None
        form = self.form
        if form.origin is None:
            form.start(float(t0[0]))
        out = form.values(t0, self.prev)
        self.prev = float(t0[-1])
        return out

    def finding(self, t: float | None) -> float | str | None:
        """A late finding's time (it names an earlier record): its time in the form, none in delta."""
        form = self.form
        if t is None or form.origin is None:
            return t
        if form.shown == DELTA:
            return NO_TIME
        return form.value(t)
