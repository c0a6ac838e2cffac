"""Two captures' figures side by side, and the ``[regress]`` thresholds they are held to (``rs30x-sniff diff``).

Pure functions of plain data: :func:`compare` takes the figures ``info --format json`` writes for two
captures (``CaptureStats.as_dict()`` with ``linted``) and gives a :class:`Comparison`: every figure before and
after, the findings by rule (new, gone, changed), and the thresholds crossed. :func:`parse_thresholds` reads a
configuration's ``[regress]`` table. Nothing here reads a capture or a file.

A figure one capture cannot give (no timestamps: no latency, no bus load, no poll rate; not linted: no
findings) is absent, with the reason, on its own side; a change needs both sides, so a threshold on it is
listed as not checked, never as crossed nor as passed. A threshold checked on nothing at all (every row it
applies to absent, or no row) is in ``Comparison.blind``: ``diff --fail-on-regress`` fails on it as "not
checkable", as a figure check (``[[expect]]``) that cannot be measured does.

Thresholds, one per figure of the figure table (sinks/figures.py: the names, scopes and units of the figure
checks; ``[regress]`` in rs30x-sniff.toml, ``[tool.rs30x-sniff.regress]`` in pyproject):

- ``"+20%"``: AFTER may be at most 20 % above BEFORE (a rise from 0 crosses any percentage);
- ``"-20%"``: AFTER may be at most 20 % below BEFORE (``poll_hz``: the servo is polled less often);
- ``"+0"``, ``"+2"``: AFTER may be at most that much above BEFORE, in the figure's unit (a latency in ms, a bus
  load in percentage points), or in another unit of its kind (``"+200us"``, ``"+0.2 ms"``);
- a number, or a value without a sign: the way the figure gets worse (up, but down for ``poll_hz`` and a
  register's minimum; a figure with no worse way needs a sign). ``new_findings = 0``: no rule may have more
  findings after than before.

A threshold on a figure of the bus and the servos holds the bus and each servo in both captures. The names of
the last release (``missing_replies_total``, ``servo_latency_p95``, ``present_temperature_min``, a bus load as
a fraction) are read for one release, with a note (language.deprecation_notes).
"""

from __future__ import annotations

import math
import re
from difflib import get_close_matches
from dataclasses import dataclass, field, replace
from typing import Any
from collections.abc import Mapping

from .language import LanguageError, note, parse_id_range
from .sinks.figures import (A_RANGE, A_RETURN, BUS, CHANGE, DOWN, FIGURES, LINTED, NEITHER, OLD_THRESHOLD_NAMES, RULE,
                            SERVO, TIMES_LATENCY, TIMES_LOAD, TIMES_POLLS, UP, Capture, Figure, dimension, unit_of)

UNSOLICITED_RULE = FIGURES["unsolicited_replies"].rules[0]  # unsolicited-return: the linter counts them
COUNT = "count"  # the unit a count is shown with in diff's JSON


class ThresholdError(ValueError):
    """A bad ``[regress]`` entry: the message names the file and the key."""


@dataclass(frozen=True)
class Threshold:
    """How far a figure may move the way it gets worse: ``percent`` of BEFORE, or ``amount`` in its unit; held
    on the rows of ``scopes`` (the figure's, or the one an old name held)."""

    figure: str
    direction: int                  # UP or DOWN
    percent: float | None = None
    amount: float | None = None
    text: str = ""                  # as written in the configuration
    scopes: tuple[str, ...] = ()    # () : every scope of the figure
    ids: tuple[int, ...] | None = None  # the servos it holds (None: every one)

    def holds(self, scope: str, servo: str | None) -> bool:
        """Whether a row of ``scope`` (and ``servo``, its ID as text) is held to this threshold."""
        if scope not in (self.scopes or FIGURES[self.figure].scopes):
            return False
        return self.ids is None or servo is None or (servo.isdigit() and int(servo) in self.ids)

    def crossed(self, before: float, after: float) -> bool:
        if self.percent is not None:
            if self.direction == UP:
                limit = before * (1 + self.percent / 100)
                return after > limit + 1e-12 * abs(limit)
            limit = before * (1 - self.percent / 100)
            return after < limit - 1e-12 * abs(limit)
        move = (after - before) * self.direction
        return move > (self.amount or 0.0) + 1e-12 * max(abs(before), abs(after), 1.0)


