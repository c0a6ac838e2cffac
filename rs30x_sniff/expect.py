"""Figure checks (``[[expect]]`` in the configuration): a small expression language over the figures ``info``
computes, checked at the end of input and reported as lint findings (docs/checks.md).

    [[expect]]
    code = "U101"
    name = "legs-polled-fast"
    severity = "error"
    check = "poll_hz >= 5 and missing_replies == 0"
    for = "id:1-6"                  # each of these servos; "each": every servo seen; omitted: the whole bus

Three pure steps: :func:`load_checks` reads the configuration's entries (one line naming the file, the
check, the key and the column on a mistake: :class:`ExpectError`); :func:`evaluate` measures them against
the figures (``CaptureStats.as_dict()``, ``info --format json``'s keys, read as the figure table
sinks/figures.py says) and gives a :class:`Result` per
check and servo: pass, fail (with the measured value) or not checkable (with the reason); :func:`findings`
turns the results that are not passes into lint Findings at the end of input. A hand-written tokenizer and
parser: nothing is ever evaluated as Python.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from difflib import get_close_matches
from typing import Any
from collections.abc import Callable, Collection, Iterable, Mapping

from .language import OPERATOR_SPELLING, OPERATORS, LanguageError, parse_id_range
from .lint.config import ConfigError
from .lint.params import MASK, Message
from .lint.params import Measured as Quantity
from .lint.registry import RULES, SEVERITIES, Finding, Rule
from .sinks import figures as table
from .sinks.figures import (A_RANGE, A_RETURN, BUS, FUNCTIONS, LINTED, REGISTERS, RULE, SERVO, TIMES_LATENCY,
                            TIMES_LOAD, TIMES_POLLS, Capture, Figure, convert, dimension, range_name, range_seen,
                            register_unit, unit_of, units_said)
from .sinks.health import WRITTEN

CODE = re.compile(r"U\d{3}")
NAME = re.compile(r"[a-z][a-z0-9]*(?:-[a-z0-9]+)*")
KEYS = ("code", "name", "severity", "check", "for", "doc", "not_checkable")
PASS, FAIL, NOT_CHECKABLE = "pass", "fail", "not checkable"


class ExpectError(ConfigError):
    """A bad ``[[expect]]`` entry; the message is one line naming the file, the check, the key (and column).
    A ConfigError: the commands report it as any bad configuration value (one line, exit 2)."""


# ---- the figures -------------------------------------------------------------------------------------------
# The names of the language: the figure table's (sinks/figures.py) that one capture gives; a register's range is
# written min(register) / max(register). A measured figure: its value in the figure's unit, or None and why not.
Measured = tuple[float | None, str]
FIGURES: dict[str, Figure] = {f.name: f for f in table.TABLE if f.checkable and f.needs != A_RANGE}
RANGES: dict[str, Figure] = {f.name: f for f in table.TABLE if f.needs == A_RANGE}


# ---- the expression: tokens --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Token:
    kind: str      # "number", "word", "op", "(", ")", "%"
    text: str
    col: int       # 1-based column in the check's text
    spaced: bool   # whitespace before it


_TOKEN = re.compile(r"""
    (?P<number>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)
  | (?P<word>[A-Za-zµ_][A-Za-z0-9µ_]*(?:/[A-Za-z]+)?)
  | (?P<op><=|>=|==|!=|<|>|=)
  | (?P<paren>[()])
  | (?P<percent>%)
