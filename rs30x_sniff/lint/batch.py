"""The linter's column form: a Block no enabled rule would speak about is checked with array operations.

:func:`quiet_block` either proves that feeding the Block's records one by one would produce no finding
and moves the linter's memory past them exactly as that would (shadows, counters, rule states), or
returns False having changed nothing, and the linter feeds the records one by one. Findings are the
same either way; the tests in tests/lint/test_batch.py compare the two on every rule's traffic.

Every rule has a column form here, by one of three means:
- rules that cannot fire on a Block's rows (garbage, corrupt frames, ACK/NACK, unpaired replies: a
  Block has none) or whose trigger is checked for on the columns (commands, flagged returns, writes of
  the registers they follow) and sends the Block to the record path;
- HEADER rules, pure functions of a packet's header, its model and (for a reply) its request's header:
  each distinct header is checked once with the rule's own check on a sample record, and remembered;
- the rules that read values, timing or the shadows (F004, F007, B006, M003, Q004, Q006, Q007), written
  out on the columns below, with the same arithmetic in the same order as their checks.
A rule not listed at all sends every Block to the record path, so a new rule is never skipped.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..decode.frame_runs import LONG, RETURN, SHORT
from ..protocol.wire import BROADCAST_ID, COMMAND_BITS
from .rules.direction import decide as decide_senders

# Pure in the packet's header (and model, and request header): checked once per distinct header.
HEADER = frozenset({"P001", "P002", "P003", "P004", "P005", "P006", "P007", "P010", "P011", "P012",
                    "M001", "M002", "M004", "B004", "B005"})
# Silent on a Block's rows whenever the checks below pass (what they watch sends the Block away).
SILENT = frozenset({"F001", "F002", "F003", "F005", "F006", "F008", "F009", "F010", "P008", "P009", "P013", "M005",
                    "B001", "B002", "B003", "B007", "B008", "B009", "S001", "S002", "S003", "S004",
                    "Q001", "Q002", "Q003", "Q005", "Q008", "Q009"})
# Written out on the columns here.
COLUMNS = frozenset({"F004", "F007", "B006", "M003", "Q004", "Q006", "Q007"})
KNOWN = HEADER | SILENT | COLUMNS
# Shadow registers a Block may change (rs30x_sniff.lint.state._TRACKED): the others (torque, limits,
# reverse, return delay, baud) change what later checks say, so a Block writing them takes the record path.
_MOVING = frozenset({"pos", "goal_time"})
_NONE = -(1 << 40)  # an unknown shadow value in an int64 column


class _Probe:
    """The linter as a HEADER rule sees it, but whose emit only notes that the rule spoke."""

    def __init__(self, lint: Any) -> None:
        self._lint = lint
        self.spoke = False

    def __getattr__(self, name: str) -> Any:
        return getattr(self._lint, name)

    def emit(self, *args: Any, **kwargs: Any) -> None:
        self.spoke = True

    emit_at = emit


def quiet_block(lint: Any, blk: Any) -> bool:
    """True if no enabled rule finds anything in ``blk``, with the linter moved past it; else False and
    the linter untouched."""
    if lint.timed is None:
        lint._setup(blk.t0 is not None)
    run = [r for r in lint.rules if lint.timed or not r.needs_time]
    codes = {r.code for r in run}
    if not codes <= KNOWN or not lint._counting:
        return False
    c = blk.cols
    kind, sid, flag = c["kind"], c["id"], c["flag"]
    address, length, dlen = c["address"].astype(np.int64), c["length"].astype(np.int64), c["data_len"]
    is_short, is_long, is_return = kind == SHORT, kind == LONG, kind == RETURN
    if (is_short & ((flag & COMMAND_BITS) != 0)).any():
        return False  # flash / reboot / initialize: command rules and their state (P008, P009, Q001-Q004)
    if (is_return & (flag != 0)).any():
        return False  # a status flag: P013, S001-S004, and the temperature lock Q009 reads
    if "M005" in codes and (is_return & (address == 0) & (dlen >= 2)).any():
        return False  # a model number to judge
    if "F009" in codes:
        tally = lint.state_of("F009")
        senders = decide_senders(tally, lint) if tally.senders is False else tally.senders
        if senders is not None:
            return False  # the capture says who sent what: each packet is checked against it
    prev = lint.prev
    if prev is not None and prev.event.kind == "garbage" and prev.event[4] == "truncated" \
            and prev.event.end_offset == int(blk.offsets[0]):
        return False  # B007: the first row starts where a cut-short frame ended
    if blk.vid_models is not None:
        return False  # servos of mixed models in long packets: per-record plans
    # Q008: the servo IDs the bus has seen, with these.
    long_rows = np.flatnonzero(is_long & (length > 0))
    a, starts = blk.run.bytes_array, blk.run.starts[blk.lo:blk.hi]
    vid_groups = []
    for key in np.unique(length[long_rows] * 256 + c["count"][long_rows]).tolist():
        rows = long_rows[length[long_rows] * 256 + c["count"][long_rows] == key]
        ln, cnt = key // 256, key % 256
        vid_groups.append((rows, a[(starts[rows] + 7)[:, None] + np.arange(cnt) * ln], ln))
    ids = set(np.unique(sid[(is_short & (sid != BROADCAST_ID)) | is_return]).tolist())
    for _, vids, _ in vid_groups:
        ids.update(np.unique(vids).tolist())
    new_ids = ids - lint.ids
    if len(lint.ids) + len(new_ids) > lint.config.max_servos:
        return False
    if not _headers_quiet(lint, blk, run, vid_groups):
        return False
    timed = blk.t0 is not None and lint.timed
    bt = lint.byte_time
    if timed and "F004" in codes:
        t0, t1 = blk.t0, blk.t1
        idle = (t1 - t0) - (blk.run.ends[blk.lo:blk.hi] - starts) * bt
        if (idle > lint.config.inter_byte_gap * bt).any():
            return False
    writes = _writes(lint, blk, is_short, is_return, address, dlen, vid_groups)
    if writes is None:
        return False
    targets, pos_sets, goal_time_sets, shadow_order = writes
    if not _values_quiet(lint, blk, codes, targets, pos_sets, goal_time_sets, timed):
        return False
    # ---- quiet: move the linter's memory past the rows, as feeding them would have ---------------
    for s in shadow_order:
        lint.shadow(s)
    servos = lint.servos
    for s, v in _last_per_servo(pos_sets).items():
        servos[s].pos = v
    for s, v in _last_per_servo(goal_time_sets).items():
        servos[s].goal_time = v
    for s in np.unique(sid[is_return]).tolist():
        servos[s].flags = 0
    if timed and "F007" in codes:
        _f007_times(lint.state_of("F007").times, blk, starts)
    lint.ids |= new_ids
    lint.records += len(blk)
    lint.prev = blk.record(len(blk) - 1)
    return True


def _headers_quiet(lint: Any, blk: Any, run: list, vid_groups: list) -> bool:
    """Every HEADER rule silent on every distinct header of the block (each checked once, remembered)."""
    memo = lint._header_memo
    c = blk.cols
    kind = c["kind"]
    # The header packed in one int64 (kind 2 bits, five header bytes, data length 14 bits).
    hdr = kind.astype(np.int64)
    for name in ("id", "flag", "address", "length", "count"):
        hdr = hdr << 8 | c[name]
    hdr = hdr << 14 | c["data_len"]
    # A reply's key carries its request's header (B004, B005): the row before it in a Block.
    req = np.zeros_like(hdr)
    req[1:] = hdr[:-1]
    req[kind != RETURN] = 0
    samples = []
    rows = np.flatnonzero(kind != LONG)
    if rows.size:
        k = np.lexsort((req[rows], hdr[rows]))
        h, r = hdr[rows][k], req[rows][k]
        new = np.ones(len(k), dtype=bool)
        new[1:] = (h[1:] != h[:-1]) | (r[1:] != r[:-1])
        samples += rows[k[new]].tolist()
    for rows, vids, _ in vid_groups:
        # Long packets: by header and VIDs (the VIDs of a row as one fixed-size byte string).
        v = np.ascontiguousarray(vids).view(np.dtype((np.void, vids.shape[1]))).ravel()
        for h in np.unique(hdr[rows]).tolist():
            sub = rows[hdr[rows] == h]
            _, at = np.unique(v[hdr[rows] == h], return_index=True)
            samples += sub[at].tolist()
    for k in samples:
        rec = blk.record(k)
        ev = rec.event
        raw = ev[1]
        asked = rec.request.event[1] if rec.request is not None else b""
        key = (raw[:7], len(raw), id(rec.model), raw[7:-1:ev.length or 1] if ev.kind == "long" else b"",
               asked[:7], len(asked))
        quiet = memo.get(key)
        if quiet is None:
            quiet = memo[key] = _header_sample_quiet(lint, run, rec, ev)
        if not quiet:
            return False
    return True


def _header_sample_quiet(lint: Any, run: list, rec: Any, ev: Any) -> bool:
    probe = _Probe(lint)
    kind = ev.kind
    for r in run:
        if r.code in HEADER and kind in r.kinds and r.when is None:
            r.check_for(kind)(probe, rec, ev)
    data = ev[1][7:-1]
    if kind != "return" and data and rec.model is not None:
        n = len(data) if kind == "short" else ev.length - 1
        if n > 0:
            plan = lint.plan(rec.model, ev.address, n)
            ids = (ev.id,) if kind == "short" else tuple(r[0] for r in ev.records)
            for r in run:
                if r.code in HEADER and "write" in r.kinds:
                    r.check_for("write")(probe, rec, plan, ids)
    return not probe.spoke


def _parts(a: np.ndarray, at: np.ndarray, plan: Any, j: int) -> np.ndarray:
    """Raw value of part ``j`` of ``plan`` for data starting at blob index ``at`` (as Plan.unpack)."""
    start, size, reg, partial = plan.model.layout(plan.address, plan.n).parts[j]
    lo = a[at + start].astype(np.int64)
    if size == 2 and not partial:
        v = lo | a[at + start + 1].astype(np.int64) << 8
        return v - (v >= 0x8000) * 0x10000 if reg.signed else v
    return lo - (lo >= 0x80) * 0x100 if reg.signed and not partial else lo


def _by_model(blk: Any, rows: np.ndarray, sid: np.ndarray) -> list[tuple[Any, np.ndarray]]:
    """``rows`` split by their servo's model (one part when every servo has the same)."""
    by: dict[int, tuple[Any, list[int]]] = {}
    for s in np.unique(sid[rows]).tolist():
        model = blk.models[s]
        by.setdefault(id(model), (model, []))[1].append(s)
    if len(by) == 1:
        return [(next(iter(by.values()))[0], rows)]
    return [(model, rows[np.isin(sid[rows], ids)]) for model, ids in by.values()]


