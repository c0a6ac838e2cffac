"""The JSON text of a packet's fields, from per-layout templates: what ``json.dumps`` writes for the
objects of ``records.field_json``, without building Field objects or dicts.

A layout (protocol.memmap.Layout: the parts of one address range of a model) gets one ``%`` template
per part and, for the whole layout, one ``%`` format with a generated function filling it in
(protocol.codegen.percent_function): the hex of the data sliced per field, and each value's JSON text
looked up by its raw value (:func:`value_text`). The templates are kept in the layout's own cache
(``Layout.cache``), a value's texts in its register's (``Register.cache``).
"""

from __future__ import annotations

import json
import struct
from typing import Any, cast
from collections.abc import Callable

from ..decode.pairing import Record
from ..protocol.events import Packet
from ..protocol.codegen import SERVO, percent_function
from ..protocol.memmap import ByRaw, Layout, Register
from ..protocol.wire import AT_ADDRESS, AT_COUNT, AT_DATA, AT_LENGTH, FRAME_OVERHEAD, SUM_SIZE

__all__ = ["MixedJson", "MixedParts", "fields_json", "long_plan", "json_scalar", "mixed_fields_json",
           "record_fields_json", "value_text"]

_TEMPLATES = "json fields"  # Layout.cache key: ((per-part templates, whole fill) spaced, (...) compact)
_INF = float("inf")


def json_scalar(v: Any) -> str:
    """``json.dumps`` of a field value after ``records.json_value`` (floats rounded to 6 places)."""
    t = type(v)
    if t is float:
        if v != v or v == _INF or v == -_INF:
            return json.dumps(v)
        return repr(round(v, 6))
    if t is int:
        return repr(v)
    return json.dumps(round(v, 6) if isinstance(v, float) else v)


def value_text(reg: Register, partial: str | None) -> ByRaw:
    """The JSON text of a part's value, by raw value: :func:`json_scalar` of ``Register.value_of``
    (what ``Layout.values`` computes), made on first sight of a raw value and kept in the register's
    cache."""
    key = ("json", partial)
    table = reg.cache.get(key)
    if table is None:
        value_of = reg.value_of
        table = reg.cache[key] = ByRaw(lambda x: json_scalar(value_of(x, partial)))
    return table


def field_template(reg: Register, partial: str | None, compact: bool) -> str:
    """``%`` template of one field's JSON object (``compact``: no spaces after , and :); id, raw and
    value are filled in per packet."""
    address = reg.address if not partial else reg.address + (partial == "high")
    unit = None if partial else reg.unit
    c, k = (",", ":") if compact else (", ", ": ")

    def lit(x: Any) -> str:
        return json.dumps(x).replace("%", "%%")

    tail = f'{c}"partial"{k}{lit(partial)}' if partial else ""
    return (f'{{"id"{k}%s{c}"address"{k}{address}{c}"name"{k}{lit(reg.name)}{c}"raw"{k}"%s"{c}'
            f'"value"{k}%s{c}"unit"{k}{lit(unit)}{tail}}}')


def _templates(layout: Layout, compact: bool) -> tuple[tuple[str, ...], Any]:
    """The layout's per-part templates, and the whole layout's fill ``(d, h, r, s)``."""
    parts = layout.parts
    tmpl = tuple(field_template(reg, partial, compact) for _, _, reg, partial in parts)
    texts = [value_text(reg, partial) for _, _, reg, partial in parts]
    items: list[tuple] = []
    if not layout.records:
        for j, (start, size, _, _) in enumerate(parts):
            items += [SERVO, ("hex", 2 * start, 2 * (start + size)), ("text", texts[j], j)]
        fmt = ("," if compact else ", ").join(tmpl)
    else:
        stride, n = layout.size + 1, len(parts)
        for rec in range(layout.records):
            base = rec * stride + 1
            for j, (start, size, _, _) in enumerate(parts):
                # unpack_raw gives each record's VID, then its parts
                items += [("byte", base - 1), ("hex", 2 * (base + start), 2 * (base + start + size)),
                          ("text", texts[j], rec * (n + 1) + 1 + j)]
        fmt = ("," if compact else ", ").join(tmpl * layout.records)
    return tmpl, percent_function(fmt, items)


def fields_json(layout: Layout, data: bytes, values: tuple, servo_id: int | None = None,
                only: set[int] | None = None, compact: bool = False) -> str:
    """The JSON text of ``layout.fields(data, values, servo_id)`` (without the brackets), exactly as
    ``json.dumps`` writes the objects of ``records.field_json``: the same keys, order, spacing and
    rounding. ``only`` keeps the fields of those servo IDs alone; ``values`` are read only then."""
    cache = layout.cache.get(_TEMPLATES)
    if cache is None:
        cache = layout.cache[_TEMPLATES] = (_templates(layout, False), _templates(layout, True))
    tmpl, whole = cache[compact]
    if only is None:
        return whole(data, data.hex(), layout.unpack_raw(data), "null" if servo_id is None else str(servo_id))
    sep = "," if compact else ", "
    parts = layout.parts
    out = []
    if not layout.records:
        if servo_id not in only:
            return ""
        sid = "null" if servo_id is None else str(servo_id)
        for (start, size, _, _), t, v in zip(parts, tmpl, values):
            out.append(t % (sid, data[start:start + size].hex(), json_scalar(v)))
        return sep.join(out)
    stride = layout.size + 1
    n = len(parts)
    for rec in range(layout.records):
        base = rec * stride
        vid = data[base]
        if vid not in only:
            continue
        sid = str(vid)
        base += 1
        for j, ((start, size, _, _), t) in enumerate(zip(parts, tmpl)):
            out.append(t % (sid, data[base + start:base + start + size].hex(), json_scalar(values[rec * n + j])))
    return sep.join(out)


