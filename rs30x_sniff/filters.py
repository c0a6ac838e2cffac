"""The filter language of the monitor and ``decode --filter`` (``id:1-6 reg:present_temperature>40 latency>1ms``)."""

from __future__ import annotations

import math
import operator
import re
from dataclasses import dataclass
from typing import Any, Protocol, cast
from collections.abc import Callable, Iterable

import numpy as np

from .language import TIME_UNITS, TIME_UNITS_SAID, LanguageError, parse_id_range, unit_scale
from .decode.frame_runs import LONG, RETURN, SHORT
from .decode.pairing import Record
from .protocol.events import LongPacket, ReturnPacket, ShortPacket
from .protocol.memmap import Model, ModelRegistry, Register, default_registry
from .protocol.wire import AT_DATA, VID_SIZE
from .render.records import direction, kind_word, summary

SEVERITIES = ("info", "warning", "error")
SEVERITY_RANK = {name: i for i, name in enumerate(SEVERITIES)}
EVENT_KINDS = ("short", "long", "return", "ack", "nack", "garbage")
# Besides the event kinds, a kind term may name what a request does (the word the timeline shows)
# or which side sent it.
OP_KINDS = ("write", "read", "write+read", "write+ack", "ping", "nop", "flash", "reboot", "init",
            "request", "reply")
KEYS = ("id", "kind", "reg", "sev", "latency", "t")
# language.OPERATORS: `=` and `==` are one operator, as in checks (read here as "=").
COMPARISONS = (">", ">=", "<", "<=", "=", "==", "!=")

# A term: optional negation, then a "quoted phrase" or a bare word.
_TOKEN = re.compile(r'(?P<neg>[-!]?)(?:"(?P<quoted>[^"]*)"|(?P<word>\S+))')
_TERM = re.compile(r"^(?P<key>[a-zA-Z_][a-zA-Z0-9_]*)(?P<op>>=|<=|!=|==|:|=|>|<)(?P<value>.*)$")
_COMPARISON = re.compile(r"^(?P<name>[a-zA-Z_][a-zA-Z0-9_]*)(?P<op>>=|<=|!=|==|=|>|<)(?P<value>.*)$")
_NUMBER = re.compile(r"^(?P<num>[-+]?(?:0[xX][0-9a-fA-F]+|(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?))\s*(?P<unit>.*)$")


class FilterError(ValueError):
    """A filter expression that cannot be parsed; the message says why, in one line."""


Predicate = Callable[[Record], bool]
_UNSEEN = object()
FindingPredicate = Callable[[Any], bool]
# A term's column form: (maybe, surely) over a Block's rows (rs30x_sniff.decode.blocks), two boolean arrays:
# the rows whose records the term may match (never missing one), and those it surely matches. A term
# without one is read as maybe everywhere, surely nowhere. The predicates carry it as ``.column``, with
# ``.kinds`` (the event kinds a record it matches can have; None: any) and ``.timed`` (it reads times).
# A column form with ``.narrows`` set also takes ``among`` (a boolean mask of rows still in question) and
# need only be right on those: a register's bytes are then read for the rows the earlier terms left.
ColumnTerm = Callable[[Any], "tuple[np.ndarray, np.ndarray]"]


class ColumnForm(Protocol):
    """A term's column form as the terms carry it: a function of a Block, marked whether it narrows."""

    narrows: bool

    def __call__(self, blk: Any, /) -> tuple[np.ndarray, np.ndarray]: ...


class NarrowingColumnForm(ColumnForm, Protocol):
    """A column form with ``narrows`` set: it also takes ``among``, the rows still in question."""

    def __call__(self, blk: Any, /, among: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]: ...


class Term(Protocol):
    """A parsed term: a test of a record that carries its column form, its event kinds and whether it reads
    times. The terms are plain functions given these attributes by :func:`_with` (a call of a function
    is cheaper than one of an object's ``__call__``, and a filter calls its terms once a record)."""

    column: ColumnForm | None
    kinds: frozenset[str] | None
    timed: bool

    def __call__(self, rec: Record, /) -> bool: ...


