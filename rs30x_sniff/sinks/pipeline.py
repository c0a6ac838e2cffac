"""The one drive loop of every command: (bytes, t) chunks -> Decoder (frames, pairs, lint) -> sinks."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

from ..decode.decoder import DecodeOptions, Decoder, Sink, Step
from ..decode.pairing import Record
from ..protocol.chunks import Marked, SourceGap
from ..sources.protocol import Pacing

# Sink (what a Step goes to) is declared beside the Step, in rs30x_sniff.decode.decoder, so that the decode
# stage's rate watches can be sinks without importing this later stage; every sink imports it from here.
__all__ = ["GROUP_BYTES", "Pipeline", "Sink", "columnar_for", "decode_records", "drive"]

# A columnar Pipeline decodes a file's chunks this many bytes at a time (unless told otherwise): each group is a
# pass of the decoder and a Block per clean stretch, so the linter, the statistics and the writers work once per
# Block. 256 KiB, as the monitor loads a file (tui/feed.py): a fourth as many passes as with 64 KiB took the user
# rules' timestamped path of bench/lint.py from 0.49-0.53 to 0.63 of the bare loop; convert's peak memory on a
# 100 MB capture stays at 106 MB (bench/convert.py).
GROUP_BYTES = 1 << 18


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
            if not step.blocks or s.takes_blocks:
                s.batch(step)
            else:
                if records is None:
                    records = step.expanded()
                s.batch(records)

    def feed_many(self, chunks: list[tuple[bytes, float | None]]) -> Step:
        """Several plain chunks through the decoder at once (Decoder.feed_many) into every sink."""
        for s in self.sinks:
            kind = type(s)  # most sinks read no chunk: a call per chunk for nothing
            if kind.chunk_group is not Sink.chunk_group or kind.chunk is not Sink.chunk:
                s.chunk_group(chunks)  # the group at once (McapSink orders its messages), or chunk by chunk
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

    def gap(self, gap: SourceGap) -> None:
        """The source lost the line until ``gap``'s time: the decoder starts a new time segment at the next
        chunk, and every sink is told (``Sink.gap``: the MCAP's metadata keeps it)."""
        self.decoder.mark_gap(gap.note)
        for s in self.sinks:
            s.gap(gap[1], gap.lost_at, gap.note)

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
                    elif type(chunk) is SourceGap:
                        self.gap(chunk)
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
                    elif type(chunk) is SourceGap:
                        self.gap(chunk)
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


def columnar_for(source: Pacing, *, follow: bool = False) -> bool:
    """Whether a command decodes ``source`` on the columnar path: the one place that decides.

    A source says what it is: a port is ``live`` (rs30x_sniff.sources.serial_tap.LiveSource), a capture
    that is not a regular file (a pipe, a FIFO) is ``streamed`` (rs30x_sniff.sources.captures.CaptureReader).
    A file takes the columnar path, GROUP_BYTES (256 KiB) at a time (the same output in a fraction of the
    time). A live source that hands over its chunks in ``batched`` gathers, each ended by an empty chunk (a
    port: LiveSource), takes it too, a gather at a time: each record is out as soon as the gather that
    completes it is in, as on the record path, at a half to two thirds of its CPU (bench/live.py). Other live
    sources (the monitor's replay and simulator) go record by record. A pipe may be live too
    (`socat ... | rs30x-sniff decode -`): a command whose output follows its input (``follow``: decode's
    lines) takes it record by record; one whose output comes at the end (a report, figures, a file) takes
    the columnar path, as for a file.
    """
    if source.live:
        return source.batched
    return not (follow and source.streamed)


def drive(chunks: Iterable[tuple[bytes, float | None]], decoder: Decoder, *sinks: Sink) -> Decoder:
    """Run ``chunks`` through ``decoder`` into ``sinks``; returns the decoder (its linter, its counts)."""
    return Pipeline(decoder, sinks).run(chunks)


def decode_records(chunks: Iterable[tuple[bytes, float | None]], options: DecodeOptions | None = None,
                   decoder: Decoder | None = None) -> Iterator[Record]:
    """Stream records from chunks (a generator over the same decoder, for library use)."""
    dec = decoder or Decoder(options)
    for chunk in chunks:  # (a columnar decoder's Blocks as their Records: expanded() is the step itself otherwise)
        if type(chunk) is Marked:
            yield from dec.feed(chunk[0], chunk[1], chunk.sender, chunk.error).expanded()
        elif type(chunk) is SourceGap:
            dec.mark_gap(chunk.note)
        else:
            yield from dec.feed(*chunk).expanded()
    yield from dec.close().expanded()
