"""The Decoder: frames, pairs and (optionally) lints chunks into steps of records; sans-IO."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Generic, TypeVar, cast
from collections.abc import Iterable, Sequence

from .blocks import Block, feed_run
from .pairing import DEFAULT_REPLY_TIMEOUT, BusTracker, Record
from ..protocol.chunks import SenderMap
from ..protocol.events import OFFSET
from .frame_runs import FrameRun
from .framing import DEFAULT_GAP_BYTES, FrameDecoder
from ..protocol.memmap import ModelRegistry, default_registry
from ..protocol.wire import DEFAULT_BAUD

if TYPE_CHECKING:  # for the checker only: the linter is a later stage, which the decoder is handed at run time
    from ..lint.linter import Linter
    from ..lint.registry import Finding
    from .framing import Seam

# What a Step holds: Records, or (from a columnar decoder) Records and Blocks. For the checker only: a sink that
# takes Blocks is a Sink[Record | Block], any other a Sink[Record] (the drive loop expands Blocks for it).
Item = TypeVar("Item", bound="Record | Block")


@dataclass
class DecodeOptions:
    """Everything that changes how bytes are decoded (built by :class:`rs30x_sniff.settings.Settings`)."""

    baud: int = DEFAULT_BAUD
    default_model: str | None = None
    models: dict[int, str] = field(default_factory=dict)  # per-ID model names
    gap_bytes: float | None = DEFAULT_GAP_BYTES
    reply_timeout: float = DEFAULT_REPLY_TIMEOUT
    registry: ModelRegistry | None = None



class Step(list[Item], Generic[Item]):
    """The records one :meth:`Decoder.feed` (or :meth:`Decoder.close`) decided, in wire order.

    ``findings`` holds every lint finding new since the previous call (those on these records, and at
    the close those only the end of input reveals); ``late`` is that last kind alone: findings about
    records handed out earlier. A columnar decoder's step may also hold Blocks (rs30x_sniff.decode.blocks):
    many records as columns; :meth:`expanded` has them as Records.
    """

    __slots__ = ("findings", "late", "blocks", "seams")

    def __init__(self, records: Iterable[Item] = (), findings: list[Finding] | None = None,
                 late: list[Finding] | None = None) -> None:
        super().__init__(records)
        self.findings: list[Finding] = findings if findings is not None else []
        self.late: list[Finding] = late if late is not None else []
        self.blocks = False  # True when some items are Blocks
        # Seams of the capture's clock (rs30x_sniff.decode.framing.Seam) that fall among these records: each
        # record at or past a seam's offset belongs to the new time segment.
        self.seams: tuple[Seam, ...] = ()

    @property  # shadows list.count (a method) on purpose: a step's size, Blocks' rows counted, is what callers ask
    def count(self) -> int:  # type: ignore[override]
        """How many records the step holds (a Block counts its rows)."""
        if not self.blocks:
            return len(self)
        items: Sequence[Record | Block] = self  # (for the checker: an Item is one or the other)
        return sum(len(x) if type(x) is Block else 1 for x in items)

    def loose(self) -> list[Finding]:
        """The findings of this step on none of its records and not late: what the decoder found between records
        (F010 at a seam of the capture: a clock restart, a lost port). An output that writes findings with their
        records places each of these before the first record at or past its offset."""
        if not self.findings:
            return []
        on = {id(f) for f in self.late}
        items: Sequence[Record | Block] = self
        for x in items:
            for rec in (x.made_rows.values() if type(x) is Block else (x,)):
                on.update(map(id, rec.findings))
        return [f for f in self.findings if id(f) not in on]

    def expanded(self) -> Step[Record]:
        """This step with each Block's rows as Records (itself when it holds no Block)."""
        if not self.blocks:
            return cast("Step[Record]", self)
        out: Step[Record] = Step((), self.findings, self.late)
        out.seams = self.seams
        items: Sequence[Record | Block] = self
        for x in items:
            if type(x) is Block:
                out += x.records()
            else:
                out.append(x)
        return out


