"""User rules: the configuration's ``[[rule]]`` tables, compiled into lint Rules that run like the built-in ones.

```toml
[[rule]]
code = "U001"                                   # U and three digits
name = "servo-too-hot"                          # kebab-case
severity = "error"                              # info, warning or error (default: warning)
when = "kind:return present_temperature>60"     # the filter language of `decode --filter`
message = "ID {id} at {present_temperature}"    # optional: fields by name
doc = "Our rig's servos must stay below 60 degC."
```

A rule is checked on every intact record (not on a packet whose Sum is wrong: its bytes are no servo's
values), and reports each record ``when`` matches. It is a :class:`rs30x_sniff.lint.registry.Rule` like any
other: ``rules``, ``--select``/``--ignore``/``--severity``, every report format, the MCAP diagnostics and the
monitor take it as they take the built-in rules. Its column form (what the linter's column path asks of a
Block, rs30x_sniff.lint.batch) is the filter's own (:meth:`rs30x_sniff.filters.Filter.may_match`): a Block none
of whose rows may match is quiet for the rule; one that may is linted record by record.

``message`` is filled by name only (``{id}``, ``{present_temperature:.1f}``): no attribute or index access,
and a field a record does not carry reads ``?``. Measured values (``{t}``, ``{latency}``, ``{offset}``, the
registers) are typed parameters (rs30x_sniff.lint.params): written with their unit (``0.080 ms``,
``61 degC``; not again when the message writes the unit right after the field) and no float noise, and
left out of a baseline's fingerprint, so a reading that moves never makes a known finding new.
"""

from __future__ import annotations

import re
import string
from typing import TYPE_CHECKING, Any
from collections.abc import Mapping

from .filters import FilterError, parse_filter
from .lint.config import ConfigError
from .lint.params import DURATION, OFFSET, TIME, Measured, Message, said
from .lint.registry import FAMILIES, KEBAB, RULES, SEVERITIES, USER_CODE, Rule
from .protocol.memmap import ModelRegistry, default_registry

if TYPE_CHECKING:  # names for the checker; no import at run time
    from .lint.linter import Linter
    from .decode.pairing import Record

KEYS = ("code", "name", "severity", "when", "message", "doc")
DEFAULT_SEVERITY = "warning"
# The kinds of record a user rule is called for (every intact one: rs30x_sniff.lint.registry.KINDS).
RECORD_KINDS = ("short", "long", "return", "ack", "nack", "garbage")
# What a message may name besides the registers of the memory maps.
RECORD_FIELDS = ("id", "kind", "offset", "t", "latency", "address", "code", "name", "severity", "when")
UNKNOWN = "?"


def compile_rules(tables: Any, where: str, registry: ModelRegistry | None = None) -> tuple[Rule, ...]:
    """The Rules of a config file's ``rule`` array (``where`` names the file in messages); raises
    ConfigError with one line naming the file, the rule and the key."""
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise ConfigError(f"{where}: rule: expected an array of tables ([[rule]])")
    reg = registry or default_registry()
    registers = frozenset(n for m in reg.models.values() for n in m.names)
    out: list[Rule] = []
    codes: dict[str, int] = {}
    names: dict[str, int] = {}
    for i, table in enumerate(tables, 1):
        r = compile_rule(table, f"{where}: rule #{i}", reg, registers)
        for seen, key, value in ((codes, "code", r.code), (names, "name", r.name)):
            if value in seen:
                raise ConfigError(f"{where}: rule #{i} ({r.code}): {key}: {value!r} is already rule #{seen[value]}'s")
            seen[value] = i
        out.append(r)
    return tuple(out)


def compile_rule(table: Mapping[str, Any], label: str, registry: ModelRegistry,
                 registers: frozenset[str]) -> Rule:
    code = table.get("code")
    at = f"{label} ({code})" if isinstance(code, str) else label

    def bad(key: str, why: str) -> ConfigError:
        return ConfigError(f"{at}: {key}: {why}")

    for key in table:
        if key not in KEYS:
            raise bad(key, f"unknown key (known: {', '.join(KEYS)})")
    if code is None:
        raise bad("code", "missing (U and three digits, such as U001)")
    if not isinstance(code, str) or not USER_CODE.fullmatch(code):
        family = FAMILIES.get(code[:1].upper()) if isinstance(code, str) else None
        why = f"; {code[:1].upper()} is the built-in family {family!r}" if family else ""
        raise bad("code", f"{code!r} is not a user rule code (U and three digits, such as U001{why})")
    name = table.get("name")
    if name is None:
        raise bad("name", "missing (kebab-case, such as servo-too-hot)")
    if not isinstance(name, str) or not KEBAB.fullmatch(name):
        raise bad("name", f"{name!r} is not kebab-case (lower-case words joined by '-')")
    if re.fullmatch(r"[a-z]\d{3}", name):
        raise bad("name", f"{name!r} reads as a rule code: a name is words (such as servo-too-hot)")
    taken = RULES.get(name)  # the built-in rules (a run's user rules are never in RULES)
    if taken is not None:
        raise bad("name", f"{name!r} is the built-in rule {taken.code}'s name")
    severity = table.get("severity", DEFAULT_SEVERITY)
    if severity not in SEVERITIES:
        raise bad("severity", f"{severity!r}: must be one of {', '.join(SEVERITIES)}")
    when = table.get("when")
    if when is None:
        raise bad("when", "missing (a filter, as decode --filter takes: kind:return present_temperature>60)")
    if not isinstance(when, str) or not when.strip():
        raise bad("when", "expected a filter, as decode --filter takes (kind:return present_temperature>60)")
    try:
        flt = parse_filter(when, registry)
    except FilterError as e:
        raise bad("when", str(e)) from None
    if flt is None:  # pragma: no cover - a non-blank text parses to a filter
        raise bad("when", "empty filter")
    if flt.uses_findings:
        raise bad("when", "sev: tests the findings of other rules; a rule's `when` tests the record itself")
    message = table.get("message")
    if message is not None:
        if not isinstance(message, str):
            raise bad("message", "expected a text")
        check_message(message, registers, lambda why: bad("message", why))
    doc = table.get("doc", "")
    if not isinstance(doc, str):
        raise bad("doc", "expected a text")
    kinds = tuple(k for k in RECORD_KINDS if flt.kinds is None or k in flt.kinds)
    text = when.strip()
    summary = doc.strip().splitlines()[0] if doc.strip() else f"Records that match `{text}`."
    full = (f"## What it does\nReports every record that matches `{text}` (the filter language of "
            f"`decode --filter`).\n\n## Why it matters\n{doc.strip() or 'A rule of the project (no doc given).'}\n\n"
            f"## Defined in\n{label}\n")
    check = _check(code, name, text, flt, message, registers)
    # A filter no record kind can pass (kind:ack present_temperature>60) still makes a rule, which never fires.
    return Rule(code, name, severity, summary, full, kinds or ("garbage",), check,
                needs_time=flt.uses_time, column=_quiet(flt) if kinds else _always_quiet)


