"""Chunks of captured bytes: plain ``(data, t)`` pairs, or marked with what the capturing tool recorded."""

from __future__ import annotations

from bisect import bisect_right
from typing import Any

Chunk = tuple  # (data: bytes, t: float | None), or a Marked one

# A chunk time this large counts seconds since 1970 (a live port, a logger's wall clock), not seconds since the
# capture began: 1e9 s is 2001, and no capture counted from its own start runs 31 years. One threshold for every
# output that tells the two apart (tables, info's summary, the text lines' --time-format).
EPOCH_MIN = 1e9

# Who sent a chunk's bytes, where the capture says so (a logger's TX/RX column, an analyzer's channel).
HOST, SERVO = "host", "servo"
SENDERS = (HOST, SERVO)

# Why a chunk's bytes could not be trusted, where the capturing tool flagged them (Garbage.reason).
FRAMING_ERROR = "framing-error"  # the stop bit was low
PARITY_ERROR = "parity-error"    # the parity bit disagreed (the RS30x bus has none: 8N1, table 4.7)
UART_ERRORS = (FRAMING_ERROR, PARITY_ERROR)


class Marked(tuple):
    """A ``(data, t)`` chunk that also says who sent it (``sender``) or that the UART flagged it (``error``).

    It unpacks as a pair, so code that only wants bytes and times needs no change; code that passes
    chunks on keeps the marks with :func:`remark`.
    """

    sender: str | None
    error: str | None

    def __new__(cls, data: bytes, t: float | None, *, sender: str | None = None, error: str | None = None):
        if sender is not None and sender not in SENDERS:
            raise ValueError(f"sender must be one of {SENDERS}, not {sender!r}")
        self = tuple.__new__(cls, (data, t))
        self.sender = sender
        self.error = error
        return self

    def __repr__(self) -> str:
        return f"Marked({self[0]!r}, {self[1]!r}, sender={self.sender!r}, error={self.error!r})"

    def __reduce__(self) -> Any:
        return (_marked, (self[0], self[1], self.sender, self.error))


def _marked(data: bytes, t: float | None, sender: str | None, error: str | None) -> Marked:
    return Marked(data, t, sender=sender, error=error)


class SourceGap(tuple):
    """Not bytes but a gap in them: ``(b"", t)`` said by a source that lost the line for a while (a port
    unplugged and found again). ``t`` is when it came back, ``lost_at`` when it went (epoch seconds, None if
    unknown), ``note`` the words for the log. The drive loop hands it to the decoder (a new time segment)
    and to the sinks that keep a list of gaps (``gap(...)``)."""

    lost_at: float | None
    note: str

    def __new__(cls, t: float, lost_at: float | None, note: str):
        self = tuple.__new__(cls, (b"", t))
        self.lost_at = lost_at
        self.note = note
        return self

    def __reduce__(self) -> Any:
        return (SourceGap, (self[1], self.lost_at, self.note))


def marks(chunk: Chunk) -> tuple[str | None, str | None]:
    """``(sender, error)`` of a chunk (both None for a plain pair)."""
    if type(chunk) is Marked:
        return chunk.sender, chunk.error
    return None, None


def remark(chunk: Chunk, data: bytes, t: float | None) -> Chunk:
    """A chunk of ``data`` at ``t`` carrying the marks of ``chunk`` (a plain pair if it had none)."""
    if type(chunk) is Marked:
        return Marked(data, t, sender=chunk.sender, error=chunk.error)
    return data, t


class SenderMap:
    """Who the capture says sent each stretch of the byte stream: stream offsets where the sender changes.

    Stays empty (and false) for captures that do not say; ``at(offset)`` is None where they do not.
    """

    __slots__ = ("_offsets", "_senders")

    def __init__(self) -> None:
        self._offsets: list[int] = []
        self._senders: list[str | None] = []

    def __bool__(self) -> bool:
        return bool(self._offsets)

    def note(self, offset: int, sender: str | None) -> None:
        """The bytes from stream ``offset`` on (until the next note) were sent by ``sender``."""
        if self._senders and self._senders[-1] == sender:
            return
        if self._offsets and self._offsets[-1] == offset:
            self._senders[-1] = sender
        else:
            self._offsets.append(offset)
            self._senders.append(sender)

    def at(self, offset: int) -> str | None:
        """The sender of the byte at stream ``offset`` (None if the capture does not say)."""
        k = bisect_right(self._offsets, offset) - 1
        return self._senders[k] if k >= 0 else None
