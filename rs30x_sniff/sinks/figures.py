"""The figure table: each figure's name, scope, unit, worse way and reading from ``CaptureStats.as_dict()``.

One vocabulary (issue 33): a figure check (``[[expect]]``, expect.py), a ``[regress]`` threshold and ``diff``'s
tables (compare.py) and docs/checks.md all name a figure from :data:`FIGURES`, with the same scope and unit.
A figure is read here, from ``info --format json``'s data; why it is absent is each report's to say, in its
own words, from what the figure needs (:attr:`Figure.needs`).

A new figure: add a row to :func:`_table` with its reading, regenerate docs/checks.md's table
(``python -m rs30x_sniff.sinks.figures``); checks, thresholds and diff take it from there.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from ..language import TIME_UNITS_SAID, unit_scale
from ..protocol.memmap import ModelError, default_registry
from ..protocol.wire import RETURN_FLAG_BITS
from .health import PRESENT, WRITTEN

BUS, SERVO, CHANGE = "bus", "servo", "change"  # CHANGE: a count of the difference of two captures (diff only)
UP, DOWN, NEITHER = 1, -1, 0

# What a figure's absence depends on; each report words it (expect.py, compare.py).
TIMES_POLLS, TIMES_LOAD, TIMES_LATENCY = "polls", "load", "latency"
LINTED, RULE, A_RETURN, A_RANGE = "linted", "rule", "a return", "a range"

# The units of the figures other than times (times: language.TIME_UNITS): unit -> (dimension, size in the
# dimension's first unit). A number in a check or a threshold may carry any unit of its figure's dimension.
UNITS: dict[str, tuple[str, float]] = {
    "Hz": ("rate", 1.0), "kHz": ("rate", 1e3),
    "%": ("share", 1.0),
    "deg": ("angle", 1.0),
    "deg/s": ("angular speed", 1.0),
    "mA": ("current", 1.0), "A": ("current", 1e3),
    "degC": ("temperature", 1.0),
    "V": ("voltage", 1.0), "mV": ("voltage", 1e-3),
}
TIME = "time"


def unit_of(unit: str | None) -> tuple[str, float] | None:
    """(dimension, size) of ``unit``: a time in seconds (language.py's units), else :data:`UNITS`' entry;
    None for no unit or an unknown one."""
    if not unit:
        return None
    if unit in UNITS:
        return UNITS[unit]
    scale = unit_scale(unit)
    return None if scale is None else (TIME, scale)


def dimension(unit: str | None) -> str | None:
    """The dimension of ``unit`` (None: a count); a unit of no known dimension is one of its own."""
    if not unit:
        return None
    got = unit_of(unit)
    return got[0] if got is not None else f"in {unit}"


def units_said(dimension: str) -> str:
    """The units of ``dimension`` as a message lists them."""
    if dimension == TIME:
        return TIME_UNITS_SAID
    return ", ".join(u for u, (d, _) in UNITS.items() if d == dimension)


def convert(value: float, unit: str | None, to: str | None) -> float:
    """``value`` in ``unit`` expressed in ``to`` (of one dimension; unchanged where either is no unit)."""
    a, b = unit_of(unit), unit_of(to)
    if a is None or b is None or unit == to:
        return value
    return value * a[1] / b[1]


# ---- reading ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Capture:
    """One capture's figures as ``info --format json`` gives them, and which lint rules ran (None: not
    linted): what a figure is read from."""

    info: Mapping[str, Any]
    rules: frozenset[str] | None = None

    def servo(self, sid: int) -> Mapping[str, Any]:
        return (self.info.get("servos") or {}).get(str(sid)) or {}

    def health(self, sid: int) -> Mapping[str, Any]:
        return (self.info.get("health") or {}).get(str(sid)) or {}

    def ids(self, sid: int | None) -> list[str]:
        """``sid`` as the key of the servo tables, or every servo's (None: the bus)."""
        return [str(sid)] if sid is not None else list(self.info.get("servos") or {})

    def ran(self, code: str | None = None) -> bool:
        """Whether the capture was linted (and rule ``code`` ran)."""
        return self.rules is not None and (code is None or code in self.rules)


