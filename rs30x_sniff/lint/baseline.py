"""A lint baseline: today's findings by fingerprints that survive a new recording of the same behaviour.

``lint --write-baseline FILE`` records them; ``lint --baseline FILE`` then fails only on findings the file
does not hold, counts the ones it absorbed and lists its entries no longer seen (stale), as ruff and mypy do.

A fingerprint is the rule's code, the servo ID and the stable part of the message: what the finding says
(the IDs, register names, addresses, flag and model codes in it), without what varies from one recording of
the same bus to the next (stream offsets, times and latencies, values measured or written, counts).

A finding made from typed parameters (rs30x_sniff.lint.params: every built-in rule, the user rules and the
figure checks; tests/lint/test_every_finding_typed.py holds the built-in ones to it) is fingerprinted by its
key: its template with every measured value left out, never by reading its text. The per-rule patterns below
(``_SHAPES``) read a text only where no key is given: a version 1 file's fingerprints, and a message a
library caller's own rule gives as plain text.

The file is JSON, its entries sorted, with a ``version``: version 2 (written since the typed parameters)
keys the findings that have them; a version 1 file is still read, and matched by the fingerprints version
1 made (patterns over the text). A user rule's message now writes its measured values with units, so its
findings do not match a version 1 entry: write the baseline anew (``lint --write-baseline``).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from typing import IO
from collections.abc import Iterable

from .params import key_of
from .registry import Finding

BASELINE_VERSION = 2
READS = (1, 2)  # the versions this rs30x-sniff reads (see above)
BASELINE_KIND = "rs30x-sniff lint baseline"

# What every message loses: offsets in the stream, times, angles, percentages, byte times.
_NUMBER = r"(?<![\w.*])-?\d+(?:\.\d+)?"
_COMMON: tuple[tuple[re.Pattern, str], ...] = (
    (re.compile(r"@\d+"), "@*"),
    (re.compile(r"\bright after\b"), "* ms after"),              # B001, Q003: "right after" is 0 ms after
    (re.compile(_NUMBER + r"(?= ?(?:ms|us|s)\b)"), "*"),          # 2.105 ms, 12 us, 0.52 s (not bit/s)
    (re.compile(_NUMBER + r"(?= ?deg\b)"), "*"),                  # 12.5deg, 300 deg/s (not 10 degC)
    (re.compile(_NUMBER + r"(?= ?%)"), "*"),
    (re.compile(_NUMBER + r"(?= byte times?\b)"), "*"),
)
_HEX = (re.compile(r"\b0x[0-9A-Fa-f]+\b"), "0x*")
# Per message shape of the built-in rules: what else in the message is a measurement of this recording.
_SHAPES: dict[str, tuple[tuple[re.Pattern, str], ...]] = {
    "F001": (_HEX,),                                                          # the Sums, by the packet's data
    "F002": ((re.compile(r"^\d+(?= byte\(s\))"), "*"),),                      # how many noise bytes
    "F003": ((re.compile(r"\d+(?= byte\(s\))"), "*"),),                       # where the frame was cut
    "F005": ((re.compile(r"\b(?:once|\d+ times)\b"), "* times"),),
    "F006": ((re.compile(r"^\d+ chunks?\b"), "* chunk(s)"),),
    "F007": ((re.compile(r"\d+(?= bytes\b)"), "*"),),
    "F008": (_HEX,),                                                          # the flagged byte's value
    "F009": ((re.compile(r"\b\d+ of \d+ packets checked disagree\b"), "* of * packets checked disagree"),),
    "B007": ((re.compile(r"\d+(?=-byte frame)"), "*"),),
    "M003": ((re.compile(r"=-?\d+ \(raw\)"), "=* (raw)"), (re.compile(r" \([^()]*\)$"), "")),  # the value written
    "Q008": ((re.compile(r"^\d+(?= servo IDs)"), "*"),),
}
_BUILT_IN_FAMILIES = frozenset("FPMBSQ")
# A user's rule or figure check (U...) says what its author wrote: every number in it but the servo IDs
# is taken for a measurement (a temperature, a rate, a latency).
_ID_LIST = re.compile(r"\b(?:V?IDs?) \d+(?:(?:, | and |-)\d+)*")
_ANY_NUMBER = re.compile(r"\b0x[0-9A-Fa-f]+\b|" + _NUMBER + r"(?![\w])")


class BaselineError(Exception):
    """A baseline file that cannot be read: one line naming it and what is wrong."""


def stable_message(code: str, message: str) -> str:
    """``message`` without what varies between two recordings of the same behaviour."""
    for pattern, repl in _COMMON:
        message = pattern.sub(repl, message)
    if code[:1] in _BUILT_IN_FAMILIES:
        for pattern, repl in _SHAPES.get(code, ()):
            message = pattern.sub(repl, message)
        return message
    parts, at = [], 0
    for m in _ID_LIST.finditer(message):
        parts.append(_ANY_NUMBER.sub("*", message[at:m.start()]))
        parts.append(m.group(0))
        at = m.end()
    parts.append(_ANY_NUMBER.sub("*", message[at:]))
    return "".join(parts)


def fingerprint(f: Finding, version: int = BASELINE_VERSION) -> str:
    """``CODE:ID:stable message`` (``-`` for a finding of no one servo): by the message's key when it was
    made from typed parameters, else by :func:`stable_message`; ``version`` 1: as version 1 made it (by
    the text alone)."""
    key = key_of(f.message) if version >= 2 else None
    stable = key if key is not None else stable_message(f.code, str(f.message))
    return f"{f.code}:{'-' if f.id is None else f.id}:{stable}"


@dataclass
class Entry:
    """One baseline entry: a fingerprint, its code and servo, an example message and how often it was seen."""

    fingerprint: str
    code: str
    id: int | None
    message: str
    count: int

    def as_json(self) -> dict:
        return {"fingerprint": self.fingerprint, "code": self.code, "id": self.id, "message": self.message,
                "count": self.count}


@dataclass
class Baseline:
    """Entries by fingerprint, and where they were read from (None: made here)."""

    entries: dict[str, Entry] = field(default_factory=dict)
    path: str | None = None
    version: int = BASELINE_VERSION  # how its fingerprints were made (a version 1 file: by the text)

    @classmethod
    def of(cls, findings: Iterable[Finding]) -> Baseline:
        """A baseline holding ``findings``: one entry per fingerprint, the first message as its example."""
        entries: dict[str, Entry] = {}
        for f in findings:
            fp = fingerprint(f)
            e = entries.get(fp)
            if e is None:
                entries[fp] = Entry(fp, f.code, f.id, f.message, 1)
            else:
                e.count += 1
        return cls(entries)

    def sorted_entries(self) -> list[Entry]:
        return sorted(self.entries.values(), key=lambda e: (e.code, -1 if e.id is None else e.id, e.fingerprint))

    def as_json(self) -> dict:
        return {"kind": BASELINE_KIND, "version": self.version,
                "entries": [e.as_json() for e in self.sorted_entries()]}

    def dump(self, out: IO[str]) -> None:
        """The file: sorted, two-space indented, one key order, a final newline (a stable diff in git)."""
        json.dump(self.as_json(), out, indent=2, ensure_ascii=False)
        out.write("\n")

    @classmethod
    def load(cls, path: str) -> Baseline:
        """Read a baseline file; a missing, unreadable or malformed one raises :class:`BaselineError`."""
        try:
            with open(path, encoding="utf-8") as fh:
                text = fh.read()
        except OSError as e:
            raise BaselineError(f"{path}: cannot read the baseline: {e.strerror or e}") from None
        except UnicodeDecodeError:
            raise BaselineError(f"{path}: not a baseline (not UTF-8 text)") from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise BaselineError(f"{path}: not a baseline: invalid JSON at line {e.lineno} column {e.colno} "
                                f"({e.msg})") from None
        return cls.from_json(data, path)

    @classmethod
    def from_json(cls, data: object, path: str) -> Baseline:
        if not isinstance(data, dict) or data.get("kind") != BASELINE_KIND:
            raise BaselineError(f"{path}: not a baseline (no \"kind\": \"{BASELINE_KIND}\"; write one with "
                                f"lint --write-baseline)")
        version = data.get("version")
        if isinstance(version, bool) or version not in READS:
            raise BaselineError(f"{path}: baseline version {version!r} is not one this rs30x-sniff reads "
                                f"({', '.join(map(str, READS))}); write it anew with lint --write-baseline")
        items = data.get("entries")
        if not isinstance(items, list):
            raise BaselineError(f"{path}: \"entries\" must be a list")
        entries: dict[str, Entry] = {}
        for k, item in enumerate(items, 1):
            if not isinstance(item, dict):
                raise BaselineError(f"{path}: entry {k} is not an object")
            fp, code, sid = item.get("fingerprint"), item.get("code"), item.get("id")
            message, count = item.get("message", ""), item.get("count", 1)
            if not isinstance(fp, str) or not fp:
                raise BaselineError(f"{path}: entry {k}: \"fingerprint\" must be a non-empty string")
            if not isinstance(code, str) or not fp.startswith(code + ":"):
                raise BaselineError(f"{path}: entry {k}: \"code\" must be the code its fingerprint starts with")
            if sid is not None and (not isinstance(sid, int) or isinstance(sid, bool)):
                raise BaselineError(f"{path}: entry {k}: \"id\" must be a servo ID or null")
            if not isinstance(message, str):
                raise BaselineError(f"{path}: entry {k}: \"message\" must be a string")
            if not isinstance(count, int) or isinstance(count, bool) or count < 0:
                raise BaselineError(f"{path}: entry {k}: \"count\" must be a whole number")
            if fp in entries:
                raise BaselineError(f"{path}: entry {k}: fingerprint {fp!r} is there twice")
            entries[fp] = Entry(fp, code, sid, message, count)
        return cls(entries, path, version)

    def split(self, findings: Iterable[Finding]) -> tuple[list[Finding], list[Finding]]:
        """``(new, absorbed)``: the findings whose fingerprint this baseline does not hold, and those it does."""
        new: list[Finding] = []
        absorbed: list[Finding] = []
        for f in findings:
            (absorbed if fingerprint(f, self.version) in self.entries else new).append(f)
        return new, absorbed

    def stale(self, absorbed: Iterable[Finding]) -> list[Entry]:
        """The entries none of ``absorbed`` matched: behaviour no longer seen."""
        seen = {fingerprint(f, self.version) for f in absorbed}
        return [e for e in self.sorted_entries() if e.fingerprint not in seen]


@dataclass
class BaselineReport:
    """What a baseline did to a run, for the reports: where it was read, how many findings it absorbed,
    and its entries no longer seen."""

    path: str
    absorbed: int
    stale: list[Entry]

    def as_json(self) -> dict:
        return {"file": self.path, "absorbed": self.absorbed, "stale": [e.as_json() for e in self.stale]}
