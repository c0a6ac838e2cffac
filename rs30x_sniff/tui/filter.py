"""The monitor's filter language (``id:1-6 kind:return reg:goal_position sev>=warning text``) as a predicate."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable

from ..bus import Record
from ..events import LongPacket, ReturnPacket, ShortPacket
from ..memmap import ModelRegistry, default_registry
from ..render import direction, kind_word, summary

SEVERITIES = ("info", "warning", "error")
SEVERITY_RANK = {name: i for i, name in enumerate(SEVERITIES)}
EVENT_KINDS = ("short", "long", "return", "ack", "nack", "garbage")
# Besides the event kinds, a kind term may name what a request does (the word the timeline shows)
# or which side sent it.
OP_KINDS = ("write", "read", "write+read", "write+ack", "ping", "nop", "flash", "reboot", "init",
            "request", "reply")
KEYS = ("id", "kind", "reg", "sev")

# A term: optional negation, then a "quoted phrase" or a bare word.
_TOKEN = re.compile(r'(?P<neg>[-!]?)(?:"(?P<quoted>[^"]*)"|(?P<word>\S+))')
_TERM = re.compile(r"^(?P<key>[a-zA-Z]+)(?P<op>>=|<=|:|=|>|<)(?P<value>.*)$")


class FilterError(ValueError):
    """A filter expression that cannot be parsed; the message says why, in one line."""


Predicate = Callable[[Record], bool]


@dataclass(frozen=True)
class Filter:
    """A parsed filter: every term must match (terms prefixed with ``-`` or ``!`` must not)."""

    text: str
    terms: tuple[Predicate, ...]
    uses_text: bool = False  # free-text terms need the rendered summary (slower)

    def matches(self, rec: Record) -> bool:
        for term in self.terms:
            if not term(rec):
                return False
        return True

    def __call__(self, rec: Record) -> bool:
        return self.matches(rec)


def parse_filter(text: str, registry: ModelRegistry | None = None) -> Filter | None:
    """Parse ``text``; None for an empty filter (show everything). Raises FilterError."""
    text = text.strip()
    if not text:
        return None
    registry = registry or default_registry()
    terms: list[Predicate] = []
    uses_text = False
    for tok in _TOKEN.finditer(text):
        quoted, word = tok["quoted"] is not None, tok["quoted"] if tok["quoted"] is not None else tok["word"]
        negate = bool(tok["neg"])
        if not quoted and '"' in word:
            raise FilterError(f"unclosed quote in {tok.group(0)!r}")
        if not word:
            raise FilterError("empty quotes: nothing to search for")
        m = None if quoted else _TERM.match(word)
        if m and m["key"].lower() in KEYS:
            pred = _keyed(m["key"].lower(), m["op"], m["value"], registry)
        elif m and m["op"] == ":" and m["value"]:
            # "ids:3" is a keyed term with a typo, not text to search for ("name=value" is text:
            # that is how the summaries read); free text with a colon can be quoted.
            raise FilterError(f"unknown filter key {m['key']!r} (keys: {', '.join(KEYS)}; quote free text)")
        else:
            pred = _text(word)
            uses_text = True
        if negate:
            pred = _negate(pred)
        terms.append(pred)
    return Filter(text, tuple(terms), uses_text)


def _negate(pred: Predicate) -> Predicate:
    return lambda rec: not pred(rec)


def _keyed(key: str, op: str, value: str, registry: ModelRegistry) -> Predicate:
    if not value:
        raise FilterError(f"{key}{op} needs a value")
    if key == "sev":
        return _severity(op, value)
    if op not in (":", "="):
        raise FilterError(f"{key} takes ':' (only sev compares with {op!r})")
    if key == "id":
        return _ids(value)
    if key == "kind":
        return _kinds(value)
    return _registers(value, registry)


# ---- id ---------------------------------------------------------------------------------------
def _ids(value: str) -> Predicate:
    wanted: set[int] = set()
    for part in value.split(","):
        lo, sep, hi = part.partition("-")
        try:
            a = int(lo, 0)
            b = int(hi, 0) if sep else a
        except ValueError:
            raise FilterError(f"id:{value}: {part!r} is not an ID or a range like 1-6") from None
        if not (0 <= a <= 255 and 0 <= b <= 255):
            raise FilterError(f"id:{value}: IDs run from 0 to 255")
        if a > b:
            raise FilterError(f"id:{value}: range {part} runs backwards")
        wanted.update(range(a, b + 1))
    frozen = frozenset(wanted)

    def match(rec: Record) -> bool:
        ev = rec.event
        if type(ev) is LongPacket:
            # A long packet concerns every servo it carries a record for, and ID 0 itself.
            return 0 in frozen or any(r.vid in frozen for r in ev.records)
        return rec.id in frozen

    return match


# ---- kind -------------------------------------------------------------------------------------
def _kinds(value: str) -> Predicate:
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

    return match


# ---- reg --------------------------------------------------------------------------------------
def _registers(value: str, registry: ModelRegistry) -> Predicate:
    names = [n for n in value.split(",") if n]
    known = {n for m in registry.models.values() for n in m.names}
    for n in names:
        if n not in known:
            close = sorted(k for k in known if n.lower() in k)
            hint = f" (did you mean {', '.join(close[:3])}?)" if close else ""
            raise FilterError(f"reg:{n}: no such register{hint}")
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
        ev = rec.event
        t = type(ev)
        model = rec.model
        if model is None:
            return False
        if t is ShortPacket:
            if ev.data and covers(model, ev.address, len(ev.data)):
                return True
            rr = ev.read_range
            return rr is not None and covers(model, *rr)
        if t is ReturnPacket:
            return covers(model, ev.address, len(ev.data))
        if t is LongPacket:
            return ev.length > 1 and covers(model, ev.address, ev.length - 1)
        return False

    return match


# ---- sev --------------------------------------------------------------------------------------
def _severity(op: str, value: str) -> Predicate:
    v = value.lower()
    aliases = {"warn": "warning", "err": "error", "any": "info"}
    v = aliases.get(v, v)
    if v not in SEVERITY_RANK:
        raise FilterError(f"sev{op}{value}: unknown severity (one of {', '.join(SEVERITIES)})")
    r = SEVERITY_RANK[v]
    test: Callable[[int], bool] = {
        ":": lambda k: k == r, "=": lambda k: k == r, ">=": lambda k: k >= r, ">": lambda k: k > r,
        "<=": lambda k: k <= r, "<": lambda k: k < r,
    }[op]

    def match(rec: Record) -> bool:
        return any(test(SEVERITY_RANK.get(f.severity, 0)) for f in rec.findings)

    return match


# ---- free text --------------------------------------------------------------------------------
def record_text(rec: Record) -> str:
    """What free text is matched against: direction, summary and finding codes and names."""
    # keep=False: a search through a long history must not leave every record's fields in memory.
    text = f"{direction(rec)} {summary(rec, keep=False)} @{rec.offset}"
    if rec.findings:
        text += " " + " ".join(f"{f.code} {f.name}" for f in rec.findings)
    return text.lower()


def _text(word: str) -> Predicate:
    needle = word.lower()
    return lambda rec: needle in record_text(rec)