@dataclass(frozen=True)
class Filter:
    """A parsed filter: every term must match (terms prefixed with ``-`` or ``!`` must not)."""

    text: str
    terms: tuple[Term, ...]
    uses_text: bool = False  # free-text terms need the rendered summary (slower)
    # The terms as tests of a lint finding shown apart from its record; None when a term cannot judge
    # one (kind, reg, latency ask for packets of a sort, and such a finding is not one).
    finding_terms: tuple[FindingPredicate, ...] | None = ()
    # The event kinds a matching record can have (None: any), whether a term reads times (latency, t),
    # and which terms are ``sev:`` (they read the findings a record has been given).
    kinds: frozenset[str] | None = None
    uses_time: bool = False
    uses_findings: bool = False

    def matches(self, rec: Record) -> bool:
        for term in self.terms:
            if not term(rec):
                return False
        return True

    def matches_finding(self, finding: Any) -> bool:
        """Whether a finding shown apart from its record (one only the end of input reveals) passes:
        only a filter of id, sev, t and free-text terms passes any, by its id, severity, time and text."""
        if self.finding_terms is None:
            return False
        for term in self.finding_terms:
            if not term(finding):
                return False
        return True

    def __call__(self, rec: Record) -> bool:
        return self.matches(rec)

    def may_match(self, blk: Any) -> np.ndarray:
        """The column form: per row of Block ``blk``, whether its record may match (True for every row
        that :meth:`matches`; rows it cannot rule out on the columns count as may-match too)."""
        maybe = np.ones(len(blk), dtype=bool)
        for term in self.terms:
            col = term.column
            if col is not None:
                # narrows says the form takes ``among`` (a flag the type checker cannot read: cast).
                maybe &= (cast(NarrowingColumnForm, col)(blk, among=maybe) if col.narrows else col(blk))[0]
                if not maybe.any():  # the terms are all required: none left, none to ask the rest about
                    break
        return maybe


def parse_filter(text: str, registry: ModelRegistry | None = None) -> Filter | None:
    """Parse ``text``; None for an empty filter (show everything). Raises FilterError."""
    text = text.strip()
    if not text:
        return None
    registry = registry or default_registry()
    known = _register_names(registry)
    terms: list[Term] = []
    finding_terms: list[FindingPredicate] | None = []
    uses_text = uses_time = uses_findings = False
    kinds: frozenset[str] | None = None
    for tok in _TOKEN.finditer(text):
        quoted, word = tok["quoted"] is not None, tok["quoted"] if tok["quoted"] is not None else tok["word"]
        negate = bool(tok["neg"])
        if not quoted and '"' in word:
            raise FilterError(f"unclosed quote in {tok.group(0)!r}")
        if not word:
            raise FilterError("empty quotes: nothing to search for")
        m = None if quoted else _TERM.match(word)
        key = m["key"].lower() if m else ""
        op = _op(m["op"]) if m else ""
        fpred: FindingPredicate | None = None
        if m and key in KEYS:
            pred, fpred = _keyed(key, op, m["value"], registry)
        elif m and op != ":" and key in known:
            # "present_temperature>40" needs no "reg:": a comparison on a register name is one.
            pred = _compare_register(word, key, op, m["value"], registry)
        elif m and op != ":" and m["value"]:
            # Free text cannot hold a comparison on a name we do not know: it is a typo far more often
            # than a search (and a search can be quoted).
            raise FilterError(f"{word}: no register or filter key {m['key']!r}{_hint(key, known)} "
                              f"(quote free text)")
        elif m and op == ":" and m["value"] and key in known:
            raise FilterError(f"{word}: {key} is a register, not a key: compare it ({key}={m['value']}, "
                              f"{key}>{m['value']}) or name it (reg:{key})")
        elif m and op == ":" and m["value"]:
            # "ids:3" is a keyed term with a typo, not text to search for; free text with a colon can be quoted.
            raise FilterError(f"unknown filter key {m['key']!r} (keys: {', '.join(KEYS)}; quote free text)")
        else:
            pred, fpred = _text(word)
            uses_text = True
        uses_time = uses_time or pred.timed
        uses_findings = uses_findings or key == "sev"
        if negate:
            pred = _negate(pred)
            fpred = None if fpred is None else _negate_finding(fpred)
        else:
            k = pred.kinds
            if k is not None:
                kinds = k if kinds is None else kinds & k
        terms.append(pred)
        if fpred is None:
            finding_terms = None
        elif finding_terms is not None:
            finding_terms.append(fpred)
    return Filter(text, tuple(terms), uses_text, None if finding_terms is None else tuple(finding_terms),
                  kinds, uses_time, uses_findings)


