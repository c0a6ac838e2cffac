"""The monitor's capture thread, with no Textual in it: the shared drive loop, batches handed up to the screen."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from queue import Empty, SimpleQueue
from typing import TYPE_CHECKING, Any
from collections.abc import Callable, Iterator

from ..decode.blocks import MIN_BLOCK, Block
from ..decode.pairing import Record
from ..sources.captures import CaptureError
from ..sinks.pipeline import GROUP_BYTES, Pipeline, Sink, columnar_for
from ..decode.decoder import DecodeOptions, Decoder, Step
from ..sinks.stats import CaptureStats
from ..sources.feeds import Feed
from .servos import ServoRow, servo_snapshot

if TYPE_CHECKING:  # names for the checker; no import at run time
    from ..lint.linter import Linter

# Seconds between batches: one screen update a second, as top and iftop refresh. Each redraws most of the
# screen (the timeline scrolls, the newest packet's detail, the servos' values, the plot), some 20-40 ms of CPU
# in Textual: two a second made the monitor on a busy port cost 6x a bare reading loop, one 2.8x
# (bench/live.py, issue 31 §5's target 3x).
POST_INTERVAL = 1.0
MAX_BATCH = 50_000      # records per batch, so one batch never stalls the screen for long
# While a file loads, the screen is told less often: a redraw of the whole screen costs the decoding
# thread ~0.1 s of the GIL, and a file is not live (the first batch still comes at once, so the screen
# fills at once; the header's tick shows the elapsed time meanwhile).
LOAD_INTERVAL = 2.0
# A file is decoded in groups this large (pipeline.GROUP_BYTES is a command's): the statistics, the
# store and the plot work once per Block, and longer Blocks are fewer. The store keeps every row anyway.
LOAD_GROUP_BYTES = 1 << 18


@dataclass
class Batch:
    """What the capture thread hands to the screen: new records, new findings, the servos' state."""

    records: list[Record | Block]  # in wire order; a Block (file sources) stands for its rows
    findings: list = field(default_factory=list)
    servos: dict[int, ServoRow] | None = None
    bytes_in: int = 0
    stats: dict[str, Any] | None = None  # info's figures the screen shows, since the last clear (screen_figures)
    done: bool = False           # the source has ended (a file read to its end, a port closed)
    error: str | None = None     # why it ended early, in one line
    recording: str | None = None  # the MCAP file being written, if any
    note: str | None = None      # a one-line message for the user (recording started/stopped, ...)
    more: bool = False           # another batch of the same post follows at once (redraw after that one)


def default_linter() -> Any:
    """A fresh Linter with its default configuration, or None when the lint package is not installed."""
    try:
        from ..lint import Linter
    except ImportError:
        return None
    return Linter(keep_findings=False)


class _Collect(Sink[Record | Block]):
    """Gathers the pipeline's records (and, from a columnar decoder, Blocks) and findings between posts,
    and hands each step to the capture statistics (one sink for both: the pipeline calls every sink
    for every chunk, and the statistics need no chunk but the byte count, which the decoder keeps)."""

    takes_blocks = True

    def __init__(self, stats: CaptureStats, bytes_in: Callable[[], int],
                 on_step: Callable[[], None] | None = None) -> None:
        self.records: list[Record | Block] = []
        self.findings: list = []
        self.count = 0  # rows collected (a Block counts its rows)
        self.bytes_in = bytes_in
        self.on_step = on_step
        self.set_stats(stats)

    def set_stats(self, stats: CaptureStats) -> None:
        """Count from here on into ``stats``."""
        self.stats = stats
        self._base = self.bytes_in()

    def batch(self, step: Step) -> None:
        self.records += step
        self.count += step.count
        if step.findings:
            self.findings += step.findings
        self.stats.batch(step)
        if self.on_step is not None:
            self.on_step()

    def close(self) -> None:
        self.stats.bytes_in = self.bytes_in() - self._base
        self.stats.close()

    def take(self, limit: int | None = None) -> tuple[list[Record | Block], list]:
        """(items, findings) collected so far, or only the first ``limit`` rows of the items (a Block
        across that line is split; the rest stays, and so do the findings)."""
        if limit is None or self.count <= limit:
            out = self.records, self.findings
            self.records, self.findings, self.count = [], [], 0
            return out
        items, rows = [], 0
        rest = self.records
        i = 0
        while rows < limit:
            x = rest[i]
            n = len(x) if type(x) is Block else 1
            if rows + n > limit:
                assert type(x) is Block  # a Record (n 1) always fits: rows < limit
                head, tail = split_block(x, limit - rows)
                items += head
                rows += sum(len(h) if type(h) is Block else 1 for h in head)
                rest[i:i + 1] = tail  # what is left of the Block (a Block, or its rows as Records)
                break
            items.append(x)
            rows += n
            i += 1
        del rest[:i]
        self.count -= rows
        return items, []


