"""JSON lines (decode --format jsonl, MCAP packet bodies) from per-shape templates: a Block's rows, and
single Records.

Byte-identical to ``render.record_json_text`` of each row's Record, without building the Records: rows
of one shape (header bytes, data length, model, long packet's VIDs) differ only in their offsets,
times, raw bytes, pairing and field values, so each shape's line is made once from a sample record,
with a ``%s`` where those go, and every row fills its template. A single Record's shape also says
which of those are there at all (its pairing, its times), which in a Block's rows is always the same.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from itertools import islice
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from ..protocol.events import OFFSET, RAW, LongPacket, ReturnPacket, ShortPacket
from ..protocol.wire import AT_DATA, AT_ID, AT_LENGTH, FRAME_OVERHEAD, HEADER_SIZE, SUM_SIZE
from ..decode.frame_runs import LONG
from .layout_json import MixedJson, fields_json, long_plan, record_fields_json
from .records import COMPACT, NO_FIELDS, SPACED, record_json, record_json_text

if TYPE_CHECKING:  # names for the checker; no import at run time
    from ..decode.blocks import Block
    from ..decode.pairing import Record

# What varies between rows of one shape (besides the fields). The templates are kept by the model
# they are for (Model.keep): (format, slots, layout) of a Block's rows, (format, slots) of a Record's.
_SLOTS = ("offset", "t", "t_end", "raw", "reply_to", "reply", "latency_s")
# Lines of a Block's JSON text written at once (block_json_pieces): about 1.4 MB of decode's lines.
PIECE_LINES = 1024


class NonFiniteError(ValueError):
    """A time or latency that is NaN or infinite reached the JSON writer: JSON has no text for it.

    Sources refuse such times as input errors (with where they are); this is the guard behind them,
    so a line is never written with ``NaN`` or ``Infinity`` (or Python's ``inf``) in it.
    """


def _not_finite(offset: int, what: str, value: float) -> NonFiniteError:
    return NonFiniteError(f"the packet at byte {offset}: {what} {value!r} is not a finite number (JSON has none)")


def block_json_lines(blk: Block, only: set[int] | None = None, compact: bool = False, rows: Any = None) -> str:
    """The JSON line of each row (or of ``rows``, ascending indexes) of ``blk``, newline-terminated."""
    return "".join(block_json_rows(blk, only, compact, rows, "\n"))


def block_json_pieces(blk: Block, only: set[int] | None = None, rows: Any = None,
                      lines: int = PIECE_LINES) -> Iterator[str]:
    """``block_json_lines`` in pieces of ``lines`` lines each: a long Block's text (1.4 kB a row) is never
    held whole, so what decode --format jsonl holds does not grow with the Block."""
    if blk.linted_by_rows:
        yield block_json_lines(blk, only, rows=rows)
        return
    it = _line_iter(blk, only, False, rows, "\n")
    while True:
        piece = "".join(islice(it, lines))
        if not piece:
            return
        yield piece


def block_json_rows(blk: Block, only: set[int] | None = None, compact: bool = False, rows: Any = None,
                    end: str = "") -> list[str]:
    """The JSON text of each row (or of ``rows``), each followed by ``end``."""
    if blk.linted_by_rows:
        # Rows checked one by one (they may carry findings): the records.
        recs = blk.records()
        chosen = recs if rows is None else [recs[k] for k in rows]
        return [record_json_line(r, only, compact) + end for r in chosen]
    return list(_line_iter(blk, only, compact, rows, end))


def _line_iter(blk: Block, only: set[int] | None, compact: bool, rows: Any, end: str) -> Iterator[str]:
    run = blk.run
    blob, lo = run.blob, blk.lo
    starts = run.starts[lo:blk.hi].tolist()
    ends = run.ends[lo:blk.hi].tolist()
    base = run.base
    kinds = blk.cols["kind"].tolist()
    c0, c1 = blk.t0, blk.t1
    timed = c0 is not None
    if c0 is not None and c1 is not None:  # (a timed Block has both, and its latencies)
        for what, col in (("t", c0), ("t_end", c1)):
            bad = ~np.isfinite(col)
            if bad.any():  # one check a Block, not one a row
                k = int(np.argmax(bad))
                raise _not_finite(base + starts[k], what, float(col[k]))
        t0, t1 = c0.tolist(), c1.tolist()
        lats = blk.latencies()
        assert lats is not None
        lat = lats.tolist()
    models, default, vid_models = blk.models, blk.default, blk.vid_models
    only_key = None if only is None else frozenset(only)
    for k in (range(len(starts)) if rows is None else rows):
        s, e = starts[k], ends[k]
        raw = blob[s:e]
        kind = kinds[k]
        if kind == LONG:
            model = default
            vids = raw[AT_DATA:-SUM_SIZE:raw[AT_LENGTH] or 1]
            # Servos of mixed models: the VIDs' models are part of the shape (a model learned later changes it).
            key: tuple[Any, ...] = ("json", raw[:HEADER_SIZE], e - s, vids, timed, compact, only_key,
                   None if vid_models is None or not raw[AT_LENGTH] else tuple([vid_models[v].name for v in vids]))
        else:
            model = models[raw[AT_ID]]
            # A reply with no latency (read with its request) has none in its line: a shape of its own.
            key = ("json", raw[:HEADER_SIZE], e - s, b"", timed, compact, only_key, timed and lat[k] != lat[k])
        tpl = model.cache.get(key)
        if tpl is None:
            tpl = _template(blk, k, model, key, only, compact)
        fmt, slots, layout = tpl
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
                x = lat[k]
                if x - x != 0.0:  # NaN or infinite (a difference of finite times never is)
                    raise _not_finite(base + s, "latency_s", x)
                vals.append(repr(x))
            else:  # fields
                if layout is None:
                    vals.append("")
                elif type(layout) is MixedJson:  # a long packet to servos of mixed models
                    vals.append(layout.text(raw[AT_DATA:-SUM_SIZE], only, compact))
                else:
                    data = raw[AT_DATA:-SUM_SIZE]
                    # fields_json reads the values only to pick fields by ID (``only``)
                    vals.append(fields_json(layout, data, () if only is None else layout.values(data),
                                            0 if kind == LONG else raw[AT_ID], only, compact))
        yield fmt % tuple(vals) + end


def json_template(obj: dict[str, Any], slots: tuple[str, ...], encode: Any, strings: tuple[str, ...] = (),
                  literals: tuple[tuple[str, str, str], ...] = ()) -> tuple[str, tuple[str, ...]]:
    """``encode(obj)`` as a ``%`` format: a ``%s`` where each key of ``slots`` that is not None goes (in
    quotes for those in ``strings``), and where each ``(name, text, replacement)`` of ``literals`` is,
    with the slots' names in the order they appear. Each slot is stood in for by its name between NULs,
    which JSON escapes and no real value holds."""
    obj = dict(obj)
    marks = list(literals)
    for name in slots:
        if obj.get(name) is not None:
            obj[name] = f"\x00{name}\x00"
            marks.append((name, encode(obj[name]), '"%s"' if name in strings else "%s"))
    text = encode(obj).replace("%", "%%")
    found = sorted((text.find(mark), name, mark, put) for name, mark, put in marks)
    for _, _, mark, put in found:
        text = text.replace(mark, put, 1)
    return text, tuple(name for _, name, _, _ in found)


def _line_template(rec: Record, only: set[int] | None, compact: bool) -> tuple[str, tuple[str, ...]]:
    """record_json_text of ``rec`` as a ``%`` format: a %s for each of _SLOTS it has, and for the fields."""
    empty = NO_FIELDS[compact]
    return json_template(record_json(rec, only, fields=False), _SLOTS, COMPACT if compact else SPACED,
                         strings=("raw",), literals=(("fields", empty, empty[:-1] + "%s]"),))


def _template(blk: Block, k: int, model: Any, key: tuple, only: set[int] | None, compact: bool) -> tuple:
    """The line of row ``k``'s shape with a %s for each part that varies, and the layout of its fields;
    kept by ``model``, the row's."""
    rec = blk.record(k)
    text, slots = _line_template(rec, only, compact)
    # One Layout (or None); for a long packet to servos that may differ in model, long_plan's.
    ev = rec.event
    raw = ev[RAW]
    if type(ev) is LongPacket and blk.vid_models is not None and raw[AT_LENGTH] and len(raw) > FRAME_OVERHEAD:
        plan = long_plan(raw, blk.vid_models)
        return model.keep(key, (text, slots, MixedJson(plan) if isinstance(plan, tuple) else plan))
    return model.keep(key, (text, slots, rec.data_layout()[0]))


def record_json_line(rec: Record, only: set[int] | None = None, compact: bool = False) -> str:
    """``record_json_text(rec, only, compact)``, from its shape's template where it has one: the record
    path's JSON (a live port's MCAP packets, jsonl from a pipe) without a dict per record.

    A record with findings (its diagnostics), no header (ACK, NACK, garbage), no model or times that
    are not plain floats (whose text ``repr`` might not give as JSON does) is written by
    record_json_text itself. The fields are filled in by layout_json.record_fields_json, so the template
    holds no layout; it is kept by the record's model."""
    ev = rec.event
    t0, t1, latency = ev.t_start, ev.t_end, rec.latency
    # x - x is 0.0 for every finite number, NaN for NaN and the infinities: three checks on the hot path.
    if ((t0 is not None and t0 - t0 != 0.0) or (t1 is not None and t1 - t1 != 0.0)
            or (latency is not None and latency - latency != 0.0)):
        what, x = next((w, v) for w, v in (("t", t0), ("t_end", t1), ("latency_s", latency))
                       if v is not None and not math.isfinite(v))
        raise _not_finite(ev.offset, what, x)
    t = type(ev)
    model = rec.model
    if rec.findings or not (t is ShortPacket or t is ReturnPacket or t is LongPacket) or model is None:
        return record_json_text(rec, only, compact)
    if ((t0 is not None and type(t0) is not float) or (t1 is not None and type(t1) is not float)
            or (latency is not None and type(latency) is not float)):
        return record_json_text(rec, only, compact)
    raw = ev[RAW]
    request, reply = rec.request, rec.reply
    key = ("json record", raw[:HEADER_SIZE], len(raw),
           raw[AT_DATA:-SUM_SIZE:raw[AT_LENGTH]] if t is LongPacket and raw[AT_LENGTH] else b"",
           ev.checksum_ok, t0 is None, t1 is None, latency is None, request is None, reply is None,
           rec.status, compact, None if only is None else frozenset(only))
    tpl = model.cache.get(key)
    if tpl is None:
        tpl = model.keep(key, _line_template(rec, only, compact))
    vals = []
    for name in tpl[1]:
        if name == "offset":
            vals.append(str(ev[OFFSET]))
        elif name == "t":
            vals.append(repr(t0))
        elif name == "t_end":
            vals.append(repr(t1))
        elif name == "raw":
            vals.append(raw.hex())
        elif name == "reply_to":  # in the template only when there is a request (its key says)
            vals.append(str(cast("Record", request).offset))
        elif name == "reply":  # likewise only with a reply
            vals.append(str(cast("Record", reply).offset))
        elif name == "latency_s":
            vals.append(repr(latency))
        else:  # fields
            vals.append(record_fields_json(rec, only, compact))
    return tpl[0] % tuple(vals)