def _negate(pred: Term) -> Term:
    def negated(rec: Record) -> bool:
        return not pred(rec)

    col = pred.column
    column: ColumnTerm | None = None
    if col is not None:
        def column(blk: Any) -> tuple[np.ndarray, np.ndarray]:
            maybe, surely = col(blk)
            return ~surely, ~maybe
    # A negated term matches records of any kind (the ones its term leaves out).
    return _with(negated, column, timed=pred.timed)


def _negate_finding(fpred: FindingPredicate) -> FindingPredicate:
    return lambda f: not fpred(f)


def _with(pred: Predicate, column: ColumnTerm | None = None, kinds: Iterable[str] | None = None,
          timed: bool = False, narrows: bool = False) -> Term:
    """``pred`` as a term: with its column form (``narrows``: the form takes ``among``), the event kinds
    it can match and whether it reads times."""
    term = cast(Term, pred)  # the attributes that make a function a Term are set here
    form = None
    if column is not None:
        form = cast(ColumnForm, column)  # likewise, narrows
        form.narrows = narrows
    term.column = form
    term.kinds = None if kinds is None else frozenset(kinds)
    term.timed = timed
    return term


# ---- column forms: what a Block's columns tell of its rows ---------------------------------------
def _long_records(blk: Any):
    """Per distinct (record size, count) of the Block's long packets: (rows, count, size, where each
    row's first record starts in the run's bytes)."""
    c = blk.cols
    rows = np.flatnonzero(c["kind"] == LONG)
    if not rows.size:
        return
    size = c["length"][rows].astype(np.int64)
    count = c["count"][rows].astype(np.int64)
    key = size * 256 + count
    starts = blk.run.starts[blk.lo:blk.hi]
    for k in np.unique(key).tolist():
        r = rows[key == k]
        yield r, k % 256, k // 256, starts[r] + AT_DATA


def _register_names(registry: ModelRegistry) -> frozenset[str]:
    return frozenset(n for m in registry.models.values() for n in m.names)


def _op(text: str) -> str:
    """A comparison as the terms read it: ``==`` is ``=`` (language.OPERATORS)."""
    return "=" if text == "==" else text


def _hint(name: str, known: frozenset[str]) -> str:
    close = sorted(k for k in known if name.lower() in k)
    return f" (did you mean {', '.join(close[:3])}?)" if close else ""


def _keyed(key: str, op: str, value: str,
           registry: ModelRegistry) -> tuple[Term, FindingPredicate | None]:
    if not value:
        raise FilterError(f"{key}{op} needs a value")
    if key == "sev":
        return _severity(op, value)
    if key == "latency":
        return _latency(op, value), None
    if key == "t":
        return _time(op, value)
    if op not in (":", "="):
        raise FilterError(f"{key} takes ':' (only sev, latency and t compare with {op!r})")
    if key == "id":
        return _ids(value)
    if key == "kind":
        return _kinds(value), None
    m = _COMPARISON.match(value)
    if m:
        return _compare_register(f"{key}{op}{value}", m["name"].lower(), _op(m["op"]), m["value"], registry), None
    return _registers(value, registry), None