""", re.VERBOSE)
COMPARISONS = ("<", "<=", ">", ">=", "==", "!=")  # and "=", read as "==" (language.OPERATORS)
_NEGATED = {"<": ">=", "<=": ">", ">": "<=", ">=": "<", "==": "!=", "!=": "=="}
_FLIPPED = {"<": ">", "<=": ">=", ">": "<", ">=": "<=", "==": "==", "!=": "!="}


class _ParseError(Exception):
    def __init__(self, col: int, text: str) -> None:
        super().__init__(text)
        self.col, self.text = col, text


def tokenize(text: str) -> list[Token]:
    out: list[Token] = []
    i, n = 0, len(text)
    while i < n:
        j = i
        while j < n and text[j].isspace():
            j += 1
        if j == n:
            break
        m = _TOKEN.match(text, j)
        if m is None:
            raise _ParseError(j + 1, f"unexpected {text[j]!r}")
        kind = m.lastgroup or ""
        kind = {"paren": m.group(), "percent": "%"}.get(kind, kind)
        out.append(Token(kind, m.group(), j + 1, j > i or not out))
        i = m.end()
    return out


# ---- the expression: parsed --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Operand:
    """A figure (``name``, or ``func(name)`` over a register) or a number (``value``, in ``unit``)."""

    col: int
    text: str                      # as written, for messages
    name: str | None = None        # a figure's name, or the register of min/max
    func: str | None = None        # "min" / "max"
    value: float | None = None     # a number
    unit: str | None = None        # a number's unit as written; a figure's unit

    @property
    def is_figure(self) -> bool:
        return self.name is not None

    @property
    def figure(self) -> Figure:
        """The figure table's row this operand names (a figure operand only)."""
        return RANGES[range_name(self.func, self.name or "")] if self.func else FIGURES[self.name or ""]


@dataclass(frozen=True)
class Comparison:
    left: Operand                  # always a figure
    op: str
    right: Operand                 # a number, or a figure of the same dimension
    col: int


def _known(unit: str | None) -> bool:
    return unit_of(unit) is not None


def _what(unit: str | None) -> str:
    """How a message names a dimension: 'a time (ns, us, ms, s, min, h, d)', 'a count'."""
    if unit is None:
        return "a count (no unit)"
    if not _known(unit):
        return f"measured in {unit}"
    dim = dimension(unit) or ""
    article = "an" if dim[:1] in "aeiou" else "a"
    return f"{article} {dim} ({units_said(dim)})"