def check_message(message: str, registers: frozenset[str], bad: Any) -> None:
    """``message``'s ``{fields}``: each a plain name a record can carry, with an optional conversion and
    format spec (no attribute or index access, no nested fields)."""
    try:
        parts = list(string.Formatter().parse(message))
    except ValueError as e:
        raise bad(f"{e} (write {{{{ and }}}} for braces)") from None
    for _, field, spec, _conv in parts:
        if field is None:
            continue
        if field == "" or not field.isidentifier():
            raise bad(f"{{{field}}}: fields are named (such as {{id}} or {{present_temperature}}), "
                      f"with no attribute or index")
        if field not in RECORD_FIELDS and field not in registers:
            raise bad(f"{{{field}}} is not a field a record carries (fields: {', '.join(RECORD_FIELDS)} "
                      f"and the registers' names)")
        if spec and ("{" in spec or "}" in spec):
            raise bad(f"{{{field}:{spec}}}: a format spec cannot hold a field")


def _always_quiet(view: Any) -> bool:
    return True  # a rule only for kinds a Block never holds (ACK, NACK, garbage)


def _quiet(flt: Any):
    def quiet(view: Any) -> bool:
        """No row of the Block may match the rule's filter (rs30x_sniff.filters.Filter.may_match)."""
        return not flt.may_match(view.blk).any()
    return quiet


def _check(code: str, name: str, when: str, flt: Any, message: str | None, registers: frozenset[str]):
    matches = flt.matches
    named = [w for w in _words(when) if w in registers]
    template = message if message is not None else None

    def check(lint: Linter, rec: Record, ev: Any) -> None:
        if matches(rec):
            lint.emit(code, rec, render(rec, lint))

    def render(rec: Record, lint: Linter) -> Message:
        values = measured_values(rec)
        if template is None:
            shown = [n for n in named if n in values]
            text = ", ".join(f"{n} {{{n}}}" for n in shown) + f" (when: {_braced(when)})" if shown else \
                f"matches when: {_braced(when)}"
            return said(text, values)
        base = {"id": rec.id, "kind": rec.kind, "offset": Measured(rec.offset, OFFSET),
                "t": None if rec.t is None else Measured(rec.t, TIME),
                "latency": None if rec.latency is None else Measured(rec.latency, DURATION),
                "address": getattr(rec.event, "address", None), "code": code, "name": name,
                "severity": lint.severity_of(code), "when": when}
        return said(template, {**values, **base})

    return check


def _braced(text: str) -> str:
    return text.replace("{", "{{").replace("}", "}}")


def fill(message: str, values: Mapping[str, Any]) -> str:
    """``message`` with its ``{fields}`` from ``values`` (checked by :func:`check_message`): a missing or
    None value reads ``?``; a value its format spec does not fit is written plainly; a :class:`Measured`
    value with its unit (rs30x_sniff.lint.params.said)."""
    return str(said(message, values, UNKNOWN))


def measured_values(rec: Record) -> dict[str, Measured]:
    """The registers a record carries (:func:`_register_values`), each a measurement in its register's unit:
    written with that unit in a message, and never part of a baseline's fingerprint."""
    model = rec.model
    out: dict[str, Measured] = {}
    for name, v in _register_values(rec).items():
        unit = ""
        if model is not None:
            try:
                unit = model.register(name).unit or ""
            except KeyError:
                unit = ""
        out[name] = Measured(v, unit)
    return out


def _register_values(rec: Record) -> dict[str, Any]:
    """The first value of each named register the record carries (a long packet: its first servo's)."""
    out: dict[str, Any] = {}
    try:
        items = rec.named_values()
    except (AttributeError, ValueError):
        return out
    for _, n, v in items:
        out.setdefault(n, v)
    return out


def _words(text: str) -> list[str]:
    seen: list[str] = []
    for w in re.findall(r"[A-Za-z_][A-Za-z0-9_]*", text):
        w = w.lower()
        if w not in seen:
            seen.append(w)
    return seen