def _number(term: str, value: str) -> tuple[float, str]:
    """A number and the unit after it (``40``, ``-1.5deg``, ``0x3030``, ``2ms``)."""
    m = _NUMBER.match(value.strip())
    if not m:
        raise FilterError(f"{term}: {value!r} is not a number")
    num = m["num"]
    x = int(num, 16) if "x" in num.lower() else float(num)
    if not math.isfinite(x):  # 1e999: a typo, never a value a field can hold
        raise FilterError(f"{term}: {value!r} is not a finite number")
    return x, m["unit"]


def _numeric_test(op: str, x: float) -> Callable[[Any], bool]:
    # "=" tolerates the last bits of a float: "goal_position=10.3" should find 103 / 10.
    if op == "=":
        return lambda v: v is not None and not isinstance(v, str) and math.isclose(v, x, rel_tol=1e-9, abs_tol=1e-12)
    if op == "!=":
        return lambda v: v is not None and not isinstance(v, str) and not math.isclose(v, x, rel_tol=1e-9,
                                                                                       abs_tol=1e-12)
    cmp = {">": operator.gt, ">=": operator.ge, "<": operator.lt, "<=": operator.le}[op]
    return lambda v: v is not None and not isinstance(v, str) and cmp(v, x)


def _duration(term: str, value: str) -> float:
    """Seconds of ``2ms``, ``150us``, ``1min``, ``0.002`` (bare numbers are seconds; language.py's units)."""
    num, unit = _number(term, value)
    scale = unit_scale(unit) if unit else 1.0
    if scale is None:
        raise FilterError(f"{term}: unit {unit!r} is not a time unit ({TIME_UNITS_SAID})")
    return num * scale


# ---- id ---------------------------------------------------------------------------------------
def _ids(value: str) -> tuple[Term, FindingPredicate]:
    try:
        frozen = frozenset(parse_id_range(value))  # 0-255: a long packet's 0 and the broadcast 255 too
    except LanguageError as e:
        raise FilterError(f"id:{value}: {e}") from None

    def match(rec: Record) -> bool:
        ev = rec.event
        if type(ev) is LongPacket:
            # A long packet concerns every servo it carries a record for, and ID 0 itself.
            return 0 in frozen or any(r.vid in frozen for r in ev.records)
        return rec.id in frozen

    table = np.zeros(256, dtype=bool)
    table[sorted(frozen)] = True

    def column(blk: Any) -> tuple[np.ndarray, np.ndarray]:
        c = blk.cols
        out = table[c["id"]]
        if 0 not in frozen:  # else every long packet matches by its own ID 0
            a = blk.run.bytes_array
            for rows, count, size, at in _long_records(blk):
                hit = np.zeros(len(rows), dtype=bool)
                for k in range(count):
                    hit |= table[a[at + k * size]]
                out[rows] = hit
        return out, out

    return _with(match, column), lambda f: f.id in frozen


