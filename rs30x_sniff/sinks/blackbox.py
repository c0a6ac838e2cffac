"""The black box: the last minutes of the bus in a ring, and a window around each trigger saved as its own capture."""

from __future__ import annotations

import re
from collections import deque
from dataclasses import dataclass, field
from datetime import datetime, UTC
from typing import Any
from collections.abc import Callable, Iterable

from ..decode.blocks import Block
from ..decode.decoder import Sink, Step
from ..decode.pairing import Record
from ..filters import Filter, FilterError, parse_filter
from ..protocol.chunks import SourceGap

RULE_CODE = re.compile(r"[A-Z]\d{3}")
HOUR = 3600.0
# A window that triggers keep extending is saved once it spans this long, and the next one begins after it:
# a storm of fires still gives files of a bounded size.
MAX_WINDOW_S = 600.0
# How far behind the newest chunk the decoder's records may be before the ring stops waiting for them.
MAX_LAG_S = 30.0


class TriggerError(ValueError):
    """A --trigger that is neither a rule code nor a filter: one line."""


@dataclass(frozen=True)
class Trigger:
    """One --trigger: a rule code (fires on its findings) or a filter (on a matching record; a filter of
    severities and IDs only, such as ``sev>=error``, on the findings themselves)."""

    text: str
    code: str | None = None
    filter: Filter | None = None

    @property
    def on_findings(self) -> bool:
        return self.code is not None or (self.filter is not None and self.filter.uses_findings
                                          and self.filter.finding_terms is not None)

    @property
    def needs_lint(self) -> bool:
        """Whether it fires on findings: the recorder then lints as it goes."""
        return self.code is not None or (self.filter is not None and self.filter.uses_findings)

    def fired_by_finding(self, f: Any) -> bool:
        if self.code is not None:
            return f.code == self.code
        return self.filter is not None and self.filter.matches_finding(f)


def parse_trigger(text: str, codes: Iterable[str], registry: Any = None) -> Trigger:
    """``S001`` (a rule code of ``codes``) or a filter (``present_temperature>70``, ``id:3 latency>5ms``)."""
    text = text.strip()
    if RULE_CODE.fullmatch(text):
        if text not in set(codes):
            raise TriggerError(f"--trigger {text}: no such rule (see `rs30x-sniff rules`)")
        return Trigger(text, code=text)
    try:
        flt = parse_filter(text, registry)
    except FilterError as e:
        raise TriggerError(f"--trigger {text!r}: {e}") from None
    if flt is None:
        raise TriggerError("--trigger: empty (a rule code such as S001, or a filter such as present_temperature>70)")
    return Trigger(text, filter=flt)


def slug(text: str) -> str:
    """A trigger's text as a file-name part: ``present_temperature>70`` -> ``present_temperature-gt-70``."""
    words = {">=": "-ge-", "<=": "-le-", "!=": "-ne-", ">": "-gt-", "<": "-lt-", "=": "-eq-", ":": "-"}
    for k, v in words.items():
        text = text.replace(k, v)
    text = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_-.")
    return text[:60] or "trigger"


def wall_name(t: float) -> str:
    """Epoch seconds as a file-name time, UTC, to the millisecond: ``2026-11-26T01-42-05.123Z``."""
    d = datetime.fromtimestamp(t, tz=UTC)
    return d.strftime("%Y-%m-%dT%H-%M-%S.") + f"{d.microsecond // 1000:03d}Z"


