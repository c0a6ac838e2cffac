"""Per-servo health: the register ranges, status flags and findings its packets show (summary.py tells them)."""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING, Any
from collections.abc import Iterable

import numpy as np

from ..protocol.events import ADDRESS, DATA, FLAG, LONG_ADDRESS, LONG_LENGTH, LONG_RECORDS, OFFSET, RAW, T_START
from ..protocol.wire import AT_DATA, FRAME_OVERHEAD, RETURN_FLAG_BITS

if TYPE_CHECKING:  # names for the checker; no import at run time
    from ..decode.blocks import Block
    from ..decode.pairing import Record

# Registers whose range a servo's returns show, and the ones the host's writes set (table 4.6).
PRESENT = ("present_position", "present_speed", "present_current", "present_temperature", "present_voltage")
WRITTEN = ("goal_position",)
FLAG_NAMES = tuple(RETURN_FLAG_BITS.values())

# Raw packets are kept per payload shape and reduced this many at a time: the frames become the rows
# of a byte matrix and each register's column is read by numpy's min/max, so a return costs the stats
# sink a list append instead of Python arithmetic per value. The column form (HealthRecorder's *_rows)
# fills the same buffers and flushes at the same count. Not more: a live bus fills a shape's buffer at its
# poll rate, and the hexapod's (18 servos, 230400 baud) took about half an hour to fill 4096 rows a shape, 2.7 MB
# of buffers rising all that time (bench/record_memory.py). 1024 holds a quarter of that, for the same CPU (a
# reduction costs microseconds).
FLUSH_ROWS = 1024


def _where(model: Any, names: tuple[str, ...], address: int, n: int) -> list[tuple[Any, int]]:
    """(register, offset in the payload) of each of ``names`` that ``n`` bytes at ``address`` hold whole."""
    out = []
    for name in names:
        try:
            reg = model.register(name)
        except KeyError:
            continue
        start = reg.address - address
        if start >= 0 and start + reg.size <= n and reg.size <= 2:
            out.append((reg, start))
    return out


class Frames(bytes):
    """Several frames of a buffer's size in one bytes object, followed in the buffer by an empty
    bytes for each frame after its first: the buffer still holds one item per row, so it is flushed
    after the same rows (a Block's rows, HealthRecorder's column form, are buffered so without a bytes object each)."""

    __slots__ = ()

    @classmethod
    def rows(cls, block: bytes, size: int) -> list[bytes]:
        """The buffer items of ``block``, whole frames of ``size`` bytes."""
        n = len(block) // size
        return [cls(block), *(b"",) * (n - 1)] if n else []


def _frame_size(key: tuple, present: bool | None) -> int:
    """The frame size a buffer's key describes: (servo, address, data length) of a short packet or
    return, (address, length, records) of a long packet."""
    return FRAME_OVERHEAD + (key[1] * key[2] if present is None else key[2])


def _buffered(run: Any, rows: np.ndarray, size: int) -> list[bytes]:
    """Buffer items for ``rows`` of ``run``: the frames of ``size`` bytes as one Frames, and the
    others (left out at the flush, counted until then) as their own bytes, one item a row."""
    starts, ends = run.starts[rows], run.ends[rows]
    fits = ends - starts == size
    items = Frames.rows(run.bytes_array[starts[fits][:, None] + np.arange(size)].tobytes(), size)
    if not fits.all():
        blob = run.blob
        items += [blob[s:e] for s, e in zip(starts[~fits].tolist(), ends[~fits].tolist())]
    return items


def _joined(rows: list[bytes], size: int) -> tuple[bytes, int]:
    """The rows as one block of ``size``-byte rows (a frame of another size, which its framing
    allowed but its header does not describe, is left out: the strides would slip)."""
    block = b"".join(rows)
    if len(block) != size * len(rows):
        block = b"".join(r for r in rows if len(r) == size or type(r) is Frames)
    return block, size