def split_block(blk: Block, k: int) -> tuple[list, list]:
    """A Block cut before row ``k`` (moved past a reply so a pair stays together): (the head, the
    tail), each a list of one Block, or of its rows as Records when shorter than blocks.MIN_BLOCK (the
    tail is empty when the cut falls at the end). Records the Block already built are kept by both
    parts, so each row stays one object."""
    k = max(1, min(k, len(blk) - 1))
    if blk.answered[k - 1]:
        k += 1  # a reply goes with its request
    if k >= len(blk):
        return [blk], []
    parts = [blk.part(0, k), blk.part(k, len(blk))]
    head, tail = [[p] if len(p) >= MIN_BLOCK else p.records() for p in parts]
    return head, tail


class _Recording(Sink[Record]):
    """The `r` recording: the MCAP sink, guarded so that a full disk stops the recording, never the capture."""

    def __init__(self, feeder: Feeder, sink: Any, path: str) -> None:
        self.feeder, self.sink, self.path = feeder, sink, path

    def _guard(self, write: Callable[..., None], *args: Any) -> None:
        try:
            write(*args)
        except OSError as e:
            self.feeder._note = f"recording stopped: {e.strerror or e}"
            self.feeder._close_sink(quiet=True)

    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        self._guard(self.sink.chunk, data, t)

    def batch(self, step: Step) -> None:
        self._guard(self.sink.batch, step)

    def close(self) -> None:
        self.feeder._close_sink()  # the end of the source ends the recording: the file is finished and indexed


def screen_figures(stats: CaptureStats) -> dict[str, Any]:
    """What the screen takes of ``info``'s figures, under their keys in CaptureStats.as_dict: the average load, the
    bus's latency and each servo's traffic. Not the whole dict: its health and "what happened" parts cost a live
    port's screen a few ms of every post, for nothing it shows."""
    return {"bus_load": stats.bus_load, "latency_s": stats.latency_dict(), "servos": stats.servos_dict()}