def wall_time(t: float) -> str:
    """Epoch seconds as a person reads them, UTC, to the millisecond (ISO 8601): ``2026-11-26T01:42:05.123Z``."""
    return datetime.fromtimestamp(t, tz=UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


@dataclass
class Window:
    """An open window: from ``start`` to ``end`` (capture seconds), its first trigger and every fire in it."""

    start: float
    end: float
    first: Trigger
    first_t: float
    fires: list[tuple[float, str]] = field(default_factory=list)


class BlackBox(Sink[Record | Block]):
    """Keeps the chunks of the last ``pre`` seconds; when a trigger fires at t, holds on until t + ``post``
    and hands ``save`` the chunks of [t - pre, end] with what fired, to be written as a capture of its own.
    A later fire whose window would overlap this one extends it instead (so a window is saved only once the bus has
    gone ``pre`` past its end), and no byte is saved in two windows. Fires beyond ``max_per_hour`` saves in the last
    hour are counted, not saved. Never reads a clock: ``now`` (capture seconds) is asked only when the bus is idle,
    to close a window no byte arrives to close.

    ``save(chunks, window, name)`` writes the window; ``name`` is its file name (wall time of the first fire
    and the trigger). Takes Blocks: a Block is judged on its columns (Filter.may_match) and only the rows that
    may match are made records."""

    takes_blocks = True

    def __init__(self, triggers: list[Trigger], pre: float, post: float,
                 save: Callable[[list, Window, str], None], *, max_per_hour: int | None = None,
                 now: Callable[[], float] | None = None, say: Callable[[str], None] | None = None) -> None:
        self.triggers = triggers
        # A trigger not on findings is a filter (parse_trigger makes a code or a filter): kept with it, typed.
        self.on_records: list[tuple[Trigger, Filter]] = [(t, t.filter) for t in triggers
                                                         if not t.on_findings and t.filter is not None]
        self.on_findings = [t for t in triggers if t.on_findings]
        self.pre, self.post = pre, post
        self.save = save
        self.max_per_hour = max_per_hour
        self.now = now
        self.say = say
        self.ring: deque = deque()  # (data, t) chunks and SourceGaps (b"", t back), oldest first
        self.last_t: float | None = None  # the newest chunk's time
        self.seen_t: float | None = None  # the newest record's time
        self.window: Window | None = None
        self.saved: list[tuple[float, str]] = []  # (first fire, file name) of each window saved
        self.saved_to: float | None = None  # the end of the last window saved
        self.suppressed = 0  # fires that found the hour's saves used up
        self._suppressing = False

    # ---- the ring -----------------------------------------------------------------------------------------
    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        if data and t is not None:
            self._keep(data, t)

    def chunk_group(self, chunks: list) -> None:
        for data, t in chunks:
            if data and t is not None:
                self._keep(data, t)

    def gap(self, t: float, lost_at: float | None, note: str) -> None:
        """The port was lost until ``t``: the gap goes in the ring at its place, so a window that spans it
        carries it (its decoder's seam, its file's gap metadata)."""
        self.ring.append(SourceGap(t, lost_at, note))

    def _keep(self, data: bytes, t: float) -> None:
        ring = self.ring
        ring.append((data, t))
        self.last_t = t
        # The chunks come in before the decoder has decided their records: a fire can only come from a record
        # at or after the last one seen, so the ring holds --pre back from there (and never more than
        # MAX_LAG_S behind the newest chunk, should records stop coming at all).
        seen = self.seen_t if self.seen_t is not None else t
        keep_from = max(seen, t - MAX_LAG_S) - self.pre
        w = self.window
        if w is not None:
            keep_from = min(keep_from, w.start)
        while ring and ring[0][1] < keep_from:
            ring.popleft()

    # ---- triggers -----------------------------------------------------------------------------------------
    def batch(self, step: Step) -> None:
        for rec in step:
            if type(rec) is Block:
                t1 = rec.t1
                if t1 is not None and len(t1):
                    self.seen_t = float(t1[-1])
                self._block(rec)
                continue
            if rec.t is not None:
                self.seen_t = rec.t
            if self.on_records and rec.t is not None:
                for trig, filt in self.on_records:
                    if filt.matches(rec):
                        self.fire(rec.t, trig)
                        break
        if self.on_findings and step.findings:
            for f in step.findings:
                t = f.t if f.t is not None else self.last_t
                if t is None:
                    continue
                for trig in self.on_findings:
                    if trig.fired_by_finding(f):
                        self.fire(t, trig)
                        break
        self._close_if_past()

    def _block(self, blk: Block) -> None:
        for trig, filt in self.on_records:
            maybe = filt.may_match(blk)
            if not maybe.any():
                continue
            for k in maybe.nonzero()[0].tolist():
                rec = blk.fresh_record(k)
                if rec.t is not None and filt.matches(rec):
                    self.fire(rec.t, trig)

    def fire(self, t: float, trig: Trigger) -> None:
        """Trigger ``trig`` fired at capture time ``t``: a window opens, or the open one reaches t + post."""
        w = self.window
        if w is not None and t - self.pre <= w.end:  # the two windows would overlap: one window
            w.end = max(w.end, t + self.post)
            w.fires.append((t, trig.text))
            if w.end - w.start > MAX_WINDOW_S:  # a storm: this window is long enough
                self._save(min(w.end, self.last_t if self.last_t is not None else w.end))
            return
        if w is not None:  # a fire whose window cannot reach back into the open one: that one is done
            self._save(w.end)
        if self.max_per_hour is not None and len([s for s, _ in self.saved if s > t - HOUR]) >= self.max_per_hour:
            self.suppressed += 1
            if not self._suppressing and self.say:
                self.say(f"rs30x-sniff: {trig.text} fired at {wall_time(t)}: not saved, {self.max_per_hour} "
                         f"windows saved within the hour already (--max-saves)")
            self._suppressing = True
            return
        self._suppressing = False
        start = t - self.pre if self.saved_to is None else max(t - self.pre, self.saved_to)  # no byte saved twice
        self.window = Window(start, t + self.post, trig, t, [(t, trig.text)])

    # ---- saving -------------------------------------------------------------------------------------------
    def _close_if_past(self) -> None:
        # Saved once no later fire could reach back into it (its --pre would start before the window's end).
        w = self.window
        if w is not None and self.last_t is not None and self.last_t > w.end + self.pre:
            self._save(w.end)

    def _save(self, end: float) -> None:
        w = self.window
        assert w is not None
        self.window = None
        w.end = end
        chunks = [c for c in self.ring if w.start <= c[1] <= end]
        self.saved_to = end
        name = f"{wall_name(w.first_t)}-{slug(w.first.text)}.mcap"
        self.save(chunks, w, name)
        self.saved.append((w.first_t, name))

    def idle(self) -> None:
        """The bus is quiet: a window whose end has passed (by ``now``) is saved without waiting for a byte."""
        w = self.window
        if w is not None and self.now is not None and self.now() > w.end + self.pre:
            self._save(w.end)

    def close(self) -> None:
        """The end of the recording: an open window is saved as far as the bus went."""
        w = self.window
        if w is not None:
            self._save(min(w.end, self.last_t) if self.last_t is not None else w.end)
