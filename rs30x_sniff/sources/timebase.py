"""What a capture's timestamps mean (the first byte of a chunk, or its arrival), told from the content."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import timedelta
from typing import Any
from collections.abc import Iterable, Iterator

from ..protocol.chunks import remark
from ..protocol.wire import byte_time
from .captures import CaptureReader

FIRST = "first"      # t is when the chunk's first byte started (our .thex, MCAP raw, the live tap)
ARRIVAL = "arrival"  # t is when the read returned: the end of the chunk's last byte (socat, spy://, ...)
TIME_REFS = (FIRST, ARRIVAL)
SAMPLE_CHUNKS = 512  # chunks looked at to tell the reference; the rest streams through

Chunk = tuple[bytes, "float | None"]


@dataclass(frozen=True)
class TimeRef:
    """The reference a capture's times are read with, and why (for `info`)."""

    ref: str
    reason: str


def judge(chunks: list[Chunk], baud: int) -> TimeRef:
    """Tell the time reference from consecutive timed chunks at ``baud``.

    Bytes cannot overlap on the wire. Read as first-byte times, a chunk must not start before the
    previous one has ended (t_next >= t + n * byte time); read as arrival times, it must not have
    started before the previous one arrived (t_next - n_next * byte time >= t). A logger that stamps
    reads on arrival breaks the first rule at every reply that follows its request closely; our own
    captures break the second whenever a chunk follows another back to back. The reading with fewer
    impossible overlaps wins; with none either way, first-byte times are assumed (and said so).
    """
    bt = byte_time(baud)
    tol = bt / 4
    as_first = as_arrival = pairs = 0
    prev: tuple[bytes, float] | None = None  # the last chunk with bytes and a time
    for data, t in chunks:
        if t is None or not data:
            continue
        if prev is not None:
            pdata, pt = prev
            pairs += 1
            if t < pt + len(pdata) * bt - tol:
                as_first += 1
            if t - len(data) * bt < pt - tol:
                as_arrival += 1
        prev = (data, t)
    if as_first > as_arrival:
        return TimeRef(ARRIVAL, f"stamped at arrival, told by the content: {as_first} of {pairs} chunks would "
                                f"start before the previous one ended if stamped at their first byte")
    if as_arrival > as_first:
        return TimeRef(FIRST, f"stamped at the first byte, told by the content: {as_arrival} of {pairs} chunks "
                              f"would overlap the previous one if stamped at arrival")
    return TimeRef(FIRST, "stamped at the first byte (assumed: the content does not tell)")


def to_first_byte(chunks: Iterable[Chunk], baud: int) -> Iterator[Chunk]:
    """Arrival times laid back to each chunk's first byte at the baud rate (t - n x byte time), never
    past the previous chunk's arrival.

    A logger's read returns whatever the OS had buffered, so a read made late is stamped late and the
    next one, made at once, returns the rest of the backlog: laid back by its whole length, it would
    start before the previous read returned, i.e. before bytes that were already in hand (socat's
    stamps only increase, yet such chunks made the clock go backwards). So a chunk starts no earlier
    than the previous chunk's own stamp; the line rate then says (F006) whether the two overlap.
    Only while the stamps are in order: a stamp earlier than the previous one (a restarted clock, two
    logs concatenated) is the log's own, kept for F005 and the time segments to tell.

    The first chunk is laid back as far as 0 and no further when its stamp is after 0: the log counts
    from a moment before its first read (pyserial's spy:// from the port's opening), and nothing was
    read before that. A first stamp of exactly 0 is that read's own arrival (socat and jpnevulator
    logs are read as seconds from their first stamp): its bytes were on the wire before it, and are
    laid back below 0 rather than squeezed onto the next chunk's.
    """
    bt = byte_time(baud)
    prev: float | None = None  # the previous timed chunk's stamp (its arrival)
    for chunk in chunks:
        data, t = chunk
        if t is None:
            yield remark(chunk, data, None)
            continue
        first = t - len(data) * bt
        if prev is None:
            if t > 0:
                first = max(first, 0.0)
        elif prev <= t:
            first = max(first, prev)
        prev = t
        yield remark(chunk, data, first)


class TimedSource:
    """A capture's chunks with their times read as first-byte times, by ``ref`` (``time_ref`` says
    which and why); other attributes (``locate``, ``warnings``, ``close``) are the source's."""

    def __init__(self, source: CaptureReader, baud: int, ref: str, why: TimeRef | None = None) -> None:
        self.source = source
        self.baud = baud
        self._time_ref = why or TimeRef(ref, "given by --time-ref")
        self._it: Iterator[Chunk] | None = None

    @property
    def time_ref(self) -> TimeRef:
        """What the times mark and why; once a timestamped capture's unit is known, the unit leads the
        reason (``in seconds since the epoch, told by the content; stamped at the first byte ...``)."""
        unit = self.source.time_unit
        if unit is None:
            return self._time_ref
        # A unit given (by an option, or by the settings from the capture's own first lines) has its origin
        # in the settings: the reason says the unit alone.
        how = "" if unit.how == "given" else f", {unit.how_known()}"
        return TimeRef(self._time_ref.ref, f"{unit.describe().removeprefix('times ')}{how}; {self._time_ref.reason}")

    # How the wrapped capture's chunks come (sources.protocol.Pacing), declared: the drive loop reads them.
    @property
    def live(self) -> bool:
        return self.source.live

    @property
    def streamed(self) -> bool:
        return self.source.streamed

    @property
    def batched(self) -> bool:
        return self.source.batched

    def __getattr__(self, name: str) -> Any:  # locate(), warnings, close()... of the wrapped source
        return getattr(self.source, name)

    def __iter__(self) -> Iterator[Chunk]:
        if self._it is None:
            it = iter(self.source)
            self._it = self._from_zero(to_first_byte(it, self.baud)) if self.time_ref.ref == ARRIVAL else it
        return self._it

    def _from_zero(self, chunks: Iterator[Chunk]) -> Iterator[Chunk]:
        """Laid-back times that would start before 0 (a log counting from its first read's arrival, whose
        bytes were on the wire before it) counted from the first byte instead: every time moves by the
        same amount, so no duration changes and no time is negative; the log's wall-clock anchor (a
        reader's ``start_time``) moves back by it, so wall-clock times stay where they were."""
        shift = None
        for chunk in chunks:
            data, t = chunk
            if t is not None and shift is None:
                shift = -t if t < 0 else 0.0
                found = self.source.context.found
                if shift and found and found.get("start_time") is not None:
                    found["start_time"] -= timedelta(seconds=shift)
            if shift and t is not None:
                chunk = remark(chunk, data, t + shift)
            yield chunk

    def __next__(self) -> Chunk:
        return next(iter(self))