def parse_check(text: str, scope: str) -> list[Comparison]:
    """The comparisons of ``text`` (joined by ``and``), each figure known in ``scope`` (BUS or SERVO) and
    each number's unit fitting its figure; raises _ParseError (with the column) otherwise."""
    toks = tokenize(text)
    pos = 0
    end_col = len(text.rstrip()) + 1

    def peek() -> Token | None:
        return toks[pos] if pos < len(toks) else None

    def take() -> Token:
        nonlocal pos
        t = peek()
        if t is None:
            raise _ParseError(end_col, "the check ends too soon")
        pos += 1
        return t

    def operand() -> Operand:
        nonlocal pos
        t = take()
        if t.kind == "number":
            if not math.isfinite(float(t.text)):  # 1e999: a typo, never a limit
                raise _ParseError(t.col, f"{t.text} is not a finite number")
            nxt = peek()
            if nxt is not None and (nxt.kind == "%" or (nxt.kind == "word" and _known(nxt.text))):
                pos += 1
                return Operand(t.col, f"{t.text} {nxt.text}" if nxt.spaced else t.text + nxt.text,
                               value=float(t.text), unit=nxt.text)
            if nxt is not None and nxt.kind == "word" and not nxt.spaced:
                raise _ParseError(nxt.col, f"unknown unit {nxt.text!r} (units: {', '.join(table.UNITS)}, "
                                           f"{units_said(table.TIME)})")
            return Operand(t.col, t.text, value=float(t.text))
        if t.kind != "word" or t.text == "and":
            raise _ParseError(t.col, f"expected a figure or a number, found {t.text!r}")
        if t.text in FUNCTIONS:
            if peek() is None or peek().kind != "(":  # type: ignore[union-attr]
                raise _ParseError(t.col + len(t.text), f"{t.text} takes a register: {t.text}(present_temperature)")
            take()
            reg = take()
            if reg.kind != "word" or reg.text not in REGISTERS:
                hint = _hint(reg.text, REGISTERS)
                raise _ParseError(reg.col, f"{t.text}() of {reg.text!r}: not a register with a range in info"
                                           f"{hint} (registers: {', '.join(REGISTERS)})")
            close = take()
            if close.kind != ")":
                raise _ParseError(close.col, f"expected ')' after {t.text}({reg.text}")
            return Operand(t.col, f"{t.text}({reg.text})", name=reg.text, func=t.text, unit=register_unit(reg.text))
        fig = FIGURES.get(t.text)
        if fig is None:
            if t.text in REGISTERS:
                raise _ParseError(t.col, f"{t.text} is a register: write max({t.text}) or min({t.text})")
            known = [*FIGURES, *FUNCTIONS]
            raise _ParseError(t.col, f"unknown figure {t.text!r}{_hint(t.text, known)} (see docs/checks.md)")
        if scope not in fig.scopes:
            raise _ParseError(t.col, f"{t.text} is a figure of each servo: give the check for = \"id:...\" "
                                     f"or for = \"each\"" if scope == BUS else
                              f"{t.text} is a figure of the whole bus (not measured per servo): "
                              f"check it without 'for'")
        return Operand(t.col, t.text, name=t.text, unit=fig.unit)

    def fits(num: Operand, fig: Operand) -> None:
        if num.unit is None:
            return  # a bare number is in the figure's own unit
        if fig.unit is None:
            raise _ParseError(num.col, f"{fig.text} is a count: no unit ({num.text})")
        if not _known(num.unit) or not _known(fig.unit):
            if num.unit != fig.unit:
                raise _ParseError(num.col, f"{fig.text} is {_what(fig.unit)}; {num.unit!r} does not fit")
            return
        if dimension(num.unit) != dimension(fig.unit):
            raise _ParseError(num.col, f"{fig.text} is {_what(fig.unit)}; {num.unit!r} is {_what(num.unit)}")

    def comparison() -> Comparison:
        left = operand()
        opt = take()
        if opt.kind != "op":
            if opt.kind == "word" and opt.text in ("or", "not"):
                raise _ParseError(opt.col, f"'{opt.text}' is not part of the language: only 'and' joins comparisons")
            raise _ParseError(opt.col, f"expected a comparison ({' '.join(COMPARISONS)}) after {left.text}, "
                                       f"found {opt.text!r}")
        right = operand()
        op = OPERATOR_SPELLING.get(opt.text, opt.text)  # `=` and `==` are one operator (language.OPERATORS)
        if not left.is_figure and not right.is_figure:
            raise _ParseError(left.col, "compares two numbers: one side must be a figure")
        if not left.is_figure:
            left, right, op = right, left, _FLIPPED[op]
        if right.is_figure:
            if dimension(left.unit) != dimension(right.unit):
                raise _ParseError(right.col, f"{left.text} is {_what(left.unit)}, {right.text} is "
                                             f"{_what(right.unit)}: they cannot be compared")
        else:
            fits(right, left)
        return Comparison(left, op, right, left.col)

    if not toks:
        raise _ParseError(1, "empty check")
    out = [comparison()]
    while pos < len(toks):
        t = take()
        if t.kind == "word" and t.text == "and":
            out.append(comparison())
        elif t.kind == "word" and t.text == "or":
            raise _ParseError(t.col, "'or' is not part of the language: write two checks")
        else:
            raise _ParseError(t.col, f"expected 'and' or the end of the check, found {t.text!r}")
    return out


def _hint(word: str, known: Iterable[str]) -> str:
    close = get_close_matches(word, list(known), n=1)
    return f" (did you mean {close[0]}?)" if close else ""


# ---- the checks --------------------------------------------------------------------------------------------
EACH = "each"


@dataclass(frozen=True)
class Check:
    """One ``[[expect]]`` entry, checked."""

    code: str
    name: str
    severity: str
    text: str                             # the check as written
    comparisons: tuple[Comparison, ...]
    ids: tuple[int, ...] | str | None     # servo IDs; EACH: every servo seen; None: the whole bus
    doc: str = ""
    not_checkable: str = ""               # severity of a not-checkable result ("" : the check's own)
    index: int = 1                        # 1-based place among the [[expect]] entries

    @property
    def unknown_severity(self) -> str:
        return self.not_checkable or self.severity

    @property
    def reads_ranges(self) -> bool:
        """Whether the check reads a register's range (min/max): only then do the stats keep ranges."""
        return any(o.func is not None for c in self.comparisons for o in (c.left, c.right))


