"""Play simulated chunks onto a port or pseudo-terminal in real time (the only sim module that may use pyserial)."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable

Chunk = tuple[bytes, float]

# Chunks due within this much of the first one held go out in one write: fewer syscalls, and still far
# finer timing than a USB adapter's latency timer (1-16 ms) gives a real capture. Well under the gap
# between a request's end and its reply's end (the reply's own bytes plus the servo's 100 us return delay,
# table 4.6 No. 7), so a reader can still tell the two apart.
COALESCE = 0.0005
LOOKAHEAD = 1.0  # seconds of chunks made ahead of the writes
SPARE = 0.001    # no chunk is made this close to a write's time (the simulator takes up to a few hundred us for one)


def play(chunks: Iterable[Chunk], write: Callable[[bytes], object], *, speed: float = 1.0,
         byte_seconds: float = 0.0, clock: Callable[[], float] = time.monotonic,
         sleep: Callable[[float], None] = time.sleep, on_write: Callable[[int, float], None] | None = None) -> int:
    """Write each chunk when its time comes, ``(t + len(data) x byte_seconds) / speed`` seconds after the start.

    A chunk's ``t`` is its first byte's time on the line. Given ``byte_seconds`` (the line's byte time), a
    chunk is written when its last byte has been on the line, as a UART hands over a frame it has finished
    receiving: a reader that stamps bytes on arrival and lays them back at the line rate then finds each
    frame where it was. Without it, a chunk is written at its first byte's time.

    ``chunks`` may be made as they are asked for (the simulator's generator): they are taken up to LOOKAHEAD
    seconds in advance, while waiting for a write, never within SPARE of one, so making them never delays a write.

    ``write`` takes bytes (``os.write`` on a pty, a pyserial port's ``write``). ``on_write(offset,
    wall_time)`` is told the stream offset of every write's first byte and when it was written
    (benchmarks use it). Returns the number of bytes written.
    """
    source = iter(chunks)
    pending: deque[tuple[bytes, float]] = deque()  # (bytes, seconds after the start when they are due)

    def pull() -> bool:
        for data, t in source:
            pending.append((data, (t + len(data) * byte_seconds) / speed))
            return True
        return False

    more = True
    while more and (not pending or pending[-1][1] < LOOKAHEAD):
        more = pull()
    start = clock()
    sent = 0
    while pending or (more and (more := pull())):
        data, first = pending.popleft()
        buf, due = bytearray(data), first
        while True:  # chunks due within COALESCE of the first go out with it, when the last is due
            if not pending and not (more and (more := pull())):
                break
            data, at = pending[0]
            if at - first > COALESCE:
                break
            pending.popleft()
            buf += data
            due = max(due, at)
        while more and (not pending or pending[-1][1] - due < LOOKAHEAD) and clock() < start + due - SPARE:
            more = pull()
        sent += _flush(buf, write, start + due, clock, sleep, sent, on_write)
    return sent


def _flush(buf: bytearray, write, due: float, clock, sleep, offset: int, on_write) -> int:
    wait = due - clock()
    if wait > 0:
        sleep(wait)
    data = bytes(buf)
    buf.clear()
    view = memoryview(data)
    while view:
        n = write(view)
        if on_write is not None:
            on_write(offset, clock())
        n = len(view) if n is None else n
        view = view[n:]
        offset += n
    return len(data)


def open_port(port: str, baud: int):
    """A pyserial port for writing (a device, a pty's path, or a pyserial URL) at ``baud`` 8N1."""
    import serial

    return serial.serial_for_url(port, baudrate=baud, bytesize=serial.EIGHTBITS, parity=serial.PARITY_NONE,
                                 stopbits=serial.STOPBITS_ONE, xonxoff=False, rtscts=False, dsrdtr=False,
                                 write_timeout=5.0)
