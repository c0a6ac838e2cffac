"""Re-times bytes sent at one baud rate into what a UART receiver set to another rate reads."""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Iterable, Iterator

from ..protocol.wire import BITS_PER_BYTE

Chunk = tuple[bytes, float]

# What a receiver does with a byte whose stop bit it samples low (a framing error):
KEEP = "keep"  # deliver the byte as sampled: what a microcontroller UART's data register holds
ZERO = "zero"  # deliver 0x00: what Linux's tty layer passes up without IGNPAR/PARMRK (pyserial's raw mode)
DROP = "drop"  # discard it (termios IGNPAR)
FRAMING_ERRORS = (KEEP, ZERO, DROP)

# Bit positions are computed from float times; a sample that lands exactly on a bit edge of the
# sender (rates in a 2:1 ratio do that) is read as the later bit, consistently.
_EPS = 1e-7


class _Line:
    """The sender's side: levels over time (idle high; 8N1 bytes back to back within each chunk)."""

    def __init__(self, chunks: Iterable[Chunk], baud: int) -> None:
        self._it = iter(chunks)
        self.bit = 1.0 / baud
        self.starts: list[float] = []
        self.ends: list[float] = []
        self.bits: list[bytes] = []  # per chunk: a leading idle 1, then every bit sent
        self.done = False

    def _pull(self) -> bool:
        for data, t in self._it:
            if not data:
                continue
            bits = bytearray(b"\x01")
            for b in data:
                # Start bit low, 8 data bits LSB first, stop bit high (8N1).
                bits.append(0)
                bits.extend((b >> i) & 1 for i in range(8))
                bits.append(1)
            self.starts.append(t)
            self.ends.append(t + len(data) * BITS_PER_BYTE * self.bit)
            self.bits.append(bytes(bits))
            return True
        self.done = True
        return False

    def known_until(self, t: float) -> None:
        """Pull chunks until one starts after ``t`` (or the input ends), so the line is known up to ``t``."""
        while not self.done and (not self.starts or self.starts[-1] <= t):
            if not self._pull():
                break

    def forget_before(self, t: float) -> None:
        k = bisect_right(self.ends, t) - 1
        if k > 0:
            del self.starts[:k], self.ends[:k], self.bits[:k]

    def level(self, t: float) -> int:
        self.known_until(t)
        k = bisect_right(self.starts, t) - 1
        if k < 0 or t >= self.ends[k]:
            return 1
        bits = self.bits[k]
        j = 1 + int((t - self.starts[k]) / self.bit + _EPS)
        return bits[j] if j < len(bits) else 1

    def next_fall(self, after: float) -> float | None:
        """Time of the first falling edge at or after ``after``; None when the input is exhausted."""
        self.known_until(after)
        k = max(0, bisect_right(self.starts, after) - 1)
        while True:
            while k >= len(self.starts):
                if not self._pull():
                    return None
            s, bits = self.starts[k], self.bits[k]
            # Index j in bits is bit j-1 of the chunk; an edge at bits[j:j+2] == 1,0 is at s + j * bit.
            j0 = max(0, int((after - s) / self.bit - _EPS)) if after > s else 0
            while True:
                j = bits.find(b"\x01\x00", j0)
                if j < 0:
                    break
                te = s + j * self.bit
                if te >= after - _EPS * self.bit:
                    return te
                j0 = j + 1
            k += 1
            self.known_until(self.ends[k - 1])


def retime(chunks: Iterable[Chunk], sent_baud: int, read_baud: int, *,
           framing_error: str = KEEP) -> Iterator[Chunk]:
    """What a UART at ``read_baud`` reads from a line carrying ``chunks`` sent at ``sent_baud``.

    ``chunks`` are ``(bytes, t)`` with the bytes back to back from ``t`` (as the simulator and the
    tap give them). The receiver waits for a falling edge, checks the start bit half a bit later
    (still high: a glitch, ignored), samples the 8 data bits and the stop bit at their centres, then
    waits for the next falling edge. A low stop bit is a framing error, handled per ``framing_error``
    (``keep``, the default: the byte as sampled). Output chunks hold bytes read back to back (each
    starting 10 bit times after the previous), stamped with the falling edge of their first byte.
    """
    if framing_error not in FRAMING_ERRORS:
        raise ValueError(f"framing_error must be one of {', '.join(FRAMING_ERRORS)}")
    line = _Line(chunks, sent_baud)
    bit = 1.0 / read_baud
    frame_time = BITS_PER_BYTE * bit
    out = bytearray()
    out_t = 0.0
    next_t = None  # where a byte must start to continue the current output chunk
    t = float("-inf")
    while True:
        fall = line.next_fall(t)
        if fall is None:
            break
        line.forget_before(fall)
        if line.level(fall + 0.5 * bit):
            t = fall + 0.5 * bit  # a glitch shorter than half a bit: not a start bit
            continue
        value = 0
        for i in range(8):
            value |= line.level(fall + (1.5 + i) * bit) << i
        stop_at = fall + 9.5 * bit
        ok = line.level(stop_at)
        t = stop_at  # the receiver looks for the next start bit after sampling the stop bit
        if not ok:
            if framing_error == DROP:
                continue
            if framing_error == ZERO:
                value = 0
        if next_t is not None and abs(fall - next_t) <= 1e-6 * bit:
            out.append(value)
        else:
            if out:
                yield bytes(out), out_t
            out = bytearray((value,))
            out_t = fall
        next_t = fall + frame_time
    if out:
        yield bytes(out), out_t


class SimWire:
    """A simulated bus line whose bytes depend on the receiver's rate: a stand-in for a port.

    ``read_for(baud, seconds)`` returns what a receiver at ``baud`` reads during the next ``seconds``
    of simulated time (then the clock moves on), like reopening a real port at each rate. The line
    carries ``source`` chunks sent at ``line_baud``; call :meth:`set_line` to change the line's rate
    mid-session (a baud change written to the servos).
    """

    def __init__(self, source: Iterable[Chunk], line_baud: int, *, start: float = 0.0) -> None:
        self.line_baud = line_baud
        self._src = iter(source)
        self._buf: list[Chunk] = []
        self.t = start
        self.reads: list[tuple[int, float, int]] = []  # (baud, seconds, bytes) per read

    def set_line(self, source: Iterable[Chunk], line_baud: int) -> None:
        """From now on the line carries ``source`` at ``line_baud`` (its chunks before now are skipped)."""
        self._src = iter(source)
        self._buf = []
        self.line_baud = line_baud

    def _window(self, t0: float, t1: float) -> list[Chunk]:
        while not self._buf or self._buf[-1][1] < t1:
            nxt = next(self._src, None)
            if nxt is None:
                break
            self._buf.append(nxt)
        bt = BITS_PER_BYTE / self.line_baud
        self._buf = [c for c in self._buf if c[1] + len(c[0]) * bt > t0]
        return [c for c in self._buf if c[1] < t1]

    def read_chunks(self, baud: int, seconds: float) -> list[Chunk]:
        """The chunks a receiver at ``baud`` reads in the next ``seconds`` (bytes whose start bit falls in it)."""
        t0, t1 = self.t, self.t + seconds
        self.t = t1
        line = self._window(t0, t1)
        got = [(d, t) for d, t in retime(line, self.line_baud, baud) if t0 <= t < t1]
        self.reads.append((baud, seconds, sum(len(d) for d, _ in got)))
        return got

    def read_for(self, baud: int, seconds: float) -> bytes:
        """The bytes a receiver at ``baud`` reads in the next ``seconds`` of simulated time."""
        return b"".join(d for d, _ in self.read_chunks(baud, seconds))
