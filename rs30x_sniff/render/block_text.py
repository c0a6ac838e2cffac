"""decode's text lines from per-shape templates: a Block's rows without Records, a Record's without Fields."""

from __future__ import annotations

from typing import Any
from collections.abc import Callable, Iterable

from ..decode.blocks import Block
from ..decode.pairing import Record
from ..protocol.codegen import line_function
from ..protocol.events import RAW, Ack, Garbage, LongPacket, Nack, ReturnPacket, ShortPacket
from ..protocol.memmap import ByRaw, Field, Model, Register
from .records import (
    OWN_TIME, bad_sum, direction, field_text, is_shown, kind_word, packet_notes, text_line, verbose_lines)
from .times import NO_TIME, WIDTH
from ..protocol.wire import (
    AT_DATA, AT_ID, AT_LENGTH, FRAME_OVERHEAD, HEADER_SIZE, LONG_PACKET_ID, RETURN_FIRST, SUM_SIZE)

__all__ = ["block_text", "record_line"]

# Compiled shapes are kept across Blocks by the model they are for (Model.keep, a capture has a handful
# of shapes), a field's texts by its register.
MAX_TEXTS = 8192  # field texts kept per register (and separator)


class _Shape:
    """How to write the rows of one shape: ``raw(data)`` gives the raw integers of the packet's data
    (Layout.unpack_raw), ``fn(t, offset, raw, latency, request offset)`` the whole line. ``fn`` is None
    when the template could not be trusted: those rows go through Records."""

    __slots__ = ("raw", "fn")

    def __init__(self, raw: Callable | None, fn: Callable | None) -> None:
        self.raw, self.fn = raw, fn


def _field_text(reg: Register, partial: str | None, sep: str) -> Callable[[int], str]:
    """raw value -> the text a field of this value adds to a line (``sep`` + ``label=value``, or "" when
    render.is_shown hides it), by render's own field_text from a Field of that value.

    The value is Register.value_of, the reference of what Layout.values computes (tests/protocol/
    test_codegen.py holds them equal), and format_value reads nothing of a Field but its register,
    partial, raw value and value: so the text is the one the record path writes."""
    value_of = reg.value_of
    address = reg.address if not partial else reg.address + (partial == "high")

    def text(x: int) -> str:
        f = Field(None, address, reg, b"", x, value_of(x, partial), partial)
        return sep + field_text(f) if is_shown(f) else ""

    return text


def _texts(reg: Register, partial: str | None, sep: str) -> ByRaw:
    """A field's texts by raw value (_field_text), made on first use and kept in the register's cache;
    noise in a 2-byte field could fill 65536 of them: the first MAX_TEXTS are kept."""
    key = ("text", partial, sep)
    memo = reg.cache.get(key)
    if memo is None:
        memo = reg.cache[key] = ByRaw(_field_text(reg, partial, sep), MAX_TEXTS)
    return memo


def _join_shown(prefix: str, items: tuple) -> str:
    """A long packet's group of one VID: ``prefix`` and the shown items, or nothing if none is shown."""
    shown = ",".join([x for x in items if x])
    return prefix + shown if shown else ""


