"""The linter's column form: a Block no enabled rule would speak about is checked with array operations.

:meth:`BlockLinter.quiet` either proves that feeding the Block's records one by one would produce no
finding and moves the linter's memory past them exactly as that would (shadows, counters, rule states),
or returns False having changed nothing, and the linter feeds the records one by one. Findings are the
same either way; the tests in tests/lint/test_batch.py compare the two on every rule's traffic.

Each rule declares its column form itself (``@rule(..., column=...)``, rs30x_sniff.lint.registry):
- "silent": the rule cannot fire on a Block that passes the common checks below (a Block has no garbage,
  corrupt frames, ACK/NACK or unpaired replies; one holding commands, flagged returns, writes of the
  registers the shadows follow other than positions and goal times, or a write a "target" rule without a
  column function would see, takes the record path);
- "header": a pure function of a packet's header, its model and (for a reply) its request's header:
  each distinct header is checked once with the rule's own check on a sample record, and remembered;
- a function quiet(view) beside the rule, written on the :class:`BlockView`'s columns with the same
  arithmetic, in the same order, as the rule's check.
Which rule has which form is said by the rules alone (``Rule.column``); this module keeps no list of them.
Nor of the rows it leaves to the record path (commands, flagged returns, a first row after a cut, a crowded
bus): each is a bail-out (rs30x_sniff.lint.registry.BAIL_OUTS) the rules that need it ask, by their
precondition (``when=``) or their kind ("command"), and the linter's memory asks commands and flags.
"""

from __future__ import annotations

from functools import partial
from typing import Any, NamedTuple
from collections.abc import Callable

import numpy as np

from ..decode.frame_runs import LONG, RETURN, SHORT
from ..protocol.events import RAW
from ..protocol.wire import (AT_DATA, AT_ID, AT_LENGTH, BROADCAST_ID, HEADER_SIZE, SUM_SIZE,
                             VID_SIZE)
from .registry import bail_outs

UNKNOWN = -(1 << 40)  # an unknown shadow value in an int64 column (BlockView.shadows)


class Target(NamedTuple):
    """Writes of one plan in a Block, a row per servo written (what a "target" rule's check sees)."""

    plan: Any           # rs30x_sniff.lint.state.Plan
    rows: np.ndarray    # the Block row of each write
    subs: np.ndarray    # 0 for a short packet, the record's place (from 1) in a long packet
    ids: np.ndarray     # the servo written (int64)
    at: np.ndarray      # where its data starts in the run's bytes
    made: dict          # part -> its raw values (BlockView.written), made on first use