def parse_ids(text: str) -> tuple[int, ...] | str:
    """``id:1-6,9`` (the filter language's IDs) or ``each``; raises ValueError with the reason."""
    text = text.strip()
    if text == EACH:
        return EACH
    if not text.startswith("id:"):
        raise ValueError(f"expected id:1-6,9 (the filter language's IDs) or \"each\", found {text!r}")
    try:
        return parse_id_range(text[3:])  # the one ID grammar (language.py), as the filters read it
    except LanguageError as e:
        raise ValueError(str(e)) from None


def load_checks(entries: Any, where: str) -> list[Check]:
    """The ``[[expect]]`` entries of a configuration file (``where``: its name, for messages), checked."""
    if not isinstance(entries, list):
        raise ExpectError(f"{where}: expect: expected [[expect]] tables (an array of tables)")
    out: list[Check] = []
    codes: dict[str, int] = {}
    names: dict[str, int] = {}
    for i, entry in enumerate(entries, 1):
        label = f"{where}: [[expect]] #{i}"
        if not isinstance(entry, Mapping):
            raise ExpectError(f"{label}: expected a table")
        code = entry.get("code")
        if isinstance(code, str):
            label += f" ({code})"
        for raw in entry:
            if raw.replace("-", "_") not in KEYS:
                raise ExpectError(f"{label}: unknown key {raw!r}{_hint(raw, KEYS)} (known: {', '.join(KEYS)})")
        get = {k.replace("-", "_"): v for k, v in entry.items()}

        def text(key: str, required: bool, get: dict = get, label: str = label) -> str:
            v = get.get(key)
            if v is None:
                if required:
                    raise ExpectError(f"{label}: {key}: missing (required)")
                return ""
            if not isinstance(v, str):
                raise ExpectError(f"{label}: {key} = {v!r}: expected a string")
            return v

        code = text("code", True)
        if not CODE.fullmatch(code):
            raise ExpectError(f"{label}: code = {code!r}: expected U and three digits (U101)")
        if code in codes:
            raise ExpectError(f"{label}: code = {code!r}: already the code of [[expect]] #{codes[code]}")
        name = text("name", True)
        if not NAME.fullmatch(name):
            raise ExpectError(f"{label}: name = {name!r}: expected lower-case words joined by '-' (legs-polled-fast)")
        if name in names:
            raise ExpectError(f"{label}: name = {name!r}: already the name of [[expect]] #{names[name]}")
        severity = text("severity", False) or "error"
        unknown = text("not_checkable", False)
        for key, level in (("severity", severity), ("not_checkable", unknown)):
            if level and level not in SEVERITIES:
                raise ExpectError(f"{label}: {key} = {level!r}: expected one of {', '.join(SEVERITIES)}")
        ids: tuple[int, ...] | str | None = None
        if "for" in get:
            try:
                ids = parse_ids(text("for", True))
            except ValueError as e:
                raise ExpectError(f"{label}: for = {get['for']!r}: {e}") from None
        src = text("check", True)
        try:
            comparisons = parse_check(src, BUS if ids is None else SERVO)
        except _ParseError as e:
            raise ExpectError(f"{label}: check = {src!r}: column {e.col}: {e.text}") from None
        codes[code], names[name] = i, i
        out.append(Check(code, name, severity, src, tuple(comparisons), ids, text("doc", False), unknown, i))
    return out


