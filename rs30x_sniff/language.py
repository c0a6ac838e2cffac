"""The words every little language shares: durations and their units, ID ranges, comparison operators."""

# One grammar for options, filters, checks and thresholds (issue 33 §2): `50ms`, `10min` and `2h` mean the same
# in `--reply-timeout`, `latency>50ms`, an [[expect]] check and a [regress] threshold. A bare number is seconds
# wherever a duration is expected. `m` used to mean minutes in `--pre` and `--keep`: it still does for one
# release, with a note, since `5m` reads as 5 ms to some and 5 minutes to others.

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable

# Seconds per unit, in any case (`MS` is `ms`); `us` and `µs` are one unit.
TIME_UNITS: dict[str, float] = {
    "ns": 1e-9, "us": 1e-6, "µs": 1e-6, "ms": 1e-3, "s": 1.0, "sec": 1.0,
    "min": 60.0, "h": 3600.0, "d": 86400.0,
}
DEPRECATED_TIME_UNITS: dict[str, tuple[float, str]] = {"m": (60.0, "min")}
TIME_UNITS_SAID = "ns, us, ms, s, min, h, d"

_DURATION = re.compile(r"\s*([-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?)\s*([a-zA-Zµ]*)\s*")
ID_MIN, ID_MAX = 0, 255  # a byte on the wire; a servo's own ID is 1-127 (table 4.6 No. 4), 0 and 255 are special


class LanguageError(ValueError):
    """A duration, ID range or operator that does not parse; its text is one line for the user."""


# Notes about old spellings, said once per process (the caller prints them: this module prints nothing).
deprecation_notes: list[str] = []


def note(text: str) -> None:
    """Keep ``text`` among the deprecation notes (once): for the modules that read an old spelling."""
    if text not in deprecation_notes:
        deprecation_notes.append(text)


def unit_scale(unit: str) -> float | None:
    """Seconds per ``unit`` (``ms`` -> 0.001), None if it is not a time unit."""
    unit = unit.lower()
    scale = TIME_UNITS.get(unit)
    if scale is None and unit in DEPRECATED_TIME_UNITS:
        scale, instead = DEPRECATED_TIME_UNITS[unit]
        note(f"the unit {unit!r} is read as {instead!r} (minutes); write {instead!r}: {unit!r} will be refused in "
              "the next release")
    return scale


def split_number(text: str) -> tuple[float, str] | None:
    """``"50ms"`` -> ``(50.0, "ms")``; ``"2"`` -> ``(2.0, "")``; None if it is not a number with a word after."""
    m = _DURATION.fullmatch(text)
    if m is None:
        return None
    return float(m.group(1)), m.group(2)


def parse_duration(text: str, *, what: str = "", allow_zero: bool = False) -> float:
    """Seconds of ``50ms``, ``1.5s``, ``10min``, ``2h``, ``1d`` or a bare number of seconds; finite and positive
    (or zero, where ``allow_zero``). Raises :class:`LanguageError` naming ``what`` (an option or a term)."""
    where = f"{what} {text}".strip()
    got = split_number(str(text))
    scale = None if got is None else (1.0 if got[1] == "" else unit_scale(got[1]))
    if got is None or scale is None:
        raise LanguageError(f"{where}: expected a duration such as 50ms, 1.5s, 10min or 2h (units: {TIME_UNITS_SAID})")
    seconds = got[0] * scale
    if not math.isfinite(seconds) or seconds < 0 or (seconds == 0 and not allow_zero):
        raise LanguageError(f"{where}: must be a finite, {'non-negative' if allow_zero else 'positive'} duration")
    return seconds


def say_duration(seconds: float) -> str:
    """The shortest exact spelling of ``seconds`` in the grammar's units (``90`` -> ``1.5min``, ``0.05`` ->
    ``50ms``)."""
    for unit in ("d", "h", "min", "s", "ms", "us", "ns"):
        size = TIME_UNITS[unit]
        if seconds >= size:
            n = seconds / size
            if math.isclose(n, round(n, 6), rel_tol=0, abs_tol=1e-9):
                return f"{round(n, 6):.15g}{unit}"
    return f"{seconds:.15g}s"


def parse_id_range(text: str, *, low: int = ID_MIN, high: int = ID_MAX) -> tuple[int, ...]:
    """The IDs of ``1-6,9,0x10`` (inclusive ranges, decimal or 0x hex), sorted; :class:`LanguageError` if not."""
    wanted: set[int] = set()
    for part in str(text).split(","):
        part = part.strip()
        lo, sep, hi = part.partition("-")
        try:
            a = int(lo.strip(), 0)
            b = int(hi.strip(), 0) if sep else a
        except ValueError:
            raise LanguageError(f"{part!r} is not an ID or a range like 1-6") from None
        if not (low <= a <= high and low <= b <= high):
            raise LanguageError(f"IDs run from {low} to {high}")
        if a > b:
            raise LanguageError(f"range {part} runs backwards")
        wanted.update(range(a, b + 1))
    return tuple(sorted(wanted))


# Comparison operators: `=` and `==` are one operator everywhere (filters said `=`, checks `==`).
OPERATORS: dict[str, Callable[[float, float], bool]] = {
    ">=": operator.ge, "<=": operator.le, "!=": operator.ne, "==": operator.eq, "=": operator.eq,
    ">": operator.gt, "<": operator.lt,
}
OPERATOR_SPELLING = {"=": "=="}  # how a report writes an operator given either way


def operator_of(text: str) -> Callable[[float, float], bool]:
    """The comparison of ``>``, ``>=``, ``<``, ``<=``, ``=``/``==`` or ``!=``."""
    try:
        return OPERATORS[text]
    except KeyError:
        raise LanguageError(f"unknown comparison {text!r} (one of {', '.join(OPERATORS)})") from None