Reader = Callable[[Capture, "int | None"], "float | None"]


@dataclass(frozen=True)
class Figure:
    """A figure: where it applies, its unit (None: a count), the way it gets worse, what it is, where
    ``info --format json`` holds it, and how it is read (a value in ``unit``, or None: absent)."""

    name: str
    scopes: tuple[str, ...]
    unit: str | None
    worse: int                  # UP, DOWN or NEITHER (a threshold then needs a sign)
    doc: str
    source: str
    read: Reader | None = None  # None: a CHANGE figure, counted by diff
    needs: str = ""             # what its absence depends on (TIMES_*, LINTED, RULE, A_RETURN, A_RANGE)
    rules: tuple[str, ...] = ()  # the lint rules whose findings say what this figure counts
    ranked: bool = True         # whether a change is worse or better (a register's range: neither)

    @property
    def checkable(self) -> bool:
        """Whether one capture gives it (a figure check can name it)."""
        return CHANGE not in self.scopes


def _count(key: str) -> Reader:
    def read(cap: Capture, sid: int | None) -> float:
        return float(sum((cap.info.get("servos") or {}).get(i, {}).get(key, 0) for i in cap.ids(sid)))
    return read


def _info(key: str) -> Reader:
    return lambda cap, sid: float(cap.info.get(key) or 0)


def _poll_hz(cap: Capture, sid: int | None) -> float | None:
    v = cap.servo(sid).get("poll_rate_hz") if sid is not None else None
    return None if v is None else float(v)


def _load(peak: bool) -> Reader:
    def read(cap: Capture, sid: int | None) -> float | None:
        v = (cap.info.get("bus_load_peak") or {}).get("load") if peak else cap.info.get("bus_load")
        return None if v is None else float(v) * 100.0  # a share of the time, in percent
    return read


def latency_of(cap: Capture, sid: int | None) -> Mapping[str, Any]:
    """The latency table a figure of ``sid`` (None: the bus) is read from."""
    return (cap.info.get("latency_s") or {}) if sid is None else (cap.servo(sid).get("latency_s") or {})


def _latency(which: str) -> Reader:
    def read(cap: Capture, sid: int | None) -> float | None:
        lat = latency_of(cap, sid)
        v = lat.get(which)
        # Some replies have no latency: a percentile over the others is not the capture's (true or absent).
        if not cap.info.get("timed") or lat.get("absent") or v is None:
            return None
        return float(v) * 1e3
    return read


def _rule_count(code: str) -> Reader:
    def read(cap: Capture, sid: int | None) -> float | None:
        if not cap.ran(code):
            return None
        if sid is not None:
            return float((cap.health(sid).get("findings") or {}).get(code, 0))
        by_rule = cap.info.get("findings_by_rule") or {}
        return float(sum(n for k, n in by_rule.items() if k.split(" ")[0] == code))
    return read


def _findings(cap: Capture, sid: int | None) -> float | None:
    if not cap.ran():
        return None
    if sid is not None:
        return float(sum((cap.health(sid).get("findings") or {}).values()))
    return float(sum((cap.info.get("findings") or {}).values()))


def _severity(level: str) -> Reader:
    return lambda cap, sid: float((cap.info.get("findings") or {}).get(level, 0)) if cap.ran() else None


def _flag(name: str) -> Reader:
    def read(cap: Capture, sid: int | None) -> float | None:
        ids = cap.ids(sid)
        servos = cap.info.get("servos") or {}
        if not any(servos.get(i, {}).get("returns", 0) for i in ids):
            return None  # no return: its status flags are unknown
        health = cap.info.get("health") or {}
        return float(sum(health.get(i, {}).get("flags", {}).get(name, {}).get("count", 0) for i in ids))
    return read


def register_unit(name: str) -> str | None:
    """The unit the bundled default model gives register ``name`` (None: none, or no such register)."""
    try:
        return default_registry().default.register(name).unit or None
    except (KeyError, ModelError):
        return None


