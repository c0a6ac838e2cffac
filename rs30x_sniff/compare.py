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

Thresholds, one per figure (``[regress]`` in rs30x-sniff.toml, ``[tool.rs30x-sniff.regress]`` in pyproject):

- ``"+20%"``: AFTER may be at most 20 % above BEFORE (a rise from 0 crosses any percentage);
- ``"-20%"``: AFTER may be at most 20 % below BEFORE (``poll_hz``: the servo is polled less often);
- ``"+0"``, ``"+2"``: AFTER may be at most that much above BEFORE, in the figure's unit (times take a unit:
  ``"+0.2 ms"``, ``"+50 us"``; a bus load is a fraction: ``"+0.05"``);
- a number, or a value without a sign: the way the figure gets worse (up, but down for ``poll_hz`` and a
  register's minimum). ``new_findings = 0``: no rule may have more findings after than before.
"""

from __future__ import annotations

import math
import re
from difflib import get_close_matches
from dataclasses import dataclass, field
from typing import Any
from collections.abc import Mapping

from .sinks.health import PRESENT, WRITTEN

UP, DOWN = 1, -1
UNSOLICITED_RULE = "B003"  # unsolicited-return: the linter counts the replies no request asked for

# Units of the figures: how a value is written, and what an absolute threshold may say.
SECONDS, FRACTION, HZ, COUNT, REGISTER = "s", "fraction", "Hz", "count", "register"
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}


@dataclass(frozen=True)
class Figure:
    """A figure that can be compared and given a threshold."""

    name: str
    scope: str      # "bus", "servo" (each servo in both captures) or "change" (a count of the difference)
    unit: str       # SECONDS, FRACTION, HZ, COUNT, or a register's unit
    worse: int      # UP or DOWN: the way the figure gets worse
    doc: str


def _figures() -> dict[str, Figure]:
    out = [
        Figure("latency_p50", "bus", SECONDS, UP, "median reply latency"),
        Figure("latency_p95", "bus", SECONDS, UP, "95th percentile of the reply latency"),
        Figure("latency_max", "bus", SECONDS, UP, "longest reply latency"),
        Figure("bus_load", "bus", FRACTION, UP, "fraction of the capture's time the line was busy"),
        Figure("bus_load_peak", "bus", FRACTION, UP, "load of the busiest second"),
        Figure("missing_replies_total", "bus", COUNT, UP, "requests of every servo whose reply never came"),
        Figure("unsolicited_replies_total", "bus", COUNT, UP, "replies no request asked for (rule B003)"),
        Figure("bad_checksums", "bus", COUNT, UP, "packets with a bad checksum"),
        Figure("garbage_bytes", "bus", COUNT, UP, "bytes outside any packet"),
        Figure("errors", "bus", COUNT, UP, "findings of severity error"),
        Figure("warnings", "bus", COUNT, UP, "findings of severity warning"),
        Figure("poll_hz", "servo", HZ, DOWN, "requests asking this servo for a reply, per second"),
        Figure("servo_latency_p50", "servo", SECONDS, UP, "median latency of this servo's replies"),
        Figure("servo_latency_p95", "servo", SECONDS, UP, "95th percentile of this servo's reply latency"),
        Figure("servo_latency_max", "servo", SECONDS, UP, "longest latency of this servo's replies"),
        Figure("missing_replies", "servo", COUNT, UP, "this servo's requests whose reply never came"),
        Figure("unsolicited_replies", "servo", COUNT, UP, "replies from this ID no request asked for (rule B003)"),
        Figure("nacks", "servo", COUNT, UP, "NACKs from this servo"),
        Figure("new_findings", "change", COUNT, UP, "findings AFTER has beyond BEFORE's count, summed over rules"),
        Figure("new_rules", "change", COUNT, UP, "rules with findings AFTER and none BEFORE"),
        Figure("servos_gone", "change", COUNT, UP, "servos seen BEFORE and not AFTER"),
    ]
    for reg in (*PRESENT, *WRITTEN):  # the register ranges info's health table holds
        out.append(Figure(f"{reg}_max", "servo", REGISTER, UP, f"highest {reg} seen"))
        out.append(Figure(f"{reg}_min", "servo", REGISTER, DOWN, f"lowest {reg} seen"))
    return {f.name: f for f in out}


FIGURES: dict[str, Figure] = _figures()


class ThresholdError(ValueError):
    """A bad ``[regress]`` entry: the message names the file and the key."""


@dataclass(frozen=True)
class Threshold:
    """How far a figure may move the way it gets worse: ``percent`` of BEFORE, or ``amount`` in its unit."""

    figure: str
    direction: int                  # UP or DOWN
    percent: float | None = None
    amount: float | None = None
    text: str = ""                  # as written in the configuration

    def crossed(self, before: float, after: float) -> bool:
        if self.percent is not None:
            if self.direction == UP:
                limit = before * (1 + self.percent / 100)
                return after > limit + 1e-12 * abs(limit)
            limit = before * (1 - self.percent / 100)
            return after < limit - 1e-12 * abs(limit)
        move = (after - before) * self.direction
        return move > (self.amount or 0.0) + 1e-12 * max(abs(before), abs(after), 1.0)


_VALUE = re.compile(r"^\s*([+-]?)\s*(\d+(?:\.\d*)?|\.\d+)\s*(%|s|ms|us|µs)?\s*$")


def parse_threshold(key: str, value: Any, where: str) -> Threshold:
    """One ``[regress]`` entry, checked; ``where`` names the file (and table) in the error's one line."""
    label = f"{where}: regress.{key} = {value!r}"
    name = key.replace("-", "_")
    fig = FIGURES.get(name)
    if fig is None:
        close = get_close_matches(name, FIGURES, n=1)
        hint = f"; did you mean {close[0]}?" if close else ""
        raise ThresholdError(f"{where}: regress.{key}: unknown figure{hint} (known: {', '.join(FIGURES)})")
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
    if fig.scope == "change":
        if direction != UP or unit is not None:
            raise ThresholdError(f"{label}: {name} is a count of the change: give the most it may be (a whole "
                                 f"number, e.g. 0)")
        return Threshold(name, UP, amount=number, text=str(value))
    if unit == "%":
        return Threshold(name, direction, percent=number, text=str(value))
    if fig.unit == SECONDS:
        if unit is None:
            raise ThresholdError(f"{label}: a time needs a unit (s, ms, us), or give a percentage")
        return Threshold(name, direction, amount=number * TIME_UNITS[unit], text=str(value))
    if unit is not None:
        raise ThresholdError(f"{label}: {name} is not a time: give a percentage or a number without a unit")
    return Threshold(name, direction, amount=number, text=str(value))


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


def bus_values(d: Mapping[str, Any]) -> dict[str, Value]:
    """The bus figures of one capture's ``info`` dict."""
    out: dict[str, Value] = {}
    lat = d.get("latency_s") or {}
    for p in ("p50", "p95", "max"):
        v = lat.get(p)
        out[f"latency_{p}"] = Value(v, None if v is not None else
                                    (lat.get("absent") or _timing_reason(d, "no reply with a latency")), SECONDS)
    load = d.get("bus_load")
    out["bus_load"] = Value(load, None if load is not None else _timing_reason(d, "an instant: no duration"),
                            FRACTION)
    peak = d.get("bus_load_peak")
    out["bus_load_peak"] = Value(peak["load"] if peak else None,
                                 None if peak else _timing_reason(d, "shorter than a one-second window"), FRACTION)
    servos = d.get("servos") or {}
    out["missing_replies_total"] = Value(sum(s.get("missing", 0) for s in servos.values()), None, COUNT)
    why = _unsolicited_counted(d)
    out["unsolicited_replies_total"] = Value(None if why else sum(
        h.get("findings", {}).get(UNSOLICITED_RULE, 0) for h in (d.get("health") or {}).values()), why, COUNT)
    out["bad_checksums"] = Value(d.get("bad_checksums", 0), None, COUNT)
    out["garbage_bytes"] = Value(d.get("garbage_bytes", 0), None, COUNT)
    why = _findings_counted(d)
    sev = d.get("findings") or {}
    out["errors"] = Value(None if why else sev.get("error", 0), why, COUNT)
    out["warnings"] = Value(None if why else sev.get("warning", 0), why, COUNT)
    return out


def servo_values(d: Mapping[str, Any]) -> dict[str, dict[str, Value]]:
    """Each servo's figures (by ID as text) of one capture's ``info`` dict."""
    servos, health = d.get("servos") or {}, d.get("health") or {}
    unsolicited_why = _unsolicited_counted(d)
    out: dict[str, dict[str, Value]] = {}
    for sid in sorted(set(servos) | set(health), key=_id_order):
        s, h = servos.get(sid), health.get(sid) or {}
        row: dict[str, Value] = {}
        if s is not None:
            rate = s.get("poll_rate_hz")
            row["poll_hz"] = Value(rate, None if rate is not None else
                                   _timing_reason(d, "fewer than two reads in one time segment"), HZ)
            lat = s.get("latency_s") or {}
            for p in ("p50", "p95", "max"):
                v = lat.get(p)
                row[f"servo_latency_{p}"] = Value(v, None if v is not None else (
                    lat.get("absent") or _timing_reason(d, "no reply of it with a latency")), SECONDS)
            row["missing_replies"] = Value(s.get("missing", 0), None, COUNT)
            row["nacks"] = Value(s.get("nacks", 0), None, COUNT)
        row["unsolicited_replies"] = Value(None if unsolicited_why else
                                           (h.get("findings") or {}).get(UNSOLICITED_RULE, 0), unsolicited_why, COUNT)
        for reg, r in (h.get("registers") or {}).items():
            row[f"{reg}_max"] = Value(r["max"], None, r.get("unit") or "")
            row[f"{reg}_min"] = Value(r["min"], None, r.get("unit") or "")
        out[sid] = row
    return out


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
        if fig is None or fig.unit == REGISTER:
            return None  # a register's range moved: no way of it is worse in itself
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


def compare(before: Mapping[str, Any], after: Mapping[str, Any],
            thresholds: Mapping[str, Threshold] | None = None) -> Comparison:
    """Two captures' ``info`` figures side by side, held to ``thresholds`` (by figure name)."""
    thresholds = dict(thresholds or {})
    vb, va = bus_values(before), bus_values(after)
    bus = [Change(name, None, vb[name], va[name]) for name in vb]
    sb, sa = servo_values(before), servo_values(after)
    servos: dict[str, list[Change]] = {}
    for sid in sorted(set(sb) & set(sa), key=_id_order):
        names = [n for n in FIGURES if n in sb[sid] or n in sa[sid]]
        servos[sid] = [Change(n, sid, sb[sid].get(n, Value(None, "not seen", "")),
                              sa[sid].get(n, Value(None, "not seen", ""))) for n in names]
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
    rows = [*bus, *changes, *(c for cs in servos.values() for c in cs)]
    blind: list[str] = []
    for name, t in thresholds.items():
        matched = [r for r in rows if r.figure == name]
        if not matched:  # never a silent pass: say that there was nothing to hold to it
            scope = FIGURES[name].scope if name in FIGURES else "bus"
            why = "no servo in both captures has it" if scope == "servo" else "neither capture gives it"
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
    """A figure's value in words: ms for times, percent for loads."""
    if v is None:
        return "-"
    if unit == SECONDS:
        return f"{v * 1e3:.3f} ms"
    if unit == FRACTION:
        return f"{v * 100:.1f} %"
    if unit == HZ:
        return f"{v:.1f} Hz"
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
    if unit == SECONDS:
        amount = f"{d * 1e3:+.3f} ms"
    elif unit == FRACTION:
        amount = f"{d * 100:+.1f} points"
    elif unit == HZ:
        amount = f"{d:+.1f} Hz"
    else:
        amount = f"{d:+g} {unit if unit != COUNT else ''}".rstrip()
    pct = c.percent
    return amount if pct is None else f"{amount} ({pct:+.1f} %)"