_VALUE = re.compile(r"^\s*([+-]?)\s*(\d+(?:\.\d*)?|\.\d+)\s*(%|[A-Za-zµ/]+)?\s*$")


def figure_named(key: str, where: str) -> tuple[Figure, tuple[str, ...]]:
    """The figure ``key`` names and the scopes it holds (() : all of the figure's); an old name of the last
    release is read with a note; an unknown one is a :class:`ThresholdError`."""
    name = key.replace("-", "_") if "(" not in key else key
    old = OLD_THRESHOLD_NAMES.get(name)
    if old is not None:
        new, scope = old
        shown = f'"{new}"' if "(" in new else new  # a TOML key with parentheses is quoted
        held = FOR_BUS if scope == BUS else FOR_EACH
        note(f"{where}: regress.{key} is now {shown} = {{ limit = ..., for = \"{held}\" }} ({new} alone holds the "
             f"bus and each servo): the old name will be refused in the next release")
        return FIGURES[new], (scope,)
    fig = FIGURES.get(name)
    if fig is None:
        close = get_close_matches(name, [*FIGURES, *OLD_THRESHOLD_NAMES], n=1)
        hint = f"; did you mean {close[0]}?" if close else ""
        raise ThresholdError(f"{where}: regress.{key}: unknown figure{hint} (known: {', '.join(FIGURES)})")
    return fig, ()


def _amount(fig: Figure, number: float, unit: str | None, label: str, where: str, key: str) -> float:
    """An absolute threshold's ``number`` (in ``unit``, None: the figure's own) in the figure's unit."""
    if unit is None:
        if fig.unit == "%" and 0 < number < 1:  # the last release's bus load was a fraction of 1
            note(f"{where}: regress.{key}: {number:g} is read as a fraction ({number * 100:g} percentage points); a "
                 f"bus load's threshold is in percentage points now: write {number * 100:g}")
            return number * 100.0
        return number
    if fig.unit is None:
        raise ThresholdError(f"{label}: {fig.name} is a count: give a percentage or a number without a unit")
    if unit == fig.unit:
        return number
    if unit_of(unit) is None or dimension(unit) != dimension(fig.unit):
        raise ThresholdError(f"{label}: {fig.name} is in {fig.unit}: {unit!r} does not fit (give a percentage, a "
                             f"number in {fig.unit}, or one with a unit of its kind)")
    a, b = unit_of(unit), unit_of(fig.unit)
    assert a is not None and b is not None
    return number * a[1] / b[1]


FOR_BUS, FOR_EACH = "bus", "each"


def _scoped(fig: Figure, key: str, value: Mapping[str, Any], where: str) -> tuple[Any, tuple[str, ...], Any]:
    """``{ limit = "+20%", for = "each" }``: the limit, and the scopes and IDs ``for`` holds (as a check's
    ``for``: "each", "id:1-6"; and "bus", the whole bus alone)."""
    label = f"{where}: regress.{key}"
    unknown = [k for k in value if k not in ("limit", "for")]
    if unknown or "limit" not in value:
        raise ThresholdError(f"{label}: expected {{ limit = \"+20%\", for = \"each\" }} (keys: limit, for)")
    said = value.get("for", None)
    if said is None:
        return value["limit"], (), None
    if not isinstance(said, str):
        raise ThresholdError(f"{label}.for = {said!r}: expected \"bus\", \"each\" or \"id:1-6\"")
    said = said.strip()
    if said == FOR_BUS:
        scopes: tuple[str, ...] = (BUS,)
        ids = None
    elif said == FOR_EACH or said.startswith("id:"):
        scopes = (SERVO,)
        try:
            ids = None if said == FOR_EACH else parse_id_range(said[3:])
        except LanguageError as e:
            raise ThresholdError(f"{label}.for = {said!r}: {e}") from None
    else:
        raise ThresholdError(f"{label}.for = {said!r}: expected \"bus\", \"each\" or \"id:1-6\"")
    if scopes[0] not in fig.scopes:
        raise ThresholdError(f"{label}.for = {said!r}: {fig.name} is no figure of "
                             f"{'the whole bus' if scopes == (BUS,) else 'each servo'}")
    return value["limit"], scopes, ids


