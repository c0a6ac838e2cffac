"""Sans-IO resynchronizing frame decoder: feed(bytes, t) -> events; never reads a clock, port or file."""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass
from functools import reduce
from operator import xor
from typing import cast

import numpy as np

from .frame_runs import FrameRun
from .framing_kernel import scan_regular_arrays
from ..protocol.events import (
    BAD_HEADER, CAPTURE_END, CAPTURE_START, FLAG, NOISE, TRUNCATED, Ack, AnyEvent, Garbage, Nack, ShortPacket,
    frame_event)
from ..protocol.wire import (
    ACK, AT_COUNT, AT_FLAG, AT_ID, AT_LENGTH, DEFAULT_BAUD, FLAG_WANTS_ACK, FRAME_OVERHEAD, HEADER_SIZE,
    LONG_PACKET_ID, NACK, REQUEST_FIRST, REQUEST_HEADER, RETURN_FIRST, RETURN_HEADER, SUM_SIZE, byte_time)

_FA, _AF = REQUEST_HEADER  # FA AF: a request (short or long packet)
_FD, _DF = RETURN_HEADER   # FD DF: a return packet

# A header claiming more data than this is noise, not a frame: the whole memory map is 140 bytes,
# and even a long packet to 24 servos of 30 registers each stays under 800.
DEFAULT_MAX_DATA = 1024
# An idle line longer than this many byte times inside a frame means the sender stopped mid-frame.
DEFAULT_GAP_BYTES = 20.0
# A run of garbage is handed out in pieces of this many bytes, counted from the run's first byte (so the
# pieces do not depend on chunking): a bus read at the wrong baud rate is all garbage and has neither
# frames nor idle gaps to end a run, and a live display must show it within a second or two.
GARBAGE_PIECE = 128

# The numpy kernel is tried on windows of this many buffered bytes (growing while runs fill them); a
# window holds at least a few frames, so a per-frame chunk never pays for a kernel call.
_KERNEL_MIN, _KERNEL_START, _KERNEL_MAX = 256, 4096, 1 << 16
# In run mode (FrameRun out, for whole files) windows grow larger, and an irregularity rests the kernel
# only for a few frames: the columnar path behind it is worth a retry much more than a few events.
_RUNS_MAX, _RUNS_REST = 1 << 20, 256

# Faults of a capture's clock (the bytes themselves may be fine): a chunk stamped before the previous
# one, or after it but before its bytes could have gone over the wire at the baud rate.
TIME_BACKWARDS = "backwards"
TIME_TOO_CLOSE = "too-close"

# Seams of a capture's clock, where a new time segment begins: times that jump back by more than
# SEAM_BACK (two captures joined, a logger restarted: more than any jitter of a USB adapter's stamps),
# or forward by more than SEAM_GAP of idle line (a capture resumed; a polling host is never that quiet).
# Nothing is paired, timed or counted across a seam (Seam).
SEAM_RESTART = "restart"
SEAM_GAP = "gap"
SEAM_SOURCE = "source"  # the source says its bytes stopped here (a port lost and reopened): Decoder.mark_gap
SEAM_BACK_S = 0.010
SEAM_GAP_S = 10.0


@dataclass(frozen=True)
class Seam:
    """Where a capture's clock restarts or resumes: a new time segment begins at stream ``offset``."""

    offset: int                 # stream offset of the new segment's first byte
    kind: str                   # SEAM_RESTART, SEAM_GAP or SEAM_SOURCE
    t_end: float | None         # end of the last byte before the seam (None: that segment had no time)
    t_start: float              # the new segment's first time
    note: str = ""              # SEAM_SOURCE: what the source said of its gap (a port re-plugged)
    # What the linter says of a seam (F010) is rs30x_sniff.lint.rules.timebase's.


@dataclass
class TimeFault:
    """The first time a capture's clock broke one way, and how often it did."""

    kind: str
    offset: int          # stream offset of the chunk's first byte
    t: float             # the time the chunk was stamped with
    earliest: float      # the earliest time its first byte could have started (the previous one's end)
    placed: float        # the time it was given instead (no earlier than the previous chunk's)
    count: int = 1