def _frames(raws: list[bytes], run: Any, rows: np.ndarray | None, size: int) -> np.ndarray:
    """Frames of ``size`` bytes as rows of a matrix: the buffered ones, then ``rows`` of FrameRun ``run``
    (if any; a frame of another size is left out, as _joined leaves it)."""
    mat = None
    if run is not None:
        starts = run.starts[rows]
        starts = starts[run.ends[rows] - starts == size]
        mat = run.bytes_array[starts[:, None] + np.arange(size)]
    if raws:
        block, _ = _joined(raws, size)
        held = np.frombuffer(block, dtype=np.uint8).reshape(-1, size)
        mat = held if mat is None else np.concatenate((held, mat))
    return mat if mat is not None else np.zeros((0, size), dtype=np.uint8)


def _register_column(mat: np.ndarray, at: int, reg: Any) -> np.ndarray:
    """A register's raw values at byte ``at`` of every row (Register.raw_column, the one decoding)."""
    return reg.raw_column(mat.T, at)


def _take(h: Any, reg: Any, col: np.ndarray) -> None:
    """ServoHealth.take, the column's range taken by numpy."""
    if len(col):
        h.take_range(reg.name, int(col.min()), int(col.max()), len(col))


class ServoHealth:
    """What one servo's returns and the writes to it showed."""

    __slots__ = ("model", "lo", "hi", "samples", "flags", "findings")

    def __init__(self) -> None:
        self.model: Any = None
        self.lo: dict[str, int] = {}       # register name -> smallest raw value seen
        self.hi: dict[str, int] = {}
        self.samples: Counter = Counter()  # register name -> packets that carried it
        self.flags: dict[str, list] = {}   # flag name -> [count, first t, first offset]
        self.findings: Counter = Counter()

    def take(self, reg: Any, col: Any) -> None:
        self.take_range(reg.name, min(col), max(col), len(col))

    def take_range(self, name: str, lo: Any, hi: Any, n: int) -> None:
        """A register's range over ``n`` more samples (the columnar path finds lo and hi with numpy)."""
        if name in self.lo:
            if lo < self.lo[name]:
                self.lo[name] = lo
            if hi > self.hi[name]:
                self.hi[name] = hi
        else:
            self.lo[name], self.hi[name] = lo, hi
        self.samples[name] += n


