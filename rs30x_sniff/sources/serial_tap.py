"""Passive serial tap: reads a port on its own thread, stamps each chunk on arrival, and never writes."""

from __future__ import annotations

import os
import queue
import select
import signal
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass
from types import FrameType
from typing import TYPE_CHECKING, Any, Protocol, final
from collections.abc import Callable, Iterator

from ..protocol.wire import BAUD_RATES, byte_time
from .captures import CaptureError

if TYPE_CHECKING:
    from serial import SerialBase

    from .port_process import PortProcess

Chunk = tuple[bytes, float]

# Rates the tap accepts: the servo's table 4.7, plus 460800 (common USB-UART rate; useful with
# simulators and for capturing a host that is misconfigured).
TAP_BAUD_RATES = (*BAUD_RATES, 460800)
READ_TIMEOUT = 0.05  # how often the reader thread looks at its stop flag
MAX_AHEAD = 0.05     # seconds a chunk may be placed after its arrival to keep bytes from overlapping
# A read that returns more bytes than the line could carry since the previous read returned, by more
# than this (read jitter, which MAX_AHEAD absorbs), means the reader fell behind: a stall. So does one
# whose bytes took longer than STALL_SPAN on the line (no packet does at any rate: 263 bytes at 9600
# take 0.27 s), since a reader waiting in read() returns at a chunk's first byte.
STALL_SLACK = MAX_AHEAD
STALL_SPAN = 0.5
# The OS moves a backlog into the port's buffer a few KiB at a time, a moment after each read: a
# backlog is looked at again after this pause, so that it comes out as one chunk, not one per buffer.
DRAIN_PAUSE = 0.002
# The most a read drains into one chunk: an OS buffers about 64 KiB for a port, so a backlog fits.
DRAIN_MAX = 1 << 20
# The most one read of a local device asks for: what a tty hands over at once (its 4 KiB buffer) and more.
READ_BYTES = 1 << 16
# The longest a backlog is drained into one chunk: a line that always has a byte waiting (a busy bus, a reader
# slower than a byte time per pass, a URL handler modelling a wire) would otherwise never yield one. A pty's
# 64 KiB backlog drains in a few milliseconds.
DRAIN_SECONDS = 0.02
# A busy bus hands the drive loop its chunks in batches at most this often, each chunk keeping its own
# arrival stamp: a pass of the loop per batch instead of per chunk (a packet each on a pty), and the batch decoded
# as one group on the columnar path (sinks.pipeline.columnar_for). A tenth of a second holds some 90 frames of a
# busy 230400-baud bus, enough for Blocks (decode.blocks.MIN_BLOCK: 20 ms held about 20, and every frame went record
# by record), for lines printed up to this much later.
GATHER_SECONDS = 0.1

# End reasons of a live capture.
STOPPED = "stopped"    # Ctrl-C, SIGTERM, SIGHUP, or stop() from the program
DURATION = "duration"  # --duration elapsed
LOST = "lost"          # the port raised an error or vanished
# Signals that end a capture cleanly (SIGHUP: the terminal or ssh session went away).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, *((signal.SIGHUP,) if hasattr(signal, "SIGHUP") else ()))


def stop_signals() -> tuple[int, ...]:
    """The signals a capture takes as a stop: :data:`STOP_SIGNALS`, less SIGHUP when this process started with it
    ignored. `nohup` (or a unit's `IgnoreSIGHUP`) asks the run to outlive its terminal, so a logout must not end
    the recording; every command keeps it so (cli.stop_on_hangup leaves an ignored SIGHUP alone too)."""
    hup = getattr(signal, "SIGHUP", None)
    if hup is not None and signal.getsignal(hup) == signal.SIG_IGN:
        return tuple(sig for sig in STOP_SIGNALS if sig != hup)
    return STOP_SIGNALS


@final  # the live source tells it from a chunk by `type(item) is TapEnd`
@dataclass(frozen=True, slots=True)
class TapEnd:
    """The last item of a tap's queue: why its reader ended."""

    reason: str
    message: str


class TapQueue(Protocol):
    """The tap's queue as its reader puts to it and the live source takes from it: a ChunkQueue on a thread,
    a PipeQueue from a child process (port_process.py)."""

    def put(self, item: Chunk | TapEnd) -> None: ...
    def get(self, timeout: float | None = None) -> Chunk | TapEnd: ...
    def get_nowait(self) -> Chunk | TapEnd: ...
    def empty(self) -> bool: ...
    def take_all(self) -> list[Chunk | TapEnd]: ...