def block_text(blk: Block, only: set[int] | None = None, verbose: bool = False,
               rows: Iterable[int] | None = None, times: list | None = None) -> str:
    """What decode's TextSink writes for the rows of ``blk`` (``rows``: those row indexes alone, in
    ascending order): ``text_line(rec, only)`` and a newline per record, with ``verbose`` its field tree.
    ``times``: the time each row shows (render.times, one per row of the Block: seconds or texts), by
    default the rows' own; a row's line is then ``text_line(rec, only, at=times[k])``.

    Byte for byte the same text as rendering ``blk.records()``. While the Block's records have not all
    been built (then the linter found its rows quiet: no findings), each row is written from a
    template compiled once per shape of packet and filled from the run's bytes and columns, with no
    Record or Field made; a row already built as a Record (the tracker and the linter keep one or two,
    which may yet be given findings) is written from that Record.
    """
    if verbose or blk.linted_by_rows:
        # A full list: the linter went through the rows one by one, and they may carry findings. The
        # field tree (verbose) has no template either: both are written from the Records.
        return _records_text(blk, only, verbose, rows, times)
    run = blk.run
    lo, n = blk.lo, len(blk)
    blob, base = run.blob, run.base
    starts = run.starts[lo:blk.hi].tolist()
    ends = run.ends[lo:blk.hi].tolist()
    t0 = blk.t0
    lat = blk.latencies()
    ts: list[Any]
    lats: list[float | None]
    if t0 is not None and lat is not None:  # (a timed Block has both)
        ts = t0.tolist() if times is None else times
        lats = lat.tolist()
        # How the time is written: a number of seconds, or a text made by render.times (absolute, delta).
        tspec = "" if n and type(ts[0]) is str else f"{WIDTH}.6f"
    else:
        ts = lats = [None] * n
        tspec = None
    made = blk.made_rows
    only_key = None if only is None else frozenset(only)
    local: dict[tuple, _Shape] = {}  # this Block's shapes by their bytes (the models are the Block's)
    out: list[str] = []
    append = out.append
    for k in (range(n) if rows is None else rows):
        if made:
            rec = made.get(k)
            if rec is not None:
                append(record_line(rec, only, ts[k] if times is not None else OWN_TIME))
                continue
        s = starts[k]
        e = ends[k]
        h = blob[s:s + HEADER_SIZE]  # sync, ID, flag, address, length, count: with the frame's size, the shape
        if h[AT_ID] != LONG_PACKET_ID or h[0] == RETURN_FIRST:
            x = lats[k]
            # A reply with no latency (read with its request) has none in its line: a shape of its own.
            key: tuple[Any, ...] = (h, e - s) if x is None or x == x else (h, e - s, None)
        else:  # a long packet: its VIDs too (every record starts with one)
            key = (h, e - s, blob[s + AT_DATA:e - SUM_SIZE:h[AT_LENGTH]] if h[AT_LENGTH] else b"")
        shape = local.get(key)
        if shape is None:
            shape = local[key] = _shape(blk, k, key, only, only_key, tspec, ts[k])
        fn = shape.fn
        if fn is None:
            append(text_line(blk.record(k), only, ts[k] if times is not None else OWN_TIME) + "\n")
            continue
        raw = shape.raw
        # The row before a return is its request (a Block pairs nothing else); for other rows the
        # request offset is not used.
        append(fn(ts[k], base + s, raw(blob[s + AT_DATA:e - SUM_SIZE]) if raw is not None else None, lats[k],
                  base + starts[k - 1]))
    return "".join(out)


def record_line(rec: Record, only: set[int] | None = None, at: Any = OWN_TIME) -> str:
    """``text_line(rec, only, at)`` and a newline, from its shape's template where it has one: the record
    path's lines (a live port, a pipe) without building the record's Field objects; ``at`` is the time
    shown (render.times), by default the record's own.

    A shape here is a Block's (header bytes, size, model) and what a Block's rows share but single
    records do not: the pairing (status, request, latency) and whether the record has times; it is
    kept by the record's model. A record with findings, a bad Sum, no header (ACK, NACK, garbage) or
    no model is written by text_line itself."""
    ev = rec.event
    t = type(ev)
    model = rec.model
    if at is OWN_TIME:
        at = ev.t_start
    if (rec.findings or not (t is ShortPacket or t is ReturnPacket or t is LongPacket) or not ev.checksum_ok
            or model is None):
        return text_line(rec, only, at) + "\n"
    lay, data = rec.data_layout()
    # A long packet to servos of mixed models has a layout per servo: the shape is theirs together.
    layouts = (lay,) if type(lay) is not list else tuple([sub for sub, _, _ in lay])
    raw = ev[RAW]
    request = rec.request
    latency = rec.latency
    key = ("text record", raw[:HEADER_SIZE], len(raw),
           raw[AT_DATA:-SUM_SIZE:raw[AT_LENGTH]] if t is LongPacket and raw[AT_LENGTH] else b"",
           layouts, _time_spec(at), rec.status, request is not None, latency is not None,
           None if only is None else frozenset(only))
    shape = model.cache.get(key)
    if shape is None:
        shape = _record_shape(rec, model, key, only, at)
    fn = shape.fn
    if fn is None:
        return text_line(rec, only, at) + "\n"
    unpack = shape.raw
    return fn(at, ev.offset, unpack(data) if unpack is not None else None, latency,
              request.offset if request is not None else None)


