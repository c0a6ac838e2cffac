"""What the monitor's feeder reads: a capture file (at once or replayed), a serial port, chunks in memory."""

from __future__ import annotations

import os
import stat
import threading
import time
from typing import Protocol
from collections.abc import Callable, Iterable, Iterator

from ..protocol.chunks import remark
from .captures import CaptureError
from .inputs import read_input
from .protocol import Pacing
from .read_ahead import ReadAhead
from ..protocol.wire import DEFAULT_BAUD, byte_time

Chunk = tuple[bytes, "float | None"]
REPLAY_SLICE = 64        # bytes per step when replaying a capture that has no timestamps
POLL_SECONDS = 0.1       # a live source yields at least this often, so commands and batches flow
# A port's bytes pile up this long between passes of the decoder (LiveSource's gather): the screen takes a
# batch every feed.POST_INTERVAL (as long) anyway, and a second of a busy bus (some 880 frames at 230400
# baud) makes Blocks that the linter and the statistics take at a fraction of the cost per frame (the
# feeder thread on the hexapod: ~0.55 s of CPU over 10 s with 0.1 s gathers, ~0.3 s with 0.5 s ones).
PORT_GATHER_SECONDS = 1.0
# A capture file at least this large is read by a child process (io.read_ahead) while this one decodes:
# below it, starting a Python process (~0.2 s) costs more than the reading it takes off this one.
READ_AHEAD_BYTES = 8 << 20


class Feed(Pacing, Protocol):
    """A source as the monitor's feeder thread reads it: chunks until told to stop (the simulator: sim/source.py)."""

    name: str        # what the header shows
    kind: str        # "file", "replay", "port", "simulator"
    time_base: str   # for the MCAP sink: "capture", "synthetic" or "wall"
    # live, streamed, batched (Pacing): a port, a replay and the simulator are paced as they happen, so decoded
    # record by record or a gather at a time; a file loads on the columnar path (sinks.pipeline.columnar_for).

    def chunks(self, stop: threading.Event) -> Iterator[Chunk]: ...

    def close(self) -> None: ...


def paced(chunks: Iterable[Chunk], stop: threading.Event, *, speed: float, byte_seconds: float,
          clock: Callable[[], float] = time.monotonic) -> Iterator[Chunk]:
    """Hand out chunks when their time comes (``t`` / ``speed`` after the first one); chunks without
    timestamps go at line rate. Returns early once ``stop`` is set."""
    start = clock()
    t0: float | None = None
    sent = 0
    for chunk in chunks:
        data, t = chunk
        pieces = [(data, t)] if t is not None else [
            (data[i:i + REPLAY_SLICE], None) for i in range(0, len(data), REPLAY_SLICE)]
        for piece, pt in pieces:
            if pt is not None:
                if t0 is None:
                    t0 = pt
                due = (pt - t0) / speed
            else:
                due = sent * byte_seconds / speed
            wait = start + due - clock()
            if wait > 0 and stop.wait(wait):
                return
            if stop.is_set():
                return
            sent += len(piece)
            yield remark(chunk, piece, pt)


def _big_file(path: str) -> bool:
    """A regular file of at least READ_AHEAD_BYTES (not a pipe or stdin, which a child cannot read again)."""
    if path == "-":
        return False
    try:
        st = os.stat(path)
    except OSError:
        return False
    return stat.S_ISREG(st.st_mode) and st.st_size >= READ_AHEAD_BYTES