# ---- kind -------------------------------------------------------------------------------------
def _kinds(value: str) -> Term:
    kinds, ops = set(), set()
    for part in value.lower().split(","):
        if part in EVENT_KINDS:
            kinds.add(part)
        elif part in OP_KINDS:
            ops.add(part)
        else:
            raise FilterError(f"kind:{part}: unknown kind (one of {', '.join(EVENT_KINDS + OP_KINDS)})")

    def match(rec: Record) -> bool:
        if rec.kind in kinds:
            return True
        if not ops:
            return False
        if ("request" in ops and rec.is_request) or ("reply" in ops and rec.is_reply):
            return True
        return kind_word(rec).split("(")[0].lower() in ops

    # What a short packet does (write, read, ...) is not in the columns: with such a word, any short may match.
    words = ops - {"request", "reply"}
    event_kinds = set(kinds)
    if "request" in ops:
        event_kinds |= {"short", "long"}
    if "reply" in ops:
        event_kinds |= {"return", "ack", "nack"}
    codes = [code for code, k in ((SHORT, "short"), (LONG, "long"), (RETURN, "return")) if k in event_kinds]

    def column(blk: Any) -> tuple[np.ndarray, np.ndarray]:
        kind = blk.cols["kind"]
        surely = np.zeros(len(kind), dtype=bool)
        for code in codes:  # (one to three codes: a comparison each is cheaper than np.isin)
            surely |= kind == code
        return (surely | (blk.cols["kind"] == SHORT) if words else surely), surely

    return _with(match, column, event_kinds | {"short"} if words else event_kinds)


# ---- reg --------------------------------------------------------------------------------------
def _registers(value: str, registry: ModelRegistry) -> Term:
    names = [n for n in value.split(",") if n]
    known = _register_names(registry)
    for n in names:
        if n not in known:
            raise FilterError(f"reg:{n}: no such register{_hint(n, known)}")
    wanted = tuple(names)

    def covers(model, address: int, length: int) -> bool:
        for n in wanted:
            try:
                reg = model.register(n)
            except KeyError:
                continue
            if address < reg.address + reg.size and reg.address < address + length:
                return True
        return False

    def match(rec: Record) -> bool:
        # By address ranges rather than decoded fields, so filtering a long history decodes nothing.
        # (type(ev) tested in each branch, not once into a name: the type checker narrows ev by the
        # test itself, and a specialised type() call costs next to nothing.)
        ev = rec.event
        model = rec.model
        if model is None:
            return False
        if type(ev) is ShortPacket:
            if ev.data and covers(model, ev.address, len(ev.data)):
                return True
            rr = rec.read_range  # by the servo's model (return modes beyond table 4.3)
            return rr is not None and covers(model, *rr)
        if type(ev) is ReturnPacket:
            return covers(model, ev.address, len(ev.data))
        if type(ev) is LongPacket:
            return ev.length > 1 and covers(model, ev.address, ev.length - 1)
        return False

    def column(blk: Any) -> tuple[np.ndarray, np.ndarray]:
        # A short packet may ask to read the register (its read range is in its flags): it may match.
        c = blk.cols
        kind = c["kind"]
        surely = np.zeros(len(kind), dtype=bool)
        address = c["address"].astype(np.int64)
        size = np.where(kind == LONG, c["length"].astype(np.int64) - VID_SIZE, c["data_len"].astype(np.int64))
        for model, rows in _rows_by_model(blk, np.flatnonzero(kind != SHORT)):
            if model is None:
                continue
            for n in wanted:
                try:
                    reg = model.register(n)
                except KeyError:
                    continue
                a, ln = address[rows], size[rows]
                surely[rows] |= (ln > 0) & (a < reg.address + reg.size) & (reg.address < a + ln)
        return surely | (kind == SHORT), surely

    return _with(match, column, ("short", "long", "return"))


def _rows_by_model(blk: Any, rows: np.ndarray):
    """``rows`` of Block ``blk`` split by the model their records carry: a short packet's and a return's
    is its servo's, a long packet's the Block's default."""
    kind, sid = blk.cols["kind"][rows], blk.cols["id"][rows]
    is_long = kind == LONG
    if is_long.any():
        yield blk.default, rows[is_long]
    rows, sid = rows[~is_long], sid[~is_long]
    by: dict[int, tuple[Any, list[int]]] = {}
    for s in np.unique(sid).tolist():
        model = blk.models.get(s)
        by.setdefault(id(model), (model, []))[1].append(s)
    for model, ids in by.values():
        yield model, (rows if len(by) == 1 else rows[np.isin(sid, ids)])


