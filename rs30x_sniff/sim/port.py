"""Play simulated chunks onto a port or pseudo-terminal in real time (the only sim module that may use pyserial)."""

from __future__ import annotations

import time
from typing import Callable, Iterable

Chunk = tuple[bytes, float]

# Chunks due within this much of each other go out in one write: fewer syscalls, and still far
# finer timing than a USB adapter's latency timer (1-16 ms) gives a real capture.
COALESCE = 0.0005


def play(chunks: Iterable[Chunk], write: Callable[[bytes], object], *, speed: float = 1.0,
         clock: Callable[[], float] = time.monotonic, sleep: Callable[[float], None] = time.sleep,
         on_write: Callable[[int, float], None] | None = None) -> int:
    """Write each chunk when its time comes (``t`` seconds after the start, divided by ``speed``).

    ``write`` takes bytes (``os.write`` on a pty, a pyserial port's ``write``). ``on_write(offset,
    wall_time)`` is told the stream offset of every write's first byte and when it was written
    (benchmarks use it). Returns the number of bytes written.
    """
    start = clock()
    sent = 0
    buf = bytearray()
    due = 0.0
    for data, t in chunks:
        target = start + t / speed
        if buf and target - due > COALESCE:
            sent += _flush(buf, write, due, clock, sleep, sent, on_write)
        if not buf:
            due = target
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
