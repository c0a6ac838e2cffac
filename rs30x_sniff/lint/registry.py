"""The rule registry: every lint rule declared once with @rule (code, name, severity, summary, doc)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any
from collections.abc import Callable, Iterable, Iterator

from ..decode.pairing import ANSWERED, PAIRED
from ..protocol.events import FLAG, OFFSET, REASON, TRUNCATED
from ..protocol.memmap import Model, loaded_models
from ..protocol.wire import COMMAND_BITS, REQUEST_HEADER, checksum

SEVERITIES = ("info", "warning", "error")
SEVERITY_RANK = {"info": 1, "warning": 2, "error": 3}
FAMILIES = {"F": "Framing", "P": "Packet structure", "M": "Memory map", "B": "Bus", "S": "Servo status",
            "Q": "Sequences"}
# A project's own rules, from its configuration ([[rule]], rs30x_sniff.user_rules): U and three digits.
USER_PREFIX, USER_FAMILY = "U", "User rules"
USER_CODE = re.compile(r"U\d{3}")
KEBAB = re.compile(r"[a-z0-9]+(-[a-z0-9]+)*")
_ORDER = "FPMBSQ" + USER_PREFIX

# What a rule's check is called with, by "kind":
#   short, long, return, ack, nack, garbage  check(lint, rec, ev) for every intact record of that kind
#   corrupt                                   check(lint, rec, ev) for a packet whose Sum is wrong (only
#                                             these rules see it: its other bytes cannot be trusted)
#   command                                   check(lint, rec, ev) for a short packet with flash/reboot/init bits
#   write                                     check(lint, rec, plan, ids) once per packet that writes memory
#   target                                    check(lint, rec, plan, targets) once per write, with targets a
#                                             list of (servo id, raw values per plan part, Shadow)
#   moved                                     check(lint, rec, moves) after a write of servo_id moved servos to
#                                             new IDs (at once, table 4.6 No. 4): moves lists (old, new) pairs,
#                                             and the Shadows have moved; a rule moves its own per-servo memory
#   seam                                      check(lint, seam) where the capture's clock restarts or resumes
#                                             (rs30x_sniff.decode.framing.Seam): a rule forgets the times it holds
#   close                                     check(lint) at end of input
# A rule declared with state= keeps its own memory: the linter makes one state object per run by calling
# that factory, and passes it first to every call of the rule's checks: check(state, lint, rec, ev).
# One function serves every kind of a rule; ``@the_check.on(kind)`` gives a kind a function of its own.
KINDS = ("short", "long", "return", "ack", "nack", "garbage", "corrupt", "command", "write", "target", "moved",
         "seam", "close")

# Every rule also declares its column form with column=: how the linter's column path
# (rs30x_sniff.lint.batch) knows the rule says nothing of a Block's rows without feeding them one by one.
#   "header"    the rule's checks are pure in a packet's header, its model and (for a reply) its request's
#               header: the batch linter runs them once per distinct header, on a sample record
#   "silent"    the rule cannot speak of a Block that passes the batch linter's common checks (a Block has
#               no garbage, corrupt frames, ACK/NACK or unpaired replies, and one holding commands, flagged
#               returns or writes of registers other than positions and goal times takes the record path);
#               a "target" rule declared silent sends every Block that writes one of its fields there
#   a function  quiet(view) -> bool, or quiet(state, view) for a rule with state=: True when the rule finds
#               nothing in the Block's rows (rs30x_sniff.lint.batch.BlockView: its columns, writes, the shadows
#               as of any row); it may call view.when_quiet(fn) to move the rule's memory past the rows once
#               the Block is accepted. It lives beside the rule, with the same arithmetic as its check.
COLUMN_DECLARATIONS = ("header", "silent")


# Preconditions a rule may declare with when=: the linter tests each once per record (for the kinds that
# have rules waiting on it) and calls the rule only when it holds, so the common healthy record costs few
# calls. Each takes (lint, rec, ev) like a check.
def follows_cut(prev, offset: int) -> bool:
    """Whether a frame at stream ``offset`` starts right where the record ``prev`` (None: nothing before),
    a cut-short frame, ended: the test of "after-cut" (B007), for a record and for a Block's first row."""
    if prev is None:
        return False
    pe = prev.event
    return pe.kind == "garbage" and pe[REASON] == TRUNCATED and pe.end_offset == offset


def _after_cut(lint, rec, ev) -> bool:
    return follows_cut(lint.prev, ev[OFFSET])


def _unpaired(lint, rec, ev) -> bool:
    st = rec.status
    return st is not None and st != PAIRED and st != ANSWERED


def _flagged(lint, rec, ev) -> bool:
    return ev[FLAG] != 0


