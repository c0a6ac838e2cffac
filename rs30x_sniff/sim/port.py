"""Play simulated chunks onto a port or pseudo-terminal in real time (the only sim module that may use pyserial)."""

from __future__ import annotations

import time
from typing import Callable, Iterable

Chunk = tuple[bytes, float]

# Chunks due within this much of the first one held go out in one write: fewer syscalls, and still far
# finer timing than a USB adapter's latency timer (1-16 ms) gives a real capture. Well under the gap
# between a request's end and its reply's end (the reply's own bytes plus the servo's 100 us return delay,
# table 4.6 No. 7), so a reader can still tell the two apart.
COALESCE = 0.0005


def play(chunks: Iterable[Chunk], write: Callable[[bytes], object], *, speed: float = 1.0,
         byte_seconds: float = 0.0, clock: Callable[[], float] = time.monotonic,
         sleep: Callable[[float], None] = time.sleep, on_write: Callable[[int, float], None] | None = None) -> int:
    """Write each chunk when its time comes, ``(t + len(data) x byte_seconds) / speed`` seconds after the start.

    A chunk's ``t`` is its first byte's time on the line. Given ``byte_seconds`` (the line's byte time), a
    chunk is written when its last byte has been on the line, as a UART hands over a frame it has finished
    receiving: a reader that stamps bytes on arrival and lays them back at the line rate then finds each
    frame where it was. Without it, a chunk is written at its first byte's time.

    ``write`` takes bytes (``os.write`` on a pty, a pyserial port's ``write``). ``on_write(offset,
    wall_time)`` is told the stream offset of every write's first byte and when it was written
    (benchmarks use it). Returns the number of bytes written.
    """
    start = clock()
    sent = 0
    buf = bytearray()
    first = due = 0.0
    for data, t in chunks:
        target = start + (t + len(data) * byte_seconds) / speed
        if buf and target - first > COALESCE:
            sent += _flush(buf, write, due, clock, sleep, sent, on_write)
        if not buf:
            first = target
        due = max(due, target) if buf else target  # the group goes out when its last byte is due
        buf += data
    if buf:
        sent += _flush(buf, write, due, clock, sleep, sent, on_write)
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