class ChunkQueue:
    """The reader thread's chunks for the main thread, cheaper than queue.Queue on a busy bus: a deque (its
    append and popleft are atomic) and an Event set only when the queue goes from empty to not, so the reader
    takes no lock per chunk and the main thread takes what a gather period brought in one go.

    ``put``, ``get(timeout)``, ``get_nowait`` and ``empty`` as queue.Queue's (raising queue.Empty); ``take_all``
    empties it."""

    def __init__(self) -> None:
        self._items: deque[Chunk | TapEnd] = deque()
        self._ready = threading.Event()

    def put(self, item: Chunk | TapEnd) -> None:
        self._items.append(item)
        if not self._ready.is_set():
            self._ready.set()

    def get_nowait(self) -> Chunk | TapEnd:
        try:
            return self._items.popleft()
        except IndexError:
            raise queue.Empty from None

    def get(self, timeout: float | None = None) -> Chunk | TapEnd:
        end = None if timeout is None else time.monotonic() + timeout
        while True:
            try:
                return self._items.popleft()
            except IndexError:
                pass
            self._ready.clear()
            if self._items:  # put between the popleft and the clear: its set() may have come first
                continue
            left = None if end is None else end - time.monotonic()
            if left is not None and left <= 0:
                raise queue.Empty
            self._ready.wait(left)

    def empty(self) -> bool:
        return not self._items

    def take_all(self) -> list[Chunk | TapEnd]:
        items = self._items
        return [items.popleft() for _ in range(len(items))]


