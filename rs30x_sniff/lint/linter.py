"""The Linter: runs the enabled rules over records as they come, dispatching by record kind."""

from __future__ import annotations

from types import MethodType
from typing import TYPE_CHECKING, Any
from collections.abc import Callable

from ..decode.framing import TimeFault
from ..decode.pairing import MISSING, Record
from ..protocol.chunks import SenderMap
from ..protocol.events import OFFSET, RAW, T_START
from ..protocol.wire import (
    AT_DATA, BROADCAST_ID, COMMAND_BITS, FLAG_INITIALIZE, FLAG_REBOOT, RETURN_TEMPERATURE_LIMIT, SUM_SIZE, byte_time)
from .batch import BlockLinter
from .config import LintConfig
from .registry import KINDS, WHEN, Finding, Rule, crowded
from .state import Plan, Shadow

if TYPE_CHECKING:  # names for the checker; no import at run time
    from ..decode.blocks import Block

_AUTO = object()


# A Block some rule speaks of is halved down to parts of this many rows at least, at most SPLIT_TRIES times: a
# finding here and there keeps the rest of its Block on the column forms (the linter's, and every writer's),
# while findings everywhere cost a few column checks before they go row by row (measured on hexapod traffic with a
# late reply every 30 to 150 rows: within 6 % of never halving; with one now and then, most rows stay on columns).
SPLIT_ROWS = 16
SPLIT_TRIES = 12
SPLIT_PAUSE = 8  # Blocks not halved after one that went three quarters row by row, halved