class BlockView:
    """A Block as a rule's column form sees it: its columns, its writes by plan (:attr:`targets`), the
    raw values they carry (:meth:`values`), and the shadow registers before any row (:meth:`shadows`,
    :meth:`before`). ``timed``: the Block has times and the linter runs its timed rules."""

    def __init__(self, lint: Any, blk: Any) -> None:
        self.lint, self.blk = lint, blk
        self.timed = blk.t0 is not None and bool(lint.timed)
        c = self.cols = blk.cols
        self.kind, self.ids, self.flag, self.data_len = c["kind"], c["id"], c["flag"], c["data_len"]
        self.address, self.length = c["address"].astype(np.int64), c["length"].astype(np.int64)
        self.is_short, self.is_long, self.is_return = self.kind == SHORT, self.kind == LONG, self.kind == RETURN
        self.bytes = blk.run.bytes_array
        self.starts = blk.run.starts[blk.lo:blk.hi]  # each row's first byte in the run's bytes
        self.ends = blk.run.ends[blk.lo:blk.hi]
        self.targets: list[Target] = []
        # Shadow values a Block's rows set, by attribute: (order keys, servo ids, values) per group; a
        # Block that sets any other shadow takes the record path.
        self.sets: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {"pos": [], "goal_time": []}
        self.made: dict[tuple[str, str], Any] = {}  # shadow columns and lookups, made on first use
        self.on_accept: list[Callable[[], None]] = []  # the rules' memory moves (when_quiet)
        self._vid_groups: list | None = None
        self._new_ids: set[int] | None = None

    def vid_groups(self) -> list[tuple[np.ndarray, np.ndarray, int]]:
        """The long packets' VIDs: (rows, their VIDs as a matrix, record length) per (length, count) shape."""
        groups = self._vid_groups
        if groups is None:
            length, count = self.length, self.blk.cols["count"]
            long_rows = np.flatnonzero(self.is_long & (length > 0))
            a, starts = self.bytes, self.starts
            groups = self._vid_groups = []
            shape = length[long_rows] * 256 + count[long_rows]
            for key in np.unique(shape).tolist():
                rows = long_rows[shape == key]
                ln, cnt = key // 256, key % 256
                groups.append((rows, a[(starts[rows] + AT_DATA)[:, None] + np.arange(cnt) * ln], ln))
        return groups

    def new_ids(self) -> set[int]:
        """The servo IDs the Block's rows show that the bus has not seen yet (requests, VIDs, returns; not 255)."""
        new = self._new_ids
        if new is None:
            sid = self.ids
            ids = set(np.unique(sid[(self.is_short & (sid != BROADCAST_ID)) | self.is_return]).tolist())
            for _, vids, _ in self.vid_groups():
                ids.update(np.unique(vids).tolist())
            new = self._new_ids = ids - self.lint.ids
        return new

    def values(self, plan: Any, j: int, at: np.ndarray) -> np.ndarray:
        """Raw value of part ``j`` of ``plan`` for data starting at ``at`` (as Plan.unpack)."""
        start, _, reg, partial_ = plan.model.layout(plan.address, plan.n).parts[j]
        return reg.raw_column(self.bytes, at + start, partial_)

    def written(self, t: Target, j: int) -> np.ndarray:
        """The raw values the writes ``t`` carry in part ``j`` of their plan (made once per Block)."""
        v = t.made.get(j)
        if v is None:
            v = t.made[j] = self.values(t.plan, j, t.at)
        return v

    def shadows(self, attr: str) -> np.ndarray:
        """Each servo's shadow ``attr`` by ID before the Block (UNKNOWN while unknown)."""
        out = self.made.get(("shadows", attr))
        if out is None:
            out = self.made["shadows", attr] = np.full(256, UNKNOWN, dtype=np.int64)
            for s, sh in self.lint.servos.items():
                v = getattr(sh, attr)
                if v is not None:
                    out[s] = v
        return out

    def before(self, attr: str, order: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """Shadow ``attr`` ("pos" or "goal_time") of servos ``ids`` just before the points ``order``
        (row * 512 + sub-order) of the Block, UNKNOWN while unknown."""
        fn = self.made.get(("before", attr))
        if fn is None:
            fn = self.made["before", attr] = _before(self.sets[attr], self.shadows(attr))
        return fn(order, ids)

    def before_rows(self, attr: str, rows: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """As :meth:`before` at the start of each of ``rows`` (sub-order 0: before the row's own writes apply),
        as a Block rows x servos matrix filled forward: no sort. The general path where a row sets ``attr``
        twice for one servo (a long packet naming a VID twice) or the matrix would be large."""
        fn = self.made.get(("before_rows", attr))
        if fn is None:
            fn = self.made["before_rows", attr] = _before_rows(self.sets[attr], self.shadows(attr), len(self.kind))
        out = fn(rows, ids)
        return self.before(attr, rows.astype(np.int64) * 512, ids) if out is None else out

    def when_quiet(self, fn: Callable[[], None]) -> None:
        """Call ``fn`` once the Block is accepted as quiet (a rule's memory moved past its rows)."""
        self.on_accept.append(fn)

    def release(self) -> None:
        """Drop what the rules made of the Block. Their closures refer to this view, and a cycle lives until the
        cyclic collector's next full pass, minutes apart: a recorder's Blocks (a second of the bus each, with their
        arrays and records) piled up between passes, and the allocators kept the pile's high-water mark as resident
        memory (bench/live.py's hour; tests/sinks/test_no_cycles.py)."""
        self.on_accept.clear()
        self.made.clear()
        for target in self.targets:
            target.made.clear()


class BlockLinter:
    """The column form of one Linter (it holds the header rules' verdicts per distinct header)."""

    def __init__(self, lint: Any) -> None:
        self.lint = lint
        self.header_verdicts: dict[tuple, bool] = {}
        self.bails: tuple[tuple, tuple] = ((), ())  # (the rules run, the bail-outs they ask)
        # After quiet() said False: the rows the rule that spoke named (its column form's array), or None.
        self.suspects: np.ndarray | None = None

    def quiet(self, blk: Any) -> bool:
        """True if no enabled rule finds anything in ``blk``, with the linter moved past it; else False
        and the linter untouched."""
        lint = self.lint
        self.suspects = None
        lint.begin(blk.t0 is not None)
        run = lint.active_rules
        if self.bails[0] is not run:
            self.bails = (run, bail_outs(run))  # what the rules declare (rs30x_sniff.lint.registry.BAIL_OUTS)
        view = BlockView(lint, blk)
        try:
            return self._quiet(lint, blk, run, view)
        finally:
            view.release()

    def _quiet(self, lint: Any, blk: Any, run: tuple, view: BlockView) -> bool:
        """:meth:`quiet` with its view made."""
        for bail in self.bails[1]:
            if bail.in_block(view):
                return False  # rows the rules that ask this bail-out see only one by one
        sid, is_return = view.ids, view.is_return
        vid_groups = view.vid_groups()
        new_ids = view.new_ids()
        if not _headers_quiet(lint, self.header_verdicts, blk, run, vid_groups):
            return False
        shadow_order = _writes(view, run, vid_groups)
        if shadow_order is None:
            return False
        for r in run:
            quiet = r.column
            if callable(quiet):
                if r.state is not None:
                    quiet = partial(quiet, lint.state_of(r.code))
                said = quiet(view)
                if said is True:
                    continue
                if said is False:
                    return False
                if len(said):  # the rows it speaks of
                    self.suspects = said
                    return False
        # ---- quiet: move the linter's memory past the rows, as feeding them would have -----------
        for s in shadow_order:
            lint.shadow(s)
        servos = lint.servos
        for s, v in _last_per_servo(view.sets["pos"]).items():
            servos[s].pos = v
        for s, v in _last_per_servo(view.sets["goal_time"]).items():
            servos[s].goal_time = v
        for s in np.unique(sid[is_return]).tolist():
            servos[s].flags = 0
        for fn in view.on_accept:
            fn()
        lint.moved_past(len(blk), blk.record(len(blk) - 1), new_ids)
        return True


def _headers_quiet(lint: Any, memo: dict, blk: Any, run: tuple, vid_groups: list) -> bool:
    """Every "header" rule silent on every distinct header of the block (each checked once, remembered
    in ``memo``)."""
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
        hs = hdr[rows]
        if (hs == hs[0]).all() and (vids == vids[0]).all():  # the usual: the same packet to the same servos
            samples.append(int(rows[0]))
            continue
        v = np.ascontiguousarray(vids).view(np.dtype((np.void, vids.shape[1]))).ravel()
        for h in np.unique(hs).tolist():
            sub = rows[hs == h]
            _, at = np.unique(v[hs == h], return_index=True)
            samples += sub[at].tolist()
    header_rules = None
    # The key of a sample, read from the bytes: what its Record would say (its bytes, its model or its VIDs'
    # models, the bytes of the request it answers; Block.record), so a header seen before builds no Record.
    blob, lo, starts, ends = blk.run.blob, blk.lo, blk.run.starts, blk.run.ends
    answered, vid_models = blk.answered, blk.vid_models
    for k in samples:
        raw = blob[int(starts[lo + k]):int(ends[lo + k])]
        row_kind = int(kind[k])
        if row_kind == LONG:
            ln = raw[AT_LENGTH]
            models: Any = (id(blk.default) if vid_models is None
                           else tuple([id(vid_models[v]) for v in (raw[AT_DATA:-SUM_SIZE:ln] if ln else b"")]))
            vids = raw[AT_DATA:-SUM_SIZE:ln or 1]
        else:
            models, vids = id(blk.models[raw[AT_ID]]), b""
        # A return in a Block answers the row before it.
        asked = (blob[int(starts[lo + k - 1]):int(ends[lo + k - 1])]
                 if row_kind == RETURN and k and answered[k - 1] else b"")
        key = (raw[:HEADER_SIZE], len(raw), models, vids, asked[:HEADER_SIZE], len(asked))
        quiet = memo.get(key)
        if quiet is None:
            if header_rules is None:
                header_rules = [r for r in run if r.column == "header"]
            rec = blk.record(k)
            quiet = memo[key] = _header_sample_quiet(lint, header_rules, rec, rec.event)
        if not quiet:
            return False
    return True


class _Probe:
    """The linter as a "header" rule sees it, but whose emit only notes that the rule spoke."""

    def __init__(self, lint: Any) -> None:
        self.linter = lint
        self.spoke = False

    def __getattr__(self, name: str) -> Any:
        return getattr(self.linter, name)

    def emit(self, *args: Any, **kwargs: Any) -> None:
        self.spoke = True

    emit_at = emit


def _header_sample_quiet(lint: Any, header_rules: list, rec: Any, ev: Any) -> bool:
    probe = _Probe(lint)
    kind = ev.kind
    for r in header_rules:
        if kind in r.kinds and r.when is None:
            r.check_for(kind)(probe, rec, ev)
    data = ev[RAW][AT_DATA:-SUM_SIZE]
    if kind != "return" and data and rec.model is not None:
        n = len(data) if kind == "short" else ev.length - 1
        if n > 0:
            vm = rec.vid_models  # a long packet to servos of mixed models: planned as the linter's _long plans it
            plan = lint.plan(rec.model if vm is None or kind != "long" else vm[0], ev.address, n)
            ids = (ev.id,) if kind == "short" else tuple(r[0] for r in ev.records)
            for r in header_rules:
                if "write" in r.kinds:
                    r.check_for("write")(probe, rec, plan, ids)
    return not probe.spoke


def _by_model(blk: Any, rows: np.ndarray, sid: np.ndarray) -> list[tuple[Any, np.ndarray]]:
    """``rows`` split by their servo's model (one part when every servo has the same)."""
    by: dict[int, tuple[Any, list[int]]] = {}
    for s in np.unique(sid[rows]).tolist():
        model = blk.models[s]
        by.setdefault(id(model), (model, []))[1].append(s)
    if len(by) == 1:
        return [(next(iter(by.values()))[0], rows)]
    return [(model, rows[np.isin(sid[rows], ids)]) for model, ids in by.values()]


def _writes(view: BlockView, run: tuple, vid_groups: list) -> list[int] | None:
    """The block's writes and position reports as columns (view.targets, view.sets) and the order the
    linter creates shadows in; None when one of them needs the record path (a followed register other
    than position and goal time, or a write a "target" rule without a column function would see)."""
    lint, blk = view.lint, view.blk
    starts, sid, address, dlen = view.starts, view.ids, view.address, view.data_len
    sets = view.sets
    mentions = []       # (order keys, servo ids): the shadows the linter creates, in order
    silent_targets = [r for r in run if "target" in r.kinds and not callable(r.column)]
    groups = []         # (model, address, n, rows, subs, sids, data starts, kind)
    short_rows = np.flatnonzero(view.is_short & (dlen > 0))
    skey = address[short_rows] * 4096 + dlen[short_rows]
    for key in np.unique(skey).tolist():
        for model, r2 in _by_model(blk, short_rows[skey == key], sid):
            groups.append((model, key // 4096, key % 4096, r2, np.zeros(len(r2), np.int64), sid[r2],
                           starts[r2] + AT_DATA, "write"))
    vid_models = blk.vid_models
    for rows, vids, ln in vid_groups:
        if ln <= VID_SIZE:  # a record with its VID and no data
            continue
        cnt = vids.shape[1]
        for ad in np.unique(address[rows]).tolist():
            r2 = rows[address[rows] == ad]
            v2 = vids[address[rows] == ad].ravel()
            at = (starts[r2][:, None] + AT_DATA + VID_SIZE + np.arange(cnt) * ln).ravel()
            r3, subs = np.repeat(r2, cnt), np.tile(np.arange(1, cnt + 1), len(r2))
            if vid_models is None:
                groups.append((blk.default, ad, ln - VID_SIZE, r3, subs, v2, at, "write"))
                continue
            # Servos of mixed models: each record in its own servo's model, as the record form plans them.
            by: dict[int, tuple[Any, list[int]]] = {}
            for v in np.unique(v2).tolist():
                m = vid_models[v]
                by.setdefault(id(m), (m, []))[1].append(v)
            for m, vs in by.values():
                mine = np.isin(v2, vs)
                groups.append((m, ad, ln - VID_SIZE, r3[mine], subs[mine], v2[mine], at[mine], "write"))
    ret_rows = np.flatnonzero(view.is_return)
    rkey = address[ret_rows] * 4096 + dlen[ret_rows]
    mentions.append((ret_rows.astype(np.int64) * 512, sid[ret_rows].astype(np.int64)))
    for key in np.unique(rkey).tolist():
        rows = ret_rows[rkey == key]
        if key % 4096 == 0:
            continue
        for model, r2 in _by_model(blk, rows, sid):
            groups.append((model, key // 4096, key % 4096, r2, np.zeros(len(r2), np.int64), sid[r2],
                           starts[r2] + AT_DATA, "return"))
    for model, ad, n, rows, subs, sids, at, what in groups:
        if model is None:
            continue
        plan = lint.plan(model, ad, n)
        if any(attr not in sets for attr, _ in plan.tracked):
            return None
        order = rows.astype(np.int64) * 512 + subs
        sids = sids.astype(np.int64)
        if what == "write":
            mentions.append((order, sids))
            names = set(plan.index)
            for r in silent_targets:
                if r.fields is None or r.fields & names:
                    return None
            t = Target(plan, rows, subs, sids, at, {})
            view.targets.append(t)
            # A write's targets are all checked before any is applied: applied just after the row's checks.
            for attr, j in plan.tracked:
                sets[attr].append((order + 256, sids, view.written(t, j)))
        else:
            for attr, j in plan.tracked:
                sets[attr].append((order, sids, view.values(plan, j, at)))
    m_order = np.concatenate([m[0] for m in mentions]) if mentions else np.zeros(0, np.int64)
    m_ids = np.concatenate([m[1] for m in mentions]) if mentions else np.zeros(0, np.int64)
    shadow_order: list[int] = []
    known = np.zeros(256, dtype=bool)
    known[list(lint.servos)] = True
    new = ~known[m_ids]  # (the usual: none, the servos' shadows made by an earlier Block)
    if new.any():
        m_order, m_ids = m_order[new], m_ids[new]
        seen: set[int] = set()
        for s in m_ids[np.argsort(m_order, kind="stable")].tolist():
            if s not in seen:
                seen.add(s)
                shadow_order.append(s)
    return shadow_order


def _concat(sets):
    if not sets:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    return (np.concatenate([s[0] for s in sets]), np.concatenate([s[1] for s in sets]),
            np.concatenate([s[2] for s in sets]))


def _last_per_servo(sets) -> dict[int, int]:
    """Each servo's value set last (the largest order key; of two at one key, the one set later), no sort."""
    order, ids, vals = _concat(sets)
    if not len(order):
        return {}
    last = np.full(256, -1, dtype=np.int64)
    np.maximum.at(last, ids, order)
    won = order == last[ids]
    return dict(zip(ids[won].tolist(), vals[won].tolist()))  # a later one of a tie replaces an earlier


MATRIX_CELLS = 1 << 22  # _before_rows' largest matrix (32 MiB of int64 per array)


def _before_rows(sets, column: np.ndarray, n_rows: int):
    """A function of (rows, servo ids): for each, the value set last in a row before that row, from ``sets`` or
    else ``column`` (the value before the Block); None when it cannot say (see BlockView.before_rows).

    No sort: the rows asked about cut the Block into spans (span k: after the k-th row asked about, up to and
    with the next), each set falls in one span (a set at row r has an order key of r * 512 and more, so it is
    before the start of any later row), and a spans x servos matrix holds each servo's last set per span (the
    largest order key), filled forward over the spans."""
    s_order, s_ids, s_vals = _concat(sets)

    def before(rows: np.ndarray, ids: np.ndarray) -> np.ndarray | None:
        if not len(s_order):
            return column[ids]
        grid = _grid(rows, ids)
        seen = np.zeros(256, dtype=bool)
        if grid is None:
            seen[ids] = True
            width = int(np.count_nonzero(seen))
            col = np.cumsum(seen) - 1  # servo id -> its column
        else:  # the same servos row after row (a long packet's VIDs): the answer is the matrix itself
            first = ids[:grid]
            width, col = grid, np.zeros(256, dtype=np.int64)
            seen[first] = True
            col[first] = np.arange(grid)
        asked = np.zeros(n_rows, dtype=bool)
        asked[rows] = True
        span = np.cumsum(asked)  # row -> the rows asked about up to and with it: the span a set there falls in
        spans = int(span[-1]) + 1
        if spans * width > MATRIX_CELLS:
            return None
        mine = seen[s_ids]
        order = s_order[mine]
        cell = span[order >> 9] * width + col[s_ids[mine]]
        last = np.full(spans * width, -1, dtype=np.int64)
        np.maximum.at(last, cell, order)
        won = order == last[cell]
        filled = last >= 0
        if np.count_nonzero(won) != np.count_nonzero(filled):
            return None  # two values set at one point (a return holding goal and present position): general path
        vals = np.empty(spans * width, dtype=np.int64)
        vals[cell[won]] = s_vals[mine][won]
        where = np.where(filled, np.arange(spans * width), -1).reshape(spans, width)
        np.maximum.accumulate(where, axis=0, out=where)  # each servo's latest span with a set, up to each span
        if grid is None:
            at = where.ravel()[(span[rows] - 1) * width + col[ids]]  # the spans before the row's own
        else:
            at = where[:-1].ravel()  # span k - 1 before the k-th row asked about, in the order asked
        found = at >= 0
        out = column[ids]
        out[found] = vals[at[found]]
        return out

    return before


def _grid(rows: np.ndarray, ids: np.ndarray) -> int | None:
    """How many servos each row asks about, when ``rows`` and ``ids`` are a rows x servos matrix (the same
    distinct servos in the same order, row after row, rows increasing), else None."""
    if not len(rows):
        return None
    width = int(np.searchsorted(rows, rows[0], side="right"))
    if len(rows) % width or len(np.unique(ids[:width])) != width:
        return None
    by_row = rows.reshape(-1, width)
    if not ((by_row == by_row[:, :1]).all() and (ids.reshape(-1, width) == ids[:width]).all()
            and (np.diff(by_row[:, 0]) > 0).all()):
        return None
    return width


def _before(sets, column: np.ndarray):
    """A function of (order, servo ids): for each, the value just before that point, from ``sets`` or
    else ``column`` (the value before the Block). The sets are sorted once, for every lookup."""
    s_order, s_ids, s_vals = _concat(sets)
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