def _raw_test(term: str, reg: Register, op: str, value: str) -> Callable[[int], bool]:
    """A test of a register's raw value against ``value`` in engineering units (or an enum label)."""
    name = reg.label
    if not value:
        raise FilterError(f"{term}: needs a value")
    if reg.enum is not None and not _NUMBER.match(value):
        labels = {str(v).lower(): k for k, v in reg.enum.items()}
        if op not in ("=", "!="):
            raise FilterError(f"{term}: {name} is one of {', '.join(map(str, reg.enum.values()))}; "
                              f"compare it with = or !=")
        code = labels.get(value.lower())
        if code is None:
            raise FilterError(f"{term}: {name} is one of {', '.join(map(str, reg.enum.values()))}")
        return (lambda raw: raw == code) if op == "=" else (lambda raw: raw != code)
    num, unit = _number(term, value)
    if reg.enum is not None:  # a number for an enum register is its code
        test = _numeric_test(op, num)
        return lambda raw: test(raw)
    if unit and unit.lower() != (reg.unit or "").lower():
        given, own = unit_scale(unit), TIME_UNITS.get((reg.unit or "").lower())
        if own is not None and given is not None:
            num = num * given / own
        elif reg.unit:
            raise FilterError(f"{term}: {name} is in {reg.unit}, not {unit}")
        else:
            raise FilterError(f"{term}: {name} has no unit")
    test = _numeric_test(op, num)
    convert = reg.convert
    return lambda raw: test(convert(raw))


