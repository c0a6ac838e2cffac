"""The monitor's capture thread, with no Textual in it: read a source, decode, lint, record, hand batches up."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from queue import Empty, SimpleQueue
from typing import Any, Callable

from ..bus import Record
from ..io.captures import CaptureError
from ..pipeline import DecodeOptions, Decoder
from .sources import Source
from .store import ServoRow, servo_snapshot

POST_INTERVAL = 0.25    # seconds between batches: a few screen updates a second are plenty
MAX_BATCH = 50_000      # records per batch, so one batch never stalls the screen for long


@dataclass
class Batch:
    """What the capture thread hands to the screen: new records, new findings, the servos' state."""

    records: list[Record]
    findings: list = field(default_factory=list)
    servos: dict[int, ServoRow] | None = None
    bytes_in: int = 0
    done: bool = False           # the source has ended (a file read to its end, a port closed)
    error: str | None = None     # why it ended early, in one line
    recording: str | None = None  # the MCAP file being written, if any
    note: str | None = None      # a one-line message for the user (recording started/stopped, ...)


def default_linter() -> Any:
    """A fresh Linter with its default configuration, or None when the lint package is not installed."""
    try:
        from ..lint import Linter
    except ImportError:
        return None
    return Linter()


class Feeder:
    """Runs in its own thread: never waits for the screen, so the capture loses nothing to it.

    Commands (stop, start or stop recording) come down through a queue and are applied between chunks;
    batches go up through ``post``, at most every ``interval`` seconds (or ``max_batch`` records).
    """

    def __init__(self, source: Source, options: DecodeOptions, post: Callable[[Batch], None], *,
                 linter: Any = None, interval: float = POST_INTERVAL, max_batch: int = MAX_BATCH,
                 clock: Callable[[], float] = time.monotonic,
                 sink_factory: Callable[..., Any] | None = None) -> None:
        self.source = source
        self.options = options
        self.post = post
        self.linter = linter
        self.decoder = Decoder(options, linter=linter)
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
        self._sink: Any = None
        self._seen_findings = 0
        self._note: str | None = None

    # ---- commands from the screen (any thread) ---------------------------------------------------
    def stop(self) -> None:
        self.stop_event.set()

    def start_recording(self, path: str) -> None:
        self._commands.put(("record", path))
        self._commands_waiting = True

    def stop_recording(self) -> None:
        self._commands.put(("stop-record", None))
        self._commands_waiting = True

    # ---- the thread --------------------------------------------------------------------------------
    def run(self) -> None:
        self.running = True
        records: list[Record] = []
        findings: list = []
        last_post = self.clock()
        error = None
        dec = self.decoder
        try:
            for data, t in self.source.chunks(self.stop_event):
                self._apply_commands()
                if data:
                    new = dec.feed(data, t)
                    found = self._new_findings()
                    if self._sink is not None:
                        self._record(data, t, new, found)
                    records += new
                    findings += found
                now = self.clock()
                if records and (now - last_post >= self.interval or len(records) >= self.max_batch) \
                        or self._note is not None:
                    self._post(records, findings)
                    records, findings = [], []
                    last_post = now
                if self.stop_event.is_set():
                    break
        except (CaptureError, OSError) as e:
            error = str(e)
        except Exception as e:  # noqa: BLE001 - a bug must not cost the records decoded so far
            error = f"capture stopped: {type(e).__name__}: {e}"
        finally:
            try:
                self.source.close()
            except Exception as e:  # noqa: BLE001 - closing must not cost the last batch
                error = error or f"closing the source: {type(e).__name__}: {e}"
        tail = dec.close()
        records += tail
        late = self._new_findings()  # end-of-input findings are in linter.findings too
        findings += late
        if self._sink is not None:
            self._record(b"", None, tail, late)
        self._apply_commands()
        self._close_sink()  # the end of the source ends the recording: the file is finished and indexed
        self.finished = True
        self.running = False
        self._post(records, findings, done=True, error=error)

    def _new_findings(self) -> list:
        lin = self.linter
        if lin is None:
            return []
        all_ = lin.findings
        new = all_[self._seen_findings:]
        self._seen_findings = len(all_)
        return list(new)

    def _post(self, records: list[Record], findings: list, done: bool = False, error: str | None = None) -> None:
        note, self._note = self._note, None
        self.post(Batch(records, findings, servo_snapshot(self.decoder.bus), self.decoder.bytes_in, done=done,
                        error=error, recording=self.recording, note=note))

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

    def _open_sink(self, path: str) -> None:
        if self._sink is not None:
            return
        factory = self.sink_factory
        if factory is None:
            from ..io.mcap_sink import McapSink  # only a recording needs the mcap library
            factory = McapSink
        models = {i: m for i, m in self.options.models.items()}
        try:
            self._sink = factory(path, source=self.source.name, baud=self.options.baud,
                                 time_base=self.source.time_base, models=models)
        except OSError as e:
            self._note = f"cannot record to {path}: {e.strerror or e}"
            return
        self.recording = path
        self._note = f"recording to {path}"

    def _record(self, data: bytes, t: float | None, records: list[Record], findings: list | None = None) -> None:
        sink = self._sink
        try:
            if data:
                sink.raw(data, t)
            for rec in records:
                sink.record(rec)
            if findings:
                sink.findings(findings)
        except OSError as e:
            # A full disk stops the recording, never the capture.
            self._note = f"recording stopped: {e.strerror or e}"
            self._close_sink(quiet=True)

    def _close_sink(self, quiet: bool = False) -> None:
        sink, path = self._sink, self.recording
        if sink is None:
            return
        self._sink = None
        self.recording = None
        try:
            sink.finish()
        except OSError as e:
            self._note = f"recording to {path} failed: {e.strerror or e}"
            return
        if not quiet:
            self._note = f"saved {path}"