def crowded(lint, more: int = 0) -> bool:
    """Whether the bus has seen more distinct servo IDs than max-servos (with ``more`` not counted yet): the
    one test of a crowded bus (Q008), for its rule, its precondition, the linter's count and a Block."""
    return len(lint.ids) + more > lint.config.max_servos


def _crowded(lint, rec, ev) -> bool:
    return crowded(lint)


def _settles(lint, rec, ev) -> bool:
    missing = lint.missing
    return missing is not None and missing.resolved_by is rec


WHEN: dict[str, tuple[str, Callable[..., bool]]] = {
    "after-cut": ("the record starts where a cut-short frame (truncated garbage) ended", _after_cut),
    "unpaired": ("the record's reply status is missing, unsolicited or extra", _unpaired),
    "flagged": ("a return packet with any status flag set", _flagged),
    "crowded": ("more distinct servo IDs seen than max-servos", _crowded),
    "settles": ("the record settled that the latest unanswered request got no reply", _settles),
}


# Rows the column path (rs30x_sniff.lint.batch) leaves to the record path, each for the rules that ask it: a
# rule asks its precondition's (when=, above: it runs on rows the precondition picks, one by one) and, if it
# checks commands (kind "command"), "command". Each is tested on a BlockView (its columns, the linter):
# True when some row of the Block may meet it. "unpaired" and "settles" need none: a Block holds no unpaired
# reply and settles no missing one (rs30x_sniff.decode.blocks).
@dataclass(frozen=True, slots=True)
class BailOut:
    """Rows of a Block some rules see only one by one: what they are, and whether a Block has any."""

    doc: str
    in_block: Callable[[Any], bool]


def _command_rows(view) -> bool:
    return bool((view.is_short & ((view.flag & COMMAND_BITS) != 0)).any())


def _flagged_rows(view) -> bool:
    return bool((view.is_return & (view.flag != 0)).any())


def _after_cut_rows(view) -> bool:
    return follows_cut(view.lint.prev, int(view.blk.offsets[0]))  # only a Block's first row can


def _crowded_rows(view) -> bool:
    return crowded(view.lint) or crowded(view.lint, len(view.new_ids()))


BAIL_OUTS: dict[str, BailOut] = {
    "command": BailOut("a short packet with flash, reboot or initialize bits (table 4.2)", _command_rows),
    "flagged": BailOut("a return with any status flag set (table 4.4)", _flagged_rows),
    "after-cut": BailOut("the Block's first row starts where a cut-short frame ended", _after_cut_rows),
    "crowded": BailOut("the Block's servo IDs bring the bus above max-servos", _crowded_rows),
}
# Asked whatever rules run: the linter's own memory of each servo (rs30x_sniff.lint.state.Shadow), which the
# rules read, follows a reboot or initialize (table 4.2) and the temperature lock (table 4.4 bit 7) on the
# record path only.
MEMORY_BAIL_OUTS = ("command", "flagged")


def bail_outs(rules: Iterable[Rule]) -> tuple[BailOut, ...]:
    """The bail-outs a Block is tested for when ``rules`` run: the linter's memory's, then the rules' own
    (:attr:`Rule.bails`), each once, cheapest first (BAIL_OUTS' order)."""
    asked = set(MEMORY_BAIL_OUTS)
    for r in rules:
        asked.update(r.bails)
    return tuple(b for name, b in BAIL_OUTS.items() if name in asked)


_ALIASES = {"request": ("short", "long"), "reply": ("return", "ack", "nack"), "packet": ("short", "long", "return")}


@dataclass(frozen=True, slots=True)
class Finding:
    """One lint finding, attached to the record it concerns. ``message`` may be a
    :class:`rs30x_sniff.lint.params.Message`: made from typed parameters, it carries them and its key."""

    code: str
    name: str
    severity: str
    message: str
    offset: int
    t: float | None
    id: int | None
    raw: bytes = field(default=b"", repr=False, compare=False)  # the record's bytes, for reports

    @property
    def params(self) -> dict[str, Any]:
        """The typed parameters the message was made from (rs30x_sniff.lint.params: measured values with
        their units); {} for a message given as plain text."""
        return dict(getattr(self.message, "params", {}))

    def as_json(self) -> dict[str, Any]:
        return {"offset": self.offset, "t": self.t, "code": self.code, "name": self.name,
                "severity": self.severity, "message": self.message, "id": self.id}


