"""The one drive loop of every command: (bytes, t) chunks -> Decoder (frames, pairs, lint) -> sinks."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable, Iterator

from .blocks import Block, feed_run
from .bus import DEFAULT_REPLY_TIMEOUT, BusTracker, Record
from .chunks import Marked, SenderMap
from .frame_runs import FrameRun
from .framing import DEFAULT_GAP_BYTES, FrameDecoder
from .memmap import ModelRegistry, default_registry
from .wire import DEFAULT_BAUD


@dataclass
class DecodeOptions:
    """Everything that changes how bytes are decoded (built by :class:`rs30x_sniff.settings.Settings`)."""

    baud: int = DEFAULT_BAUD
    default_model: str | None = None
    models: dict[int, str] = field(default_factory=dict)  # per-ID model names
    gap_bytes: float | None = DEFAULT_GAP_BYTES
    reply_timeout: float = DEFAULT_REPLY_TIMEOUT
    registry: ModelRegistry | None = None


# A columnar Pipeline decodes a file's chunks this many bytes at a time (unless told otherwise).
GROUP_BYTES = 1 << 16


class Step(list):
    """The records one :meth:`Decoder.feed` (or :meth:`Decoder.close`) decided, in wire order.

    ``findings`` holds every lint finding new since the previous call (those on these records, and at
    the close those only the end of input reveals); ``late`` is that last kind alone: findings about
    records handed out earlier. A columnar decoder's step may also hold Blocks (rs30x_sniff.blocks):
    many records as columns; :meth:`expanded` has them as Records.
    """

    __slots__ = ("findings", "late", "blocks", "seams")

    def __init__(self, records: Iterable[Record] = (), findings: list | None = None, late: list | None = None) -> None:
        super().__init__(records)
        self.findings = findings if findings is not None else []
        self.late = late if late is not None else []
        self.blocks = False  # True when some items are Blocks
        # Seams of the capture's clock (rs30x_sniff.framing.Seam) that fall among these records: each
        # record at or past a seam's offset belongs to the new time segment.
        self.seams: tuple = ()

    @property
    def count(self) -> int:
        """How many records the step holds (a Block counts its rows)."""
        if not self.blocks:
            return len(self)
        return sum(len(x) if type(x) is Block else 1 for x in self)

    def expanded(self) -> Step:
        """This step with each Block's rows as Records (itself when it holds no Block)."""
        if not self.blocks:
            return self
        out = Step((), self.findings, self.late)
        out.seams = self.seams
        for x in self:
            if type(x) is Block:
                out += x.records()
            else:
                out.append(x)
        return out


