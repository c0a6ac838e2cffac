"""8N1 UART bytes from a logic analyzer's samples (vectorised with numpy), and the bit rate the samples show."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Iterable, Iterator

import numpy as np

from ..protocol.chunks import FRAMING_ERROR, Marked
from ..protocol.wire import BAUD_RATES, BITS_PER_BYTE

# Rates a logic capture is matched against: table 4.7, then two faster ones the servos cannot run at
# but a user's other devices (or a --baud-any bus) may; a capture is no place to hold anyone to the table.
ANY_RATES: tuple[int, ...] = (460800, 921600)
CANDIDATE_RATES: tuple[int, ...] = BAUD_RATES + ANY_RATES

MIN_SAMPLES_PER_BIT = 3.0  # below this the bit centre cannot be told from the edges
_STOP_BIT = BITS_PER_BYTE - 1  # 0: start bit, 1-8: data (LSB first), 9: stop bit


@dataclass(frozen=True)
class UartBytes:
    """Bytes decoded from samples: values, the sample where each start bit began, and framing errors."""

    values: np.ndarray   # uint8
    starts: np.ndarray   # int64, absolute sample index of the first low sample of the start bit
    errors: np.ndarray   # bool, True where the stop bit was low

    def __len__(self) -> int:
        return len(self.values)


_EMPTY = UartBytes(np.zeros(0, np.uint8), np.zeros(0, np.int64), np.zeros(0, bool))


class UartDecoder:
    """A streaming 8N1 receiver over boolean samples (True = high; the line idles high).

    Like a UART: a frame starts at a falling edge, every bit is read at its centre (so one sample per
    bit decides, counted from the edge), a low stop bit is a framing error, and the next start bit
    is looked for only after the stop bit's centre. A start bit that is high again at its centre is
    a glitch and is skipped. Feed blocks of samples in order; the frame the block cuts is kept for the
    next block, so blocks may end anywhere. The edges are found with numpy and the bits of every frame
    of a block are read in one fancy-indexing step; only the walk from one frame to the next is a loop
    of integers (one step per byte).
    """

    def __init__(self, samplerate: float, baud: float) -> None:
        if not samplerate > 0 or not baud > 0:
            raise ValueError("the sample rate and the baud rate must be positive")
        self.samplerate = float(samplerate)
        self.baud = float(baud)
        self.bit = self.samplerate / self.baud
        if self.bit < MIN_SAMPLES_PER_BIT:
            raise ValueError(f"{self.samplerate:g} samples/s is too slow for {self.baud:g} bit/s "
                             f"({self.bit:.2f} samples per bit; at least {MIN_SAMPLES_PER_BIT:g} are needed)")
        # Offsets from the first low sample to each bit's centre: the edge lies half a sample before
        # that sample, so the centre of bit k is at edge + (k + 0.5) bits, rounded to a sample.
        self._offsets = np.floor((np.arange(BITS_PER_BYTE) + 0.5) * self.bit).astype(np.int64)
        self._stop = int(self._offsets[_STOP_BIT])
        self._tail = np.zeros(0, bool)
        self._base = 0          # absolute sample index of _tail[0]
        self._before = False    # the level before _tail[0]; False at the start: a capture that begins low
        # has no falling edge there, so a byte it cuts in half is not decoded as one
        self._resume = 0        # absolute index from which a falling edge may start a frame
        self.samples = 0        # samples fed so far
        self.low_samples = 0    # ... of which low (a line low most of the time is not an idle-high UART)

    def feed(self, block: np.ndarray, final: bool = False) -> UartBytes:
        """Decode ``block`` (the samples after the previous block); ``final`` ends the capture, dropping
        a frame it cuts short. Returns the bytes whose stop bit is in the samples fed so far."""
        block = np.asarray(block, dtype=bool)
        self.samples += len(block)
        self.low_samples += len(block) - int(np.count_nonzero(block))
        x = np.concatenate((self._tail, block)) if len(self._tail) else block
        base, n = self._base, len(x)
        if n == 0:
            return _EMPTY
        edges = np.flatnonzero(x[:-1] > x[1:]) + 1  # first low sample after a high one
        if self._before and not x[0]:
            edges = np.concatenate(([0], edges))
        lo = self._resume - base
        if lo > 0:
            edges = edges[np.searchsorted(edges, lo):]
        # Frames whose stop bit is in x can be read now; the rest wait for the next block.
        k = int(np.searchsorted(edges, n - self._stop))
        ready, pending = edges[:k], edges[k:]
        ready = ready[~x[ready + self._offsets[0]]]  # a start bit high again at its centre was a glitch
        end = max(lo, 0)  # where the next frame may start (relative to x)
        if len(ready):
            # Each frame's successor is the first edge after its stop bit's centre: one vectorised search,
            # then a walk along the chain from the first frame (edges inside a frame are skipped).
            following = np.searchsorted(ready, ready + self._stop + 1).tolist()
            chosen = []
            i, m = 0, len(ready)
            while i < m:
                chosen.append(i)
                i = following[i]
            starts = ready[chosen]
            end = int(starts[-1]) + self._stop + 1
            bits = x[starts[:, None] + self._offsets[None, :]]
            values = np.packbits(bits[:, 1:_STOP_BIT], axis=1, bitorder="little")[:, 0]
            out = UartBytes(values, starts.astype(np.int64) + base, ~bits[:, _STOP_BIT])
        else:
            out = _EMPTY
        if final:
            cut = n
        else:
            waiting = pending[np.searchsorted(pending, end):]
            cut = int(waiting[0]) if len(waiting) else n
        if cut > 0:
            self._before = bool(x[cut - 1])
        self._tail = x[cut:].copy() if cut < n else np.zeros(0, bool)
        self._base = base + cut
        self._resume = max(base + end, self._base)
        return out

    def close(self) -> UartBytes:
        """End of the capture: the bytes still held (none: a frame cut by the end is dropped)."""
        return self.feed(np.zeros(0, bool), final=True)


def decode(samples: np.ndarray, samplerate: float, baud: float) -> UartBytes:
    """Every 8N1 byte in a whole array of samples (True or 1 = high)."""
    dec = UartDecoder(samplerate, baud)
    return dec.feed(samples, final=True)


def encode(chunks: Iterable[tuple[bytes, float | None]], samplerate: float, baud: float, *,
           lead: float = 0.0, trail: float | None = None) -> np.ndarray:
    """The samples of a line carrying ``chunks`` as 8N1 (bytes of a chunk back to back from its time ``t``).

    The inverse of :class:`UartDecoder`, for tests, benchmarks and sample files: the line idles high,
    ``lead`` seconds come before the time origin and ``trail`` seconds (default: two byte times) after
    the last stop bit. Bits are placed at their exact times rounded to the nearest sample.
    """
    bit_s = 1.0 / baud
    byte_s = BITS_PER_BYTE * bit_s
    times: list[float] = []
    values = bytearray()
    t_next = 0.0
    for data, t in chunks:
        if not data:
            continue
        t0 = t_next if t is None else max(t, t_next)  # bytes cannot overlap on one wire
        times.extend(t0 + i * byte_s for i in range(len(data)))
        values += data
        t_next = t0 + len(data) * byte_s
    end_s = lead + t_next + (2 * byte_s if trail is None else trail)
    line = np.ones(int(math.ceil(end_s * samplerate)) + 1, dtype=bool)
    if not values:
        return line
    v = np.frombuffer(bytes(values), np.uint8)
    starts = lead + np.asarray(times)
    # Bit levels of every frame: start 0, data LSB first, stop 1.
    levels = np.zeros((len(v), BITS_PER_BYTE), dtype=bool)
    levels[:, 1:_STOP_BIT] = np.unpackbits(v[:, None], axis=1, bitorder="little")
    levels[:, _STOP_BIT] = True
    edges = np.rint((starts[:, None] + np.arange(BITS_PER_BYTE + 1)[None, :] * bit_s) * samplerate).astype(np.int64)
    lengths = np.diff(edges, axis=1).ravel()
    firsts = edges[:, :-1].ravel()
    total = int(lengths.sum())
    # Sample positions of every bit, run-length expanded: first sample of the bit plus 0..length-1.
    offsets = np.arange(total) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    line[np.repeat(firsts, lengths) + offsets] = np.repeat(levels.ravel(), lengths)
    return line


def chunks(found: UartBytes, samplerate: float, baud: float) -> Iterator[tuple[bytes, float]]:
    """Decoded bytes as chunks: runs of back-to-back bytes (each byte's start within half a bit of where
    the run's pace puts it, so no byte's time is off by more than that) as ``(bytes, t)``, and each byte
    with a framing error as its own :class:`Marked` chunk. ``t`` is the start bit's first sample, in seconds."""
    n = len(found)
    if not n:
        return
    values = found.values.tobytes()
    starts = found.starts.tolist()
    errors = found.errors.tolist()
    per_byte = BITS_PER_BYTE * samplerate / baud  # samples
    slack = 0.5 * samplerate / baud
    sr = float(samplerate)
    run_start = 0
    for i in range(n + 1):
        if i < n and i > run_start and not errors[i] and not errors[run_start] and \
                abs(starts[i] - starts[run_start] - (i - run_start) * per_byte) <= slack:
            continue
        if i > run_start:
            if errors[run_start]:
                yield Marked(values[run_start:i], starts[run_start] / sr, error=FRAMING_ERROR)
            else:
                yield values[run_start:i], starts[run_start] / sr
            run_start = i