@dataclass(frozen=True, slots=True)
class Rule:
    """A declared rule: its public identity, its documentation and its check."""

    code: str
    name: str
    severity: str
    summary: str
    doc: str
    kinds: tuple[str, ...]
    check: Callable[..., Any]
    needs_time: bool = False
    fields: frozenset[str] | None = None  # for "target" rules: run only when the write carries one of these
    when: str | None = None  # a cheap precondition the linter tests once for all rules sharing it (WHEN)
    state: Callable[[], Any] | None = None  # makes the rule's own memory, once per linter run
    handlers: dict[str, Callable[..., Any]] = field(default_factory=dict)  # kind -> check, where not ``check``
    # The column form: "header", "silent" or quiet(view) (KINDS). quiet(view) answers whether the rule is silent on
    # the Block's rows, or may name the rows it speaks of instead (an array of row indexes, empty when silent), so
    # that a finding here and there is cut out of a live Block rather than found by halving it (Linter.feed_block).
    column: str | Callable[..., Any] | None = None

    @property
    def bails(self) -> tuple[str, ...]:
        """The bail-outs (BAIL_OUTS) the rule asks of the column path: its precondition's, and "command"
        for a rule that checks commands."""
        own = ("command",) if "command" in self.kinds else ()
        return own + ((self.when,) if self.when in BAIL_OUTS else ())

    def check_for(self, kind: str) -> Callable[..., Any]:
        """The function that checks records of ``kind`` (unbound: a stateful rule's take the state first)."""
        return self.handlers.get(kind, self.check)

    @property
    def family(self) -> str:
        return FAMILIES.get(self.code[0]) or USER_FAMILY

    @property
    def is_user(self) -> bool:
        """A rule of the project's configuration rather than one of the built-in rules."""
        return self.code[0] == USER_PREFIX

    def section(self, title: str) -> str:
        """The text of one section of the doc ("What it does", "Why it matters", "Example")."""
        m = re.search(rf"^## {re.escape(title)}\n(.*?)(?=^## |\Z)", self.doc, re.M | re.S)
        return m.group(1).strip() if m else ""

    @property
    def example(self) -> str:
        """The example capture of the doc (hex lines, possibly timestamped)."""
        m = re.search(r"```\n(.*?)```", self.section("Example"), re.S)
        return m.group(1) if m else ""


class Registry:
    """Every rule, by code and by name, iterated in code order. :data:`RULES` holds the built-in rules (added by
    ``@rule``) and never a configuration's: a run's rule set is :meth:`with_user` (the built-in rules and that
    run's user rules), carried by its LintConfig (``rules``), which every consumer then treats alike."""

    def __init__(self, rules: Iterable[Rule] = ()) -> None:
        rules = tuple(rules)  # already checked: those of another registry (with_user)
        self._by_code: dict[str, Rule] = {r.code: r for r in rules}
        self._by_name: dict[str, Rule] = {r.name: r for r in rules}

    def add(self, r: Rule) -> None:
        if not re.fullmatch(r"[FPMBSQ]\d{3}", r.code):
            raise ValueError(f"bad rule code {r.code!r}")
        for part in ("What it does", "Why it matters", "Example"):
            if not r.section(part):
                raise ValueError(f"{r.code}: doc has no {part!r} section")
        self._put(r)

    def _put(self, r: Rule) -> None:
        if not KEBAB.fullmatch(r.name):
            raise ValueError(f"{r.code}: name {r.name!r} is not kebab-case")
        if r.severity not in SEVERITIES:
            raise ValueError(f"{r.code}: bad severity {r.severity!r}")
        if r.code in self._by_code or r.name in self._by_name:
            raise ValueError(f"{r.code} {r.name}: declared twice")
        if r.column not in COLUMN_DECLARATIONS and not callable(r.column):
            raise ValueError(f"{r.code}: column={r.column!r}: declare the rule's column form (column='header', "
                             "'silent' or a function quiet(view), see rs30x_sniff.lint.registry)")
        self._by_code[r.code] = r
        self._by_name[r.name] = r

    # ---- user rules ----------------------------------------------------------------------------
    def with_user(self, rules: Iterable[Rule]) -> Registry:
        """The rule set of one run: this registry's rules and ``rules`` as its user rules, this registry
        unchanged; ValueError on a bad user rule code or a code or name given twice."""
        out = Registry(self)
        for r in rules:
            out.add_user(r)
        return out

    def add_user(self, r: Rule) -> None:
        """Register a user rule (code U and three digits; its name clashes with no rule's), in a rule set of
        one run (:meth:`with_user`), never in :data:`RULES`."""
        if self is RULES:
            raise ValueError(f"{r.code}: user rules go in a run's rule set (RULES.with_user), not in RULES")
        if not USER_CODE.fullmatch(r.code):
            raise ValueError(f"bad user rule code {r.code!r} (U and three digits)")
        self._put(r)

    def remove_user(self, code: str) -> None:
        """Take user rule ``code`` out again (nothing if it is not there; never a built-in rule)."""
        r = self._by_code.get(code)
        if r is not None and r.is_user:
            del self._by_code[code]
            del self._by_name[r.name]

    def user(self) -> list[Rule]:
        """The user rules in effect, in code order."""
        return [r for r in self if r.is_user]

    def builtin(self) -> list[Rule]:
        """The built-in rules, in code order (what docs/rules.md lists)."""
        return [r for r in self if not r.is_user]

    def __iter__(self) -> Iterator[Rule]:
        return iter(sorted(self._by_code.values(), key=lambda r: (_ORDER.index(r.code[0]), r.code)))

    def __len__(self) -> int:
        return len(self._by_code)

    def __contains__(self, key: str) -> bool:
        return key in self._by_code or key in self._by_name

    def __getitem__(self, code: str) -> Rule:
        return self._by_code[code]

    def get(self, key: str) -> Rule | None:
        """A rule by code (any case) or name."""
        return self._by_code.get(key.upper()) or self._by_name.get(key.lower())

    def codes(self) -> list[str]:
        return [r.code for r in self]

    def match(self, selector: str) -> list[str]:
        """Codes a selector picks: ALL, a code, a code prefix (``Q``, ``B00``) or a name; [] if none."""
        s = selector.strip()
        if s.upper() == "ALL":
            return self.codes()
        r = self.get(s)
        if r is not None:
            return [r.code]
        up = s.upper()
        if re.fullmatch(r"[A-Z]\d{0,3}", up):
            return [c for c in self.codes() if c.startswith(up)]
        return []


