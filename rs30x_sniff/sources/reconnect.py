"""A port that may go away: when it is lost, wait for it (the same path or its /dev/serial/by-id link) and go on."""

from __future__ import annotations

import glob
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator

from ..protocol.chunks import SourceGap
from .ports import is_port
from .serial_tap import DURATION, GATHER_SECONDS, LOST, STOPPED, LiveSource, SerialTap, stop_signals

BY_ID = "/dev/serial/by-id"
WAIT_STEP = 0.2  # seconds between looks for the port while it is gone


def by_id_link(port: str, folder: str = BY_ID) -> str | None:
    """The /dev/serial/by-id link naming ``port``'s adapter (its serial number, not the order it was found in),
    if there is one: the path to wait for when a re-plugged adapter may come back as another ttyUSBn."""
    try:
        real = os.path.realpath(port)
    except OSError:
        return None
    for link in sorted(glob.glob(os.path.join(folder, "*"))):
        if os.path.realpath(link) == real and link != port:
            return link
    return None


class ReconnectingSource:
    """Chunks from ``port`` as LiveSource gives them, across losses of the port: when it is lost, the chunks
    stop, the port (or its by-id link) is looked for every WAIT_STEP seconds and reopened, and a SourceGap
    says where the bytes stopped and for how long. Never writes to the port. Ends on Ctrl-C, SIGTERM, SIGHUP,
    or ``duration`` seconds in all (:attr:`reason` STOPPED or DURATION); never on a lost port.

    ``open_source(path, duration)`` makes a started LiveSource (a test gives its own); ``say`` gets one line
    per loss and per return."""

    live = True
    streamed = True  # a port's bytes are arriving as they are read
    batched = True  # LiveSource.chunks' batches, each ended by an empty chunk, passed on

    def __init__(self, port: str, baud: int, *, duration: float | None = None,
                 open_source: Callable[[str, float | None], LiveSource] | None = None,
                 say: Callable[[str], None] | None = None, clock: Callable[[], float] = time.monotonic,
                 gather: float = GATHER_SECONDS) -> None:
        self.port = port
        self.baud = baud
        self.gather = gather
        self.duration = duration
        self.open_source = open_source or self._open
        self.say = say
        self.clock = clock
        self.link = by_id_link(port) if is_port(port) else None
        self.reason: str | None = None
        self.message = ""
        self.gaps: list[tuple[float | None, float, str]] = []  # (lost at, back at, why), epoch seconds
        self.stalls: list[tuple[float, float, int]] = []  # every source's, as LiveSource.stalls
        self._deadline = None if duration is None else clock() + duration
        self._stop: str | None = None
        # The handlers before any source of ours: each LiveSource installs its own and puts back what it found,
        # so across a loss they would be lost or stacked in the wrong order; we hold ours over all of them and
        # put these back at the end.
        self._before = ({sig: signal.getsignal(sig) for sig in stop_signals()}
                        if threading.current_thread() is threading.main_thread() else {})
        self.source: LiveSource = self.open_source(port, duration)  # the first open fails as LiveSource's does

    def _open(self, path: str, duration: float | None) -> LiveSource:
        tap = SerialTap(path, self.baud)
        # One list for every tap: a part finished mid-run (record --split-time) already knows this tap's stalls.
        tap.stalls = self.stalls
        return LiveSource(path, self.baud, duration=duration, announce=False, tap=tap, gather=self.gather).start()

    @property
    def metadata(self) -> dict[str, str]:
        meta = dict(self.source.metadata)
        meta["port"] = self.port
        if self.link:
            meta["port_by_id"] = self.link
        return meta

    @property
    def lost(self) -> bool:
        return False  # a lost port is waited for, never the end

    def _remaining(self) -> float | None:
        return None if self._deadline is None else max(0.0, self._deadline - self.clock())

    def chunks(self, idle: float = 0.1) -> Iterator[tuple]:
        """LiveSource.chunks across losses, with a SourceGap before the first chunk after each return."""
        try:
            while True:
                src = self.source
                self._hold_signals()  # over the handlers this source installed as it started
                if self._stop is not None:
                    src.request_stop(self._stop)
                last_t = None
                for chunk in src.chunks(idle):
                    if chunk[1] is not None:
                        last_t = chunk[1] + len(chunk[0]) * 10 / self.baud
                    yield chunk
                self._take_stalls(src)
                self._hold_signals()  # the ended source put back what it found
                if src.reason != LOST:
                    self.reason, self.message = src.reason, src.message
                    return
                lost_at = time.time() if last_t is None else last_t
                why = src.message
                if self.say:
                    self.say(f"rs30x-sniff: {self.port}: port lost ({why}); waiting for it to come back")
                back = yield from self._wait(idle)
                if back is None:
                    return
                self.source = back
                t_back = back.tap.wall_start_ns / 1e9
                # Words only: F010 measures the span itself, so a known loss keeps its baseline fingerprint.
                note = f"the port was lost ({why}) and reopened"
                self.gaps.append((lost_at, t_back, why))
                if self.say:
                    self.say(f"rs30x-sniff: {self.port}: back after {t_back - lost_at:.1f} s; recording goes on")
                yield SourceGap(t_back, lost_at, note)
        finally:
            self.source.close()
            self._release_signals()

    def _hold_signals(self) -> None:
        """Our stop handler for SIGINT, SIGTERM and SIGHUP (main thread only): a stop reaches the source of the
        moment, or ends the wait for a lost port, whatever was opened in between."""
        if self._before and threading.current_thread() is threading.main_thread():
            for sig in self._before:
                signal.signal(sig, self._on_signal)

    def _release_signals(self) -> None:
        if self._before and threading.current_thread() is threading.main_thread():
            for sig, handler in self._before.items():
                signal.signal(sig, handler)

    def _wait(self, idle: float):
        """Look for the port until it opens (the new LiveSource), or a stop or the duration (None). Yields empty
        chunks meanwhile, so the drive loop still flushes files and refreshes its status."""
        next_idle = self.clock()
        while True:
            if self._stop is not None:
                self.reason, self.message = STOPPED, self._stop
                return None
            left = self._remaining()
            if left is not None and left <= 0:
                self.reason, self.message = DURATION, f"{self.duration:g} s elapsed"
                return None
            for path in (self.port, self.link):
                if path and (not is_port(path) or os.path.exists(path)):
                    try:
                        return self.open_source(path, left)
                    except Exception:  # noqa: BLE001 - not back yet (a node still settling): look again
                        pass
            time.sleep(WAIT_STEP)
            if self.clock() >= next_idle:
                next_idle = self.clock() + idle
                yield b"", None

    def _on_signal(self, signum: int, frame: object) -> None:
        self._stop = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        self.source.request_stop(self._stop)

    def _take_stalls(self, src: LiveSource) -> None:
        """A source made by ``open_source`` keeps its own list: its stalls join ours when it ends."""
        if src.stalls is not self.stalls:
            self.stalls.extend(src.stalls)

    def close(self) -> None:
        self.source.close()
        self._release_signals()
        if self.reason is None:
            self.reason, self.message = STOPPED, "closed"

    def stall_report(self) -> str | None:
        return self.source.stall_report()
