"""A finding's typed parameters: its message made from a template and values, the measured ones with their units.

A rule that says "ID 3 at 61.5 degC, 0.080 ms after its request" gives the template and the values; the
message is rendered from them, and so is the finding's key: the same template with every value measured
in this recording (a time, a latency, a register's value, a stream offset) written ``*``. The key is what
a lint baseline fingerprints (rs30x_sniff.lint.baseline), so a latency that moves by 10 us, or a float's
last digits, never make a known finding new; what names the behaviour (servo IDs, register names, the
rule's own words) stays in it.
"""

from __future__ import annotations

import functools
import math
import string
from dataclasses import dataclass
from typing import Any
from collections.abc import Mapping

# Units a measured value may carry besides a register's own (deg, degC, mA, ...):
DURATION = "s"      # a span of time in seconds, written in ms as every report writes latencies (0.080 ms)
TIME = "time"       # a point in the capture's time, in seconds (written with six decimals and "s")
OFFSET = "offset"   # a position in the byte stream (written bare)
MASK = "*"          # what a measured value is in a key
MISSING = "?"       # what a value the record does not carry reads


@dataclass(frozen=True, slots=True)
class Measured:
    """A value this recording measured, in ``unit`` ("" for a bare count or a value with no unit): written with
    its unit and no float noise in the message, ``*`` in the key."""

    value: Any
    unit: str = ""

    def number(self) -> tuple[Any, str]:
        """The value as it is written, and the unit written after it (a duration in ms)."""
        v = self.value
        if self.unit == DURATION and _is_number(v):
            return v * 1e3, "ms"
        if self.unit == TIME and _is_number(v):
            return v, "s"
        if self.unit == OFFSET:
            return v, ""
        return v, self.unit

    def render(self, spec: str = "", unit_follows: bool = False) -> str:
        """The value (in ``spec``'s format when one is given and fits), then its unit unless the message
        writes it right after the field itself (``unit_follows``)."""
        v, unit = self.number()
        text = _plain(v, self.unit) if not spec else _formatted(v, spec)
        if not unit or unit_follows or not _is_number(v):
            return text
        return f"{text} {unit}"

    def __str__(self) -> str:
        return self.render()


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _plain(v: Any, unit: str) -> str:
    """A number without float noise: ms to three decimals (the reports' microsecond), a time to six, other
    floats to six decimals at most, trailing zeros dropped (a register's scale leaves 12.300000000000001)."""
    if isinstance(v, bool) or not _is_number(v):
        return str(v)
    if isinstance(v, int):
        return str(v)
    if not math.isfinite(v):
        return str(v)
    if unit == DURATION:
        return f"{v:.3f}"
    if unit == TIME:
        return f"{v:.6f}"
    # A register's step is 0.1 or 0.01 (its scale): six decimals lose nothing, and never an exponent.
    shown = f"{v:.6f}".rstrip("0").rstrip(".")
    return "0" if shown in ("-0", "") else shown


def _formatted(v: Any, spec: str) -> str:
    try:
        return format(v, spec)
    except (TypeError, ValueError):
        return str(v)


class Message(str):
    """A finding's message: the text, the parameters it was made from, and its key (the text with each
    measured value written ``*``). It is a str, so every report takes it as any message."""

    key: str
    params: Mapping[str, Any]

    def __new__(cls, text: str, key: str | None = None, params: Mapping[str, Any] | None = None) -> Message:
        self = super().__new__(cls, text)
        self.key = text if key is None else key
        self.params = dict(params or {})
        return self

    def __reduce__(self) -> tuple:  # lint -j sends findings between processes
        return (Message, (str(self), self.key, self.params))

    def prefixed(self, words: str) -> Message:
        """The same message after ``words`` (words of no measurement)."""
        return Message(words + self, words + self.key, self.params)


def said(template: str, params: Mapping[str, Any], missing: str = MISSING) -> Message:
    """``template`` (``str.format`` fields by name, with an optional conversion and format spec) filled from
    ``params``: a :class:`Measured` value with its unit, any other value as it is; a field with no value (or
    None) reads ``missing``. A value its format spec does not fit is written plainly."""
    parts = _parsed(template)
    text: list[str] = []
    key: list[str] = []
    for i, (literal, field, spec, conv) in enumerate(parts):
        text.append(literal)
        key.append(literal)
        if field is None:
            continue
        v = params.get(field)
        if v is None:
            text.append(missing)
            key.append(missing)
            continue
        if isinstance(v, Measured):
            after = parts[i + 1][0] if i + 1 < len(parts) else ""
            unit = v.number()[1]
            follows = bool(unit) and after.lstrip().startswith(unit)
            text.append(v.render(spec or "", follows) if conv is None else _converted(v.value, conv))
            key.append(MASK)
            continue
        shown = _formatted(_converted(v, conv) if conv else v, spec or "")
        text.append(shown)
        key.append(shown)
    return Message("".join(text), "".join(key), params)


def said_as(template: str, params: Mapping[str, Any], shown: Mapping[str, str]) -> Message:
    """:func:`said`, but the fields named in ``shown`` are written as given there (a count in words, "once" or
    "2 chunks"; a span in seconds): the key still masks each one whose value is :class:`Measured`, and the
    parameters keep the typed values."""
    return Message(str(said(template, {**params, **shown})), said(template, params).key, params)


def said_keyed(text_template: str, key_template: str, params: Mapping[str, Any]) -> Message:
    """The message ``text_template`` says, with the key of ``key_template``: for a figure that only a timed
    capture gives (B003's gap, B009's latency), left out of the key so that the finding stays the same one
    whether the capture was timed or not."""
    return Message(said(text_template, params), said(key_template, params).key, params)


@functools.lru_cache(maxsize=1024)
def _parsed(template: str) -> tuple:
    # A rule that can fire on every frame says the same few templates: parse each once.
    return tuple(string.Formatter().parse(template))


def _converted(v: Any, conv: str) -> str:
    return repr(v) if conv == "r" else ascii(v) if conv == "a" else str(v)


def key_of(message: str) -> str | None:
    """The key of a message made from typed parameters; None for a plain text."""
    return message.key if isinstance(message, Message) else None