class Decoder:
    """Frame decoder, bus tracker and (optionally) linter in one object: feed chunks, get records.

    Still sans-IO. A linter, if given, sees every record before it is returned, so the record's
    ``findings`` already hold what the linter could tell at that point.
    """

    def __init__(self, options: DecodeOptions | None = None, linter: Any = None, columnar: bool = False) -> None:
        o = self.options = options or DecodeOptions()
        # columnar: clean stretches of traffic come out as Blocks (rs30x_sniff.blocks) instead of a
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
        self.late_findings: list = []  # after close(): findings only the end of input revealed
        self._seen = 0  # findings of linter.findings already handed out
        self._seams = 0  # seams of frames.seams already handed out

    def _new_findings(self) -> list:
        found = self.linter.findings
        if len(found) == self._seen:
            return []
        new = found[self._seen:]
        self._seen = len(found)
        return new

    def feed(self, data: bytes, t: float | None = None, sender: str | None = None,
             error: str | None = None) -> Step:
        """Decode one chunk (its first byte at capture time ``t``); the records it completes.

        ``sender`` is who the capture says sent these bytes, ``error`` a UART fault it flagged on them
        (rs30x_sniff.chunks): flagged bytes become garbage with that reason.
        """
        if sender is not None or self.senders:
            self.senders.note(self.bytes_in, sender)
        self.bytes_in += len(data)
        events = self.frames.feed(data, t) if error is None else self.frames.feed_fault(data, t, error)
        return self._decided(events)

    def feed_many(self, chunks: list[tuple[bytes, float | None]]) -> Step:
        """Decode several plain chunks (nothing said of their sender or errors) at once: the same
        records as feeding them one by one, in one step (the columnar path's way in)."""
        if self.senders:
            self.senders.note(self.bytes_in, None)
        self.bytes_in += sum(map(len, [c[0] for c in chunks]))
        return self._decided(self.frames.feed_many(chunks))

    def _track(self, events: list, out: Step) -> Step:
        """Pair ``events`` (and in columnar mode, FrameRuns) into ``out``."""
        if not self.columnar:
            return self.bus.feed_many(events, out)
        bus = self.bus
        track = bus._feed
        for ev in events:
            if type(ev) is FrameRun:
                out.blocks |= feed_run(bus, ev, out)  # True only when it made a Block
            else:
                track(ev, out)
        return out

    def _lint(self, out: Step) -> None:
        """Every item of ``out`` to the linter, in order: a Record by feed, a Block by feed_block."""
        linter = self.linter
        lint = linter.feed
        for rec in out:
            if type(rec) is Block:
                linter.feed_block(rec)
            else:
                lint(rec)

    def _decided(self, events: list) -> Step:
        if len(self.frames.seams) > self._seams:
            return self._across_seams(events)
        out = self._track(events, Step())
        if self.linter is not None and out:
            self._lint(out)
            out.findings = self._new_findings()
        return out

    def _across_seams(self, events: list) -> Step:
        """:meth:`_decided` for events among which the clock has a seam: each time segment is paired
        and linted on its own, as if one capture ended at the seam and another began."""
        seams = self.frames.seams[self._seams:]
        self._seams = len(self.frames.seams)
        out = Step()
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

    def _take_piece(self, out: Step, piece: Step) -> None:
        if self.linter is not None and piece:
            self._lint(piece)
        out += piece
        out.blocks |= piece.blocks

    def close(self) -> Step:
        """End of input: the records still pending, and the findings only the end reveals (``late``)."""
        out = self._decided(self.frames.close())  # linted, its findings taken
        tail = Step(self.bus.close(self.frames.end_time))
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
    return item.base if type(item) is FrameRun else item[0]


class Sink:
    """Where decoded traffic goes (text, JSON lines, a lint report, MCAP, statistics, the monitor).

    The drive loop calls ``chunk`` with the raw bytes before they are decoded (so nothing read is lost
    to a decoding error; ``sender`` and ``error`` are what the capture said of them, rs30x_sniff.chunks),
    ``batch`` with each :class:`Step`, ``idle`` when a live source had nothing for a moment, and
    ``close`` once at the end. Every method is optional.

    A sink with ``takes_blocks`` True is handed a columnar decoder's steps as they are (Records and
    Blocks, rs30x_sniff.blocks); any other sink gets them with every Block's rows as Records.
    """

    takes_blocks = False

    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        pass

    def batch(self, step: Step) -> None:
        pass

    def idle(self) -> None:
        pass

    def close(self) -> None:
        pass


