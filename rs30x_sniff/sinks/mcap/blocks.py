"""A Block's MCAP messages (packets, servo states, transactions) from templates: what JsonChannels.record
writes for each row, byte for byte, without building the rows' Records."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

import numpy as np

from ...render.block_json import block_json_rows, json_template
from ...decode.frame_runs import LONG
from ...protocol.mcap_names import PACKETS_TOPIC, TRANSACTIONS_TOPIC
from ...protocol.memmap import Layout
from ...protocol.wire import (
    AT_ADDRESS, AT_COUNT, AT_DATA, AT_ID, AT_LENGTH, BROADCAST_ID, FRAME_OVERHEAD, HEADER_SIZE, SUM_SIZE)
from ...render.layout_json import MixedParts, long_plan, value_text
from .transactions import transaction_json

if TYPE_CHECKING:  # names for the checker; no import at run time
    from ...decode.blocks import Block

_encode = json.JSONEncoder(separators=(",", ":"), check_circular=False).encode
_TX_SLOTS = ("request_offset", "t_request", "request_raw", "reply_offset", "t_reply", "reply_raw", "latency_s")


def _named_plan(layout: Layout) -> tuple:
    """For each record of the layout (one for a short packet or a return): the index of its VID in
    ``unpack_raw`` (None without one) and each whole named register as (raw index, name, '"name":', text
    by raw value) — Layout.named_values with each value's JSON text (JsonChannels' _fragment) looked up.
    Kept in the layout's cache."""
    plan = layout.cache.get("mcap states")
    if plan is not None:
        return plan
    n = len(layout.parts)
    named = [(j, reg) for j, (_, _, reg, partial) in enumerate(layout.parts) if reg.name is not None and not partial]
    if not layout.records:
        plan = ((None, tuple((j, reg.name, f'"{reg.name}":', value_text(reg, None)) for j, reg in named)),)
    else:
        plan = tuple((r * (n + 1), tuple((r * (n + 1) + 1 + j, reg.name, f'"{reg.name}":', value_text(reg, None))
                                         for j, reg in named)) for r in range(layout.records))
    layout.cache["mcap states"] = plan
    return plan


def _state_plan(raw: bytes, kind: int, model: Any, vid_models: Any) -> tuple[Any, tuple]:
    """What the servo states of a row of ``raw``'s shape read: (unpack, ((servo or None, VID index, parts),
    ...)) for one layout, whose values one unpack gives, or (None, ((servo, parts, unpack, start, end), ...))
    for a long packet to servos of mixed models, a record's slice of the data each; only the records that
    name registers, in field order."""
    n = len(raw) - FRAME_OVERHEAD
    layout: Layout | MixedParts | None = None
    if kind == LONG:
        if raw[AT_LENGTH] and n > 0:
            if vid_models is None:
                layout = model.long_layout(raw[AT_ADDRESS], raw[AT_LENGTH], raw[AT_COUNT])
            else:
                layout = long_plan(raw, vid_models)
    elif n > 0:
        layout = model.layout(raw[AT_ADDRESS], n)
    if layout is None:
        return None, ()
    if isinstance(layout, tuple):  # MixedParts (a Layout is no tuple)
        return None, tuple((tid, parts, sub.unpack_raw, a, b) for sub, a, b, tid in layout
                           for parts in (_named_plan(sub)[0][1],) if parts)
    return layout.unpack_raw, tuple((raw[AT_ID] if vid_at is None else None, vid_at, parts)
                                    for vid_at, parts in _named_plan(layout) if parts)


def _tx_template(blk: Block, k: int, model: Any, key: tuple) -> tuple[str | None, tuple[str, ...]]:
    """The /rs30x/transactions body of row ``k``'s shape with a %s where each row differs (None when
    the row's request expects no reply: no message) and the slots; kept by ``model``, the row's."""
    rec = blk.record(k)
    tpl: tuple[str | None, tuple[str, ...]] = (None, ())
    if rec.expects is not None:
        tpl = json_template(transaction_json(rec), _TX_SLOTS, _encode, strings=("request_raw", "reply_raw"))
    return model.keep(key, tpl)


def _log_times(origin: float, byte_time: float, t0: Any, starts: Any, base: int) -> list[int]:
    """log_time_ns(time_of(t, offset)) of every row at once: the same float operations in the same order
    (origin + t, or origin + offset * byte_time; times 1e9, rounded half to even), so the same integers."""
    x = origin + (t0 if t0 is not None else (base + starts.astype(np.int64)).astype(np.float64) * byte_time)
    ns = np.rint(x * 1e9)
    return np.where(x > 0, ns, 0.0).astype(np.int64).tolist()