class Feeder:
    """Runs in its own thread: never waits for the screen, so the capture loses nothing to it.

    It drives the same pipeline as every command (source -> Decoder -> sinks): the screen's batches,
    the capture statistics and, while `r` records, the MCAP sink. Commands (stop, start or stop
    recording, clear the statistics) come down through a queue and are applied between chunks;
    batches go up through ``post``, at most every ``interval`` seconds (or ``max_batch`` records).
    """

    def __init__(self, source: Feed, options: DecodeOptions, post: Callable[[Batch], None], *,
                 linter: Linter | None = None, interval: float = POST_INTERVAL, max_batch: int = MAX_BATCH,
                 clock: Callable[[], float] = time.monotonic,
                 sink_factory: Callable[..., Any] | None = None) -> None:
        self.source = source
        self.options = options
        self.post = post
        self.linter = linter
        # A file, and a port a gather at a time, are decoded columnar (rs30x_sniff.decode.blocks): clean
        # stretches come as Blocks, which the screen keeps as columns and makes Records of only for the
        # rows it shows; the simulator and a replay go record by record as they come.
        columnar = columnar_for(source)
        self.loading = columnar and not source.live  # a file: loaded, not followed live
        self.decoder = Decoder(options, linter=linter, columnar=columnar)
        self._collect = _Collect(CaptureStats(options.baud), lambda: self.decoder.bytes_in,
                                 self._step if self.loading else None)
        self.pipeline = Pipeline(self.decoder, [self._collect], LOAD_GROUP_BYTES if self.loading else GROUP_BYTES)
        self.interval = interval
        self.max_batch = max_batch
        self.clock = clock
        self.sink_factory = sink_factory
        self.stop_event = threading.Event()
        self.running = False
        self.finished = False
        self.recording: str | None = None
        self._commands: SimpleQueue = SimpleQueue()
        self._commands_waiting = False  # a plain flag, so the per-chunk check takes no lock
        self._sink: _Recording | None = None
        self._note: str | None = None
        self._last_post = 0.0
        self._posts = 0

    # ---- commands from the screen (any thread) ---------------------------------------------------
    def stop(self) -> None:
        self.stop_event.set()

    def _command(self, cmd: str, arg: Any = None) -> None:
        self._commands.put((cmd, arg))
        self._commands_waiting = True

    def start_recording(self, path: str) -> None:
        self._command("record", path)

    def stop_recording(self) -> None:
        self._command("stop-record")

    def clear_stats(self) -> None:
        """Start the statistics afresh (the screen's `c`): a new window, the same arithmetic."""
        self._command("clear-stats")

    # ---- the thread --------------------------------------------------------------------------------
    @property
    def stats(self) -> CaptureStats:
        """The capture statistics since the start or the last clear."""
        return self._collect.stats

    def _chunks(self) -> Iterator[tuple[bytes, float | None]]:
        """A live source's chunks, with the screen's commands applied and batches posted between them."""
        self._last_post = self.clock()
        for chunk in self.source.chunks(self.stop_event):
            if self._commands_waiting:
                self._apply_commands()
            yield chunk
            self._take_warnings()
            self._maybe_post(self.interval)
            if self.stop_event.is_set():
                return

    def _collect_last(self) -> None:
        """The collecting sink after every other (a recording, Foxglove): a file's batches are posted
        from it, so a Block reaches the screen only once no other sink will touch it (one that takes
        Records has the Block build them all, on this thread)."""
        pipeline = self.pipeline
        if pipeline.sinks[-1] is not self._collect:
            pipeline.remove(self._collect)
            pipeline.add(self._collect)

    def _step(self) -> None:
        """After each step of a file (the decoder takes a file ~256 KiB at a time, so between chunks
        there is nothing new to do): the screen's commands, the reader's warnings, a post when due.
        The source itself stops when told (Feed.chunks)."""
        if self._commands_waiting:
            self._apply_commands()
        self._take_warnings()
        # The first batch comes as from a live source, so the screen fills at once; then the screen is
        # told less often: each redraw holds the GIL the decoding thread needs.
        self._maybe_post(self.interval if not self._posts else max(self.interval, LOAD_INTERVAL))

    def _take_warnings(self) -> None:
        """What the reader worked around so far (its ``warnings``), as the note for the screen: shown
        there, not printed behind it; each once."""
        warnings = getattr(self.source, "warnings", None)
        if warnings:
            self._note = "; ".join(warnings)
            warnings.clear()

    def _maybe_post(self, interval: float) -> None:
        # Posted when the interval is up, or sooner when the screen would have many objects to take
        # (a Record each; a Block is one, its rows being columns); a post holds max_batch rows a batch.
        n = len(self._collect.records)
        now = self.clock()
        if n and (now - self._last_post >= interval or n >= self.max_batch) or self._note is not None:
            self._post()
            self._last_post = now

    def run(self) -> None:
        self.running = True
        error = None
        try:
            if self.loading:
                self._last_post = self.clock()
                self._apply_commands()  # a recording asked for before the start takes it all
                self._collect_last()
                self.pipeline.run(self.source.chunks(self.stop_event))
            else:
                self.pipeline.run(self._chunks())
        except (CaptureError, OSError) as e:
            error = str(e)
        except Exception as e:  # noqa: BLE001 - a bug must not cost the records decoded so far
            error = f"capture stopped: {type(e).__name__}: {e}"
        finally:
            try:
                self.source.close()
            except Exception as e:  # noqa: BLE001 - closing must not cost the last batch
                error = error or f"closing the source: {type(e).__name__}: {e}"
        self._take_warnings()
        self._apply_commands()
        self._close_sink()
        self.finished = True
        self.running = False
        self._post(done=True, error=error)

    def _post(self, done: bool = False, error: str | None = None) -> None:
        """Hand what was collected to the screen, in batches of ``max_batch`` rows at most (a Block
        across the line is split); the findings go with the last."""
        collect = self._collect
        while True:
            more = collect.count > self.max_batch
            records, findings = collect.take(self.max_batch if more else None)
            self._post_one(records, findings, done and not more, None if more else error, more)
            if not more:
                return

    def _post_one(self, records: list, findings: list, done: bool, error: str | None, more: bool = False) -> None:
        note, self._note = self._note, None
        self._posts += 1
        if more:  # the screen redraws after the last batch of a post: what it needs is in that one
            self.post(Batch(records, findings, bytes_in=self.decoder.bytes_in, more=True, note=note,
                            recording=self.recording))
            return
        self.post(Batch(records, findings, servo_snapshot(self.decoder.bus), self.decoder.bytes_in,
                        stats=screen_figures(self.stats), done=done, error=error, recording=self.recording, note=note))

    # ---- recording ---------------------------------------------------------------------------------
    def _apply_commands(self) -> None:
        if not self._commands_waiting:
            return
        self._commands_waiting = False  # cleared before draining: a command put meanwhile sets it again
        while True:
            try:
                cmd, arg = self._commands.get_nowait()
            except Empty:
                return
            if cmd == "record":
                self._open_sink(arg)
            elif cmd == "stop-record":
                self._close_sink()
            elif cmd == "clear-stats":
                self._collect.set_stats(CaptureStats(self.options.baud))

    def _open_sink(self, path: str) -> None:
        if self._sink is not None or self.pipeline.closed:
            return
        factory = self.sink_factory
        if factory is None:
            from ..sinks.mcap.writer import McapSink  # only a recording needs the mcap library
            factory = McapSink
        models = {i: m for i, m in self.options.models.items()}
        try:
            sink = factory(path, source=self.source.name, baud=self.options.baud,
                           time_base=self.source.time_base, models=models)
        except OSError as e:
            self._note = f"cannot record to {path}: {e.strerror or e}"
            return
        self._sink = _Recording(self, sink, path)
        self.pipeline.add(self._sink)
        self._collect_last()
        self.recording = path
        self._note = f"recording to {path}"

    def _close_sink(self, quiet: bool = False) -> None:
        rec, path = self._sink, self.recording
        if rec is None:
            return
        self._sink = None
        self.recording = None
        if rec in self.pipeline.sinks:
            self.pipeline.remove(rec)
        try:
            rec.sink.finish()
        except OSError as e:
            self._note = f"recording to {path} failed: {e.strerror or e}"
            return
        if not quiet:
            self._note = f"saved {path}"