def check_clashes(rules: Iterable[Rule], checks: Iterable[Check], where: str) -> None:
    """One line (an :class:`ExpectError`) when an ``[[expect]]`` takes the code or name of a ``[[rule]]`` of
    the same file, or a built-in rule's name: both become rules of the registry, where each is one."""
    by_code = {r.code: r for r in rules}
    by_name = {r.name: r for r in rules}
    for c in checks:
        label = f"{where}: [[expect]] #{c.index} ({c.code})"
        if c.code in by_code:
            raise ExpectError(f"{label}: code = {c.code!r}: already the code of [[rule]] {c.code} "
                              f"({by_code[c.code].name}): give each its own")
        if c.name in by_name:
            raise ExpectError(f"{label}: name = {c.name!r}: already the name of [[rule]] {by_name[c.name].code}: "
                              f"give each its own")
        taken = RULES.get(c.name)
        if taken is not None and not taken.is_user:
            raise ExpectError(f"{label}: name = {c.name!r}: the built-in rule {taken.code}'s name")


def _checked_at_the_end(lint: Any) -> None:
    """A figure check's rule does nothing in the linter: the check is measured once the figures are in."""


def as_rule(check: Check) -> Rule:
    """``check`` as a rule of the registry (a user rule: code U and three digits), so that rule selection,
    severities, the reports' rule lists and ``rules`` know it; its findings come from :func:`findings`, not
    from the linter (its one kind, "close", does nothing)."""
    scope = "the whole bus" if check.ids is None else "every servo seen" if check.ids == EACH else \
        "IDs " + ", ".join(map(str, check.ids))
    summary = f"Figure check: {check.text} ({scope})."
    doc = (f"## What it does\nChecks `{check.text}` over the capture's figures (those of `info`) for {scope}, "
           f"at the end of input (docs/checks.md). A figure the capture cannot give is reported as not "
           f"checkable, at severity {check.unknown_severity}.\n")
    if check.doc:
        doc += f"\n## Why it matters\n{check.doc}\n"
    return Rule(check.code, check.name, check.severity, summary, doc, ("close",), _checked_at_the_end,
                column="silent")


def matches(check: Check, selector: str) -> bool:
    """Whether a --select/--ignore/--severity selector names ``check``: ALL, its code, a prefix of its code
    (U, U1), or its name, as the built-in rules' selectors do."""
    return selector == "ALL" or check.code.startswith(selector) or selector == check.name


def select_checks(checks: Iterable[Check], select: Iterable[str] | None = None, ignore: Iterable[str] = (),
                  severity: Mapping[str, str] | None = None) -> list[Check]:
    """The checks a lint configuration keeps (``select`` None: every one), with its severities applied
    (``severity``: selector -> level; a not-checkable result follows the new level unless the check sets
    its own ``not_checkable``)."""
    sel = None if select is None else list(select)
    ign = list(ignore)
    out = []
    for c in checks:
        if sel is not None and not any(matches(c, s) for s in sel):
            continue
        if any(matches(c, s) for s in ign):
            continue
        for key, level in (severity or {}).items():
            if matches(c, key) and key != "ALL":
                c = replace(c, severity=level)
        out.append(c)
    return out


# ---- measuring ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Result:
    """One check's outcome for one servo (``id``) or the bus (None)."""

    check: Check
    id: int | None
    status: str           # PASS, FAIL, NOT_CHECKABLE
    message: str


@dataclass
class _Context:
    capture: Capture                 # the figures, and the lint codes that ran (None: not linted)

    @property
    def info(self) -> Mapping[str, Any]:
        return self.capture.info

    def servo_ids(self) -> list[int]:
        return sorted({int(k) for k in self.info.get("servos", {})} | {int(k) for k in self.info.get("health", {})})


NO_TIMES = "the capture has no timestamps"


def _measure(ctx: _Context, op: Operand, sid: int | None) -> Measured:
    """The figure ``op`` of servo ``sid`` (None: the bus), in the figure's unit, or None and why not: read as
    the figure table says (sinks/figures.py), its absence told in the checks' words."""
    fig = op.figure
    assert fig.read is not None  # the language names only the figures one capture gives
    value = fig.read(ctx.capture, sid)
    if value is not None:
        return value, ""
    return None, _WHY_ABSENT[fig.needs](ctx, fig, op, sid)