def block_messages(ch: Any, blk: Block, emit: Any) -> None:
    """Emit (log_time, channel, body) for each row of ``blk`` as ``ch.record`` would, in the same order:
    the packet, the state of each servo it sets, the transaction of a request that expects a reply."""
    if blk.linted_by_rows:
        for rec in blk.records():
            ch.record(rec)
        return
    run = blk.run
    blob, lo, base = run.blob, blk.lo, run.base
    starts, ends = run.starts[lo:blk.hi].tolist(), run.ends[lo:blk.hi].tolist()
    kinds = blk.cols["kind"].tolist()
    c0, lats = blk.t0, blk.latencies()
    timed = c0 is not None
    t0: list[Any] = c0.tolist() if c0 is not None else []  # (read only when timed)
    lat: list[Any] = lats.tolist() if lats is not None else []
    answered = blk.answered.tolist()
    packets = block_json_rows(blk, None, compact=True)
    log_times = _log_times(ch.origin, ch.byte_time,
                           c0, run.starts[lo:blk.hi], base)
    cid_packets = ch.channel(PACKETS_TOPIC, "rs30x.Packet")
    cid_tx = None
    servos = ch.servos
    models, known = servos.models, servos.known
    slot = ch.state_slot
    state_models = ch.model_names
    blk_models, default, vid_models = blk.models, blk.default, blk.vid_models
    plans: dict[tuple, tuple] = {}               # a row's shape -> _state_plan (the Block's models are fixed)
    slot_of: dict[int, tuple[Any, dict[str, str]]] = {}  # ch.state_slot's, kept for the Block
    for k, (s, e, kind, log_time) in enumerate(zip(starts, ends, kinds, log_times)):
        offset = base + s
        t = t0[k] if timed else None
        emit((log_time, cid_packets, packets[k].encode()))
        raw = blob[s:e]
        if kind == LONG:
            model = default
            shape = (raw[:HEADER_SIZE], e - s, raw[AT_DATA:-SUM_SIZE:raw[AT_LENGTH] or 1])
        else:
            sid = raw[AT_ID]
            model = blk_models[sid]
            if sid != BROADCAST_ID:
                models[sid] = model.name  # ServoStates.changes: the model name the servo's records used
            shape = (raw[:HEADER_SIZE], e - s, b"")
        plan = plans.get(shape)
        if plan is None:
            plan = plans[shape] = _state_plan(raw, kind, model, vid_models)
        unpack, entries = plan
        if entries:
            data = raw[AT_DATA:-SUM_SIZE]
            if unpack is not None:
                values = unpack(data)
                items = [(fixed if vid_at is None else values[vid_at], parts, values)
                         for fixed, vid_at, parts in entries]
            else:
                items = [(tid, parts, sub(data[a:b])) for tid, parts, sub, a, b in entries]
            # Each servo's fragments are set as its parts come (a servo named twice keeps the later
            # value, as when its pairs were gathered first); one message per servo after them all.
            changed: dict[int, tuple[Any, dict[str, str]]] = {}
            for tid, parts, values in items:
                got = changed.get(tid)
                if got is None:
                    got = slot_of.get(tid)
                    if got is None:
                        got = slot_of[tid] = slot(tid)
                    changed[tid] = got
                    known[tid] = None
                st = got[1]
                for at, name, prefix, text in parts:
                    st[name] = prefix + text[values[at]]
            if changed:
                tail = f',"t":{"null" if t is None else repr(t)},"offset":{offset},'
                fallback = model.name
                for tid, (cid, st) in changed.items():
                    body = f'{{"id":{tid},"model":"{state_models.get(tid) or fallback}"{tail}{",".join(st.values())}}}'
                    emit((log_time, cid, body.encode()))
        if answered[k]:
            # A reply with no latency (read with its request): a transaction without one, a shape of its own.
            key = ("mcap transaction", raw[:HEADER_SIZE], e - s, timed, timed and lat[k + 1] != lat[k + 1])
            tpl = model.cache.get(key)
            if tpl is None:
                tpl = _tx_template(blk, k, model, key)
            fmt, slots = tpl
            if fmt is not None:
                vals = []
                for name in slots:
                    if name == "request_offset":
                        vals.append(str(offset))
                    elif name == "t_request":
                        vals.append(repr(t))
                    elif name == "request_raw":
                        vals.append(raw.hex())
                    elif name == "reply_offset":
                        vals.append(str(base + ends[k]))
                    elif name == "t_reply":
                        vals.append(repr(t0[k + 1]))
                    elif name == "reply_raw":
                        vals.append(blob[ends[k]:ends[k + 1]].hex())
                    else:
                        vals.append(repr(lat[k + 1]))
                if cid_tx is None:
                    cid_tx = ch.channel(TRANSACTIONS_TOPIC, "rs30x.Transaction")
                emit((log_time, cid_tx, (fmt % tuple(vals)).encode()))