# Garbage reasons that, before a segment's first frame, mean the capture cut a frame (CAPTURE_START);
# bytes the capturing UART flagged keep their own reason.
_CUT_BY_START = (NOISE, TRUNCATED, BAD_HEADER)
_HEADERS = (REQUEST_HEADER, RETURN_HEADER)
_SYNC = len(REQUEST_HEADER)  # the two header bytes a frame starts with

# Results of FrameDecoder._frame_end besides an end index.
_WAIT = -1      # cannot decide yet: more bytes are needed
_NOT_SYNC = -2  # no frame header here
_BAD = -3       # a header whose length cannot be a real frame
_CUT = -4       # _CUT - k: the frame is cut short at buffer index k


class FrameDecoder:
    """Turns a byte stream into events; every byte lands in exactly one event.

    Call :meth:`feed` with each chunk as it arrives (``t`` is the capture time of the chunk's first
    byte, or None) and :meth:`close` at the end of input. The events do not depend on how the input
    was split into chunks, as long as the timestamps agree (later bytes of a chunk are placed one
    byte time apart at ``baud``).
    """

    def __init__(self, baud: int = DEFAULT_BAUD, gap_bytes: float | None = DEFAULT_GAP_BYTES,
                 max_data: int = DEFAULT_MAX_DATA, kernel: bool = True, runs: bool = False) -> None:
        self.baud = baud
        self.byte_time = byte_time(baud)
        self.gap_bytes = gap_bytes
        self.max_data = max_data
        self._buf = bytearray()
        self._base = 0          # stream offset of _buf[0]
        self._scan = 0          # index in _buf where scanning resumes; _buf[:_scan] is pending garbage
        self._garbage_reason = NOISE
        self._ack_pending = False
        # Chunk start offsets and their times, for byte times and gap detection.
        self._chunk_offsets: list[int] = []
        self._chunk_times: list[float | None] = []
        self._breaks: list[int] = []  # stream offsets preceded by an idle gap, ascending
        self._last_t: float | None = None  # start time of the last byte fed so far
        self._chunk_t: float | None = None  # the time the last timed chunk was stamped with
        self._start_t: float | None = None  # ... and the time it was placed at (no earlier than the one before)
        # Times that went backwards or came too close are kept here (first place and count) and the
        # clock is held monotonic: a later chunk starts no earlier than the previous one ended, so no
        # latency is ever negative (the linter reports these as F005/F006).
        self.time_faults: dict[str, TimeFault] = {}
        self.seams: list[Seam] = []  # every seam so far, in stream order
        self._source_gap: str | None = None  # mark_gap's note, for the next timed chunk's seam
        # Until the first frame of the input (or of a time segment), garbage is the tail of a frame
        # whose start came before the capture did (CAPTURE_START), unless it runs on for longer than
        # any frame: then it is what it looks like.
        self._lead = True
        self._seg_start = 0
        self._lead_max = FRAME_OVERHEAD + max_data
        self._final = False
        self.closed = False
        # The numpy kernel (rs30x_sniff.decode.framing_kernel) for long clean runs; kernel=False is the plain
        # state machine, which the differential tests compare it with.
        self.kernel = kernel or runs
        # runs=True: the kernel's runs come out as one FrameRun each instead of an event per frame (the
        # columnar path: rs30x_sniff.decode.frame_runs); every other byte still becomes an event.
        self.runs = runs
        self._kernel_window = _KERNEL_START
        self._kernel_rest = 0  # stream offset before which the kernel is not tried again

    @property
    def offset(self) -> int:
        """Stream offset of the next byte to be fed."""
        return self._base + len(self._buf)

    @property
    def end_time(self) -> float | None:
        """When the last byte fed so far ended (None without timestamps)."""
        return None if self._last_t is None else self._last_t + self.byte_time

    # ---- seams -------------------------------------------------------------------------------
    def mark_gap(self, note: str) -> None:
        """The source lost bytes here (a port that went away and came back): the next timed chunk opens a
        seam (SEAM_SOURCE, said with ``note``) however short the silence was, so nothing pairs across it."""
        if self._chunk_t is not None:  # no byte before the gap: nothing to part from
            self._source_gap = note

    def _seam_kind(self, t: float) -> str | None:
        """The seam a chunk stamped ``t`` opens, if any (the previous chunk had a time)."""
        if self._source_gap is not None:
            return SEAM_SOURCE
        if t < cast(float, self._chunk_t) - SEAM_BACK_S:  # callers test _chunk_t first
            return SEAM_RESTART
        if self._last_t is not None and t - self._last_t > SEAM_GAP_S:
            return SEAM_GAP
        return None

    def _cut_at_seam(self, t: float) -> list[AnyEvent]:
        """If a chunk stamped ``t`` opens a seam, end the current time segment before it: what is pending
        becomes events (a frame the seam cuts is CAPTURE_END), and the clock starts afresh with that
        chunk. The events ended (none without a seam)."""
        kind = self._seam_kind(t)
        if kind is None:
            return []
        out = self._parse(final=True, ended=True)
        self.seams.append(Seam(self.offset, kind, self.end_time, t, self._source_gap or ""))
        self._source_gap = None
        self._last_t = self._chunk_t = self._start_t = None
        self._lead = True
        self._seg_start = self.offset
        return out

    # ---- input -------------------------------------------------------------------------------
    def feed(self, data: bytes, t: float | None = None) -> list[AnyEvent]:
        """Add bytes (their first byte seen at capture time ``t``); return the events now decided."""
        if self.closed:
            raise RuntimeError("feed() after close()")
        if not data:
            return []
        out = self._cut_at_seam(t) if t is not None and self._chunk_t is not None else None
        self._add(data, t)
        return out + self._parse(final=False) if out else self._parse(final=False)

    def feed_many(self, chunks: list[tuple[bytes, float | None]]) -> list:
        """Add several chunks, then decode once: the events (and, in run mode, FrameRuns) they decide.

        The same as feeding them one by one, but the kernel sees them as one buffer, and a clean
        stretch of timestamped chunks is placed in time with a few array operations.
        """
        if self.closed:
            raise RuntimeError("feed_many() after close()")
        datas = [c[0] for c in chunks]
        lens = list(map(len, datas))
        if 0 in lens:
            chunks = [c for c in chunks if c[0]]
            datas = [c[0] for c in chunks]
            lens = list(map(len, datas))
        if not chunks:
            return []
        out: list = []
        if not (len(chunks) > 8 and self._add_many(chunks, datas, lens)):
            for data, t in chunks:
                if t is not None and self._chunk_t is not None:
                    out += self._cut_at_seam(t)
                self._add(data, t)
        return out + self._parse(final=False) if out else self._parse(final=False)

    def _add_many(self, chunks: list[tuple[bytes, float | None]], datas: list[bytes], sizes: list[int]) -> bool:
        """:meth:`_add` for a list of chunks at once, when all are timestamped and the clock keeps pace
        (no time fault); False, having changed nothing, otherwise. Same floating-point operations in
        the same order as ``_add``, so every time is bit-identical."""
        times = [c[1] for c in chunks]
        if None in times or self._source_gap is not None:
            return False
        bt = self.byte_time
        lens = np.array(sizes, dtype=np.int64)
        ts = np.array(times, dtype=np.float64)
        last = ts + (lens - 1) * bt              # _last_t after each chunk
        prev = np.empty_like(ts)
        prev[1:] = last[:-1]
        prev[0] = np.nan if self._last_t is None else self._last_t
        if (ts < (prev + bt) - bt / 4).any():    # a clock fault or a restart somewhere: placed one by one
            return False
        if (ts - prev > SEAM_GAP_S).any():       # a seam: the segment ends there
            return False
        offsets = self.offset + np.cumsum(lens) - lens
        if self.gap_bytes is not None:
            idle = ts - prev - bt
            self._breaks += offsets[idle > self.gap_bytes * bt].tolist()
        self._chunk_offsets += offsets.tolist()
        self._chunk_times += times
        self._last_t = float(last[-1])
        self._chunk_t = self._start_t = times[-1]
        self._buf += b"".join(datas)
        return True

    def feed_fault(self, data: bytes, t: float | None, reason: str) -> list[AnyEvent]:
        """Add bytes the capturing UART flagged (``reason``: a framing or parity error, rs30x_sniff.protocol.chunks).

        Their values cannot be trusted, so no frame is made of them: whatever was pending ends here as
        if the input had (a frame in progress is cut short), and the flagged bytes become garbage with
        ``reason``, in pieces of at most GARBAGE_PIECE bytes. Returns those events.
        """
        if self.closed:
            raise RuntimeError("feed_fault() after close()")
        if not data:
            return []
        out = self._parse(final=True)  # leaves the buffer empty
        if t is not None and self._chunk_t is not None:
            out += self._cut_at_seam(t)
        self._add(data, t)
        self._start = 0
        while self._start < len(data):
            self._garbage_reason = reason
            self._emit_garbage(out, min(self._start + GARBAGE_PIECE, len(data)))
        del self._buf[:]
        self._base += len(data)
        self._scan = 0
        return out

    def _add(self, data: bytes, t: float | None) -> None:
        """Append a chunk to the buffer, placing it in time (clock faults held monotonic, idle gaps noted)."""
        start = self.offset
        stamped = t
        if t is not None and self._last_t is not None:
            earliest = self._last_t + self.byte_time
            if t < earliest - self.byte_time / 4:  # a quarter byte of slack for rounded timestamps
                # the three clocks are set together (below and in feed_many): typed here, not tested
                chunk_t, start_t = cast(float, self._chunk_t), cast(float, self._start_t)
                # Backwards: stamped before the previous chunk's own stamp (not its corrected time).
                kind = TIME_BACKWARDS if t < chunk_t else TIME_TOO_CLOSE
                # Held at the previous chunk's start, not pushed past its last byte: at a wrong baud rate
                # every chunk comes "too close", and pushing each one on would run the clock ahead of the
                # capture without bound (a 6 s recording stamped as 31.8 s). Latencies never go below 0.
                placed = start_t if t < start_t else t
                fault = self.time_faults.get(kind)
                if fault is None:
                    self.time_faults[kind] = TimeFault(kind, start, t, earliest, placed)
                else:
                    fault.count += 1
                t = placed
        if stamped is not None:
            self._chunk_t = stamped
            self._start_t = t
        if t is not None or self._chunk_times:
            if t is not None and self._last_t is not None and self.gap_bytes is not None:
                idle = t - self._last_t - self.byte_time
                if idle > self.gap_bytes * self.byte_time:
                    self._breaks.append(start)
            self._chunk_offsets.append(start)
            self._chunk_times.append(t)
            self._last_t = None if t is None else t + (len(data) - 1) * self.byte_time
        self._buf += data

    def close(self) -> list[AnyEvent]:
        """End of input: whatever is still pending becomes truncated frames or garbage."""
        if self.closed:
            return []
        events = self._parse(final=True, ended=True)
        self.closed = True
        return events

    # ---- times -------------------------------------------------------------------------------
    def time_of(self, offset: int) -> float | None:
        """Capture time of the byte at stream ``offset`` (None without timestamps)."""
        offs = self._chunk_offsets
        if not offs:
            return None
        k = bisect_right(offs, offset) - 1
        if k < 0:
            return None
        t = self._chunk_times[k]
        return None if t is None else t + (offset - offs[k]) * self.byte_time

    def _times(self, start: int, end: int) -> tuple[float | None, float | None]:
        if not self._chunk_offsets:
            return None, None
        t0 = self.time_of(start)
        t1 = self.time_of(end - 1)
        return t0, (None if t1 is None else t1 + self.byte_time)

    def _next_break(self, after: int, before: int) -> int | None:
        """First gap break offset b with after < b < before, if any."""
        br = self._breaks
        if not br:
            return None
        k = bisect_right(br, after)
        if k < len(br) and br[k] < before:
            return br[k]
        return None

    # ---- parsing -----------------------------------------------------------------------------
    def _frame_end(self, i: int, final: bool) -> int:
        """Classify a candidate frame at buffer index i (which holds FA or FD).

        Returns the buffer index one past the frame when it is all here, or one of: ``_WAIT`` (more
        bytes are needed to know), ``_NOT_SYNC`` (no header here), ``_BAD`` (a header whose length is
        implausible), or ``_CUT - k``: the frame is cut short at buffer index k (an idle gap inside it,
        or the end of input).
        """
        buf = self._buf
        n = len(buf)
        if i + 1 >= n:
            return _CUT - n if final else _WAIT
        first = buf[i]
        second = buf[i + 1]
        if not ((first == _FA and second == _AF) or (first == _FD and second == _DF)):
            return _NOT_SYNC
        base = self._base
        if self._breaks:
            # An idle gap inside the header cuts the frame before its length means anything.
            cut = self._next_break(base + i, base + min(i + HEADER_SIZE, n))
            if cut is not None:
                return _CUT - (cut - base)
        if i + HEADER_SIZE > n:
            return _CUT - n if final else _WAIT
        length = buf[i + AT_LENGTH]
        # Data bytes = Length x Count for requests, Length for returns ("Format of Packets").
        data_len = length * buf[i + AT_COUNT] if first == _FA else length
        if data_len > self.max_data:
            return _BAD
        end = i + FRAME_OVERHEAD + data_len
        if self._breaks:
            cut = self._next_break(base + i, base + min(end, n))
            if cut is not None:
                return _CUT - (cut - base)
        if end > n:
            return _CUT - n if final else _WAIT
        return end

    def _intact(self, i: int, final: bool) -> int:
        """Buffer index past an intact (complete, checksum-valid) frame at i; _NOT_SYNC if none; _WAIT."""
        end = self._frame_end(i, final)
        if end < 0:
            return _WAIT if end == _WAIT else _NOT_SYNC
        buf = self._buf
        last = end - SUM_SIZE
        return end if reduce(xor, buf[i + AT_ID:last], 0) == buf[last] else _NOT_SYNC

    def _find_intact_inside(self, i: int, end: int, final: bool) -> int:
        """Index of the first intact frame starting in (i, end); _NOT_SYNC if none; _WAIT if undecidable."""
        buf = self._buf
        j = i + 1
        while True:
            a = buf.find(REQUEST_HEADER, j, end + 1)
            b = buf.find(RETURN_HEADER, j, end + 1)
            if a >= end:
                a = -1
            if b >= end:
                b = -1
            if a < 0 and b < 0:
                # A sync byte in the last place may start a frame whose second byte is still to come.
                if end == len(buf) and not final and buf[end - 1] in (_FA, _FD):
                    return _WAIT
                return _NOT_SYNC
            q = a if b < 0 or 0 <= a < b else b
            r = self._intact(q, final)
            if r == _WAIT:
                return _WAIT
            if r >= 0:
                return q
            j = q + 1

    def _leading(self, i: int) -> bool:
        """Whether garbage up to buffer index ``i`` may still be the tail of a frame cut by the start."""
        if self._base + i - self._seg_start < self._lead_max:
            return True
        self._lead = False  # longer than any frame: no tail of one
        return False

    def _parse(self, final: bool, ended: bool = False) -> list[AnyEvent]:
        """Events from the buffer; ``final``: nothing more comes before them (the end of input or of a
        time segment when ``ended``, else bytes the UART flagged), so partial frames are cut.

        One pass from the scan position, each step by what the byte there is: a run of clean frames (the
        numpy kernel), an intact frame (inline: the hottest code of the product), any other header
        (:meth:`_at_header`: cut, corrupt or still coming), the ACK/NACK byte a request asked for, or
        garbage up to the next header or idle gap (:meth:`_skip`); then what is in events leaves the buffer."""
        out: list[AnyEvent] = []
        buf = self._buf
        n = len(buf)
        self._start = 0   # buffer index of the first byte not yet in an event
        self._final = final
        i = self._scan
        kernel = self.kernel
        # The packet layout (protocol.wire) as locals for the intact frame's test below.
        at_id, at_length, at_count, header_size, overhead = AT_ID, AT_LENGTH, AT_COUNT, HEADER_SIZE, FRAME_OVERHEAD
        while i < n:
            # [start, i) is garbage already: handed out in pieces (the leading tail of a frame whole).
            while i - self._start >= GARBAGE_PIECE and not (self._lead and self._leading(i)):
                self._emit_garbage(out, self._start + GARBAGE_PIECE)
            start = self._start
            br = self._breaks
            if br and self._at_break(out, i):
                continue
            if i == start and n - i >= _KERNEL_MIN and kernel and not self._ack_pending \
                    and self._base + i >= self._kernel_rest:
                j = self._run_kernel(out, i)
                if j > i:
                    i = j
                    continue
            c = buf[i]
            if self._ack_pending and self._at_ack(out, i, c):
                i += 1
                continue
            if c == _FA or c == _FD:
                # An intact frame right here, with no idle gap to consider.
                if not br and i + header_size <= n and buf[i + 1] == (_AF if c == _FA else _DF):
                    length = buf[i + at_length]
                    size = length * buf[i + at_count] if c == _FA else length
                    end = i + overhead + size
                    last = end - 1  # the Sum (SUM_SIZE)
                    if end <= n and size <= self.max_data and reduce(xor, buf[i + at_id:last], 0) == buf[last]:
                        if i > start:
                            self._emit_garbage(out, i)
                        self._emit_frame(out, end, True)
                        i = end
                        continue
                j = self._at_header(out, i, final, ended)
                if j == _WAIT:
                    break  # the scan resumes at this header when more bytes come
                i = j
                continue
            i = self._skip(i)
        # The pass's end, inline: it runs once per feed, a frame's worth of work on a port read frame by frame.
        while i - self._start >= GARBAGE_PIECE and not (self._lead and self._leading(i)):
            self._emit_garbage(out, self._start + GARBAGE_PIECE)
        if final and n > self._start:
            self._emit_garbage(out, n)
            i = n
        # Drop what is now in events; keep pending garbage and any partial frame.
        start = self._start
        if start:
            del buf[:start]
            self._base += start
            i -= start
        self._scan = i
        self._trim_chunks()
        return out

    def _at_break(self, out: list[AnyEvent], i: int) -> bool:
        """Drop the idle gaps behind the events; True when one falls at ``i`` and ends the garbage before it
        (garbage runs end at idle gaps, so a live display sees them promptly)."""
        br = self._breaks
        at = self._base + self._start
        while br and br[0] <= at:
            br.pop(0)
        if i > self._start and br and br[0] == self._base + i:
            self._emit_garbage(out, i)
            return True
        return False

    def _at_ack(self, out: list[AnyEvent], i: int, c: int) -> bool:
        """The byte right after a request that asked for an ACK (return mode 0001, table 4.3): True when it
        is that ACK or NACK (handed out); it has no header, so no other byte is one."""
        self._ack_pending = False
        if i == self._start and (c == ACK or c == NACK):
            self._emit_single(out, Ack if c == ACK else Nack)
            return True
        return False

    def _at_header(self, out: list[AnyEvent], i: int, final: bool, ended: bool) -> int:
        """A header at ``i`` that is not an intact frame here and now: where the scan goes on, or _WAIT
        (more bytes are needed to tell).

        Not a header after all, or one whose length is implausible: one byte on. Cut short (an idle gap or
        the end) or corrupt with an intact frame starting inside it: the head is garbage, up to that frame.
        Corrupt with none inside: a frame with a bad Sum."""
        buf = self._buf
        start = self._start
        end = self._frame_end(i, final)
        if end == _WAIT:
            return _WAIT
        if end == _NOT_SYNC or end == _BAD:
            if end == _BAD:
                self._garbage_reason = BAD_HEADER
            return i + 1
        ok = end >= 0 and reduce(xor, buf[i + AT_ID:end - SUM_SIZE], 0) == buf[end - SUM_SIZE]
        if not ok:
            stop = end if end >= 0 else _CUT - end
            q = self._find_intact_inside(i, stop, final)
            if q == _WAIT:
                return _WAIT
            if q >= 0 or end < 0:
                if i > start:
                    self._emit_garbage(out, i)
                self._garbage_reason = CAPTURE_END if ended and q < 0 and stop == len(buf) else TRUNCATED
                i = q if q >= 0 else stop
                self._emit_garbage(out, i)
                return i
        if i > start:
            self._emit_garbage(out, i)
        self._emit_frame(out, end, ok)
        return end

    def _skip(self, i: int) -> int:
        """Past a byte that starts no frame: the next possible header (FA or FD), or the next idle gap if
        sooner, or the end of the buffer."""
        buf = self._buf
        a = buf.find(REQUEST_FIRST, i + 1)
        b = buf.find(RETURN_FIRST, i + 1)
        nxt = len(buf) if a < 0 else a
        if 0 <= b < nxt:
            nxt = b
        if self._breaks:
            base = self._base
            gap = self._next_break(base + i, base + nxt)
            if gap is not None:
                nxt = gap - base
        return nxt

    # ---- emitting ----------------------------------------------------------------------------
    def _take(self, end: int) -> tuple[int, bytes, float | None, float | None]:
        start = self._start
        off = self._base + start
        raw = bytes(self._buf[start:end])
        self._start = end
        if self._chunk_offsets:
            t0, t1 = self._times(off, off + end - start)
        else:
            t0 = t1 = None
        return off, raw, t0, t1

    def _trim_chunks(self) -> None:
        offs = self._chunk_offsets
        if len(offs) > 64:
            k = bisect_right(offs, self._base) - 1
            if k > 0:
                del offs[:k]
                del self._chunk_times[:k]

    def _emit_single(self, out: list[AnyEvent], cls: type) -> None:
        self._lead = False
        off, raw, t0, t1 = self._take(self._start + 1)
        out.append(tuple.__new__(cls, (off, raw, t0, t1)))

    def _emit_garbage(self, out: list[AnyEvent], end: int) -> None:
        reason = self._garbage_reason
        if self._lead and reason in _CUT_BY_START:
            if self._base + self._start == self._seg_start and self._buf[self._start:self._start + _SYNC] in _HEADERS:
                self._lead = False  # the segment starts with a header: no frame was cut by its start
            elif not (self._final and end == len(self._buf)):
                # Before the segment's first frame: the tail of a frame that began before the capture
                # did (not when nothing but garbage reaches the end: a segment with no frame is what it
                # looks like).
                reason = CAPTURE_START
        off, raw, t0, t1 = self._take(end)
        out.append(tuple.__new__(Garbage, (off, raw, t0, t1, reason)))
        self._garbage_reason = NOISE
        self._ack_pending = False

    def _emit_frame(self, out: list[AnyEvent], end: int, ok: bool) -> None:
        self._lead = False
        off, raw, t0, t1 = self._take(end)
        ev = frame_event(off, raw, t0, t1, ok)
        out.append(ev)
        # Only the byte right after a request in return mode 0001 may be its ACK/NACK (table 4.3).
        self._ack_pending = type(ev) is ShortPacket and FLAG_WANTS_ACK[raw[AT_FLAG]]

    def _run_kernel(self, out: list[AnyEvent], i: int) -> int:
        """At a clean boundary (nothing pending, no idle gap, no ACK due): emit the run of back-to-back
        intact frames the numpy kernel finds from buffer index i; returns where the run stopped.

        The kernel takes exactly the frames the state machine's fast path would, so the events are the
        same either way; the window grows while runs fill it and shrinks (and rests a while) when they
        do not, so noisy input pays little for the attempts.
        """
        window = self._kernel_window
        starts, ends, more = scan_regular_arrays(bytes(self._buf[i:i + window]), self.max_data)
        base = self._base + i
        if self._breaks and len(starts):
            # An idle gap strictly inside a frame cuts it (_frame_end): the run stops before that frame.
            br = np.array(self._breaks, dtype=np.int64)
            k = np.searchsorted(br, base + starts, side="right")
            inside = np.flatnonzero((k < len(br)) & (br[np.minimum(k, len(br) - 1)] < base + ends))
            if inside.size:
                starts, ends, more = starts[:inside[0]], ends[:inside[0]], False
        covered = int(ends[-1]) if len(ends) else 0
        if not more:
            # An irregularity: let the state machine have the next stretch before trying again.
            self._kernel_window = max(window // 2, _KERNEL_MIN)
            rest = _RUNS_REST if self.runs else 4 * self._kernel_window
            self._kernel_rest = base + covered + rest
        elif covered * 2 >= window:
            self._kernel_window = min(window * 2, _RUNS_MAX if self.runs else _KERNEL_MAX)
        if not len(ends):
            return i
        self._lead = False
        blob = bytes(self._buf[i:i + covered])
        self._start = i + covered
        times = self._run_times(base, starts, ends) if self.runs else None
        if times is not None:
            # Run mode only: its callers (feed_many's run readers) take FrameRuns among the events.
            cast("list[AnyEvent | FrameRun]", out).append(FrameRun(base, blob, starts, ends, *times))
            s = int(starts[-1])
            self._ack_pending = (blob[s] == _FA and blob[s + AT_ID] != LONG_PACKET_ID
                                 and FLAG_WANTS_ACK[blob[s + AT_FLAG]])
            return i + covered
        starts, ends = starts.tolist(), ends.tolist()
        timed = bool(self._chunk_offsets)
        times = self._times
        event = frame_event
        append = out.append
        t0 = t1 = None
        for s, e in zip(starts, ends):
            off = base + s
            if timed:
                t0, t1 = times(off, base + e)
            append(event(off, blob[s:e], t0, t1, True))
        last = out[-1]
        self._ack_pending = type(last) is ShortPacket and FLAG_WANTS_ACK[last[FLAG]]
        return i + covered

    def _run_times(self, base: int, starts: np.ndarray, ends: np.ndarray):
        """Each frame's (t_start, t_end) as :meth:`_times` gives them, for a whole run at once (the
        same operations in the same order, so the same floats): (None, None) without timestamps, and
        None when some bytes have no time (an untimed chunk among timed ones: events, frame by frame)."""
        offs = self._chunk_offsets
        if not offs:
            return None, None
        first = base + starts
        last = base + ends - 1
        o = np.array(offs, dtype=np.int64)
        k0 = np.searchsorted(o, first, side="right") - 1
        k1 = np.searchsorted(o, last, side="right") - 1
        lo, hi = int(k0[0]), int(k1[-1]) + 1
        times = self._chunk_times[lo:hi] if lo >= 0 else [None]
        if None in times:
            return None
        tm = np.array(times, dtype=np.float64)
        bt = self.byte_time
        t0 = tm[k0 - lo] + (first - o[k0]) * bt
        t1 = (tm[k1 - lo] + (last - o[k1]) * bt) + bt
        return t0, t1


def decode_all(chunks, baud: int = DEFAULT_BAUD, **kw) -> list[AnyEvent]:
    """Decode an iterable of ``(bytes, t)`` chunks completely (a convenience for tests and tools)."""
    dec = FrameDecoder(baud, **kw)
    out: list[AnyEvent] = []
    for data, t in chunks:
        out += dec.feed(data, t)
    out += dec.close()
    return out