class SerialTap:
    """Opens ``port`` at ``baud`` 8N1 for reading only, and reads it on a daemon thread into an
    unbounded queue, so a slow consumer (decoder, screen, disk) never makes it drop bytes.

    The port is opened with pyserial's ``serial_for_url`` (device paths and URLs alike), with
    software and hardware flow control off. The tap never calls ``write``. Note that pyserial itself,
    when it opens a local device, sets DTR and RTS to its defaults (asserted, as the OS and every
    terminal program do); we leave them alone after that. A tap wired only to RX and GND does not
    connect those pins to anything, so this is harmless on the bus.

    Each chunk is stamped with ``time.monotonic_ns()`` when the read returns. Its first byte's time
    is back-computed from the baud rate (``t_arrival - len(chunk) x byte time``) and kept after the
    previous chunk's last byte. A reader that was held up (a stall) finds a backlog: it drains it
    into one chunk, lays that back from its arrival at the line rate, and notes the stall in
    :attr:`stalls`. ``t`` is wall-clock time (seconds since the epoch), read from the
    monotonic clock anchored once to the system clock when the port opened (:attr:`wall_start_ns`):
    a log lines up with a ROS bag or a video, and a clock step during the capture cannot make time
    run backwards.
    """

    def __init__(self, port: str, baud: int, *, read_timeout: float = READ_TIMEOUT,
                 clock: Callable[[], int] = time.monotonic_ns, process: bool = True) -> None:
        if baud not in TAP_BAUD_RATES:
            raise CaptureError(f"--baud {baud}: not a bus rate (table 4.7: "
                               f"{', '.join(map(str, TAP_BAUD_RATES))})")
        self.port = port
        self.baud = baud
        self.byte_time = byte_time(baud)
        self.read_timeout = read_timeout
        self.clock = clock
        # Not SimpleQueue: CPython 3.11's SimpleQueue.get(timeout) can block for good when a signal (Ctrl-C)
        # interrupts it, and the main thread waits on this queue with signals live.
        self.queue: TapQueue = ChunkQueue()
        self.bytes_read = 0
        self.start_ns = 0
        self.wall_start_ns = 0
        self._serial: SerialBase | None = None
        self._thread: threading.Thread | None = None
        # Read and stamped by a child process (port_process.py): the decoding in this one never delays a stamp.
        self.process = process
        self._child: PortProcess | None = None
        self._stop = threading.Event()
        self._next_t = 0.0  # earliest start time of the next chunk (end of the previous one)
        self._last_t = 0.0  # the previous chunk's time: a stalled chunk's bound
        self._last_arrival: float | None = None  # when the previous read returned (None: the port's opening)
        # (t, seconds behind, bytes) of each read that found a backlog: the reader had fallen behind,
        # and its oldest byte had waited that long in the OS.
        self.stalls: list[tuple[float, float, int]] = []

    # ---- lifecycle ---------------------------------------------------------------------------
    def open(self) -> SerialTap:
        """Open the port and start reading it (in a child process, or on a thread without ``process``); a
        one-line CaptureError if the port cannot be opened."""
        if self.process:
            from .port_process import PortProcess

            self._child = PortProcess(self)  # raises the child's CaptureError when the port cannot be opened
            return self
        self.open_port()
        self._thread = threading.Thread(target=self.run, name=f"tap {self.port}", daemon=True)
        self._thread.start()
        return self

    def open_port(self) -> None:
        """Open the port itself, here (pyserial's ``serial_for_url``), and note when on both clocks."""
        import serial  # pyserial is needed only for live capture

        try:
            ser = serial.serial_for_url(self.port, do_not_open=True, baudrate=self.baud,
                                        bytesize=serial.EIGHTBITS, parity=serial.PARITY_NONE,
                                        stopbits=serial.STOPBITS_ONE, timeout=self.read_timeout,
                                        xonxoff=False, rtscts=False, dsrdtr=False)
            ser.open()
        except (serial.SerialException, ValueError, OSError) as e:
            raise CaptureError(f"{self.port}: cannot open port: {_one_line(e)}") from None
        self._serial = ser
        self.wall_start_ns = time.time_ns()
        self.start_ns = self.clock()

    def request_stop(self) -> None:
        """Have :meth:`run` read what the OS still holds and end."""
        self._stop.set()

    def stop(self, timeout: float = 2.0) -> None:
        """Ask the reader to finish (it first reads what the OS still holds), wait for it, close the port."""
        self._stop.set()
        if self._child is not None:
            self._child.stop(timeout)
            return
        if self._thread is not None:
            self._thread.join(timeout)
        if self._serial is not None:
            try:
                self._serial.close()
            except Exception:  # noqa: BLE001 - closing a vanished device may fail; nothing to save
                pass

    @property
    def running(self) -> bool:
        if self._child is not None:
            return self._child.running
        return self._thread is not None and self._thread.is_alive()

    # ---- the reader ------------------------------------------------------------------------------
    def run(self) -> None:
        """Read the open port until a stop or a failure, stamping each chunk into :attr:`queue`, then put a TapEnd."""
        ser = self._serial
        assert ser is not None, "run() reads the port open_port() opened"
        put = self.queue.put
        if hasattr(signal, "pthread_sigmask") and threading.current_thread() is not threading.main_thread():
            # Ctrl-C and SIGTERM go to the main thread, whose handler stops the capture: delivered
            # there, they also wake it from its wait at once. (Never blocked in the main thread itself:
            # the mask would stay, and every process it starts would inherit it.)
            signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        fd = _device_fd(ser)
        try:
            while not self._stop.is_set():
                data = self._read_chunk(ser) if fd is None else self._read_device(ser, fd)
                if data:
                    self._stamp(data, self.clock())
            more = ser.in_waiting  # a requested stop: keep what has already arrived
            if more:
                self._stamp(ser.read(more), self.clock())
            put(TapEnd(STOPPED, "stopped"))
        except Exception as e:  # noqa: BLE001 - SerialException, OSError, a vanished device: all end the capture
            put(TapEnd(LOST, _one_line(e)))

    def _read_device(self, ser, fd: int) -> bytes:
        """A local device's chunk in one wait and one read: all that has arrived (a plain reading loop makes two
        more calls per chunk through pyserial: a read of one byte, then one of what is waiting). A backlog
        (more than STALL_SLACK of the line) is drained further as :meth:`_read_chunk` does."""
        ready, _, _ = select.select((fd,), (), (), self.read_timeout)
        if not ready:
            return b""
        try:
            data = os.read(fd, READ_BYTES)
        except (BlockingIOError, InterruptedError):
            return b""
        if not data:  # readable but nothing: the device is gone (an unplugged adapter), as pyserial says it
            raise OSError("device reports readiness to read but returned no data "
                          "(device disconnected or multiple access on port?)")
        if len(data) * self.byte_time <= STALL_SLACK:
            return data
        return self._drain(ser, bytearray(data))

    def _read_chunk(self, ser) -> bytes:
        """What has arrived, or (nothing yet) the next byte and what came in with it; a backlog drained, boundedly."""
        waiting = ser.in_waiting
        # One read call for a chunk already in the OS's buffer, as a plain reading loop would make; with nothing
        # there, wait for the next byte up to the read timeout.
        data = ser.read(min(waiting, DRAIN_MAX) or 1)
        if not data:
            return data
        bt = self.byte_time
        buf = bytearray(data)  # what was read so far: kept (stamped) if the port fails mid-drain
        try:
            if not waiting:
                # It waited for a first byte: the rest of that arrival (a pty's write, a USB packet) is waiting now.
                more = ser.in_waiting
                if more:
                    buf += ser.read(min(more, DRAIN_MAX - 1))
            if len(buf) * bt <= STALL_SLACK:
                return bytes(buf)  # live traffic: no backlog to drain
        except Exception:
            self._stamp(bytes(buf), self.clock())  # the port failed: keep the bytes already read
            raise
        return self._drain(ser, buf)

    def _drain(self, ser, buf: bytearray) -> bytes:
        bt = self.byte_time
        try:
            # A held-up reader finds a backlog that the OS hands over a buffer at a time: read it all into one
            # chunk, so that laying it back from its arrival at the line rate spreads it over the time it took
            # to come in, not over one buffer's worth. Only the backlog, though: what the line could have
            # carried since the drain began is live traffic for the next chunk, and the drain ends after
            # DRAIN_SECONDS whatever comes, so that a line that always has a byte waiting still yields chunks.
            began = self.clock()
            while len(buf) < DRAIN_MAX:
                more = ser.in_waiting
                if not more:
                    time.sleep(DRAIN_PAUSE)
                    more = ser.in_waiting
                elapsed = (self.clock() - began) / 1e9
                if more * bt <= elapsed + 2 * DRAIN_PAUSE or elapsed >= DRAIN_SECONDS:
                    break
                buf += ser.read(min(more, DRAIN_MAX - len(buf)))
            return bytes(buf)
        except Exception:
            if buf:
                self._stamp(bytes(buf), self.clock())  # the port failed: keep the bytes already read
            raise

    def _stamp(self, data: bytes, arrival_ns: int) -> None:
        n = len(data)
        arrival = (self.wall_start_ns + arrival_ns - self.start_ns) / 1e9
        span = n * self.byte_time
        t = arrival - span
        since = arrival - (self.wall_start_ns / 1e9 if self._last_arrival is None else self._last_arrival)
        behind = span - since
        fits = (self.bytes_read + n) * self.byte_time <= arrival - self.wall_start_ns / 1e9 + STALL_SLACK
        if (behind > STALL_SLACK or span > STALL_SPAN) and fits:
            # More bytes than the line could carry since the last read, or than a reader waiting in read() lets pile
            # up: they waited in the OS while the reader was held up. Laid back from their arrival at the line rate,
            # they start where they came in, before the previous chunk ended (pushed past it, a 3 s backlog was once
            # stamped within 0.36 s, at 100 % load); no earlier than the previous chunk, so no time runs backwards.
            # Not when the whole capture holds more bytes than the line could carry since the port opened: then the
            # baud rate is wrong, and F006 says so (below).
            t = max(t, self._last_t)
            self.stalls.append((t, arrival - t, n))
        elif t < self._next_t:
            # Bytes cannot overlap the previous chunk's: read jitter (USB latency, a pty's writer catching
            # up) is absorbed by placing the chunk after them. But not by more than MAX_AHEAD past its
            # arrival: at a wrong baud rate every chunk would push the clock further ahead of real time
            # (a 6 s recording stamped as 31.8 s); there it keeps its arrival, and the decoder's F006
            # says the bytes came faster than the rate allows.
            t = self._next_t if self._next_t - arrival <= MAX_AHEAD else arrival
        self._next_t = t + span
        self._last_t = t
        self._last_arrival = arrival
        self.bytes_read += n
        self.queue.put((data, t))


