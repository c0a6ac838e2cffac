"""The Linter: runs the enabled rules over records as they come, dispatching by record kind."""

from __future__ import annotations

from typing import Any

from ..bus import ANSWERED, MISSING, PAIRED, Record
from ..wire import BROADCAST_ID, COMMAND_BITS, FLAG_INITIALIZE, FLAG_REBOOT, RETURN_TEMPERATURE_LIMIT, byte_time
from .config import LintConfig
from .registry import KINDS, RULES, Finding
from .state import Plan, Shadow

_AUTO = object()


class Linter:
    """Feed it records (``Decoder(options, linter)`` does); findings land on the records they concern.

    Whether the capture has timestamps is decided from the first record: without them the rules
    that need time are skipped, and :attr:`skipped` names them.
    """

    def __init__(self, config: LintConfig | None = None) -> None:
        c = self.config = config or LintConfig()
        codes = c.enabled_codes()
        self.rules = [RULES[code] for code in codes]
        self._sev = c.severities()
        self.findings: list[Finding] = []
        self.timed: bool | None = None
        self.skipped: tuple[str, ...] = ()
        self.byte_time = byte_time(c.baud)
        self.records = 0
        self._new: list[Finding] = []
        self._on: dict[str, tuple] = {}
        self._plans: dict[tuple, Plan] = {}
        # State the rules share or keep (wire order, so no lookahead is needed).
        self.servos: dict[int, Shadow] = {}
        self.prev: Record | None = None        # the record before this one (B007)
        self.missing: Record | None = None     # the latest request whose reply never came (B001)
        self.ids: set[int] = set()             # servo IDs seen on the bus (Q008)
        self.q001: dict[int, list] = {}        # servo -> [baud write record, "flash" | "reboot"]
        self.q002: dict[int, Record] = {}      # new servo ID -> the write that set it
        self.q003: dict[int, float] = {}       # servo -> time its last flash write was done
        self.q008 = False                      # Q008 said already
        self._counting = True
        self._vid_sets: set[bytes] = set()

    # ---- setup -------------------------------------------------------------------------------
    def _setup(self, timed: bool) -> None:
        self.timed = timed
        run = [r for r in self.rules if timed or not r.needs_time]
        self.skipped = tuple(r.code for r in self.rules if r.needs_time and not timed)
        self._target_rules = [r for r in run if "target" in r.kinds]
        self._on = {k: tuple(r.check for r in run if k in r.kinds and r.when is None) for k in KINDS}
        self._when = {}
        for k in KINDS:
            conds: dict[str, list] = {}
            for r in run:
                if k in r.kinds and r.when is not None:
                    conds.setdefault(r.when, []).append(r.check)
            self._when[k] = tuple((c, tuple(fns)) for c, fns in conds.items())

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
            p.target_checks = tuple(r.check for r in self._target_rules if r.fields is None or r.fields & names)
        return p

    # ---- findings ----------------------------------------------------------------------------
    def emit(self, code: str, rec: Record, message: str, sid: Any = _AUTO) -> Finding:
        """Report a finding of rule ``code`` on ``rec`` (appended to ``rec.findings``)."""
        ev = rec.event
        f = Finding(code, RULES[code].name, self._sev[code], message, ev[0], ev[2],
                    rec.id if sid is _AUTO else sid, ev[1])
        rec.findings.append(f)
        self.findings.append(f)
        self._new.append(f)
        return f

    # ---- input -------------------------------------------------------------------------------
    def feed(self, rec: Record) -> list[Finding]:
        """Check one record (records must come in wire order); returns the findings it produced."""
        new = self._new = []
        ev = rec.event
        if self.timed is None:
            self._setup(ev[2] is not None)
        self.records += 1
        on = self._on
        kind = ev.kind
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
        for cond, fns in self._when[kind]:
            if cond == "unpaired":
                st = rec.status
                ok = st is not None and st != PAIRED and st != ANSWERED
            elif cond == "flagged":
                ok = ev[5] != 0
            elif cond == "after-cut":
                prev = self.prev
                ok = prev is not None and prev.event.kind == "garbage" and prev.event[4] == "truncated" \
                    and prev.event.end_offset == ev[0]
            elif cond == "settles":
                ok = self.missing is not None and self.missing.resolved_by is rec
            else:  # crowded
                ok = len(self.ids) > self.config.max_servos
            if ok:
                for fn in fns:
                    fn(self, rec, ev)
        if kind == "short" or kind == "long" or kind == "return":
            if kind == "short":
                self._short(rec, ev)
            elif kind == "long":
                self._long(rec, ev)
            elif kind == "return":
                self._return(rec, ev)
        if rec.status == MISSING:
            self.missing = rec
        self.prev = rec
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
                vids = ev.raw[7:-1:ev.length]  # every record starts with its VID
                if vids not in self._vid_sets:
                    self._vid_sets.add(vids)
                    ids.update(vids)
        elif kind != "ack" and kind != "nack":
            sid = ev.id
            if sid != BROADCAST_ID:
                ids.add(sid)
        if len(ids) > self.config.max_servos:
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
        data = ev.raw[7:-1]
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
            return
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