def _writes(lint, blk, is_short, is_return, address, dlen, vid_groups):
    """The block's writes and position reports as columns: (targets, pos_sets, goal_time_sets, shadow
    creation order), or None when one of them needs the record path (a followed register other than
    position and goal time, or a target rule without a column form)."""
    a, starts = blk.run.bytes_array, blk.run.starts[blk.lo:blk.hi]
    sid = blk.cols["id"]
    targets = []        # (plan, rows, subs, servo ids, data starts)
    pos_sets = []       # (order keys, servo ids, values): pos changes
    goal_time_sets = []
    mentions = []       # (order keys, servo ids): the shadows the linter creates, in order
    target_codes = {r.code: r for r, _ in lint._target_rules}
    groups = []         # (model, address, n, rows, subs, sids, data starts, kind)
    short_rows = np.flatnonzero(is_short & (dlen > 0))
    skey = address[short_rows] * 4096 + dlen[short_rows]
    for key in np.unique(skey).tolist():
        for model, r2 in _by_model(blk, short_rows[skey == key], sid):
            groups.append((model, key // 4096, key % 4096, r2, np.zeros(len(r2), np.int64), sid[r2],
                           starts[r2] + 7, "write"))
    for rows, vids, ln in vid_groups:
        if ln < 2:
            continue
        cnt = vids.shape[1]
        for ad in np.unique(address[rows]).tolist():
            r2 = rows[address[rows] == ad]
            v2 = vids[address[rows] == ad]
            groups.append((blk.default, ad, ln - 1, np.repeat(r2, cnt), np.tile(np.arange(1, cnt + 1), len(r2)),
                           v2.ravel(), (starts[r2][:, None] + 8 + np.arange(cnt) * ln).ravel(), "write"))
    ret_rows = np.flatnonzero(is_return)
    rkey = address[ret_rows] * 4096 + dlen[ret_rows]
    mentions.append((ret_rows.astype(np.int64) * 512, sid[ret_rows].astype(np.int64)))
    for key in np.unique(rkey).tolist():
        rows = ret_rows[rkey == key]
        if key % 4096 == 0:
            continue
        for model, r2 in _by_model(blk, rows, sid):
            groups.append((model, key // 4096, key % 4096, r2, np.zeros(len(r2), np.int64), sid[r2],
                           starts[r2] + 7, "return"))
    for model, ad, n, rows, subs, sids, at, what in groups:
        if model is None:
            continue
        plan = lint.plan(model, ad, n)
        if any(attr not in _MOVING for attr, _ in plan.tracked):
            return None
        order = rows.astype(np.int64) * 512 + subs
        if what == "write":
            mentions.append((order, sids.astype(np.int64)))
            names = set(plan.index)
            for code, r in target_codes.items():
                if (r.fields is None or r.fields & names) and code not in ("M003", "Q004", "Q006", "Q007"):
                    return None
            targets.append((plan, rows, subs, sids.astype(np.int64), at))
        for attr, j in plan.tracked:
            sets = pos_sets if attr == "pos" else goal_time_sets
            # A write's targets are all checked before any is applied: applied just after the row's checks.
            sets.append((order + (256 if what == "write" else 0), sids.astype(np.int64), _parts(a, at, plan, j)))
    m_order = np.concatenate([m[0] for m in mentions]) if mentions else np.zeros(0, np.int64)
    m_ids = np.concatenate([m[1] for m in mentions]) if mentions else np.zeros(0, np.int64)
    shadow_order = []
    seen = set(lint.servos)
    for s in m_ids[np.argsort(m_order, kind="stable")].tolist():
        if s not in seen:
            seen.add(s)
            shadow_order.append(s)
    return targets, pos_sets, goal_time_sets, shadow_order