def range_seen(cap: Capture, sid: int | None, register: str) -> list[Mapping[str, Any]]:
    """The ranges of ``register`` the servo (None: every servo) showed, with their units."""
    health = cap.info.get("health") or {}
    rows = [health[str(sid)]] if sid is not None and str(sid) in health else [] if sid is not None \
        else list(health.values())
    return [h["registers"][register] for h in rows if register in (h.get("registers") or {})]


def _range(func: str, register: str) -> Reader:
    unit = register_unit(register)

    def read(cap: Capture, sid: int | None) -> float | None:
        got = range_seen(cap, sid, register)
        if not got:
            return None
        have = got[0].get("unit") or None
        if unit is not None and have != unit and dimension(have) != dimension(unit):
            return None  # the servo's map gives it in another dimension: no figure of this unit
        vals = [r[func] for r in got]
        return convert(float(min(vals) if func == "min" else max(vals)), have, unit)
    return read


def range_name(func: str, register: str) -> str:
    return f"{func}({register})"


REGISTERS = (*PRESENT, *WRITTEN)  # the registers whose range info's health table holds
FUNCTIONS = ("min", "max")


def _table() -> list[Figure]:
    both = (SERVO, BUS)
    out = [
        Figure("latency_p50", both, "ms", UP, "median reply latency (a servo's: over its replies)",
               "`servos.ID.latency_s.p50`, `latency_s.p50`", _latency("p50"), TIMES_LATENCY),
        Figure("latency_p95", both, "ms", UP, "95th percentile of the reply latency",
               "`servos.ID.latency_s.p95`, `latency_s.p95`", _latency("p95"), TIMES_LATENCY),
        Figure("latency_max", both, "ms", UP, "longest reply latency",
               "`servos.ID.latency_s.max`, `latency_s.max`", _latency("max"), TIMES_LATENCY),
        Figure("bus_load", (BUS,), "%", UP, "share of the capture's time the line was busy", "`bus_load`",
               _load(False), TIMES_LOAD),
        Figure("bus_load_peak", (BUS,), "%", UP, "the busiest one-second window's load", "`bus_load_peak.load`",
               _load(True), TIMES_LOAD),
        Figure("missing_replies", both, None, UP, "requests that asked for a reply and got none",
               "`servos.ID.missing`", _count("missing"), rules=("B002",)),
        Figure("unsolicited_replies", both, None, UP, "replies no request asked for: rule B003's findings",
               "`health.ID.findings.B003`, `findings_by_rule`", _rule_count("B003"), RULE, ("B003",)),
        Figure("bad_checksums", (BUS,), None, UP, "packets whose checksum is wrong", "`bad_checksums`",
               _info("bad_checksums"), rules=("F001",)),
        Figure("garbage_bytes", (BUS,), None, UP, "bytes that are no packet", "`garbage_bytes`",
               _info("garbage_bytes"), rules=("F002",)),
        Figure("errors", (BUS,), None, UP, "lint findings of severity error", "`findings.error`",
               _severity("error"), LINTED),
        Figure("warnings", (BUS,), None, UP, "lint findings of severity warning", "`findings.warning`",
               _severity("warning"), LINTED),
        Figure("findings", both, None, UP, "lint findings (a servo's: those naming it)",
               "`health.ID.findings`, `findings`", _findings, LINTED),
        Figure("poll_hz", (SERVO,), "Hz", DOWN,
               "requests asking the servo for a reply, per second, within the time segments (info's poll rate)",
               "`servos.ID.poll_rate_hz`", _poll_hz, TIMES_POLLS),
        Figure("requests", both, None, NEITHER, "short packets addressed to the servo (bus: to any servo)",
               "`servos.ID.requests`", _count("requests")),
        Figure("reads", both, None, NEITHER, "requests that asked for a reply", "`servos.ID.reads`", _count("reads")),
        Figure("long_writes", both, None, NEITHER, "records for the servo in long packets", "`servos.ID.long_writes`",
               _count("long_writes")),
        Figure("returns", both, None, NEITHER, "return packets heard from the servo", "`servos.ID.returns`",
               _count("returns")),
        Figure("acks", both, None, NEITHER, "ACKs heard from the servo", "`servos.ID.acks`", _count("acks")),
        Figure("nacks", both, None, UP, "NACKs heard from the servo", "`servos.ID.nacks`", _count("nacks")),
    ]
    status_rules = {"temperature_limit": "S001", "temperature_alarm": "S002", "flash_write_error": "S003",
                    "received_packet_error": "S004"}  # rules/status.py: one rule per flag of table 4.4
    for flag in RETURN_FLAG_BITS.values():
        out.append(Figure(flag, both, None, UP, f"returns carrying the {flag.replace('_', '-')} status flag "
                          "(table 4.4)", "`health.ID.flags`", _flag(flag), A_RETURN,
                          (status_rules[flag],) if flag in status_rules else ()))
    out += [
        Figure("duration", (BUS,), "s", NEITHER,
               "first to last byte, added up over the time segments (line time without timestamps)", "`duration_s`",
               _info("duration_s")),
        Figure("bytes", (BUS,), None, NEITHER, "bytes of the capture", "`bytes`", _info("bytes")),
        Figure("packets", (BUS,), None, NEITHER, "packets (records that are not garbage)", "`packets`",
               _info("packets")),
        Figure("servos", (BUS,), None, NEITHER, "servo IDs the traffic names", "`servos`",
               lambda cap, sid: float(len(cap.info.get("servos") or {}))),
        Figure("segments", (BUS,), None, NEITHER,
               "time segments (the clock restarts or resumes between them, F010)", "`segments`", _info("segments")),
    ]
    for reg in REGISTERS:
        said = "the host's writes set" if reg in WRITTEN else "the returns showed"
        for func, worse, word in (("max", UP, "highest"), ("min", DOWN, "lowest")):
            out.append(Figure(range_name(func, reg), both, register_unit(reg), worse,
                              f"the {word} {reg} {said}", "`health.ID.registers`", _range(func, reg), A_RANGE,
                              ranked=False))
    out += [
        Figure("new_findings", (CHANGE,), None, UP, "findings AFTER has beyond BEFORE's count, summed over rules",
               "`findings_by_rule` of both"),
        Figure("new_rules", (CHANGE,), None, UP, "rules with findings AFTER and none BEFORE",
               "`findings_by_rule` of both"),
        Figure("servos_gone", (CHANGE,), None, UP, "servos seen BEFORE and not AFTER", "`servos` of both"),
    ]
    return out