# Why a figure is absent, by what it needs (Figure.needs); a figure that needs nothing is never absent.
def _why_untimed_polls(ctx: _Context, fig: Figure, op: Operand, sid: int | None) -> str:
    if not ctx.info.get("timed"):
        return NO_TIMES
    reads = ctx.capture.servo(sid).get("reads", 0) if sid is not None else 0
    return f"fewer than two polls of ID {sid} in one time segment ({reads} reads)"


def _why_no_load(ctx: _Context, fig: Figure, op: Operand, sid: int | None) -> str:
    info = ctx.info
    if not info.get("timed"):
        return NO_TIMES
    if info.get("timing_unsupported"):
        return str(info["timing_unsupported"])
    return "the capture is shorter than one second" if fig.name == "bus_load_peak" else "the capture lasts no time"


def _why_no_latency(ctx: _Context, fig: Figure, op: Operand, sid: int | None) -> str:
    lat = table.latency_of(ctx.capture, sid)
    if not ctx.info.get("timed"):
        return NO_TIMES
    if lat.get("absent"):  # some or all replies have no latency: a percentile over the rest is not true
        return str(lat["absent"])
    return "no reply was paired with its request" if sid is None else \
        f"no reply of ID {sid} was paired with its request"


def _why_not_linted(ctx: _Context, fig: Figure, op: Operand, sid: int | None) -> str:
    """Why lint-derived figures cannot be given."""
    if ctx.capture.rules is None:
        return "the capture was not linted"
    missing = [code for code in fig.rules if not ctx.capture.ran(code)]
    return f"rule {missing[0]} did not run (--select/--ignore)" if missing else ""


def _why_no_return(ctx: _Context, fig: Figure, op: Operand, sid: int | None) -> str:
    return (f"ID {sid} sent no return: its status flags are unknown" if sid is not None
            else "no servo sent a return: the status flags are unknown")


def _why_no_range(ctx: _Context, fig: Figure, op: Operand, sid: int | None) -> str:
    name = op.name or ""
    got = range_seen(ctx.capture, sid, name)
    if got:  # seen, in a unit of another dimension
        return f"the memory map gives {name} in {got[0].get('unit') or 'no unit'}"
    if sid is None:
        return f"no servo showed {name}"
    return f"ID {sid} showed no {name} in its {'writes' if name in WRITTEN else 'returns'}"


_WHY_ABSENT = {TIMES_POLLS: _why_untimed_polls, TIMES_LOAD: _why_no_load, TIMES_LATENCY: _why_no_latency,
               LINTED: _why_not_linted, RULE: _why_not_linted, A_RETURN: _why_no_return, A_RANGE: _why_no_range}


def _scaled(value: float, op: Operand, shown: str | None) -> float:
    """``value`` (in ``op``'s unit) in the unit ``shown``."""
    if shown is None or op.unit is None or shown == op.unit:
        return value
    return convert(value, op.unit, shown)


def _fmt(v: float, keeps: Callable[[float], bool] | None = None) -> str:
    """``v`` short, yet with the digits that keep its comparison's outcome (``keeps(shown) -> bool``)."""
    if math.isfinite(v) and v == int(v) and abs(v) < 1e15:
        return str(int(v))
    for digits in range(3, 17):
        s = f"{v:.{digits}g}"
        if keeps is None or keeps(float(s)):
            return s
    return repr(v)