def _concat(sets):
    if not sets:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    return (np.concatenate([s[0] for s in sets]), np.concatenate([s[1] for s in sets]),
            np.concatenate([s[2] for s in sets]))


def _last_per_servo(sets) -> dict[int, int]:
    order, ids, vals = _concat(sets)
    if not len(order):
        return {}
    k = np.lexsort((order, ids))
    ids, vals = ids[k], vals[k]
    last = np.flatnonzero(np.append(ids[1:] != ids[:-1], True))
    return dict(zip(ids[last].tolist(), vals[last].tolist()))


def _before(sets, lint, attr: str):
    """A function of (order, servo ids): for each, the shadow's ``attr`` just before that point (_NONE
    while unknown). The sets are sorted once, for every lookup."""
    s_order, s_ids, s_vals = _concat(sets)
    column = _shadow_column(lint, attr)
    if not len(s_order):
        return lambda order, ids: column[ids]
    key = s_ids << 32 | s_order
    k = np.argsort(key)
    key, s_vals = key[k], s_vals[k]

    def before(order: np.ndarray, ids: np.ndarray) -> np.ndarray:
        out = column[ids]
        at = np.searchsorted(key, ids << 32 | order, side="left") - 1
        ok = at >= 0
        ok[ok] = (key[at[ok]] >> 32) == ids[ok]
        out[ok] = s_vals[at[ok]]
        return out

    return before