TABLE: tuple[Figure, ...] = tuple(_table())
FIGURES: dict[str, Figure] = {f.name: f for f in TABLE}
assert all(f.read is not None for f in TABLE if f.checkable)


# ---- old spellings -----------------------------------------------------------------------------------------
# A [regress] name of the last release -> (the figure, the one scope it held there). Read for one release, with
# a note (language.deprecation_notes).
OLD_THRESHOLD_NAMES: dict[str, tuple[str, str]] = {
    "missing_replies_total": ("missing_replies", BUS),
    "unsolicited_replies_total": ("unsolicited_replies", BUS),
    **{f"servo_latency_{p}": (f"latency_{p}", SERVO) for p in ("p50", "p95", "max")},
    **{f"{reg}_{func}": (range_name(func, reg), SERVO) for reg in REGISTERS for func in FUNCTIONS},
}


# ---- docs/checks.md ----------------------------------------------------------------------------------------
def doc_table() -> str:
    """The figures as docs/checks.md's markdown table (tests/sinks/test_figures.py holds the file to it)."""
    rows = ["| name | of | unit | worse | what | from (`info --format json`) |", "|---|---|---|---|---|---|"]
    for f in TABLE:
        worse = {UP: "up", DOWN: "down", NEITHER: "-"}[f.worse]
        rows.append(f"| `{f.name}` | {', '.join(f.scopes)} | {f.unit or 'count'} | {worse} | {f.doc} | {f.source} |")
    return "\n".join(rows) + "\n"


if __name__ == "__main__":
    print(doc_table(), end="")