class LiveSource:
    """A port as an input: chunks until Ctrl-C / SIGTERM, ``duration`` seconds, or the port is lost.

    Iterate it for ``(bytes, t)`` chunks, or call :meth:`poll` for whatever arrived within a
    timeout (a loop that also refreshes a screen). After the end, :attr:`reason` is ``stopped``,
    ``duration`` or ``lost`` and :attr:`message` says why; with ``announce`` a lost port is also
    reported on stderr as one line. SIGINT and SIGTERM handlers are installed while it runs (from
    the main thread only) and restored at the end.
    """

    live = True
    streamed = True  # a port's bytes are arriving as they are read
    batched = True  # chunks() ends each batch with an empty chunk (sinks.pipeline.columnar_for)

    def __init__(self, port: str, baud: int, *, duration: float | None = None, announce: bool = True,
                 tap: SerialTap | None = None, gather: float = GATHER_SECONDS) -> None:
        self.port = port
        self.tap = tap or SerialTap(port, baud)
        self.duration = duration
        self.announce = announce
        self.gather = gather
        self._handed_out = float("-inf")  # when poll last returned chunks (time.monotonic)
        self.reason: str | None = None
        self.message = ""
        self._stop_signal: str | None = None
        self._saved: dict[int, Callable[[int, FrameType | None], Any] | int | None] = {}
        self._deadline: float | None = None
        self._started = False

    @property
    def lost(self) -> bool:
        return self.reason == LOST

    @property
    def stalls(self) -> list[tuple[float, float, int]]:
        """``(t, seconds behind, bytes)`` of each time the reader fell behind (:attr:`SerialTap.stalls`)."""
        return self.tap.stalls

    def stall_report(self) -> str | None:
        """One line saying how often the reader fell behind and how its bytes were timed, or None."""
        stalls = self.tap.stalls
        if not stalls:
            return None
        t, behind, _ = max(stalls, key=lambda s: s[1])
        times = "once" if len(stalls) == 1 else f"{len(stalls)} times"
        return (f"rs30x-sniff: {self.port}: the reader fell behind {times} (longest {behind:.3f} s at "
                f"{t - self.tap.wall_start_ns / 1e9:.3f} s); their bytes are timed at the line rate")

    @property
    def ended(self) -> bool:
        return self.reason is not None

    def start(self) -> LiveSource:
        if self._started:
            return self
        self._started = True
        self.tap.open()
        if threading.current_thread() is threading.main_thread():
            # SIGHUP too: a closed ssh session must leave a finished log, as Ctrl-C does.
            for sig in stop_signals():
                self._saved[sig] = signal.signal(sig, self._on_signal)
        if self.duration is not None:
            self._deadline = time.monotonic() + self.duration
        return self

    def _on_signal(self, signum: int, frame: object) -> None:
        self._stop_signal = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name

    def request_stop(self, why: str = "stop requested") -> None:
        self._stop_signal = why

    def poll(self, timeout: float = 0.1) -> list[Chunk]:
        """Chunks that arrived within ``timeout`` seconds (possibly none); [] for ever once ended.

        A poll that follows one with chunks first lets ``gather`` seconds pass since then, so what
        arrives meanwhile comes out together."""
        if self.reason is not None:
            return []
        self.start()
        out = self._poll(timeout)
        if out:
            self._handed_out = time.monotonic()
        return out

    def _poll(self, timeout: float) -> list[Chunk]:
        hold = self._handed_out + self.gather - time.monotonic()
        if self._deadline is not None:
            hold = min(hold, self._deadline - time.monotonic())
        if hold > 0 and self._stop_signal is None:
            time.sleep(hold)  # a stop signal's handler runs during the sleep, which is short
        out: list[Chunk] = []
        q = self.tap.queue
        end_at = time.monotonic() + timeout
        while True:
            if self._stop_signal is not None or (self._deadline is not None and time.monotonic() >= self._deadline):
                return out + self._finish()
            wait = end_at - time.monotonic()
            if self._deadline is not None:
                wait = min(wait, self._deadline - time.monotonic())
            try:
                item = q.get(timeout=max(0.0, min(wait, 0.05))) if wait > 0 else q.get_nowait()
            except queue.Empty:
                if wait <= 0:
                    return out
                continue
            # Everything already queued, without waiting again.
            for item in (item, *q.take_all()):  # noqa: B020 - the first item, then the rest
                if type(item) is TapEnd:
                    self._close(item)
                    return out
                out.append(item)
            return out

    def _finish(self) -> list[Chunk]:
        """A requested stop or the duration: stop the reader, then hand out everything it read."""
        why = self._stop_signal
        self.tap.stop()
        out: list[Chunk] = []
        end = TapEnd(STOPPED, why) if why is not None else TapEnd(DURATION, f"{self.duration:g} s elapsed")
        while True:
            try:
                item = self.tap.queue.get_nowait()
            except queue.Empty:
                break
            if type(item) is TapEnd:
                if item.reason == LOST:
                    end = item
                continue
            out.append(item)
        self._close(end)
        return out

    def _close(self, end: TapEnd) -> None:
        self.reason, self.message = end.reason, end.message
        self.tap.stop()
        for sig, handler in self._saved.items():
            signal.signal(sig, handler)
        self._saved = {}
        if self.announce and self.reason == LOST:
            print(f"rs30x-sniff: {self.port}: port lost ({self.message}); "
                  f"{self.tap.bytes_read} bytes received", file=sys.stderr)
        report = self.stall_report()
        if self.announce and report:
            print(report, file=sys.stderr)
        if self.announce and self.reason != LOST and self.message != "closed":
            # The end line of a command reading a port (decode, lint, info): why it stopped, what it read.
            print(f"rs30x-sniff: {self.message}: {self.port}: {self.tap.bytes_read:,} bytes received",
                  file=sys.stderr)

    def close(self) -> None:
        """End the capture now (idempotent)."""
        if self.reason is None:
            if self._started:
                self.request_stop("closed")
                self._finish()
            else:
                self.reason, self.message = STOPPED, "closed"

    def __iter__(self) -> Iterator[Chunk]:
        try:
            while self.reason is None:
                yield from self.poll(0.25)
        finally:
            self.close()

    def chunks(self, idle: float = 0.1) -> Iterator[tuple[bytes, float | None]]:
        """Like iterating, but an empty chunk ``(b"", None)`` after each ``idle`` seconds without bytes,
        so a drive loop can refresh a status line or flush a file while the bus is quiet, and after each
        batch (``batched``): what came in one gather period is decoded as one group (Pipeline)."""
        try:
            while self.reason is None:
                batch = self.poll(idle)
                if batch:
                    yield from batch
                yield b"", None
        finally:
            self.close()

    @property
    def metadata(self) -> dict[str, str]:
        """What a capture file should say about this source."""
        return {"port": self.port, "baud": str(self.tap.baud),
                "wall_start_ns": str(self.tap.wall_start_ns),
                "monotonic_start_ns": str(self.tap.start_ns),
                "timing": "chunk arrival stamped with a monotonic clock; byte times back-computed from the baud rate"}