# ---- the bit rate ---------------------------------------------------------------------------------
PULSE_PERCENTILE = 10   # of pulse widths: the shortest pulses are single bits, the shortest few may be noise
MIN_PULSES = 20         # edges needed before saying anything
CANDIDATE_SPAN = 1.5    # rates within this factor of the pulse-width estimate are tried


@dataclass(frozen=True)
class RateTry:
    """What decoding the samples at one rate gave."""

    baud: int
    bytes: int
    framing_errors: int
    frames: int        # checksum-valid RS30x frames (and ACK/NACK bytes after one)
    frame_bytes: int

    @property
    def valid_share(self) -> float:
        return self.frame_bytes / self.bytes if self.bytes else 0.0

    def describe(self) -> str:
        return f"{self.baud}: {self.frames} frames, {self.framing_errors} framing errors in {self.bytes} bytes"


@dataclass(frozen=True)
class BaudGuess:
    """The rate a logic capture was sent at (None: the samples do not tell), with its score in [0, 1]
    (the share of decoded bytes in checksum-valid frames) and why."""

    baud: int | None
    score: float
    evidence: str
    bit_samples: float | None = None
    tries: list[RateTry] = field(default_factory=list)

    def __bool__(self) -> bool:
        return self.baud is not None


def pulse_bit(samples: np.ndarray) -> tuple[float | None, int]:
    """Samples per bit read off the pulse widths (a low percentile, refined by the pulses near it), and
    how many pulses there were. None with fewer than MIN_PULSES."""
    x = np.asarray(samples, dtype=bool)
    if len(x) < 2:
        return None, 0
    changes = np.flatnonzero(x[1:] != x[:-1])
    widths = np.diff(changes)  # whole pulses only: the runs before the first and after the last change are cut
    if len(widths) < MIN_PULSES:
        return None, len(widths)
    low = float(np.percentile(widths, PULSE_PERCENTILE))
    # Single-bit pulses come out one sample longer or shorter as the edges fall between samples: the
    # mean of those near the percentile is a finer bit time than the percentile itself.
    near = widths[(widths >= low * 0.7) & (widths <= low * 1.3)]
    return (float(near.mean()) if len(near) else low), len(widths)