def _time_spec(at: Any) -> str | None:
    """How a shape writes its time: None (no time: a dash), a number's format, or "" (a text already made)."""
    if at is None:
        return None
    return "" if type(at) is str else f"{WIDTH}.6f"


def _record_shape(rec: Record, model: Model, key: tuple, only: set[int] | None, at: Any) -> _Shape:
    """A single record's compiled shape, checked once against text_line as a Block's are."""
    raw, fn = _compile(rec, only, _time_spec(at))
    if fn is not None:
        ev = rec.event
        request = rec.request
        got = fn(at, ev.offset, raw(ev[RAW][AT_DATA:-SUM_SIZE]) if raw is not None else None, rec.latency,
                 request.offset if request is not None else None)
        if got != text_line(rec, only, at) + "\n":
            fn = None
    return model.keep(key, _Shape(raw, fn))


def _records_text(blk: Block, only: set[int] | None, verbose: bool, rows: Iterable[int] | None,
                  times: list | None = None) -> str:
    """TextSink.line of each record (its sink is not imported here: sinks may come to use this module)."""
    recs = blk.records()
    ks = range(len(recs)) if rows is None else rows
    ats = [OWN_TIME] * len(recs) if times is None else times
    if verbose:
        return "".join(text_line(recs[k], only, ats[k]) + "\n" + "\n".join(verbose_lines(recs[k])) + "\n"
                       for k in ks)
    return "".join([record_line(recs[k], only, ats[k]) for k in ks])


# ---- compiling a shape --------------------------------------------------------------------------
def _shape(blk: Block, k: int, key: tuple, only: set[int] | None, only_key: frozenset | None,
           tspec: str | None, at: Any) -> _Shape:
    """The compiled shape of row ``k``, from the cache of the model it is for (a long packet's: the
    Block's default model, with the models of its VIDs in the key); ``tspec`` is how its time is written
    (_time_spec), ``at`` the row's shown time."""
    h = key[0]
    is_long = h[AT_ID] == LONG_PACKET_ID and h[0] != RETURN_FIRST
    if is_long:
        vm = blk.vid_models
        vid_models = None if vm is None or not h[AT_LENGTH] else tuple([vm[v] for v in key[2]])
        owner = blk.default
        gkey: tuple[Any, ...] = ("text", tspec, key, vid_models, only_key)
    else:
        owner = blk.models[h[AT_ID]]
        gkey = ("text", tspec, key)
    shape = owner.cache.get(gkey)
    if shape is not None:
        return shape
    sample = blk.fresh_record(k)
    raw, fn = _compile(sample, only, tspec)
    if fn is not None:
        # The template against the record path on its first row: what depends on the data comes from
        # render's own functions (_field_text), the rest is checked here once; a mismatch (a case this
        # module does not know) sends the shape's rows through Records instead.
        ev = sample.event
        data = ev[RAW][AT_DATA:-SUM_SIZE]
        got = fn(at, ev.offset, raw(data) if raw is not None else None, sample.latency,
                 sample.request.offset if sample.request is not None else None)
        if got != text_line(sample, only, at) + "\n":
            fn = None
    return owner.keep(gkey, _Shape(raw, fn))