def _device_fd(ser) -> int | None:
    """The file descriptor of a local device opened by pyserial (read directly), or None (a URL's handler)."""
    try:
        from serial.serialposix import Serial as PosixSerial
    except ImportError:  # not a POSIX system
        return None
    if type(ser) is not PosixSerial:
        return None
    try:
        return ser.fileno()
    except Exception:  # noqa: BLE001 - no descriptor: read through pyserial
        return None


def _one_line(e: BaseException) -> str:
    text = str(e).strip() or type(e).__name__
    return " ".join(text.split())


def port_reader(port: str, *, read_timeout: float = READ_TIMEOUT) -> Callable[[int, float], bytes]:
    """A ``read_for(baud, seconds) -> bytes`` for :func:`rs30x_sniff.decode.autobaud.scan` on a real port.

    Each call opens ``port`` at ``baud`` (8N1, no flow control, as :class:`SerialTap`), drops what the
    OS buffered before, reads for ``seconds`` and closes the port. It never writes.
    """
    import serial

    def read_for(baud: int, seconds: float) -> bytes:
        try:
            ser = serial.serial_for_url(port, baudrate=baud, bytesize=serial.EIGHTBITS,
                                        parity=serial.PARITY_NONE, stopbits=serial.STOPBITS_ONE,
                                        timeout=read_timeout, xonxoff=False, rtscts=False, dsrdtr=False)
        except (serial.SerialException, ValueError, OSError) as e:
            raise CaptureError(f"{port}: cannot open port at {baud}: {_one_line(e)}") from None
        try:
            ser.reset_input_buffer()  # bytes read at the previous rate are not this rate's
            out = bytearray()
            end = time.monotonic() + seconds
            while time.monotonic() < end:
                out += ser.read(max(1, ser.in_waiting))
            return bytes(out)
        except (serial.SerialException, OSError) as e:
            raise CaptureError(f"{port}: port lost while scanning rates: {_one_line(e)}") from None
        finally:
            ser.close()

    return read_for