# A long packet to servos of mixed models has no one Layout: each record has its own servo's. Its fields, as a
# template keeps them: (layout, start, stop, VID) of each record's data within the packet's data.
MixedParts = tuple[tuple[Layout, int, int, int], ...]


def long_plan(raw: bytes, vid_models: dict[int, Any]) -> Layout | MixedParts:
    """The fields of a long packet's data (``raw``: the whole frame, Length and data there) when its servos may
    differ in model (``vid_models``: servo -> model): the long layout of their one model, or each record's
    (MixedParts), as Record.data_layout gives them. Kept in the first VID's model: a shape's, not a packet's."""
    length, count, address = raw[AT_LENGTH], raw[AT_COUNT], raw[AT_ADDRESS]
    vids = raw[AT_DATA:-SUM_SIZE:length]
    models = tuple([vid_models[v] for v in vids])
    first = models[0]
    key = ("long plan", address, length, len(raw), vids, tuple([m.name for m in models]))
    got = first.cache.get(key)
    if got is None:
        n = len(raw) - FRAME_OVERHEAD
        if n == length * count and all(m is first for m in models):
            got = first.long_layout(address, length, count)
        else:  # records ``length`` apart, each its VID and then its data (events.frame_event)
            spans = [(m, k * length + 1, min(k * length + length, n), vids[k]) for k, m in enumerate(models)]
            got = tuple((m.layout(address, b - a), a, b, vid) for m, a, b, vid in spans)
        got = first.keep(key, got)
    return got


class MixedJson:
    """The fields' JSON of one shape of long packet to servos of mixed models (its MixedParts): what
    :func:`mixed_fields_json` writes, from one generated fill of the whole packet's data (made on first use, for
    each spacing) where every servo's fields are wanted, instead of a fill per record."""

    __slots__ = ("parts", "fills")

    def __init__(self, parts: MixedParts) -> None:
        self.parts = parts
        self.fills: dict[bool, Callable[[bytes], str] | None] = {}

    def text(self, data: bytes, only: set[int] | None = None, compact: bool = False) -> str:
        """``mixed_fields_json(self.parts, data, only, compact)``."""
        if only is None:
            fills = self.fills
            if compact not in fills:
                fills[compact] = _mixed_fill(self.parts, compact)
            fill = fills[compact]
            if fill is not None:
                return fill(data)
        return mixed_fields_json(self.parts, data, only, compact)


def _mixed_fill(parts: MixedParts, compact: bool) -> Callable[[bytes], str] | None:
    """:func:`mixed_fields_json` of every servo as one ``%`` of one format (percent_function): the records' part
    templates one after the other, their raw values by one struct unpack of the whole data (each record's own
    layout's format, a pad byte for its VID before it); None when a layout has no struct format to join."""
    formats, templates, items = ["<"], [], []
    base = 0  # the raw values before this record's
    for sub, a, b, vid in parts:
        unpacker = getattr(sub.unpack_raw, "__self__", None)
        if not isinstance(unpacker, struct.Struct) or not unpacker.format.startswith("<") or unpacker.size != b - a:
            return None
        formats.append("x" + unpacker.format[1:])  # the record's VID (at a - 1), then its parts
        for j, (start, size, reg, partial) in enumerate(sub.parts):
            # The VID is the shape's (long_plan's key holds them): written into the template, the first %s (id).
            templates.append(field_template(reg, partial, compact).replace("%s", str(vid), 1))
            items += [("hex", 2 * (a + start), 2 * (a + start + size)), ("text", value_text(reg, partial), base + j)]
        base += len(sub.parts)
    whole = struct.Struct("".join(formats))
    if parts and whole.size != parts[-1][2]:  # the records, VIDs and all, are the whole data
        return None
    fill = percent_function(("," if compact else ", ").join(templates), items)
    unpack = whole.unpack
    return lambda data: fill(data, data.hex(), unpack(data), "")


def mixed_fields_json(parts: MixedParts, data: bytes, only: set[int] | None = None, compact: bool = False) -> str:
    """record_fields_json of a long packet to servos of mixed models, from its shape's MixedParts."""
    out = []
    for sub, a, b, vid in parts:
        d = data[a:b]
        text = fields_json(sub, d, () if only is None else sub.values(d), vid, only, compact)
        if text:
            out.append(text)
    return ("," if compact else ", ").join(out)


def record_fields_json(rec: Record, only: set[int] | None = None, compact: bool = False) -> str:
    """The JSON text of the record's fields' objects (``records.field_json``), without the brackets
    (``only``: those servo IDs); a long packet to servos of mixed models joins its servos' layouts."""
    lay, data = rec.data_layout()
    if lay is None:
        return ""
    if isinstance(lay, list):
        parts = [fields_json(sub, d, sub.values(d), vid, only, compact) for sub, d, vid in lay]
        return ("," if compact else ", ").join(p for p in parts if p)
    return fields_json(lay, data, rec.values, cast(Packet, rec.event).id, only, compact)  # a layout means a packet