class Pipeline:
    """A decoder and its sinks: the drive loop every command and the monitor share.

    Sinks may be added and removed between chunks (the monitor's ``r`` starts and stops an MCAP sink).
    """

    def __init__(self, decoder: Decoder, sinks: Iterable[Sink] = (), group_bytes: int = GROUP_BYTES) -> None:
        self.decoder = decoder
        self.sinks: tuple[Sink, ...] = tuple(sinks)  # replaced, never changed in place: safe to edit mid-loop
        self.closed = False
        self.group_bytes = group_bytes  # a columnar decoder's group of plain chunks

    def add(self, sink: Sink) -> None:
        self.sinks = (*self.sinks, sink)

    def remove(self, sink: Sink) -> None:
        self.sinks = tuple(s for s in self.sinks if s is not sink)

    def _hand_out(self, step: Step) -> None:
        """``step`` to every sink, as Blocks to those that take them and as Records to the rest."""
        records = None
        for s in self.sinks:
            if not step.blocks or getattr(s, "takes_blocks", False):
                s.batch(step)
            else:
                if records is None:
                    records = step.expanded()
                s.batch(records)

    def feed_many(self, chunks: list[tuple[bytes, float | None]]) -> Step:
        """Several plain chunks through the decoder at once (Decoder.feed_many) into every sink."""
        for s in self.sinks:
            group = getattr(s, "chunk_group", None)
            if group is not None:
                group(chunks)  # a sink that takes the group's chunks at once (McapSink orders its messages)
            elif type(s).chunk is not Sink.chunk:  # (most sinks read no chunk: a call per chunk for nothing)
                for data, t in chunks:
                    s.chunk(data, t, None, None)
        step = self.decoder.feed_many(chunks)
        if step or step.findings:
            self._hand_out(step)
        return step

    def feed(self, data: bytes, t: float | None = None, sender: str | None = None,
             error: str | None = None) -> Step:
        """One chunk through the decoder into every sink; an empty chunk means the source is idle."""
        sinks = self.sinks
        if not data:
            for s in sinks:
                s.idle()
            return Step()
        for s in sinks:
            s.chunk(data, t, sender, error)
        step = self.decoder.feed(data, t, sender, error)
        if step or step.findings:
            self._hand_out(step)
        return step

    def close(self) -> Step:
        """End of input: the decoder's last records and late findings, then every sink closes (once)."""
        if self.closed:
            return Step()
        self.closed = True
        step = self.decoder.close()
        try:
            self._hand_out(step)
        finally:
            errors = []
            for s in self.sinks:
                try:
                    s.close()
                except Exception as e:  # noqa: BLE001 - close them all; raise the first failure after
                    errors.append(e)
            if errors:
                raise errors[0]
        return step

    def run(self, chunks: Iterable[tuple[bytes, float | None]]) -> Decoder:
        """Feed every chunk, then close. The sinks are closed even when the source fails midway (a
        corrupt file, a lost port), so what was read is written; the source's error is raised after."""
        try:
            if self.decoder.columnar:
                self._run_grouped(chunks)
            else:
                feed = self.feed
                for chunk in chunks:
                    if type(chunk) is Marked:
                        feed(chunk[0], chunk[1], chunk.sender, chunk.error)
                    else:
                        feed(*chunk)
        except BaseException:
            try:
                self.close()
            except Exception:  # noqa: BLE001 - the source's error is the one to report
                pass
            raise
        self.close()
        return self.decoder


    def _run_grouped(self, chunks: Iterable[tuple[bytes, float | None]]) -> None:
        """The columnar decoder's loop: plain chunks in groups of about ``group_bytes`` (one kernel pass
        and one Block per clean stretch), marked and empty ones alone, in order."""
        group: list[tuple[bytes, float | None]] = []
        size = 0
        feed_many = self.feed_many
        group_bytes = self.group_bytes
        append = group.append
        marked = Marked
        try:
            for chunk in chunks:
                data = chunk[0]
                if not data or type(chunk) is marked:
                    if group:
                        group, pending = [], group  # taken before it is fed: never fed twice
                        append = group.append
                        size = 0
                        feed_many(pending)
                    if type(chunk) is Marked:
                        self.feed(chunk[0], chunk[1], chunk.sender, chunk.error)
                    else:
                        self.feed(*chunk)
                    continue
                append(chunk)
                size += len(data)
                if size >= group_bytes:
                    group, pending = [], group
                    append = group.append
                    size = 0
                    feed_many(pending)
        finally:
            # What was read is decoded, also when the source fails or the run is stopped midway.
            if group:
                feed_many(group)


def drive(chunks: Iterable[tuple[bytes, float | None]], decoder: Decoder, *sinks: Sink) -> Decoder:
    """Run ``chunks`` through ``decoder`` into ``sinks``; returns the decoder (its linter, its counts)."""
    return Pipeline(decoder, sinks).run(chunks)


def decode_records(chunks: Iterable[tuple[bytes, float | None]], options: DecodeOptions | None = None,
                   decoder: Decoder | None = None) -> Iterator[Record]:
    """Stream records from chunks (a generator over the same decoder, for library use)."""
    dec = decoder or Decoder(options)
    for chunk in chunks:
        if type(chunk) is Marked:
            yield from dec.feed(chunk[0], chunk[1], chunk.sender, chunk.error)
        else:
            yield from dec.feed(*chunk)
    yield from dec.close()