RULES = Registry()


def frame(*body: int, header: bytes = REQUEST_HEADER) -> bytes:
    """A frame from its ID..data bytes with the right Sum (for doc examples of malformed packets)."""
    return header + bytes(body) + bytes((checksum(bytes(body)),))


def models_where(test: Callable[[Model], bool]) -> str:
    """The models of the memory maps for which ``test`` holds, by name ("RS301CR, RS302CD"), for a rule's doc:
    what a rule says of a model's behaviour comes from its map's [behaviour], never from a list here."""
    return ", ".join(m.name for m in loaded_models() if test(m)) or "none of the memory maps"


def example(*frames: bytes | tuple[float, bytes], note: str = "") -> str:
    """A doc's example capture: one frame per line in hex (``(t, bytes)`` for timestamped lines)."""
    lines = []
    for fr in frames:
        if isinstance(fr, tuple):
            lines.append(f"{fr[0]:.6f} {fr[1].hex(' ').upper()}")
        else:
            lines.append(fr.hex(" ").upper())
    text = ("" if not note else note.strip() + "\n\n") + "```\n" + "\n".join(lines) + "\n```"
    return text


def _expand(code: str, kinds: tuple[str, ...]) -> list[str]:
    expanded: list[str] = []
    for k in kinds:
        for kk in _ALIASES.get(k, (k,)):
            if kk not in KINDS:
                raise ValueError(f"{code}: unknown kind {kk!r}")
            expanded.append(kk)
    return expanded


def rule(code: str, name: str, severity: str, summary: str, doc: str, *, kinds: tuple[str, ...],
         needs_time: bool = False, fields: tuple[str, ...] | None = None, when: str | None = None,
         state: Callable[[], Any] | None = None, column: str | Callable[..., Any] | None = None) -> Callable:
    """Declare a rule; the decorated function is its check (see KINDS for how it is called).

    ``column`` is the rule's column form, required: "header", "silent" or a function (see
    COLUMN_DECLARATIONS); a rule without one is an error here, at import.

    ``state`` (a class or any callable) makes the rule's own memory; the decorated function gains
    ``.on(kind)``, a decorator giving one of the declared kinds a check of its own.
    """
    expanded = _expand(code, kinds)
    if when is not None and when not in WHEN:
        raise ValueError(f"{code}: unknown precondition {when!r}")

    def deco(fn: Callable) -> Callable:
        r = Rule(code, name, severity, summary, doc.strip() + "\n", tuple(expanded), fn, needs_time,
                 frozenset(fields) if fields else None, when, state, column=column)
        RULES.add(r)

        def on(*kinds_: str) -> Callable:
            ks = _expand(code, kinds_)
            for k in ks:
                if k not in r.kinds:
                    raise ValueError(f"{code}: .on({k!r}) for a kind the rule does not declare")

            def register(handler: Callable) -> Callable:
                for k in ks:
                    r.handlers[k] = handler
                return handler

            return register

        fn.on = on  # type: ignore[attr-defined]  # a function takes attributes; the docstring above promises .on
        return fn

    return deco
