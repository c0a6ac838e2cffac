"""`decode --format fields`: chosen columns of each record, tab-separated, as tshark's -T fields writes them."""

from __future__ import annotations

import difflib
import json
from collections.abc import Callable, Iterable
from typing import Any

from ..decode.pairing import Record
from ..protocol.memmap import ByRaw, Layout, ModelRegistry, Register
from .layout_json import value_text
from .records import direction, json_id, record_json

OCCURRENCES = " "  # between the values of one column in one record, as the tables' list columns (sinks/tables.py)
# Other names of a column: the filter language's word for the JSON's "type" (kind:return), and the packets table's
# for its "diagnostics" (their codes, as that table's column holds them).
ALIASES = {"kind": "type", "findings": "diagnostics"}
Column = Callable[[Record, set[int] | None], str]


def _text(v: Any) -> str:
    """A value as its JSON text says it (true, 0.25; a string without its quotes), and nothing for none."""
    if v is None:
        return ""
    if v is True or v is False:
        return "true" if v else "false"
    return repr(v) if isinstance(v, float) else str(v)


def _from_object(key: str) -> Callable[[dict[str, Any]], str]:
    """A column read from the record's whole JSON object (render.records.record_json, made once per line), for the
    keys whose value takes that object's logic (flag, address, op, model, flags, vids, ...)."""
    def column(obj: dict[str, Any]) -> str:
        v = obj.get(key)
        return OCCURRENCES.join(map(_text, v)) if isinstance(v, list) else _text(v)
    return column


# The JSON object's keys a column reads straight from the record (each as record_json sets it), and the packets
# table's direction; every other key of the object comes from record_json itself.
_DIRECT: dict[str, Column] = {
    "type": lambda rec, only: rec.event.kind,
    "offset": lambda rec, only: str(rec.event.offset),
    "t": lambda rec, only: _text(rec.event.t_start),
    "t_end": lambda rec, only: _text(rec.event.t_end),
    "raw": lambda rec, only: rec.event.raw.hex(),
    "checksum_ok": lambda rec, only: _text(rec.event.checksum_ok),
    "id": lambda rec, only: _text(json_id(rec)),
    "reply_to": lambda rec, only: "" if rec.request is None else str(rec.request.offset),
    "reply": lambda rec, only: "" if rec.reply is None else str(rec.reply.offset),
    "latency_s": lambda rec, only: _text(rec.latency),
    "status": lambda rec, only: _text(rec.status),
    "diagnostics": lambda rec, only: OCCURRENCES.join(d.code for d in rec.findings),
    "direction": lambda rec, only: direction(rec),  # the packets table's (host, servo, ?); no key of the JSON
}


def _later(rec: Record, only: set[int] | None) -> str:
    """The place of a column read from the line's JSON object instead (Columns.line)."""
    return ""


_OBJECT_KEYS = ("flag", "address", "length", "count", "op", "model", "flags", "vids", "reason")


def _value_texts(reg: Register) -> ByRaw:
    """A register's value as a column shows it, by raw value: the JSON's value (value_text) without quotes."""
    table = reg.cache.get("column")
    if table is None:
        json_text = value_text(reg, None)
        table = reg.cache["column"] = ByRaw(lambda x: _text(json.loads(json_text[x])))
    return table


def _places(layout: Layout, name: str) -> tuple[tuple[int, int | None, ByRaw], ...]:
    """Where the whole register ``name`` sits in ``layout.unpack_raw``'s values: (its index, the index of its
    record's VID or None, its texts by raw value), in field order; kept in the layout's cache."""
    key = ("column", name)
    got = layout.cache.get(key)
    if got is None:
        n = len(layout.parts)
        at = [(j, reg) for j, (_, _, reg, partial) in enumerate(layout.parts) if reg.name == name and not partial]
        if not layout.records:
            got = tuple((j, None, _value_texts(reg)) for j, reg in at)
        else:  # unpack_raw gives each record's VID, then its parts
            got = tuple((r * (n + 1) + 1 + j, r * (n + 1), _value_texts(reg))
                        for r in range(layout.records) for j, reg in at)
        layout.cache[key] = got
    return got


def _register(name: str) -> Column:
    """The values of the register ``name`` in a record, in its order (a long packet: one per servo it sets), read
    from the packet's bytes by its layout (no Field objects made)."""
    def column(rec: Record, only: set[int] | None) -> str:
        lay, data = rec.data_layout()
        if lay is None:
            return ""
        pieces = lay if isinstance(lay, list) else [(lay, data, None)]
        out = []
        for layout, d, vid in pieces:
            places = _places(layout, name)
            if not places:
                continue
            raw = layout.unpack_raw(d)
            for j, vid_at, texts in places:
                sid = vid if vid_at is None else raw[vid_at]
                if only is None or sid is None or sid in only:
                    out.append(texts[raw[j]])
        return OCCURRENCES.join(out)
    return column


class ColumnError(ValueError):
    """A column that is neither a key of the JSON lines nor a register of a loaded memory map."""


class Columns:
    """The columns ``names`` (JSON keys and register names), each checked as the maps are loaded."""

    def __init__(self, names: Iterable[str], registry: ModelRegistry) -> None:
        self.names = tuple(names)
        registers = {n for m in registry.models.values() for reg in m.registers if (n := reg.name) is not None}
        known = set(_DIRECT) | set(_OBJECT_KEYS) | set(ALIASES) | registers
        self._columns: list[Column] = []
        self._from_object: dict[int, Callable[[dict[str, Any]], str]] = {}  # by place: they share one object a line
        for given in self.names:
            name = ALIASES.get(given, given)
            if name in _DIRECT:
                self._columns.append(_DIRECT[name])
            elif name in _OBJECT_KEYS:
                self._from_object[len(self._columns)] = _from_object(name)
                self._columns.append(_later)
            elif name in registers:
                self._columns.append(_register(name))
            else:
                close = difflib.get_close_matches(name, sorted(known), n=1)
                hint = f" (did you mean {close[0]}?)" if close else ""
                raise ColumnError(f"no column {name!r}{hint}: a key of the JSON lines (type, t, id, op, latency_s, "
                                  f"diagnostics, ...) or a register's name (present_position, ...)")
        if not self._columns:
            raise ColumnError("no columns: name at least one (e.g. t,id,type,present_position)")

    def heading(self) -> str:
        return "\t".join(self.names) + "\n"

    def line(self, rec: Record, only: set[int] | None = None) -> str:
        cells = [col(rec, only) for col in self._columns]
        if self._from_object:
            obj = record_json(rec, only, fields=False)
            for k, col in self._from_object.items():
                cells[k] = col(obj)
        return "\t".join(cells) + "\n"


def parse_columns(text: str, registry: ModelRegistry) -> Columns:
    """``--fields t,id,present_position``: the names, comma-separated, spaces around them ignored."""
    return Columns([n.strip() for n in text.split(",") if n.strip()], registry)
