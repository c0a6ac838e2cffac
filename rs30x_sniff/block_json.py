"""A Block's rows as JSON lines (decode --format jsonl, MCAP packet bodies) from per-shape templates.

Byte-identical to ``render.record_json_text`` of each row's Record, without building the Records: rows
of one shape (header bytes, data length, model, long packet's VIDs) differ only in their offsets,
times, raw bytes, pairing and field values, so each shape's line is made once from a sample record,
with a ``%s`` where those go, and every row fills its template.
"""

from __future__ import annotations

import json
from typing import Any

from .frame_runs import LONG
from .render import _NO_FIELDS, record_json, record_json_text

_SPACED = json.JSONEncoder(check_circular=False).encode
_COMPACT = json.JSONEncoder(separators=(",", ":"), check_circular=False).encode
# Stand-ins for what varies between rows of one shape: JSON escapes NUL, and no real value holds one.
_SLOTS = ("offset", "t", "t_end", "raw", "reply_to", "reply", "latency_s")
_MARK = {k: f"\x00{k}\x00" for k in _SLOTS}
_TEMPLATES: dict[tuple, tuple[str, tuple[str, ...], Any, Any]] = {}  # key -> (format, slots, layout, model)
_MAX_TEMPLATES = 4096


def block_json_lines(blk: Any, only: set[int] | None = None, compact: bool = False, rows: Any = None) -> str:
    """The JSON line of each row (or of ``rows``, ascending indexes) of ``blk``, newline-terminated."""
    return "".join(block_json_rows(blk, only, compact, rows, "\n"))


def block_json_rows(blk: Any, only: set[int] | None = None, compact: bool = False, rows: Any = None,
                    end: str = "") -> list[str]:
    """The JSON text of each row (or of ``rows``), each followed by ``end``."""
    recs = blk._records
    if isinstance(recs, list) or blk.vid_models is not None:
        # Rows checked one by one (they may carry findings), or servos of mixed models: the records.
        recs = blk.records()
        chosen = recs if rows is None else [recs[k] for k in rows]
        return [record_json_text(r, only, compact) + end for r in chosen]
    return _lines(blk, only, compact, rows, end)


def _lines(blk: Any, only: set[int] | None, compact: bool, rows: Any, end: str) -> list[str]:
    run = blk.run
    blob, lo = run.blob, blk.lo
    starts = run.starts[lo:blk.hi].tolist()
    ends = run.ends[lo:blk.hi].tolist()
    base = run.base
    kinds = blk.cols["kind"].tolist()
    timed = blk.t0 is not None
    if timed:
        t0, t1 = blk.t0.tolist(), blk.t1.tolist()
        lat = blk.latencies().tolist()
    models, default = blk.models, blk.default
    only_key = None if only is None else frozenset(only)
    out = []
    get = _TEMPLATES.get
    for k in (range(len(starts)) if rows is None else rows):
        s, e = starts[k], ends[k]
        raw = blob[s:e]
        kind = kinds[k]
        if kind == LONG:
            model = default
            key = (raw[:7], e - s, id(model), raw[7:-1:raw[5] or 1], timed, compact, only_key)
        else:
            model = models[raw[2]]
            key = (raw[:7], e - s, id(model), b"", timed, compact, only_key)
        tpl = get(key)
        if tpl is None or tpl[3] is not model:  # (an id is reused once its model is gone)
            tpl = _template(blk, k, key, only, compact)
        fmt, slots, layout, _ = tpl
        vals = []
        for name in slots:
            if name == "offset":
                vals.append(str(base + s))
            elif name == "t":
                vals.append(repr(t0[k]))
            elif name == "t_end":
                vals.append(repr(t1[k]))
            elif name == "raw":
                vals.append(raw.hex())
            elif name == "reply_to":
                vals.append(str(base + starts[k - 1]))
            elif name == "reply":
                vals.append(str(base + starts[k + 1]))
            elif name == "latency_s":
                vals.append(repr(lat[k]))
            else:  # fields
                if layout is None:
                    vals.append("")
                else:
                    data = raw[7:-1]
                    vals.append(layout.fields_json(data, layout.values(data), 0 if kind == LONG else raw[2],
                                                   only, compact))
        out.append(fmt % tuple(vals) + end)
    return out


def _template(blk: Any, k: int, key: tuple, only: set[int] | None, compact: bool) -> tuple:
    """The line of row ``k``'s shape with a %s for each part that varies, and the layout of its fields."""
    rec = blk.record(k)
    obj = record_json(rec, only, fields=False)
    slots = []
    for name in _SLOTS:
        if obj.get(name) is not None:
            obj[name] = _MARK[name]
    encode = _COMPACT if compact else _SPACED
    text = encode(obj).replace("%", "%%")
    # Where each stand-in sits, in order of appearance in the line.
    found = []
    for name in _SLOTS:
        mark = encode(_MARK[name])
        at = text.find(mark)
        if at >= 0:
            found.append((at, name, mark))
    layout = None
    ev = rec.event
    if ev.kind == "long":
        if ev.length and ev.records:
            layout = rec.model.long_layout(ev.address, ev.length, ev.count)
    elif ev[9]:
        layout = rec.model.layout(ev.address, len(ev[9]))
    empty = _NO_FIELDS[compact]
    at = text.find(empty)
    found.append((at, "fields", empty))
    found.sort()
    for _, name, mark in found:
        put = empty[:-1] + "%s]" if name == "fields" else ('"%s"' if name == "raw" else "%s")  # raw: a string
        text = text.replace(mark, put, 1)
        slots.append(name)
    tpl = (text, tuple(slots), layout, rec.model)
    if len(_TEMPLATES) >= _MAX_TEMPLATES:
        _TEMPLATES.clear()
    _TEMPLATES[key] = tpl
    return tpl