def parse_threshold(key: str, value: Any, where: str) -> Threshold:
    """One ``[regress]`` entry, checked; ``where`` names the file (and table) in the error's one line. A table
    ``{ limit = "+20%", for = "each" }`` holds the figure where ``for`` says."""
    fig, scopes = figure_named(key, where)
    ids = None
    if isinstance(value, Mapping):
        value, scopes, ids = _scoped(fig, key, value, where)
    label = f"{where}: regress.{key} = {value!r}"
    t = _limit(fig, key, value, where, label)
    return replace(t, scopes=scopes or t.scopes, ids=ids)


def _limit(fig: Figure, key: str, value: Any, where: str, label: str) -> Threshold:
    name = fig.name
    scopes: tuple[str, ...] = ()
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ThresholdError(f"{label}: expected a number or a text such as \"+20%\" or \"+0\"")
    if isinstance(value, (int, float)):
        if not math.isfinite(value):
            raise ThresholdError(f"{label}: must be a finite number")
        sign, number, unit = ("-" if value < 0 else ""), abs(float(value)), None
    else:
        m = _VALUE.match(value)
        if m is None:
            raise ThresholdError(f"{label}: expected a signed amount such as \"+20%\", \"-10%\", \"+0\" or "
                                 f"\"+0.2 ms\"")
        sign, number, unit = m.group(1), float(m.group(2)), m.group(3)
    if not math.isfinite(number):
        raise ThresholdError(f"{label}: must be a finite number")
    direction = {"+": UP, "-": DOWN}.get(sign, fig.worse)
    if CHANGE in fig.scopes:
        if direction != UP or unit is not None:
            raise ThresholdError(f"{label}: {name} is a count of the change: give the most it may be (a whole "
                                 f"number, e.g. 0)")
        return Threshold(name, UP, amount=number, text=str(value), scopes=scopes)
    if direction == NEITHER:
        raise ThresholdError(f"{label}: {name} gets neither better nor worse by itself: give a sign (+ or -)")
    if unit == "%":
        return Threshold(name, direction, percent=number, text=str(value), scopes=scopes)
    amount = _amount(fig, number, unit, label, where, key)
    text = str(value) if amount == number or unit is not None else f"{sign}{amount:g}"
    return Threshold(name, direction, amount=amount, text=text, scopes=scopes)


def parse_thresholds(table: Any, where: str) -> dict[str, Threshold]:
    """The ``[regress]`` table of a configuration (``where``: its file and table, for messages)."""
    if not isinstance(table, Mapping):
        raise ThresholdError(f"{where}: regress: expected a table of FIGURE = THRESHOLD")
    out: dict[str, Threshold] = {}
    for key, value in table.items():
        t = parse_threshold(str(key), value, where)
        if t.figure in out:
            raise ThresholdError(f"{where}: regress.{key}: {t.figure} is given twice")
        out[t.figure] = t
    return out


# ---- the figures of one capture ---------------------------------------------------------------------
@dataclass(frozen=True)
class Value:
    """A figure of one capture: its value, or None with the reason it cannot be given."""

    value: float | None
    absent: str | None = None
    unit: str = ""


def _timing_reason(d: Mapping[str, Any], short: str) -> str:
    if d.get("timing_unsupported"):
        return str(d["timing_unsupported"])
    if not d.get("timed"):
        return "no timestamps"
    return short


def _findings_counted(d: Mapping[str, Any]) -> str | None:
    """None when the capture was linted, else why its findings are absent."""
    return None if d.get("linted", True) else "not linted (--no-lint)"


def _unsolicited_counted(d: Mapping[str, Any]) -> str | None:
    why = _findings_counted(d)
    if why is None and not d.get("unsolicited_counted", True):
        why = f"rule {UNSOLICITED_RULE} (unsolicited-return) not selected"
    return why


def capture_of(d: Mapping[str, Any]) -> Capture:
    """One capture's ``info`` dict (with ``linted`` and ``unsolicited_counted``) as the figure table reads it."""
    if not d.get("linted", True):
        return Capture(d, None)
    return Capture(d, frozenset({UNSOLICITED_RULE} if d.get("unsolicited_counted", True) else ()))