class Sink(Generic[Item]):
    """Where decoded traffic goes (text, JSON lines, a lint report, MCAP, statistics, the monitor): what
    takes the Steps a :class:`Decoder` gives. Declared here, beside the Step, so that a piece of the decode
    stage can be one (rs30x_sniff.decode.autobaud's rate watches); the drive loop that feeds sinks is
    rs30x_sniff.sinks.pipeline, which hands this class on to the sinks of every later stage.

    The drive loop calls ``chunk`` with the raw bytes before they are decoded (so nothing read is lost
    to a decoding error; ``sender`` and ``error`` are what the capture said of them, rs30x_sniff.protocol.chunks),
    ``batch`` with each :class:`Step`, ``idle`` when a live source had nothing for a moment, ``gap`` when
    the source lost the line for a while, and ``close`` once at the end. Each does nothing unless a sink
    overrides it; the drive loop calls neither ``chunk`` nor ``chunk_group`` of a sink that overrides
    neither (most read no raw bytes: a call per chunk for nothing).

    A sink with ``takes_blocks`` True is handed a columnar decoder's steps as they are (Records and
    Blocks, rs30x_sniff.decode.blocks); any other sink gets them with every Block's rows as Records.
    """

    takes_blocks: bool = False

    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        pass

    def chunk_group(self, chunks: list[tuple[bytes, float | None]]) -> None:
        """A columnar decoder's group of plain chunks, before they are decoded (Pipeline.feed_many): each to
        ``chunk`` unless the sink takes the group at once (the MCAP sink orders its messages by it)."""
        for data, t in chunks:
            self.chunk(data, t, None, None)

    def gap(self, t: float, lost_at: float | None, note: str) -> None:
        """The source lost the line from ``lost_at`` until ``t`` (``note`` says why): a sink that keeps gaps
        (the MCAP's metadata, the black box) notes it."""

    def batch(self, step: Step[Item]) -> None:
        pass

    def idle(self) -> None:
        pass

    def close(self) -> None:
        pass