class FileSource:
    """A capture file read as fast as it decodes."""

    kind = "file"
    live = False
    streamed = False
    batched = False
    reads_ahead = True  # a big file is read by a child process (a replay is paced: no need)

    def __init__(self, path: str, fmt: str | None = None, *, baud: int = DEFAULT_BAUD,
                 time_ref: str | None = None, options: dict | None = None) -> None:
        self.path = path
        self.name = path
        self.fmt = fmt
        self.time_base = "capture"
        self.warnings: list[str] = []  # what the reader worked around (a damaged MCAP), for the screen
        # The one way a file is read (io.inputs): arrival-stamped logs are laid back to the first byte
        # here as in every other command, so the monitor's latencies are info's.
        # ``options`` go to another tool's reader (a logic capture's channel and rate).
        ahead = self.reads_ahead and _big_file(path)
        self._it: Iterator[Chunk] = read_input(path, fmt, baud=baud, time_ref=time_ref,
                                               warn=None if ahead else self.warnings.append, options=options)
        self._first = next(self._it, None)  # reads the head now, so a bad file fails before the screen starts
        if ahead:
            # The child reads it all again (the same reader: the same chunks and warnings, given to the
            # screen once); the head read here only checked that it can be read.
            self.close()
            try:
                self._it = ReadAhead(path, fmt, baud=baud, time_ref=time_ref, warn=self.warnings.append,
                                     options=options)
                self._first = None
            except OSError:  # no process to be had (a limit reached): read it here, as a small file is
                self._it = read_input(path, fmt, baud=baud, time_ref=time_ref, warn=self.warnings.append,
                                      options=options)
                self._first = next(self._it, None)

    def chunks(self, stop: threading.Event) -> Iterator[Chunk]:
        # Per chunk on files of millions of lines: the reader's own iterator, and ``stop`` looked at
        # every few dozen chunks (microseconds apart as a file is read).
        first, self._first = self._first, None
        n = 0
        for part in ((first,) if first is not None else (), self._it):
            for chunk in part:
                if chunk[1] is None:
                    self.time_base = "synthetic"
                yield chunk  # as read: a foreign log's marks (who sent it, UART errors) go on to the decoder
                n += 1
                if not n & 31 and stop.is_set():
                    return

    def close(self) -> None:
        close = getattr(self._it, "close", None)
        if close is not None:
            close()


class ReplaySource(FileSource):
    """A capture file played at its own pace (``speed`` times faster), as if it were live."""

    kind = "replay"
    live = True  # paced at the capture's own speed: decoded record by record, as a port
    reads_ahead = False

    def __init__(self, path: str, fmt: str | None = None, *, speed: float = 1.0, baud: int = DEFAULT_BAUD,
                 time_ref: str | None = None, clock: Callable[[], float] = time.monotonic,
                 options: dict | None = None) -> None:
        if not speed > 0:
            raise ValueError("speed must be positive")
        super().__init__(path, fmt, baud=baud, time_ref=time_ref, options=options)
        self.speed = speed
        self.byte_seconds = byte_time(baud)
        self.clock = clock

    def chunks(self, stop: threading.Event) -> Iterator[Chunk]:
        yield from paced(super().chunks(stop), stop, speed=self.speed, byte_seconds=self.byte_seconds,
                         clock=self.clock)


class PortSource:
    """A serial port through the passive tap (which never writes to the bus)."""

    kind = "port"
    live = True
    streamed = True
    # chunks() ends each gather with an empty chunk: decoded a gather at a time on the columnar path
    # (sinks.pipeline.columnar_for), as `record` takes a port, at a half to two thirds of the CPU.
    batched = True
    time_base = "wall"

    def __init__(self, port: str, baud: int) -> None:
        from .serial_tap import LiveSource  # pyserial is needed only for live capture

        self.name = port
        self.tap = LiveSource(port, baud, announce=False, gather=PORT_GATHER_SECONDS)
        # Open the port now, so a missing one is a one-line error rather than a blank screen. Started
        # off the main thread, the tap installs no signal handlers: the screen owns Ctrl-C, and the
        # handlers could not be restored from the capture thread at the end.
        failure: list[BaseException] = []

        def start() -> None:
            try:
                self.tap.start()
            except BaseException as e:  # noqa: BLE001 - handed back to the caller below
                failure.append(e)

        opener = threading.Thread(target=start, name=f"open {port}")
        opener.start()
        opener.join()
        if failure:
            raise failure[0]

    def chunks(self, stop: threading.Event) -> Iterator[Chunk]:
        live = self.tap
        while not stop.is_set() and not live.ended:
            yield from live.poll(POLL_SECONDS)
            yield b"", None  # let the feeder post and take commands while the bus is idle
        if live.lost:
            raise CaptureError(f"{self.name}: port lost ({live.message})")

    def close(self) -> None:
        self.tap.close()


class ChunkSource:
    """Chunks already in memory (a simulated capture, a test's bytes), handed out at once."""

    kind = "file"
    live = False
    streamed = False
    batched = False
    time_base = "capture"

    def __init__(self, name: str, chunks: Iterable[Chunk]) -> None:
        self.name = name
        self._chunks = chunks

    def chunks(self, stop: threading.Event) -> Iterator[Chunk]:
        for chunk in self._chunks:
            yield chunk
            if stop.is_set():
                return

    def close(self) -> None:
        pass