# Why a figure is absent, in diff's words, by what it needs (Figure.needs).
def _absent(d: Mapping[str, Any], fig: Figure, sid: int | None) -> str:
    needs = fig.needs
    if needs == TIMES_LATENCY:
        lat = (d.get("latency_s") or {}) if sid is None else (((d.get("servos") or {}).get(str(sid)) or {})
                                                              .get("latency_s") or {})
        return lat.get("absent") or _timing_reason(d, "no reply with a latency" if sid is None else
                                                   "no reply of it with a latency")
    if needs == TIMES_LOAD:
        return _timing_reason(d, "shorter than a one-second window" if fig.name == "bus_load_peak" else
                              "an instant: no duration")
    if needs == TIMES_POLLS:
        return _timing_reason(d, "fewer than two reads in one time segment")
    if needs == RULE:
        return _unsolicited_counted(d) or ""
    if needs == LINTED:
        return _findings_counted(d) or ""
    if needs == A_RETURN:
        return "no return: its status flags are unknown"
    if needs == A_RANGE:
        return "not seen"
    return ""


def _value(d: Mapping[str, Any], cap: Capture, fig: Figure, sid: int | None) -> Value:
    assert fig.read is not None
    v = fig.read(cap, sid)
    return Value(v, None if v is not None else _absent(d, fig, sid), fig.unit or COUNT)


def bus_values(d: Mapping[str, Any]) -> dict[str, Value]:
    """The bus figures of one capture's ``info`` dict, in the figure table's order."""
    cap = capture_of(d)
    return {f.name: _value(d, cap, f, None) for f in FIGURES.values() if BUS in f.scopes}


def servo_values(d: Mapping[str, Any]) -> dict[str, dict[str, Value]]:
    """Each servo's figures (by ID as text) of one capture's ``info`` dict."""
    servos, health = d.get("servos") or {}, d.get("health") or {}
    cap = capture_of(d)
    per_servo = [f for f in FIGURES.values() if SERVO in f.scopes]
    return {sid: {f.name: _value(d, cap, f, int(sid)) for f in per_servo}
            for sid in sorted(set(servos) | set(health), key=_id_order)}


def _id_order(sid: str) -> tuple[int, str]:
    return (int(sid), "") if str(sid).isdigit() else (1 << 30, str(sid))


# ---- the comparison ---------------------------------------------------------------------------------
@dataclass
class Change:
    """One figure before and after (for one servo, or the bus)."""

    figure: str
    servo: str | None
    before: Value
    after: Value

    @property
    def unit(self) -> str:
        return self.after.unit or self.before.unit

    @property
    def absent(self) -> str | None:
        """Why the two cannot be compared (None: both are known)."""
        if self.before.value is None and self.after.value is None and self.before.absent == self.after.absent:
            return f"{self.before.absent} (both)"
        if self.before.value is None:
            return f"BEFORE: {self.before.absent}"
        if self.after.value is None:
            return f"AFTER: {self.after.absent}"
        return None

    @property
    def delta(self) -> float | None:
        if self.absent is not None:
            return None
        return self.after.value - self.before.value  # type: ignore[operator]

    @property
    def percent(self) -> float | None:
        """The change in percent of BEFORE (None when absent or BEFORE is 0)."""
        d = self.delta
        if d is None or not self.before.value:
            return None
        return 100.0 * d / abs(self.before.value)

    @property
    def trend(self) -> str | None:
        """"worse", "better" or "same" (None: not comparable, or a figure with no worse way)."""
        d = self.delta
        if d is None:
            return None
        if d == 0:
            return "same"
        fig = FIGURES.get(self.figure)
        if fig is None or not fig.ranked or fig.worse == NEITHER:
            return None  # a register's range moved, or a count of traffic: no way of it is worse in itself
        return "worse" if d * fig.worse > 0 else "better"

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"figure": self.figure, "unit": self.unit, "before": self.before.value,
                               "after": self.after.value, "delta": self.delta, "percent": self.percent,
                               "trend": self.trend}
        if self.absent is not None:
            out["absent"] = self.absent
        return out


