"""Columnar pairing: a FrameRun's clean transactions as one Block, the tracker's state moved in bulk.

The BusTracker pairs record by record (rs30x_sniff.decode.pairing). Most of a healthy capture is simpler than
that: each request that asks for a reply is followed at once by a return, and no frame is one of the
tracker's special cases (no servo changes its ID or reports its model, nothing is broadcast:
BusTracker.rows_needing_tracker says which are). Such stretches of a FrameRun become a :class:`Block`
(rows as columns, no Python object per frame), and the tracker's state (servo shadows, counters,
latencies, record index) is advanced with array operations. Every other frame goes through the tracker
as an event, in wire order, so the records either way are the same: :meth:`Block.records` builds them
exactly as the tracker would have.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any, final

import numpy as np

from .pairing import ANSWERED, MIN_REPLY_LATENCY, PAIRED, BusTracker, Record, reply_latency
from .frame_runs import LONG, RETURN, SHORT, FrameRun
from ..protocol.events import ID, LONG_RECORDS
from ..protocol.wire import AT_DATA, BROADCAST_ID, FLAG_WANTS_REPLY

_WANTS_REPLY = np.array(FLAG_WANTS_REPLY, dtype=bool)
# A clean stretch shorter than this goes through the tracker record by record (a block costs ~100 us).
MIN_BLOCK = 32


@final  # the checker narrows by `type(x) is Block` both ways (a Step holds Records and Blocks)
class Block:
    """Rows ``lo``..``hi`` of a FrameRun, paired and annotated: each request asking for a reply is
    directly followed by its return. ``index0`` is the first row's record index."""

    __slots__ = ("run", "lo", "hi", "index0", "cols", "answered", "models", "default", "vid_models", "_records",
                 "_latencies")

    def __init__(self, run: FrameRun, lo: int, hi: int, index0: int, answered: np.ndarray,
                 models: dict[int, Any], default: Any, vid_models: dict[int, Any] | None) -> None:
        self.run, self.lo, self.hi, self.index0 = run, lo, hi, index0
        self.cols = {k: v[lo:hi] for k, v in run.header().items()}
        self.answered = answered      # rows that are requests answered by the next row
        self.models = models          # servo id -> model of its short packets and returns
        self.default = default        # the model a long packet's record carries
        self.vid_models = vid_models  # servo id -> model, for long packets when servos differ in model
        self._records: list[Record] | dict[int, Record] | None = None  # all rows, or those asked for one by one
        self._latencies: tuple[np.ndarray, np.ndarray] | None = None

    def __len__(self) -> int:
        return self.hi - self.lo

    def __repr__(self) -> str:
        return f"<Block {len(self)} records from {self.index0}>"

    @property
    def t0(self) -> np.ndarray | None:
        return None if self.run.t0 is None else self.run.t0[self.lo:self.hi]

    @property
    def t1(self) -> np.ndarray | None:
        return None if self.run.t1 is None else self.run.t1[self.lo:self.hi]

    @property
    def offsets(self) -> np.ndarray:
        return self.run.base + self.run.starts[self.lo:self.hi]

    def reply_latencies(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(rows of the replies, their latencies) as bus.reply_latency computes them, in row order, for the replies
        that have one; None for an untimed capture. Made once: the tracker, the linter and the statistics read it."""
        got = self._latencies
        if got is not None:
            return got
        t0, t1 = self.t0, self.t1
        if t0 is not None and t1 is not None:  # (a timed run has both)
            replies = np.flatnonzero(self.answered) + 1
            lat = t0[replies] - t1[replies - 1]
            # A reply that came in one read with its request has no latency to give (pairing.reply_latency): it
            # is paired all the same, and left out here.
            timed = lat >= MIN_REPLY_LATENCY
            got = self._latencies = (replies, lat) if timed.all() else (replies[timed], lat[timed])
        return got

    def latencies(self) -> np.ndarray | None:
        """Per row: the reply latency of a return that has one (NaN elsewhere), as the tracker computes it; None
        untimed."""
        got = self.reply_latencies()
        if got is None:
            return None
        out = np.full(len(self), np.nan)
        out[got[0]] = got[1]
        return out

    # ---- the rows as Records -------------------------------------------------------------------
    # A Block keeps the Records it has built: none; some, row by row (a dict: :meth:`record`, the ones the
    # tracker and the linter hold, which may yet be given findings); or all (a list: :meth:`records`, as
    # when the linter went through the rows one by one). The column forms read the rows from the run's
    # bytes unless a Record of them is kept.

    @property
    def linted_by_rows(self) -> bool:
        """True once every row is built as a Record (:meth:`records`: the linter went through the rows one
        by one, so they may carry findings): each column form then writes the rows from their Records."""
        return type(self._records) is list

    @property
    def made_rows(self) -> Mapping[int, Record]:
        """The rows built as Records so far, row -> Record (empty when none is): read-only."""
        made = self._records
        if made is None:
            return {}
        if isinstance(made, list):  # (once a Block: its rows, all built)
            return _AllRows(made)
        return made

    def forget_before(self, cut: int) -> None:
        """Let go of the Records built one by one for rows before ``cut`` (a request whose reply is at
        ``cut`` or later stays: the two are built together). A Block linted by rows keeps them all."""
        made = self._records
        if isinstance(made, dict):
            answered, n = self.answered, len(self)
            for k in [k for k in made if k < cut and not (k + 1 < n and answered[k] and k + 1 >= cut)]:
                del made[k]

    def part(self, a: int, b: int) -> Block:
        """Rows ``a``..``b`` as a Block of their own (a pair is not to be cut: the caller keeps a reply
        with its request), keeping the Records already built of them, so each row stays one object."""
        sub = Block(self.run, self.lo + a, self.lo + b, self.index0 + a, self.answered[a:b], self.models,
                    self.default, self.vid_models)
        made = self._records
        if isinstance(made, list):
            sub._records = made[a:b]
        elif made:
            sub._records = {k - a: r for k, r in made.items() if a <= k < b}
        return sub

    def records(self) -> list[Record]:
        """The rows as the Records the tracker would have made (built once, then kept)."""
        recs = self._records
        if not isinstance(recs, list):
            recs = self._records = self.rows(0, len(self))
        return recs

    def rows(self, a: int, b: int) -> list[Record]:
        """Rows ``a``..``b`` as Records, paired as the tracker pairs them, built for the moment: the
        Block does not keep them (:meth:`record` and :meth:`records` do). The Records it already keeps
        are used as they are (a finding may be on one), so a row is never two different objects at once."""
        made = self._records
        if isinstance(made, list):
            return made[a:b]
        answered = self.answered
        a0 = a - 1 if a > 0 and answered[a - 1] else a        # a reply is made with its request
        b0 = b + 1 if b < len(self) and answered[b - 1] else b  # and a request with its reply
        events = self.run.events(self.lo + a0, self.lo + b0)
        kinds = self.cols["kind"][a0:b0].tolist()
        make = self._record
        if made:
            get = made.get
            recs = [get(k) or make(ev, kind, k) for k, ev, kind in zip(range(a0, b0), events, kinds)]
        else:
            recs = [make(ev, kind, k) for k, ev, kind in zip(range(a0, b0), events, kinds)]
        n = len(recs)
        for k in np.flatnonzero(answered[a0:b0]).tolist():
            if k + 1 < n and not (made and (a0 + k) in made):  # kept ones are paired already
                _pair(recs[k], recs[k + 1])
        return recs[a - a0:b - a0]

    def record(self, k: int) -> Record:
        """Row ``k`` alone as its Record (with its reply, if it is an answered request); kept, so
        :meth:`records` hands out the same object."""
        recs = self._records
        if recs is None:
            recs = self._records = {}
        if isinstance(recs, list):
            return recs[k]
        rec = recs.get(k)
        if rec is None and k > 0 and self.answered[k - 1]:
            self.record(k - 1)  # a reply is built with its request, and linked to it
            return recs[k]
        if rec is None:
            rec = recs[k] = self._record(self.run.event(self.lo + k), int(self.cols["kind"][k]), k)
            if self.answered[k]:
                rep = recs[k + 1] = self._record(self.run.event(self.lo + k + 1), RETURN, k + 1)
                _pair(rec, rep)
        return rec

    def fresh_record(self, k: int) -> Record:
        """Row ``k`` as a Record built anew as :meth:`records` builds it (paired with its request or reply,
        also built anew), kept nowhere: what the row reads as, whatever the Records the Block keeps have
        been given since (findings). A template's sample, or a row read for its event and model."""
        run, kinds, answered = self.run, self.cols["kind"], self.answered

        def build(j: int) -> Record:
            return self._record(run.event(self.lo + j), int(kinds[j]), j)

        rec = build(k)
        if int(kinds[k]) == RETURN and k > 0 and answered[k - 1]:
            _pair(build(k - 1), rec)
        elif k + 1 < len(self) and answered[k]:
            _pair(rec, build(k + 1))
        return rec

    def _record(self, ev: Any, kind: int, k: int) -> Record:
        if kind == LONG:
            rec = Record(ev, self.index0 + k, self.default)
            vm = self.vid_models
            if vm is not None:
                rec.vid_models = tuple([vm[r[0]] for r in ev[LONG_RECORDS]])  # r[0]: the record's VID
            return rec
        return Record(ev, self.index0 + k, self.models[ev[ID]])


def _pair(req: Record, rep: Record) -> None:
    """Link an answered request and its reply, as the tracker links them."""
    req.status = ANSWERED
    rep.status = PAIRED
    req.reply = rep
    rep.request = req
    rep.latency = reply_latency(req.event, rep.event)


class _AllRows(Mapping):
    """Block.made_rows of a Block linted by rows: its list of Records as a mapping row -> Record."""

    __slots__ = ("_list",)

    def __init__(self, records: list[Record]) -> None:
        self._list = records

    def __getitem__(self, k: int) -> Record:
        if not isinstance(k, (int, np.integer)) or not 0 <= k < len(self._list):
            raise KeyError(k)
        return self._list[k]

    def __iter__(self) -> Iterator[int]:
        return iter(range(len(self._list)))

    def __len__(self) -> int:
        return len(self._list)

    def values(self) -> list[Record]:  # type: ignore[override]
        return self._list

    def __sizeof__(self) -> int:  # what it holds is the list (a memory estimate weighs it)
        return self._list.__sizeof__()


def feed_run(tracker: BusTracker, run: FrameRun, out: list) -> bool:
    """Append what ``run`` gives to ``out``: Blocks for its clean stretches, Records (through the
    tracker, one by one) for the rest, in wire order. True when some Block was appended."""
    h = run.header()
    n = len(run)
    kind, flag = h["kind"], h["flag"]
    is_short, is_return = kind == SHORT, kind == RETURN
    # Frames the columnar path leaves to the tracker: the special cases, each changing the tracker's
    # state in a way only it follows (broadcast writes, servo_id writes, data past the map, model numbers), and
    # requests of a return mode only a model's map defines (whether a return is due is the servo's model's say).
    slow = tracker.rows_needing_tracker(h)
    # Pairing: a request asking for a reply must be followed at once, within the timeout, by a return
    # the columnar path takes; a return must follow such a request.
    wants = is_short & _WANTS_REPLY[flag]
    nxt_return = np.zeros(n, dtype=bool)
    nxt_return[:-1] = is_return[1:] & ~slow[1:]
    ok_pair = wants & ~slow & nxt_return
    rt0, rt1 = run.t0, run.t1
    if rt0 is not None and rt1 is not None and n > 1:  # (a timed run has both)
        in_time = np.zeros(n, dtype=bool)
        gap = rt0[1:] - rt1[:-1]
        # Within the timeout, as the tracker pairs. A reply the clock puts sooner than a servo can answer (read in
        # one piece with its request) is paired too, with no latency (Block.reply_latencies).
        in_time[:-1] = ~(gap > tracker.reply_timeout)
        ok_pair &= in_time
    answered_return = np.zeros(n, dtype=bool)
    answered_return[1:] = ok_pair[:-1]
    fast = np.where(wants, ok_pair, np.where(is_return, answered_return, ~slow))
    brk = np.flatnonzero(~fast)  # rows the tracker takes: each clean stretch ends at the next one
    blocks = False
    pos = 0
    feed = tracker.feed_into
    while pos < n:
        if tracker.waiting is not None or not fast[pos]:
            feed(run.event(pos), out)
            pos += 1
            continue
        j = int(np.searchsorted(brk, pos))
        hi = n if j == len(brk) else int(brk[j])
        if hi - pos < MIN_BLOCK:
            # Too short to repay a block's fixed cost: record by record.
            for ev in run.events(pos, hi):
                feed(ev, out)
        else:
            out.append(_block(tracker, run, pos, hi, ok_pair[pos:hi]))
            blocks = True
        pos = hi
    return blocks


def _block(tracker: BusTracker, run: FrameRun, lo: int, hi: int, answered: np.ndarray) -> Block:
    """The Block of rows lo..hi, with the tracker's state advanced past them."""
    h = {k: v[lo:hi] for k, v in run.header().items()}
    kind, sid, dlen, count = h["kind"], h["id"], h["data_len"], h["count"].astype(np.int64)
    address, length = h["address"].astype(np.int64), h["length"].astype(np.int64)
    n = hi - lo
    a = run.bytes_array
    starts = run.starts[lo:hi]
    t0 = None if run.t0 is None else run.t0[lo:hi]
    is_short, is_long, is_return = kind == SHORT, kind == LONG, kind == RETURN
    servos = tracker.servos
    # Each servo the rows mention, in the order the tracker would create them: shorts (not broadcast)
    # and returns by ID, long packets by each record's VID (when a record has data past the VID).
    rows_sr = np.flatnonzero((is_short & (sid != BROADCAST_ID)) | is_return)
    long_rows = np.flatnonzero(is_long & (length > 1))
    mention_rows = [rows_sr]
    mention_ids = [sid[rows_sr].astype(np.int64)]
    mention_sub = [np.zeros(len(rows_sr), dtype=np.int64)]
    vid_groups = []  # (rows, VID matrix, record length) per (length, count) of long packets
    if long_rows.size:
        keys = length[long_rows] * 256 + count[long_rows]
        for key in np.unique(keys).tolist():
            rows = long_rows[keys == key]
            ln, cnt = key // 256, key % 256
            vids = a[(starts[rows] + AT_DATA)[:, None] + np.arange(cnt) * ln]  # each record starts with its VID
            vid_groups.append((rows, vids, ln))
            mention_rows.append(np.repeat(rows, cnt))
            mention_ids.append(vids.ravel().astype(np.int64))
            mention_sub.append(np.tile(np.arange(1, cnt + 1), len(rows)))
    m_rows = np.concatenate(mention_rows)
    m_ids = np.concatenate(mention_ids)
    m_sub = np.concatenate(mention_sub)
    if any(i not in servos for i in np.unique(m_ids).tolist()):
        for i in m_ids[np.lexsort((m_sub, m_rows))].tolist():
            if i not in servos:
                tracker.servo(i)  # adds it to servos: created once, at its first mention
    # Models: a short packet's record has its servo's model, a return's the model of its ServoState
    # (the same, as no model is learned here); a long packet's, the default.
    models = {i: servos[i].model if i in servos else tracker.model_of(i)
              for i in set(sid[is_short | is_return].tolist())}
    vid_models = None
    if not tracker.uniform and is_long.any():
        # Then every long packet's record has its VIDs' models, as the tracker gives them: a tuple (empty
        # for Length 0), never None.
        vid_models = {i: tracker.model_of(i) for g in vid_groups for i in np.unique(g[1]).tolist()}
        # Long packets of Length 1 carry VIDs only; their records still have a model (bus.Record.vid_models).
        for r in np.flatnonzero(is_long & (length == 1)).tolist():
            s0 = int(starts[r]) + AT_DATA
            for v in a[s0:s0 + int(count[r])].tolist():
                if v not in vid_models:
                    vid_models[v] = tracker.model_of(v)
    # Counters: requests per short packet to a servo, returns per return.
    req_counts = np.bincount(sid[is_short & (sid != BROADCAST_ID)], minlength=256)
    ret_counts = np.bincount(sid[is_return], minlength=256)
    for i in np.flatnonzero(req_counts).tolist():
        servos[i].requests += int(req_counts[i])
    for i in np.flatnonzero(ret_counts).tolist():
        servos[i].returns += int(ret_counts[i])
    blk = Block(run, lo, hi, tracker.next_index, answered, models, tracker.default, vid_models)
    # Latencies of the paired returns, in order, per servo.
    got = blk.reply_latencies()
    if got is not None:
        replies, lat = got
        rid = sid[replies]
        for i in np.unique(rid).tolist():
            servos[i].latencies.extend(lat[rid == i].tolist())
    # Memory images: the last write of each shape to each servo wins, applied in row order.
    stores: dict[int, list[tuple[int, int, int, int]]] = {}  # servo -> (row, byte index in blob, address, n)
    store_rows = np.flatnonzero((is_short & (dlen > 0)) | is_return)
    if store_rows.size:
        keys = address[store_rows] * 4096 + dlen[store_rows]
        for key in np.unique(keys).tolist():
            rows = store_rows[keys == key]
            last = np.full(256, -1, dtype=np.int64)
            np.maximum.at(last, sid[rows], rows)
            ad, nb = key // 4096, key % 4096
            for i in np.flatnonzero(last >= 0).tolist():
                r = int(last[i])
                stores.setdefault(i, []).append((r, int(starts[r]) + AT_DATA, ad, nb))
    for group_rows, group_vids, ln in vid_groups:
        cnt = group_vids.shape[1]
        # Each address of these long packets on its own: the last write there to each servo wins.
        for ad in np.unique(address[group_rows]).tolist():
            at_ad = address[group_rows] == ad
            rows, vids = group_rows[at_ad], group_vids[at_ad]
            seq = np.repeat(rows, cnt) * 256 + np.tile(np.arange(cnt), len(rows))
            last = np.full(256, -1, dtype=np.int64)
            np.maximum.at(last, vids.ravel(), seq)
            for i in np.flatnonzero(last >= 0).tolist():
                r, k = divmod(int(last[i]), 256)
                # Record k's data: after the VID that starts it.
                stores.setdefault(i, []).append((r, int(starts[r]) + AT_DATA + k * int(ln) + 1, ad, int(ln) - 1))
    blob = run.blob
    for i, items in stores.items():
        st = servos[i]
        items.sort()
        image = st.image
        known = st.known
        for _, at, ad, nb in items:
            image[ad:ad + nb] = blob[at:at + nb]
            known |= ((1 << nb) - 1) << ad
        st.known = known
        # last_t: the time of its last store, the last row of the sorted items (a return stores even
        # with no data; so does any write).
        st.last_t = None if t0 is None else float(t0[items[-1][0]])
    tracker.advance(n)  # the next record's index; the segment has had its first packet
    # The latest answered request, unless a request came after it (a later reply would be EXTRA to it).
    req_rows = np.flatnonzero(is_short | is_long)
    ans = np.flatnonzero(answered)
    if ans.size and (not req_rows.size or req_rows[-1] == ans[-1]):
        tracker.last_answered = blk.record(int(ans[-1]))
    elif req_rows.size:
        tracker.last_answered = None
    return blk