def _shadow_column(lint, attr: str) -> np.ndarray:
    """Each servo's shadow ``attr`` by ID (_NONE while unknown)."""
    out = np.full(256, _NONE, dtype=np.int64)
    for s, sh in lint.servos.items():
        v = getattr(sh, attr)
        if v is not None:
            out[s] = v
    return out


def _values_quiet(lint, blk, codes, targets, pos_sets, goal_time_sets, timed) -> bool:
    """M003, Q004, Q006, Q007 on the writes' values; B006 on the latencies."""
    a = blk.run.bytes_array
    torque = _shadow_column(lint, "torque") if "Q004" in codes else None
    said = lint.state_of("Q004") if "Q004" in codes else None
    if "Q006" in codes:
        cw, ccw, rev = _shadow_column(lint, "cw"), _shadow_column(lint, "ccw"), _shadow_column(lint, "reverse")
    pos_before = goal_time_before = None  # made on first use (_before)
    for plan, rows, subs, ids, at in targets:
        if "M003" in codes:
            for j, _, lo, hi in plan.ranged:
                v = _parts(a, at, plan, j)
                if ((v < lo) | (v > hi)).any():
                    return False
        g = plan.index.get("goal_position")
        if g is None:
            continue
        goal = _parts(a, at, plan, g)
        if torque is not None:
            off = (torque[ids] == 0) & (ids != BROADCAST_ID)
            if off.any() and any(s not in said for s in ids[off].tolist()):
                return False
        if "Q006" in codes:
            free = rev[ids] != 1
            over = free & (cw[ids] != _NONE) & (goal > cw[ids])
            under = free & ~over & (ccw[ids] != _NONE) & (goal < ccw[ids])
            if (over | under).any():
                return False
        if "Q007" in codes:
            order = rows.astype(np.int64) * 512  # checked before the row's writes apply (its sub-order 0)
            if pos_before is None:
                pos_before = _before(pos_sets, lint, "pos")
            pos = pos_before(order, ids)
            j = plan.index.get("goal_time")
            if j is not None:
                gt = _parts(a, at, plan, j)
            else:
                if goal_time_before is None:
                    goal_time_before = _before(goal_time_sets, lint, "goal_time")
                gt = goal_time_before(order, ids)
                gt = np.where(gt == _NONE, 0, gt)
            known = (pos != _NONE) & (gt != 0)
            dist = np.abs(goal - pos)
            if (known & (dist * plan.model.top_speed_s_per_60deg > 6 * gt)).any():
                return False
    if timed and "B006" in codes:
        replies, lat = blk.reply_latencies()
        if replies.size:
            # The requests' servos' return delay (0 while unknown), as return_latency reads it.
            rd = _shadow_column(lint, "return_delay")[blk.cols["id"][replies - 1]]
            expected = 100e-6 + 50e-6 * np.where(rd == _NONE, 0, rd)
            if (np.abs(lat - expected) > lint.config.latency_margin).any():
                return False
    return True


def _f007_times(times: Any, blk: Any, starts: np.ndarray) -> None:
    """F007's line-rate estimator fed each packet's (length, start time), as its packet check does."""
    lens = blk.run.ends[blk.lo:blk.hi] - starts
    t0 = blk.t0
    prev_len = np.empty(len(lens), dtype=np.int64)
    prev_t = np.empty(len(lens))
    prev_len[1:], prev_t[1:] = lens[:-1], t0[:-1]
    p = times._prev
    keep = np.ones(len(lens), dtype=bool)
    if p is None:
        keep[0] = False
        prev_len[0], prev_t[0] = 1, 0.0
    else:
        prev_len[0], prev_t[0] = p[0], p[1]
    keep &= t0 > prev_t
    rows = np.flatnonzero(keep)
    if times._samples.maxlen:
        rows = rows[-times._samples.maxlen:]  # the deque keeps the last ones only: make those alone
    if len(rows):
        lens_kept = prev_len[rows]
        times._samples.extend(zip(((t0[rows] - prev_t[rows]) / lens_kept).tolist(), lens_kept.tolist()))
        times._cached = None
    times._prev = (int(lens[-1]), float(t0[-1]))