@dataclass
class Crossing:
    """A threshold crossed: which figure, which servo, before -> after, the threshold."""

    change: Change
    threshold: Threshold

    def as_dict(self) -> dict[str, Any]:
        return {"figure": self.change.figure, "servo": self.change.servo, "before": self.change.before.value,
                "after": self.change.after.value, "threshold": self.threshold.text, "text": self.describe()}

    def describe(self) -> str:
        c = self.change
        where = "bus" if c.servo is None else f"servo {c.servo}"
        return (f"{c.figure} ({where}): {show(c.before.value, c.unit)} -> {show(c.after.value, c.unit)}, "
                f"{change_text(c)}, threshold {self.threshold.text}")


@dataclass
class Unchecked:
    """A threshold that could not be checked on a figure, and why (never a pass, never a crossing)."""

    figure: str
    servo: str | None
    threshold: str
    reason: str

    def as_dict(self) -> dict[str, Any]:
        return {"figure": self.figure, "servo": self.servo, "threshold": self.threshold, "reason": self.reason}

    def describe(self) -> str:
        where = "bus" if self.servo is None else f"servo {self.servo}"
        return f"{self.figure} ({where}), threshold {self.threshold}: {self.reason}"


@dataclass
class FindingsDiff:
    """Findings by rule (``CODE name`` -> count): new, gone, changed, the same; or absent with the reason."""

    new: dict[str, int] = field(default_factory=dict)
    gone: dict[str, int] = field(default_factory=dict)
    changed: dict[str, tuple[int, int]] = field(default_factory=dict)
    same: dict[str, int] = field(default_factory=dict)
    absent: str | None = None

    @property
    def new_findings(self) -> int:
        return sum(self.new.values()) + sum(max(0, a - b) for b, a in self.changed.values())

    def rows(self) -> list[tuple[str, str, int, int]]:
        """(status, rule, before, after) for each rule: the new, then the gone, the changed and the same."""
        return [*(("new", r, 0, n) for r, n in self.new.items()), *(("gone", r, n, 0) for r, n in self.gone.items()),
                *(("changed", r, b, a) for r, (b, a) in self.changed.items()),
                *(("same", r, n, n) for r, n in self.same.items())]

    def as_dict(self) -> dict[str, Any]:
        if self.absent is not None:
            return {"absent": self.absent}
        return {"new": self.new, "gone": self.gone,
                "changed": {k: {"before": b, "after": a} for k, (b, a) in self.changed.items()},
                "same": self.same, "new_findings": self.new_findings}


def diff_findings(before: Mapping[str, Any], after: Mapping[str, Any]) -> FindingsDiff:
    why_b, why_a = _findings_counted(before), _findings_counted(after)
    if why_b or why_a:
        return FindingsDiff(absent=f"BEFORE: {why_b}" if why_b else f"AFTER: {why_a}")
    b, a = dict(before.get("findings_by_rule") or {}), dict(after.get("findings_by_rule") or {})
    out = FindingsDiff()
    for rule in sorted(set(b) | set(a)):
        nb, na = b.get(rule, 0), a.get(rule, 0)
        if not nb:
            out.new[rule] = na
        elif not na:
            out.gone[rule] = nb
        elif nb != na:
            out.changed[rule] = (nb, na)
        else:
            out.same[rule] = na
    return out


@dataclass
class Comparison:
    before: Mapping[str, Any]
    after: Mapping[str, Any]
    bus: list[Change]
    servos: dict[str, list[Change]]
    only_before: list[str]
    only_after: list[str]
    findings: FindingsDiff
    changes: list[Change]           # new_findings, new_rules, servos_gone
    thresholds: dict[str, Threshold]
    crossings: list[Crossing]
    unchecked: list[Unchecked]
    blind: list[str] = field(default_factory=list)  # thresholds checked on nothing: every row unchecked

    @property
    def regressed(self) -> bool:
        return bool(self.crossings)

    def as_dict(self) -> dict[str, Any]:
        def side(d: Mapping[str, Any]) -> dict[str, Any]:
            return {"input": d.get("input"), "duration_s": d.get("duration_s"), "timed": d.get("timed"),
                    "linted": d.get("linted", True), "bytes": d.get("bytes"), "baud": d.get("baud")}

        return {"before": side(self.before), "after": side(self.after),
                "bus": [c.as_dict() for c in self.bus],
                "servos": {sid: [c.as_dict() for c in rows] for sid, rows in self.servos.items()},
                "servos_only_before": self.only_before, "servos_only_after": self.only_after,
                "findings": self.findings.as_dict(),
                "changes": [c.as_dict() for c in self.changes],
                "thresholds": {k: t.text for k, t in self.thresholds.items()},
                "regressions": [c.as_dict() for c in self.crossings],
                "unchecked": [u.as_dict() for u in self.unchecked],
                "not_checkable": list(self.blind)}