def estimate_baud(samples: np.ndarray, samplerate: float, rates: Iterable[int] = CANDIDATE_RATES) -> BaudGuess:
    """The rate of an 8N1 line from its samples: the bit time from the shortest pulses, then each nearby
    standard rate scored by decoding the samples at it (RS30x frames with good checksums, then the
    fewest framing errors, then the closest to the pulse widths)."""
    from ..decode.autobaud import score_bytes  # the same frame count the port scan uses

    x = np.asarray(samples, dtype=bool)
    bit, pulses = pulse_bit(x)
    if bit is None:
        return BaudGuess(None, 0.0, f"{pulses} pulses: too few to tell the rate")
    est = samplerate / bit
    near = [r for r in rates if abs(math.log(r / est)) <= math.log(CANDIDATE_SPAN)
            and samplerate / r >= MIN_SAMPLES_PER_BIT]
    if not near:
        nearest = min(rates, key=lambda r: abs(math.log(r / est)))
        if samplerate / nearest < MIN_SAMPLES_PER_BIT:
            return BaudGuess(None, 0.0, f"pulses of {bit:.1f} samples ({est:.0f} bit/s): the sample rate is too "
                                        f"low to decode {nearest} bit/s", bit)
        return BaudGuess(None, 0.0, f"pulses of {bit:.1f} samples ({est:.0f} bit/s): no standard rate within "
                                    f"a factor {CANDIDATE_SPAN:g}", bit)
    tries: list[RateTry] = []
    for r in near:
        got = decode(x, samplerate, r)
        s = score_bytes(got.values.tobytes(), r, 1.0)
        tries.append(RateTry(r, len(got), int(np.count_nonzero(got.errors)), s.frames, s.frame_bytes))

    def rank(t: RateTry) -> tuple:
        errs = t.framing_errors / t.bytes if t.bytes else 1.0
        return (t.frame_bytes, -errs, -abs(math.log(t.baud / est)))

    best = max(tries, key=rank)
    pulse = f"bits of {bit / samplerate * 1e6:.2f} us (the short pulses among {pulses})"
    tried = ", ".join(f"{t.baud}: {t.frames}" for t in tries)
    if best.frames:
        why = (f"{pulse}; {best.frames} valid frames and {best.framing_errors} framing errors in {best.bytes} bytes "
               f"at {best.baud} bit/s (valid frames at each rate tried: {tried})")
    else:
        why = (f"{pulse}; no valid RS30x frame at any rate tried ({', '.join(str(t.baud) for t in tries)}): "
               f"{best.baud} bit/s has the fewest framing errors ({best.framing_errors} in {best.bytes} bytes)")
    return BaudGuess(best.baud, round(best.valid_share, 3), why, bit, tries)