def _compare_register(term: str, name: str, op: str, value: str, registry: ModelRegistry) -> Term:
    known = _register_names(registry)
    if name not in known:
        raise FilterError(f"{term}: no such register{_hint(name, known)}")

    # One compiled check per model: (address, size, signed, test of the raw value). The register's
    # bytes are read straight from the packet, so a scan over a long history decodes nothing else.
    tables: list[tuple[Register, Any]] = []
    arrays: dict[Model, tuple[Register, np.ndarray]] = {}  # the tables as arrays, for the column form

    def compile_for(model: Model):
        try:
            reg = model.register(name)
        except KeyError:
            return None
        test = _raw_test(term, reg, op, value)
        if reg.size > 2:
            return reg.address, reg.size, reg.signed, test
        # Every raw value of a 1- or 2-byte register judged once (the same register in another model
        # shares the table): a scan of a million records then looks bytes up instead of converting them.
        for r, table in tables:  # noqa: B007 - the table found is used after the loop
            if r == reg:
                break
        else:
            bits = 8 * reg.size
            half = 1 << (bits - 1)
            table = bytes(bool(test(u - (1 << bits) if reg.signed and u >= half else u)) for u in range(1 << bits))
            tables.append((reg, table))
        arrays[model] = (reg, np.frombuffer(table, dtype=bool))
        return reg.address, reg.size, False, table.__getitem__

    specs: dict[Model, Any] = {}  # by model (a Model hashes as itself)
    refused: list[FilterError] = []
    for model in registry.models.values():  # every model now, so a bad value is an error at once
        try:
            specs[model] = compile_for(model)
        except FilterError as e:
            # One model may not take the value (its map gives this register no unit, as RS405CB's warm_up_time):
            # no match there. An error only when no model that has the register takes it.
            specs[model] = None
            refused.append(e)
    if refused and not any(specs.values()):
        raise refused[0]

    def spec_of(model: Model):
        try:
            s = compile_for(model)
        except FilterError:  # a model outside the registry that takes the value otherwise: no match
            s = None
        specs[model] = s
        return s

    def spec_for(model: Model):
        spec = specs.get(model, _UNSEEN)
        return spec_of(model) if spec is _UNSEEN else spec

    def carries(spec, address: int, data: bytes) -> bool:
        if spec is None:
            return False
        a, size, signed, test = spec
        start = a - address
        if start < 0 or start + size > len(data):
            return False
        return test(int.from_bytes(data[start:start + size], "little", signed=signed))

    def match(rec: Record) -> bool:
        ev = rec.event
        if type(ev) is ReturnPacket or type(ev) is ShortPacket:  # (tests the type checker narrows ev by)
            model = rec.model
            if model is None or not ev.checksum_ok:
                return False  # bytes that failed their checksum are no servo's values
            return bool(ev.data) and carries(spec_for(model), ev.address, ev.data)
        if type(ev) is not LongPacket:
            return False
        model = rec.model
        if model is None or not ev.checksum_ok:
            return False
        vm = rec.vid_models
        address = ev.address
        if vm is None:
            spec = spec_for(model)
            if spec is None:
                return False
            # One model for every servo (the common case): one bounds check, then each servo's bytes.
            a, size, signed, test = spec
            start = a - address
            if start < 0:
                return False
            end = start + size
            for r in ev.records:
                d = r.data
                if end <= len(d) and test(int.from_bytes(d[start:end], "little", signed=signed)):
                    return True
            return False
        return any(carries(spec_for(m), address, r.data) for m, r in zip(vm, ev.records))

    def column(blk: Any, among: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        # The register's raw value read from the run's bytes and judged by the model's table; a model
        # whose test has no table (a register wider than 2 bytes) leaves its rows may-match.
        c = blk.cols
        kind = c["kind"]
        n = len(kind)
        maybe, surely = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        a = blk.run.bytes_array
        starts = blk.run.starts[blk.lo:blk.hi]
        address = c["address"].astype(np.int64)
        dlen = c["data_len"].astype(np.int64)

        def judge(at: np.ndarray, reg: Register, table: np.ndarray) -> np.ndarray:
            return table[reg.raw_column(a, at)]  # the one decoding of a register from columns

        for model, rows in _rows_by_model(blk, np.arange(n) if among is None else np.flatnonzero(among)):
            spec = None if model is None else spec_for(model)
            if spec is None:
                continue
            arr = arrays.get(model)
            is_long = kind[rows] == LONG
            if arr is None or (is_long.any() and blk.vid_models is not None):
                maybe[rows] = True  # no table to read columns by, or servos of mixed models: ask the records
                continue
            reg, table = arr
            reg_address, size = reg.address, reg.size
            start = reg_address - address[rows]
            if not is_long[0]:
                ok = (start >= 0) & (start + size <= dlen[rows])
                r = rows[ok]
                hit = judge(starts[r] + AT_DATA + start[ok], reg, table)
                maybe[r] = surely[r] = hit
                continue
            for lrows, count, rsize, at in _long_records(blk):
                st = reg_address - address[lrows]
                ok = (st >= 0) & (st + size <= rsize - VID_SIZE)
                if among is not None:
                    ok &= among[lrows]
                if not ok.any():
                    continue
                lr, at, st = lrows[ok], at[ok], st[ok]
                hit = np.zeros(len(lr), dtype=bool)
                for k in range(count):
                    hit |= judge(at + k * rsize + VID_SIZE + st, reg, table)
                maybe[lr] = surely[lr] = hit
        return maybe, surely

    return _with(match, column, ("short", "long", "return"), narrows=True)


# ---- latency ----------------------------------------------------------------------------------
def _latency(op: str, value: str) -> Term:
    term = f"latency{op}{value}"
    if op not in COMPARISONS:
        raise FilterError(f"{term}: latency compares with {' '.join(COMPARISONS)} (latency>1ms)")
    test = _numeric_test(op, _duration(term, value))

    def match(rec: Record) -> bool:
        # A reply's: the time from the end of its request to its start.
        lat = rec.latency
        return lat is not None and test(lat)

    def column(blk: Any) -> tuple[np.ndarray, np.ndarray]:
        lat = blk.latencies()  # NaN but for the replies; None: no times, no latency
        if lat is None:
            none = np.zeros(len(blk), dtype=bool)
            return none, none
        return _column_test(op, lat, limit)

    limit = _duration(term, value)
    return _with(match, column, timed=True)


def _column_test(op: str, values: np.ndarray, x: float) -> tuple[np.ndarray, np.ndarray]:
    """(maybe, surely) of :func:`_numeric_test` on a column of floats (NaN: no value). The same comparison
    for an order; "=" and "!=" (a tolerance math.isclose sets) say may-match wherever there is a value."""
    present = ~np.isnan(values)
    if op in ("=", "!="):
        return present, np.zeros(len(values), dtype=bool)
    cmp = {">": np.greater, ">=": np.greater_equal, "<": np.less, "<=": np.less_equal}[op]
    out = present & cmp(np.where(present, values, 0.0), x)
    return out, out


# ---- t ----------------------------------------------------------------------------------------
def _time(op: str, value: str) -> tuple[Term, FindingPredicate]:
    term = f"t{op}{value}"
    if op in (":", "="):
        lo_text, sep, hi_text = value.partition("-")
        if not sep:
            raise FilterError(f"{term}: t takes a range like t:1.5-3.0 (or t:1.5-, t:-3)")
        lo = _duration(term, lo_text) if lo_text.strip() else -math.inf
        hi = _duration(term, hi_text) if hi_text.strip() else math.inf
        if lo > hi:
            raise FilterError(f"{term}: range runs backwards")

        def test(t: float | None) -> bool:
            return t is not None and lo <= t <= hi
    elif op == "!=":
        raise FilterError(f"{term}: t takes a range (t:1.5-3.0) or compares with > >= < <=")
    else:
        test = _numeric_test(op, _duration(term, value))  # type: ignore[assignment]

    def column(blk: Any) -> tuple[np.ndarray, np.ndarray]:
        t0 = blk.t0
        if t0 is None:
            none = np.zeros(len(blk), dtype=bool)
            return none, none
        if op in (":", "="):
            out = (t0 >= lo) & (t0 <= hi)
            return out, out
        return _column_test(op, t0, _duration(term, value))

    return _with(lambda rec: test(rec.event.t_start), column, timed=True), (lambda f: test(f.t))


# ---- sev --------------------------------------------------------------------------------------
def _severity(op: str, value: str) -> tuple[Term, FindingPredicate]:
    v = value.lower()
    aliases = {"warn": "warning", "err": "error", "any": "info"}
    v = aliases.get(v, v)
    if v not in SEVERITY_RANK:
        raise FilterError(f"sev{op}{value}: unknown severity (one of {', '.join(SEVERITIES)})")
    r = SEVERITY_RANK[v]
    test: Callable[[int], bool] = {
        ":": lambda k: k == r, "=": lambda k: k == r, ">=": lambda k: k >= r, ">": lambda k: k > r,
        "<=": lambda k: k <= r, "<": lambda k: k < r, "!=": lambda k: k != r,
    }[op]

    def match(rec: Record) -> bool:
        return any(test(SEVERITY_RANK.get(f.severity, 0)) for f in rec.findings)

    return _with(match), lambda f: test(SEVERITY_RANK.get(f.severity, 0))


# ---- free text --------------------------------------------------------------------------------
def record_text(rec: Record) -> str:
    """What free text is matched against: direction, summary and finding codes and names."""
    # keep=False: a search through a long history must not leave every record's fields in memory.
    text = f"{direction(rec)} {summary(rec, keep=False)} @{rec.offset}"
    if rec.findings:
        text += " " + " ".join(f"{f.code} {f.name}" for f in rec.findings)
    return text.lower()


def _text(word: str) -> tuple[Term, FindingPredicate]:
    needle = word.lower()
    return (_with(lambda rec: needle in record_text(rec)),
            (lambda f: needle in f"{f.code} {f.name} {f.message}".lower()))