class Decoder:
    """Frame decoder, bus tracker and (optionally) linter in one object: feed chunks, get records.

    Still sans-IO. A linter, if given, sees every record before it is returned, so the record's
    ``findings`` already hold what the linter could tell at that point.
    """

    def __init__(self, options: DecodeOptions | None = None, linter: Linter | None = None,
                 columnar: bool = False) -> None:
        o = self.options = options or DecodeOptions()
        # columnar: clean stretches of traffic come out as Blocks (rs30x_sniff.decode.blocks) instead of a
        # Record each; whoever reads the steps must take Blocks (Step.expanded gives Records).
        self.columnar = columnar
        self.frames = FrameDecoder(o.baud, gap_bytes=o.gap_bytes, runs=columnar)
        self.bus = BusTracker(o.registry or default_registry(), o.models, o.reply_timeout, o.default_model)
        self.linter = linter
        # Who sent which bytes, where the capture says so (a serial logger's TX/RX): the linter checks
        # the decoder's own reading of each packet against it.
        self.senders = SenderMap()
        if linter is not None:
            linter.senders = self.senders
        self.bytes_in = 0
        self.late_findings: list[Finding] = []  # after close(): findings only the end of input revealed
        self._seams = 0  # seams of frames.seams already handed out

    def _new_findings(self) -> list[Finding]:
        assert self.linter is not None  # asked only of a decoder that lints
        return self.linter.new_findings()

    def feed(self, data: bytes, t: float | None = None, sender: str | None = None,
             error: str | None = None) -> Step[Record | Block]:
        """Decode one chunk (its first byte at capture time ``t``); the records it completes.

        ``sender`` is who the capture says sent these bytes, ``error`` a UART fault it flagged on them
        (rs30x_sniff.protocol.chunks): flagged bytes become garbage with that reason.
        """
        if sender is not None or self.senders:
            self.senders.note(self.bytes_in, sender)
        self.bytes_in += len(data)
        events = self.frames.feed(data, t) if error is None else self.frames.feed_fault(data, t, error)
        return self._decided(events)

    def mark_gap(self, note: str) -> None:
        """The source lost bytes here (a port lost and reopened, ``note`` says so): the next chunk begins a new
        time segment (FrameDecoder.mark_gap), reported as F010 like any seam of the capture's clock."""
        self.frames.mark_gap(note)

    def feed_many(self, chunks: list[tuple[bytes, float | None]]) -> Step[Record | Block]:
        """Decode several plain chunks (nothing said of their sender or errors) at once: the same
        records as feeding them one by one, in one step (the columnar path's way in)."""
        if self.senders:
            self.senders.note(self.bytes_in, None)
        self.bytes_in += sum(map(len, [c[0] for c in chunks]))
        return self._decided(self.frames.feed_many(chunks))

    def _track(self, events: list, out: Step[Record | Block]) -> Step[Record | Block]:
        """Pair ``events`` (and in columnar mode, FrameRuns) into ``out``."""
        if not self.columnar:
            return self.bus.feed_many(events, out)
        bus = self.bus
        track = bus.feed_into
        for ev in events:
            if type(ev) is FrameRun:
                out.blocks |= feed_run(bus, ev, out)  # True only when it made a Block
            else:
                track(ev, out)
        return out

    def _lint(self, out: Step[Record | Block]) -> None:
        """Every item of ``out`` to the linter, in order: a Record by feed, a Block by feed_block (which may
        halve it: its parts take its place in ``out``)."""
        linter = self.linter
        assert linter is not None  # called only when the decoder lints
        lint = linter.feed
        parted = False
        items = []
        for rec in out:
            if type(rec) is Block:
                parts = linter.feed_block(rec)
                if len(parts) > 1:
                    parted = True
                items += parts
            else:
                lint(rec)
                items.append(rec)
        if parted:
            out[:] = items

    def _decided(self, events: list) -> Step[Record | Block]:
        if len(self.frames.seams) > self._seams:
            return self._across_seams(events)
        out = self._track(events, Step())
        if self.linter is not None and out:
            self._lint(out)
            out.findings = self._new_findings()
        return out

    def _across_seams(self, events: list) -> Step[Record | Block]:
        """:meth:`_decided` for events among which the clock has a seam: each time segment is paired
        and linted on its own, as if one capture ended at the seam and another began."""
        seams = self.frames.seams[self._seams:]
        self._seams = len(self.frames.seams)
        out: Step[Record | Block] = Step()
        out.seams = tuple(seams)
        k = 0
        for seam in seams:
            j = k
            while j < len(events) and _offset_of(events[j]) < seam.offset:
                j += 1
            piece = self._track(events[k:j], Step())
            piece += self.bus.seam(seam.t_end)
            self._take_piece(out, piece)
            if self.linter is not None:
                self.linter.seam(seam)
            k = j
        self._take_piece(out, self._track(events[k:], Step()))
        if self.linter is not None:
            out.findings = self._new_findings()
        return out

    def _take_piece(self, out: Step[Record | Block], piece: Step[Record | Block]) -> None:
        if self.linter is not None and piece:
            self._lint(piece)
        out += piece
        out.blocks |= piece.blocks

    def close(self) -> Step[Record | Block]:
        """End of input: the records still pending, and the findings only the end reveals (``late``)."""
        out = self._decided(self.frames.close())  # linted, its findings taken
        tail: Step[Record | Block] = Step(self.bus.close(self.frames.end_time))
        if self.linter is not None:
            self._lint(tail)
        out += tail
        if self.linter is not None:
            self.linter.time_faults = self.frames.time_faults  # the capture's clock, for F005/F006
            self.linter.end_t = self.frames.end_time
            out.late = self.late_findings = self.linter.close()
            out.findings = out.findings + self._new_findings()
        return out


def _offset_of(item: Any) -> int:
    """Stream offset of an event's first byte, or a FrameRun's."""
    return item.base if type(item) is FrameRun else item[OFFSET]