def _compare(ctx: _Context, c: Comparison, sid: int | None) -> tuple[str, Message]:
    """(status, text) of one comparison for servo ``sid`` (None: the bus)."""
    left, why = _measure(ctx, c.left, sid)
    if left is None:
        return NOT_CHECKABLE, Message(f"{c.left.text} not checkable: {why}")
    test = OPERATORS[c.op]
    if c.right.is_figure:
        right, why = _measure(ctx, c.right, sid)
        if right is None:
            return NOT_CHECKABLE, Message(f"{c.right.text} not checkable: {why}")
        limit_text = f"{c.right.text} {_fmt(right)}" + (f" {c.right.unit}" if c.right.unit else "")
        limit_key = f"{c.right.text} {MASK}" + (f" {c.right.unit}" if c.right.unit else "")
        shown = c.left.unit
        if _known(c.right.unit) and _known(shown):
            right = _scaled(right, c.right, shown)
    else:
        assert c.right.value is not None
        right = c.right.value
        shown = c.right.unit                # the unit the check was written in (None: the figure's own)
        if _known(shown) and _known(c.left.unit):
            left = _scaled(left, c.left, shown)
        limit_text = limit_key = c.right.text
    ok = test(left, right)
    op = c.op if ok else _NEGATED[c.op]
    value = _fmt(left, lambda x: test(x, right) == ok)
    unit = f" {shown}" if shown else ""
    # The measured value (and a figure the check compares it with) is no part of the finding's key.
    return (PASS if ok else FAIL), Message(f"{c.left.text} {value}{unit} {op} {limit_text}",
                                           f"{c.left.text} {MASK}{unit} {op} {limit_key}",
                                           {c.left.text: Quantity(left, shown or "")})


def _judge(ctx: _Context, check: Check, sid: int | None) -> Result:
    who = f"ID {sid}: " if sid is not None else ""
    outcomes = [_compare(ctx, c, sid) for c in check.comparisons]
    failed = [t for s, t in outcomes if s == FAIL]
    unknown = [t for s, t in outcomes if s == NOT_CHECKABLE]
    if failed:
        return Result(check, sid, FAIL, _joined(who, failed + unknown))
    if unknown:
        return Result(check, sid, NOT_CHECKABLE, _joined(who, unknown))
    return Result(check, sid, PASS, _joined(who, [t for _, t in outcomes]))


def _joined(who: str, parts: list[Message]) -> Message:
    """One result's message from its comparisons' (``who``: the servo), its key from theirs."""
    params: dict[str, Any] = {}
    for p in parts:
        params.update(p.params)
    return Message(who + "; ".join(parts), who + "; ".join(p.key for p in parts), params)


def evaluate(checks: Iterable[Check], info: Mapping[str, Any], rules: Collection[str] | None = None) -> list[Result]:
    """Each check against ``info`` (``CaptureStats.as_dict()``: ``info --format json``'s figures), per servo
    of its ``for`` (or once for the bus): pass, fail or not checkable. ``rules``: the codes of the lint rules
    that ran (None: the capture was not linted; the figures drawn from findings are then not checkable)."""
    ctx = _Context(Capture(info, None if rules is None else frozenset(rules)))
    seen = set(ctx.servo_ids())
    out: list[Result] = []
    for check in checks:
        if check.ids is None:
            out.append(_judge(ctx, check, None))
            continue
        ids = sorted(seen) if isinstance(check.ids, str) else list(check.ids)  # a str: EACH
        if not ids:
            out.append(Result(check, None, NOT_CHECKABLE, "no servo seen"))
        for sid in ids:
            if sid not in seen:
                out.append(Result(check, sid, NOT_CHECKABLE, f"ID {sid} not seen"))
            else:
                out.append(_judge(ctx, check, sid))
    return out


def findings(results: Iterable[Result], offset: int, t: float | None = None) -> list[Finding]:
    """The results that are not passes as lint findings at the end of input (``offset``: the capture's byte
    count; ``t``: its last time, or None): a failure at the check's severity, a not-checkable result at its
    ``not_checkable`` severity with a message that starts "not checkable: "."""
    out = []
    for r in results:
        if r.status == PASS:
            continue
        c = r.check
        if r.status == FAIL:
            out.append(Finding(c.code, c.name, c.severity, r.message, offset, t, r.id))
        else:
            said = r.message if isinstance(r.message, Message) else Message(r.message)
            out.append(Finding(c.code, c.name, c.unknown_severity, said.prefixed("not checkable: "), offset, t, r.id))
    return out


def figures_doc() -> list[tuple[str, str, str, str]]:
    """(name, where it applies, unit, what it is) of every name of the language (the figure table's rows that
    one capture gives), as docs/checks.md lists them."""
    return [(f.name, " and ".join(f.scopes), f.unit or "count", f.doc) for f in table.TABLE if f.checkable]