class Linter:
    """Feed it records (``Decoder(options, linter)`` does); findings land on the records they concern.

    Whether the capture has timestamps is decided from the first record: without them the rules
    that need time are skipped, and :attr:`skipped` names them.

    :attr:`findings` holds every finding so far; with ``keep_findings=False`` it holds only those not yet taken by
    :meth:`new_findings` (the decoder takes them a step at a time): a live run that lints for days keeps none it
    has handed on, however noisy the bus.
    """

    def __init__(self, config: LintConfig | None = None, keep_findings: bool = True) -> None:
        c = self.config = config or LintConfig()
        self.keep_findings = keep_findings
        self._taken = 0  # findings already taken by new_findings (when they are kept)
        codes = c.enabled_codes()
        rule_set = c.rules  # the run's: built-in rules and its user rules (LintConfig.rules)
        self.rules = [rule_set[code] for code in codes]
        self._names = {r.code: r.name for r in rule_set}
        self._sev = c.severities()
        self.findings: list[Finding] = []
        self.timed: bool | None = None
        self.skipped: tuple[str, ...] = ()
        self.active_rules: tuple[Rule, ...] = ()  # the enabled rules that run (all but the skipped)
        self.byte_time = byte_time(c.baud)
        self.records = 0
        self._halving_off = 0  # Blocks still to check whole (feed_block)
        self._new: list[Finding] = []
        self._on: dict[str, tuple] = {}
        self._plans: dict[tuple, Plan] = {}
        # State the rules share (wire order, so no lookahead is needed); a rule's own memory is its state.
        self.servos: dict[int, Shadow] = {}
        self.prev: Record | None = None        # the record before this one (B007)
        self.missing: Record | None = None     # the latest request whose reply never came (B001)
        self.last_request: Record | None = None  # the latest request (B003 says how a reply stands to it)
        self.end_t: float | None = None        # when the input's last byte ended (set before close)
        # Set by the Decoder (rs30x_sniff.decode.decoder) that feeds this linter: who sent which bytes, where the
        # capture says so (D-rules check the decoder's reading against it), and before the close the faults of
        # the capture's clock (F005, F006). A linter fed by hand has neither.
        self.senders: SenderMap | None = None
        self.time_faults: dict[str, TimeFault] = {}
        self.ids: set[int] = set()             # servo IDs seen on the bus (Q008)
        self._states = {r.code: r.state() for r in self.rules if r.state is not None}
        self._counting = True
        self._vid_sets: set[bytes] = set()
        self._columns = BlockLinter(self)  # the column form, for Blocks (rs30x_sniff.lint.batch)

    # ---- setup -------------------------------------------------------------------------------
    def begin(self, timed: bool) -> None:
        """Decide whether the capture has timestamps, unless the first record (or Block) already did."""
        if self.timed is None:
            self._setup(timed)

    def _setup(self, timed: bool) -> None:
        self.timed = timed
        run = [r for r in self.rules if timed or not r.needs_time]
        self.active_rules = tuple(run)
        self.skipped = tuple(r.code for r in self.rules if r.needs_time and not timed)
        self._target_rules = [(r, self._bound(r, "target")) for r in run if "target" in r.kinds]
        self._on = {k: tuple(self._bound(r, k) for r in run if k in r.kinds and r.when is None) for k in KINDS}
        # Per kind: (precondition, the checks waiting on it), preconditions in the order rules declare them.
        self._when = {}
        for k in KINDS:
            conds: dict[str, list] = {}
            for r in run:
                if k in r.kinds and r.when is not None:
                    conds.setdefault(r.when, []).append(self._bound(r, k))
            self._when[k] = tuple((WHEN[c][1], tuple(fns)) for c, fns in conds.items())

    def _bound(self, r: Rule, kind: str) -> Callable[..., Any]:
        """The check for ``kind``, with the rule's own state bound as its first argument if it has one."""
        fn = r.check_for(kind)
        return fn if r.state is None else MethodType(fn, self._states[r.code])

    def stop_calling(self, state: Any, kinds: Any) -> None:
        """Take the checks of ``kinds`` bound to a rule's ``state`` out of the per-kind dispatch for the rest
        of this run (or time segment): a rule that found it has nothing to check stops costing a call per record."""
        on = self._on
        for kind in kinds:
            if kind in on:
                on[kind] = tuple(fn for fn in on[kind] if getattr(fn, "__self__", None) is not state)

    def severity_of(self, code: str) -> str:
        """The severity rule ``code`` reports at in this run (its own, or as --severity / the config set it)."""
        return self._sev[code]

    def state_of(self, code: str) -> Any:
        """The state object of rule ``code`` in this run (None for a rule without state or not enabled)."""
        return self._states.get(code)

    def shadow(self, sid: int) -> Shadow:
        sh = self.servos.get(sid)
        if sh is None:
            sh = self.servos[sid] = Shadow()
        return sh

    def plan(self, model: Any, address: int, n: int) -> Plan:
        key = (id(model), address, n)
        p = self._plans.get(key)
        if p is None:
            p = self._plans[key] = Plan(model, address, n)
            names = set(p.index)
            p.target_checks = tuple(fn for r, fn in self._target_rules if r.fields is None or r.fields & names)
        return p

    # ---- findings ----------------------------------------------------------------------------
    def new_findings(self) -> list[Finding]:
        """The findings reported since the last call, in the order reported."""
        found = self.findings
        if self.keep_findings:
            if len(found) == self._taken:
                return []
            new = found[self._taken:]
            self._taken = len(found)
            return new
        if not found:
            return []
        self.findings = []
        return found

    def emit(self, code: str, rec: Record, message: str, sid: Any = _AUTO) -> Finding:
        """Report a finding of rule ``code`` on ``rec`` (appended to ``rec.findings``)."""
        ev = rec.event
        f = Finding(code, self._names[code], self._sev[code], message, ev[OFFSET], ev[T_START],
                    rec.id if sid is _AUTO else sid, ev[RAW])
        rec.findings.append(f)
        self.findings.append(f)
        self._new.append(f)
        return f

    def emit_at(self, code: str, offset: int, t: float | None, message: str, sid: int | None = None) -> Finding:
        """Report a finding about a place in the stream rather than a record (the capture's own clock)."""
        f = Finding(code, self._names[code], self._sev[code], message, offset, t, sid)
        self.findings.append(f)
        self._new.append(f)
        return f

    # ---- input -------------------------------------------------------------------------------
    def feed(self, rec: Record) -> list[Finding]:
        """Check one record (records must come in wire order); returns the findings it produced."""
        new = self._new = []
        ev = rec.event
        if self.timed is None:
            self._setup(ev[T_START] is not None)
        self.records += 1
        on = self._on
        kind: str = ev.kind  # or "corrupt", a kind of the dispatch's own
        if kind == "garbage":
            for fn in on["garbage"]:
                fn(self, rec, ev)
        elif not ev.checksum_ok:
            kind = "corrupt"
            for fn in on["corrupt"]:
                fn(self, rec, ev)
        else:
            if self._counting:
                self._count_ids(kind, ev)
            for fn in on[kind]:
                fn(self, rec, ev)
        for holds, fns in self._when[kind]:
            if holds(self, rec, ev):
                for fn in fns:
                    fn(self, rec, ev)
        if kind == "short" or kind == "long" or kind == "return":
            if kind == "short":
                self.last_request = rec
                self._short(rec, ev)
            elif kind == "long":
                self.last_request = rec
                self._long(rec, ev)
            elif kind == "return":
                self._return(rec, ev)
        elif kind == "corrupt" and ev.kind != "return":
            self.last_request = rec  # a request with a wrong Sum still ends the wait for the one before (pairing)
        if rec.status == MISSING:
            self.missing = rec
        self.prev = rec
        return new

    def feed_block(self, blk: Block) -> list[Any]:
        """Check a Block's rows (rs30x_sniff.decode.blocks), in wire order, as if fed one by one: on the columns
        when no rule has anything to say of them (rs30x_sniff.lint.batch), else record by record. A large Block
        a rule speaks of is halved, and each half checked in turn, so that a finding here and there (a late
        reply on a live port) costs the rows around it, not the whole Block: the Blocks it became, in order."""
        out: list[Any] = []
        if self._halving_off:  # halving has not paid lately: findings are everywhere
            self._halving_off -= 1
            self._check_parts(blk, out, [0])
            return out
        self._check_parts(blk, out, [SPLIT_TRIES])
        if len(out) > 1 and 4 * sum(len(b) for b in out if b.linted_by_rows) >= 3 * len(blk):
            self._halving_off = SPLIT_PAUSE  # three quarters of it went row by row all the same
        return out

    def _check_parts(self, blk: Block, out: list[Any], tries: list[int]) -> None:
        if self._columns.quiet(blk):
            out.append(blk)
            return
        n = len(blk)
        rows = self._columns.suspects
        if rows is not None and tries[0] > 0 and 8 * len(rows) < n:
            # A rule named the few rows it speaks of (a late reply): those rows, with a reply's request, go
            # record by record, and the rows before and after are checked again on the columns.
            tries[0] -= 1
            r = int(rows[0])
            a = r - 1 if r and blk.answered[r - 1] else r
            b = r + 2 if blk.answered[r] else r + 1  # a request with its reply
            if a:
                self._check_parts(blk.part(0, a), out, tries)
            cut = blk.part(a, b)
            feed = self.feed
            for rec in cut.records():
                feed(rec)
            out.append(cut)
            if b < n:
                self._check_parts(blk.part(b, n), out, tries)
            return
        mid = n // 2
        if mid and blk.answered[mid - 1]:
            mid += 1  # a request and its reply stay together (Block.part)
        if n < 2 * SPLIT_ROWS or mid >= n or tries[0] <= 0:
            feed = self.feed
            for rec in blk.records():
                feed(rec)
            out.append(blk)
            return
        tries[0] -= 1  # each halving costs column checks: findings everywhere soon go row by row
        self._check_parts(blk.part(0, mid), out, tries)
        self._check_parts(blk.part(mid, n), out, tries)

    def moved_past(self, n: int, last: Record, ids: set[int]) -> None:
        """The linter's counters moved past ``n`` records checked on the columns (rs30x_sniff.lint.batch),
        as feeding them would have: ``last`` is the last of them, ``ids`` the servo IDs they add."""
        self.ids |= ids
        self.records += n
        self.prev = last
        # A Block's last row is a request, or the reply paired with the request just before it.
        self.last_request = last if last.request is None else last.request

    def seam(self, seam: Any) -> list[Finding]:
        """A seam of the capture's clock (rs30x_sniff.decode.framing.Seam) before the next record: nothing before
        it is compared in time with anything after it (the rules of kind "seam" forget their times)."""
        new = self._new = []
        if self.timed is None:
            self._setup(True)  # only timestamps have seams
        for fn in self._on["seam"]:
            fn(self, seam)
        # Then everything the rules know of the bus starts afresh, as for a capture of its own: the
        # servos' shadows (torque, positions, limits) and each rule's memory. The IDs seen stay (Q008).
        self.missing = None
        self.prev = None
        self.last_request = None
        self.servos = {}
        self._states = {r.code: r.state() for r in self.rules if r.state is not None}
        self._setup(True)
        self._plans = {}  # their target checks are bound to the old states
        return new

    def close(self) -> list[Finding]:
        """Findings only the end of input reveals (they still attach to the records they concern)."""
        new = self._new = []
        if self.timed is None:
            self._setup(False)
        for fn in self._on["close"]:
            fn(self)
        return new

    def _count_ids(self, kind: str, ev: Any) -> None:
        ids = self.ids
        if kind == "long":
            if ev.length:
                vids = ev.raw[AT_DATA:-SUM_SIZE:ev.length]  # every record starts with its VID
                if vids not in self._vid_sets:
                    self._vid_sets.add(vids)
                    ids.update(vids)
        elif kind != "ack" and kind != "nack":
            sid = ev.id
            if sid != BROADCAST_ID:
                ids.add(sid)
        if crowded(self):
            self._counting = False  # Q008 has all it needs; stop paying for the count

    # ---- per kind ----------------------------------------------------------------------------
    def _short(self, rec: Record, ev: Any) -> None:
        sid = ev.id
        data = ev.data
        if data:
            plan = self.plan(rec.model, ev.address, len(data))
            for fn in self._on["write"]:
                fn(self, rec, plan, (sid,))
            if len(data) == plan.n:
                raws = plan.unpack(data)
                sh = self.shadow(sid)
                targets = [(sid, raws, sh)]
                for fn in plan.target_checks:
                    fn(self, rec, plan, targets)
                plan.apply(sh, raws)
                if plan.id_part is not None and sid != BROADCAST_ID:
                    self._renumber(rec, plan, [(sid, raws[plan.id_part])])
        if ev.flag & COMMAND_BITS:
            for fn in self._on["command"]:
                fn(self, rec, ev)
            self._command_state(ev)

    def _command_state(self, ev: Any) -> None:
        flag, sid = ev.flag, ev.id
        if flag & FLAG_REBOOT:
            for s in (self.servos.values() if sid == BROADCAST_ID else (self.shadow(sid),)):
                s.reboot()
        if flag & FLAG_INITIALIZE:
            for s in (self.servos.values() if sid == BROADCAST_ID else (self.shadow(sid),)):
                s.cw = s.ccw = s.reverse = None
                s.return_delay = 0
                s.baud = None  # RAM holds the default now, the servo still runs at its old rate (No. 6)

    def _renumber(self, rec: Record, plan: Plan, moves: list[tuple[int, int]]) -> None:
        """A write of servo_id: each (old, new) servo answers to its new ID at once (table 4.6 No. 4), so
        its Shadow moves there, and the rules move what they remember of it (kind "moved")."""
        lo, hi = plan.id_range
        moves = [(old, new) for old, new in moves if old != new and lo <= new <= hi]
        if not moves:
            return
        for fn in self._on["moved"]:
            fn(self, rec, moves)
        servos = self.servos
        taken = [(new, servos.pop(old, None)) for old, new in moves]  # all out first: a long packet may swap
        for new, sh in taken:
            if sh is None:
                servos.pop(new, None)
            else:
                servos[new] = sh

    def _long(self, rec: Record, ev: Any) -> None:
        records = ev.records
        n = ev.length - 1
        if n <= 0 or not records:
            return
        vid_models = rec.vid_models  # each VID's model, settled by the tracker; None: all rec.model
        plan = self.plan(rec.model if vid_models is None else vid_models[0], ev.address, n)
        vids = tuple(r[0] for r in records)
        for fn in self._on["write"]:
            fn(self, rec, plan, vids)
        checks = plan.target_checks
        shadow = self.shadow
        data = ev.raw[AT_DATA:-SUM_SIZE]
        if vid_models is None and len(data) == ev.length * ev.count:
            flat = plan.unpack_long(ev.count)(data)
            stride = len(plan.parts) + 1
            get = self.servos.get
            targets = []
            for k in range(0, len(flat), stride):
                vid = flat[k]
                targets.append((vid, flat[k + 1:k + stride], get(vid) or shadow(vid)))
            for fn in checks:
                fn(self, rec, plan, targets)
            apply = plan.apply
            for _, raws, sh in targets:
                apply(sh, raws)
            part = plan.id_part
            if part is not None:
                self._renumber(rec, plan, [(vid, raws[part]) for vid, raws, _ in targets])
            return
        moves = []
        for (vid, d), model in zip(records, vid_models or (rec.model,) * len(records)):
            p = self.plan(model, ev.address, len(d))
            if len(d) != p.n:
                continue
            raws = p.unpack(d)
            sh = shadow(vid)
            targets = [(vid, raws, sh)]
            for fn in p.target_checks:
                fn(self, rec, p, targets)
            p.apply(sh, raws)
            if p.id_part is not None:
                moves.append((vid, raws[p.id_part]))
        if moves:
            self._renumber(rec, p, moves)

    def _return(self, rec: Record, ev: Any) -> None:
        sh = self.shadow(ev.id)
        flags = ev.flags
        data = ev.data
        if data and rec.model is not None:
            plan = self.plan(rec.model, ev.address, len(data))
            if plan.tracked and len(data) == plan.n:
                raws = plan.unpack(data)
                for attr, j in plan.tracked:
                    setattr(sh, attr, raws[j])
        sh.flags = flags
        if flags & RETURN_TEMPERATURE_LIMIT:  # table 4.4 bit 7: locked until a reboot (Q009)
            sh.temp_limit = True