def _compile(rec: Record, only: set[int] | None, tspec: str | None) -> tuple[Callable | None, Callable | None]:
    """(raw, fn) of the record's shape: ``fn(t, offset, raw, latency, request offset)``, the line as one
    generated f-string (protocol.codegen.line_function, from the pieces worked out here); ``tspec``: how
    ``t`` is written (_time_spec)."""
    ev = rec.event
    kind = ev.kind
    if type(ev) is Garbage or type(ev) is Ack or type(ev) is Nack or rec.findings:  # only packets have shapes
        return None, None
    # Literal text, or (what, ...) for codegen.line_function: an argument, a text by raw value, a group.
    pieces: list[Any] = []
    pieces.append(("arg", "t", tspec) if tspec is not None else NO_TIME)
    pieces += [" @", ("arg", "o", "<8"), f" {direction(rec):<5} "]
    pieces.append(kind_word(rec) + ("(BAD-SUM)" if bad_sum(rec) else ""))
    if kind != "long":
        pieces.append(f" id={ev.id}")
    raw: Callable | None = None
    lay, data = rec.data_layout()
    if kind != "long":
        if lay is not None:
            raw = lay.unpack_raw
            for j, (_, _, reg, partial) in enumerate(lay.parts):
                pieces.append(("text", _texts(reg, partial, " "), j))
    elif lay is not None:
        # Items per VID: (raw index, register, partial), in field order.
        items: list[tuple[int, int, Register, str | None]] = []
        if isinstance(lay, list):
            at = 0
            for sub, _, vid in lay:
                items += [(vid, at + j, reg, partial) for j, (_, _, reg, partial) in enumerate(sub.parts)]
                at += len(sub.parts)
            raw = _mixed_raw(ev, [sub for sub, _, _ in lay])
        else:
            raw = lay.unpack_raw
            stride = len(lay.parts) + 1  # unpack_raw has each record's VID before its parts
            for i in range(lay.records):
                vid = data[i * (lay.size + 1)]
                items += [(vid, i * stride + 1 + j, reg, partial) for j, (_, _, reg, partial) in enumerate(lay.parts)]
        by_vid: dict[int, list[tuple[int, Register, str | None]]] = {}
        for vid, at, reg, partial in items:
            if only is None or vid in only:
                by_vid.setdefault(vid, []).append((at, reg, partial))
        assert type(ev) is LongPacket  # (kind is "long")
        vids = [r.vid for r in ev.records]
        for vid, group in by_vid.items():
            hidden = [reg.name is None for _, reg, _ in group]
            if not any(hidden):
                pieces.append(f" {vid}:")
                for j, (at, reg, partial) in enumerate(group):
                    pieces.append(("text", _texts(reg, partial, "," if j else ""), at))
            elif vids.count(vid) > 1:
                # A VID met twice, with items that may hide: where its group stands depends on the data.
                return None, None
            else:
                pieces.append(("join", _join_shown, f" {vid}:",
                               tuple((_texts(reg, partial, ""), at) for at, reg, partial in group)))
    pieces += [" " + note for note in packet_notes(rec)]
    if rec.is_reply:
        if rec.request is not None:
            pieces += [" reply_to=@", ("arg", "q", "")]
        if rec.latency is not None:
            pieces += [" latency=", ("arg", "l", ".3f", 1e3), "ms"]
        if rec.status and rec.status != "paired":
            pieces.append(" " + rec.status.upper())
    elif rec.status == "missing":
        pieces.append(" NO-REPLY")
    elif rec.status == "unknown":
        pieces.append(" CAPTURE-ENDED")
    pieces.append("\n")
    return raw, line_function(pieces)


def _mixed_raw(ev: Any, subs: list) -> Callable:
    """unpack_raw of a long packet to servos of different models: each record's layout on its bytes."""
    length = ev.length
    size = len(ev[RAW]) - FRAME_OVERHEAD
    spans = [(sub.unpack_raw, i * length + 1, min(i * length + length, size)) for i, sub in enumerate(subs)]

    def raw(data: bytes) -> tuple:
        out: tuple = ()
        for unpack, a, b in spans:
            out += unpack(data[a:b])
        return out

    return raw