class HealthRecorder:
    """Fed by CaptureStats per intact packet (the record form) or per Block's rows (the column form, the
    ``*_rows`` methods): keeps the raw packets, the flags, the findings per servo.

    Both forms fill the same buffers ``returns``, ``writes`` and ``long_writes`` (shape key -> [model,
    raw frames]), ``open_buffer`` to start one, ``flush_short`` / ``flush_long`` to reduce one (with a
    FrameRun's rows read in place), at ``FLUSH_ROWS`` frames a buffer.
    """

    def __init__(self, ranges: bool = True) -> None:
        # ranges False: no register ranges kept (a figure check that reads none), flags and findings still.
        self.ranges = ranges
        self.servos: dict[int, ServoHealth] = {}
        # Raw packets by shape, each [model, rows]: returns and short writes by (servo, address, data
        # length), long packets by (address, length, count). One model per buffer: a servo whose model
        # is learned midway starts a new one.
        self.returns: dict[tuple, list] = {}
        self.writes: dict[tuple, list] = {}
        self.long_writes: dict[tuple, list] = {}
        self.codes: dict[str, list] = {}       # code -> [count, first t, first offset, severity, name, ids]

    def servo(self, sid: int) -> ServoHealth:
        h = self.servos.get(sid)
        if h is None:
            h = self.servos[sid] = ServoHealth()
        return h

    # ---- the record form (per record: keep it cheap) -----------------------------------------
    def returned(self, rec: Record, ev: Any, sid: int) -> None:
        """An intact return packet from ``sid``."""
        data = ev[DATA]
        if data and self.ranges:
            key = (sid, ev[ADDRESS], len(data))
            b = self.returns.get(key)
            if b is None or b[0] is not rec.model:
                b = self.open_buffer(self.returns, key, rec.model)
            rows = b[1]
            rows.append(ev[RAW])
            if len(rows) >= FLUSH_ROWS:
                self.flush_short(key, b, True)
        flags = ev[FLAG]
        if flags:
            self._flags(sid, flags, ev)

    def written(self, rec: Record, ev: Any, sid: int) -> None:
        """An intact short packet to ``sid`` carrying data."""
        if not self.ranges:
            return
        key = (sid, ev[ADDRESS], len(ev[DATA]))
        b = self.writes.get(key)
        if b is None or b[0] is not rec.model:
            b = self.open_buffer(self.writes, key, rec.model)
        b[1].append(ev[RAW])
        if len(b[1]) >= FLUSH_ROWS:
            self.flush_short(key, b, False)

    def long_written(self, rec: Record, ev: Any) -> None:
        """An intact long packet."""
        if not self.ranges:
            return
        records = ev[LONG_RECORDS]
        vm = rec.vid_models
        if vm is not None:
            # Servos of mixed models in one packet: each record on its own, in its servo's model.
            for m, (vid, data) in zip(vm, records):
                for reg, off in _where(m, WRITTEN, ev[LONG_ADDRESS], len(data)):
                    self.servo(vid).take(reg, _register_column(np.frombuffer(data, np.uint8)[None], off, reg).tolist())
            return
        key = (ev[LONG_ADDRESS], ev[LONG_LENGTH], len(records))
        b = self.long_writes.get(key)
        if b is None or b[0] is not rec.model:
            b = self.open_buffer(self.long_writes, key, rec.model)
        b[1].append(ev[RAW])
        if len(b[1]) >= FLUSH_ROWS:
            self.flush_long(key, b)

    # ---- the column form (a Block's rows: rs30x_sniff.decode.blocks) --------------------------
    def returned_rows(self, blk: Block, rows: np.ndarray) -> None:
        """Returns of the Block (``rows``): :meth:`returned` of each."""
        cols = blk.cols
        with_data = rows[cols["data_len"][rows] > 0] if self.ranges else rows[:0]
        if with_data.size:
            self._buffer_rows(blk, with_data, self.returns, True)
        flagged = rows[cols["flag"][rows] != 0]
        if flagged.size:
            self._flag_rows(blk, flagged)

    def written_rows(self, blk: Block, rows: np.ndarray) -> None:
        """Short packets of the Block to one servo carrying data (``rows``): :meth:`written` of each."""
        if self.ranges:
            self._buffer_rows(blk, rows, self.writes, False)

    def long_written_rows(self, blk: Block, rows: np.ndarray) -> None:
        """Long packets of the Block (``rows``): :meth:`long_written` of each."""
        if not self.ranges:
            return
        if blk.vid_models is None:
            self._buffer_rows(blk, rows, self.long_writes, None)
            return
        self._mixed_long_rows(blk, rows)

    def _mixed_long_rows(self, blk: Block, rows: np.ndarray) -> None:
        """Long packets to servos of mixed models (``rows``), as :meth:`long_written` takes each record in its
        own servo's model: by shape (address, Length, data length), then by record place and VID (the same
        servo in every packet, as a rule), each register's column taken at once."""
        cols, run, vid_models = blk.cols, blk.run, blk.vid_models
        assert vid_models is not None
        a, starts = run.bytes_array, run.starts[rows + blk.lo] + AT_DATA
        length = cols["length"][rows].astype(np.int64)
        dl = cols["data_len"][rows].astype(np.int64)
        keys = (cols["address"][rows].astype(np.int64) * 256 + length) * (1 << 20) + dl
        takes = []  # (first row, record place, VID, register, its column)
        for key in np.unique(keys[length > 0]).tolist():
            mine = np.flatnonzero(keys == key)
            rest, n = divmod(key, 1 << 20)
            address, ln = rest >> 8, rest & 255
            for k in range(-(-n // ln)):
                size = min(ln - 1, n - k * ln - 1)  # the record's data, the last one cut short
                if size <= 0:
                    continue
                at = starts[mine] + k * ln
                vids = a[at]
                one = vids.min() == vids.max()
                for vid in ([int(vids[0])] if one else np.unique(vids).tolist()):
                    where = _where(vid_models[vid], WRITTEN, address, size)
                    if not where:
                        continue
                    sub = at if one else at[vids == vid]
                    first = int(mine[0]) if one else int(mine[np.argmax(vids == vid)])
                    for reg, off in where:
                        takes.append((first, k, vid, reg, reg.raw_column(a, sub + 1 + off)))
        takes.sort(key=lambda x: x[:2])  # servos made in the order their records came
        for _, _, vid, reg, col in takes:
            _take(self.servo(vid), reg, col)

    def _buffer_rows(self, blk: Block, rows: np.ndarray, bufs: dict, present: bool | None) -> None:
        """Rows of the Block into ``bufs``, as returned() / written() / long_written() put them
        (``present`` True, False, None): by shape, each shape in the order its first row came, flushed
        every FLUSH_ROWS rows of a shape as they are."""
        cols, run = blk.cols, blk.run
        address = cols["address"][rows].astype(np.int64)
        if present is None:  # long packets: (address, length, records)
            length = cols["length"][rows].astype(np.int64)
            dl = cols["data_len"][rows].astype(np.int64)
            nrec = np.where(length > 0, -(-dl // np.maximum(length, 1)), 0)
            keys = (address * 256 + length) * (1 << 20) + nrec
        else:  # returns and short writes: (servo, address, data length)
            keys = (cols["id"][rows].astype(np.int64) * 256 + address) * (1 << 20) + cols["data_len"][rows]
        order = np.argsort(keys, kind="stable")
        sk = keys[order]
        cut = np.flatnonzero(sk[1:] != sk[:-1]) + 1
        bounds = [0, *cut.tolist(), len(sk)]
        heads = bounds[:-1]
        groups = sorted(zip(order[heads].tolist(), heads, bounds[1:], sk[heads].tolist()))  # by first row
        grouped = rows[order] + blk.lo  # rows of the run, shape by shape
        models = blk.models
        for _, g0, g1, key in groups:
            rest, third = divmod(key, 1 << 20)
            key_t = (rest >> 8, rest & 255, third)
            model = blk.default if present is None else models[key_t[0]]
            b = bufs.get(key_t)
            if b is None or b[0] is not model:
                b = self.open_buffer(bufs, key_t, model)
            i = g0
            while True:
                room = FLUSH_ROWS - len(b[1])
                if g1 - i < room:  # the rest waits in the buffer, as raw frames
                    b[1] += _buffered(run, grouped[i:g1], _frame_size(key_t, present))
                    break
                # These rows fill the buffer: the record form's flush, their bytes read in place.
                if present is None:
                    self.flush_long(key_t, b, run, grouped[i:i + room])
                else:
                    self.flush_short(key_t, b, present, run, grouped[i:i + room])
                i += room
                if i == g1:
                    break

    def _flag_rows(self, blk: Block, rows: np.ndarray) -> None:
        """Status flags of a Block's returns (rows), counted per servo and flag with the first seen."""
        cols = blk.cols
        flags, ids = cols["flag"][rows], cols["id"][rows]
        t0 = blk.t0
        offsets = blk.offsets[rows]
        for i in np.unique(ids).tolist():
            mine = ids == i
            h = self.servos.get(i) or self.servo(i)
            for bit, name in RETURN_FLAG_BITS.items():
                hit = np.flatnonzero(mine & ((flags & bit) != 0))
                if not hit.size:
                    continue
                seen = h.flags.get(name)
                if seen is None:
                    k = int(hit[0])
                    h.flags[name] = [len(hit), None if t0 is None else float(t0[rows[k]]), int(offsets[k])]
                else:
                    seen[0] += len(hit)

    def open_buffer(self, bufs: dict, key: tuple, model: Any) -> list:
        """A new [model, frames] buffer for ``key`` in ``bufs`` (one of returns, writes, long_writes);
        the old one of a different model is reduced first."""
        old = bufs.get(key)
        if old is not None and old[1]:  # the servo's model changed: what came before keeps its own
            if bufs is self.long_writes:
                self.flush_long(key, old)
            else:
                self.flush_short(key, old, bufs is self.returns)
        b = bufs[key] = [model, []]
        return b

    def _flags(self, sid: int, flags: int, ev: Any) -> None:
        h = self.servos.get(sid) or self.servo(sid)
        for bit, name in RETURN_FLAG_BITS.items():
            if flags & bit:
                seen = h.flags.get(name)
                if seen is None:
                    h.flags[name] = [1, ev[T_START], ev[OFFSET]]
                else:
                    seen[0] += 1

    def findings(self, findings: Iterable[Any]) -> None:
        codes = self.codes
        for f in findings:
            c = codes.get(f.code)
            if c is None:
                c = codes[f.code] = [0, f.t, f.offset, f.severity, f.name, set()]
            c[0] += 1
            if f.id is not None:
                if len(c[5]) < 128:
                    c[5].add(f.id)
                self.servo(f.id).findings[f.code] += 1

    # ---- reducing ----------------------------------------------------------------------------
    def flush(self) -> None:
        """Reduce every buffer (before the figures are read: the monitor asks every second)."""
        for key, b in self.returns.items():
            if b[1]:
                self.flush_short(key, b, True)
        for key, b in self.writes.items():
            if b[1]:
                self.flush_short(key, b, False)
        for key, b in self.long_writes.items():
            if b[1]:
                self.flush_long(key, b)

    def short_target(self, key: tuple, model: Any, present: bool) -> tuple[Any, list]:
        """The servo of a (servo, address, length) buffer and where its followed registers sit in the
        data (_where); a return's model is the servo's latest (a model-number return may have taught it)."""
        sid, address, n = key
        h = self.servo(sid)
        if present:
            h.model = model
        return h, _where(model, PRESENT if present else WRITTEN, address, n)

    def flush_short(self, key: tuple, b: list, present: bool, run: Any = None,
                    rows: np.ndarray | None = None) -> None:
        """Returns (``present``) or short writes of one servo, address and length: raw frames whose
        data starts at AT_DATA (header, ID, flags, address, length, count); the buffered ones, then
        ``rows`` of FrameRun ``run`` (if any), read in place."""
        raws, b[1] = b[1], []
        h, where = self.short_target(key, b[0], present)
        if not where:
            return
        mat = _frames(raws, run, rows, FRAME_OVERHEAD + key[2])
        if len(mat):
            for reg, off in where:
                _take(h, reg, _register_column(mat, AT_DATA + off, reg))

    def flush_long(self, key: tuple, b: list, run: Any = None, rows: np.ndarray | None = None) -> None:
        """Long packets of one shape: each of ``count`` records is a VID and ``length - 1`` bytes (the
        buffered frames, then ``rows`` of ``run``, as flush_short)."""
        raws, b[1] = b[1], []
        model = b[0]
        address, length, count = key
        where = _where(model, WRITTEN, address, length - 1)
        if not where or length < 2:
            return
        mat = _frames(raws, run, rows, FRAME_OVERHEAD + length * count)
        if not len(mat):
            return
        for j in range(count):
            base = AT_DATA + j * length
            vids = mat[:, base]
            one = vids.min() == vids.max()
            for reg, off in where:
                col = _register_column(mat, base + 1 + off, reg)
                if one:  # the usual: record j is the same servo in every packet
                    _take(self._written_to(int(vids[0]), model), reg, col)
                    continue
                ids, first = np.unique(vids, return_index=True)
                for vid in ids[np.argsort(first)].tolist():  # servos made in the order they came
                    _take(self._written_to(vid, model), reg, col[vids == vid])

    def _written_to(self, sid: int, model: Any) -> ServoHealth:
        h = self.servo(sid)
        if h.model is None:  # a servo only ever written to: the model its writes were decoded as
            h.model = model
        return h