def _seen(rows: list[Change]) -> list[Change]:
    """``rows`` without the registers neither capture showed: a range never seen is no figure of the bus or servo."""
    return [c for c in rows if not (FIGURES[c.figure].needs == A_RANGE and c.before.value is None
                                    and c.after.value is None)]


def compare(before: Mapping[str, Any], after: Mapping[str, Any],
            thresholds: Mapping[str, Threshold] | None = None) -> Comparison:
    """Two captures' ``info`` figures side by side, held to ``thresholds`` (by figure name)."""
    thresholds = dict(thresholds or {})
    vb, va = bus_values(before), bus_values(after)
    bus = _seen([Change(name, None, vb[name], va[name]) for name in vb])  # the figure table's order
    sb, sa = servo_values(before), servo_values(after)
    servos: dict[str, list[Change]] = {}
    for sid in sorted(set(sb) & set(sa), key=_id_order):
        servos[sid] = _seen([Change(n, sid, sb[sid][n], sa[sid][n]) for n in sb[sid]])
    only_before = [s for s in sb if s not in sa]
    only_after = [s for s in sa if s not in sb]
    findings = diff_findings(before, after)
    zero = Value(0, None, COUNT)
    changes = [Change("servos_gone", None, zero, Value(len(only_before), None, COUNT))]
    if findings.absent is None:
        changes.append(Change("new_findings", None, zero, Value(findings.new_findings, None, COUNT)))
        changes.append(Change("new_rules", None, zero, Value(len(findings.new), None, COUNT)))
    else:
        for name in ("new_findings", "new_rules"):
            changes.append(Change(name, None, zero, Value(None, findings.absent, COUNT)))
    crossings: list[Crossing] = []
    unchecked: list[Unchecked] = []
    rows = [*((BUS, c) for c in bus), *((CHANGE, c) for c in changes),
            *((SERVO, c) for cs in servos.values() for c in cs)]
    blind: list[str] = []
    for name, t in thresholds.items():
        held = t.scopes or FIGURES[t.figure].scopes
        matched = [r for scope, r in rows if r.figure == t.figure and t.holds(scope, r.servo)]
        if not matched:  # never a silent pass: say that there was nothing to hold to it
            why = "no servo in both captures has it" if held == (SERVO,) else "neither capture gives it"
            unchecked.append(Unchecked(name, None, t.text, why))
        checked = False
        for c in matched:
            if c.absent is not None:
                unchecked.append(Unchecked(name, c.servo, t.text, c.absent))
                continue
            checked = True
            if t.crossed(c.before.value, c.after.value):  # type: ignore[arg-type]
                crossings.append(Crossing(c, t))
        if not checked:  # a gate that could not be run: never a pass (diff --fail-on-regress exits 1)
            blind.append(name)
    return Comparison(before, after, bus, servos, only_before, only_after, findings, changes, thresholds,
                      crossings, unchecked, blind)


# ---- words ------------------------------------------------------------------------------------------
def show(v: float | None, unit: str) -> str:
    """A figure's value in words, in its unit (a count without one)."""
    if v is None:
        return "-"
    if unit in ("ms", "s"):
        return f"{v:.3f} {unit}"
    if unit in ("%", "Hz"):
        return f"{v:.1f} {unit}"
    if unit == COUNT:
        return f"{v:g}"
    return f"{v:g} {unit}".rstrip()


def change_text(c: Change) -> str:
    """``+0.100 ms (+88.5 %)``, ``same``, or "" when there is no change to tell."""
    d = c.delta
    if d is None:
        return ""
    if d == 0:
        return "same"
    unit = c.unit
    if unit in ("ms", "s"):
        amount = f"{d:+.3f} {unit}"
    elif unit == "%":
        amount = f"{d:+.1f} points"
    elif unit == "Hz":
        amount = f"{d:+.1f} Hz"
    else:
        amount = f"{d:+g} {unit if unit != COUNT else ''}".rstrip()
    pct = c.percent
    return amount if pct is None else f"{amount} ({pct:+.1f} %)"
