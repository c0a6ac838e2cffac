"""Per-servo health (register ranges, status flags, findings) and the plain-language "what happened" summary."""

from __future__ import annotations

import sys
from collections import Counter
from datetime import datetime, timezone
from typing import Any, Iterable

import numpy as np

from ..protocol.wire import RETURN_FLAG_BITS

# Registers whose range a servo's returns show, and the ones the host's writes set (table 4.6).
PRESENT = ("present_position", "present_speed", "present_current", "present_temperature", "present_voltage")
WRITTEN = ("goal_position",)
FLAG_NAMES = tuple(RETURN_FLAG_BITS.values())

# Raw packets are kept per payload shape and reduced this many at a time: the frames become the rows
# of a byte matrix and each register's column is read by numpy's min/max, so a return costs the stats
# sink a list append instead of Python arithmetic per value. Public: CaptureStats' column form
# (sinks/stats.py) fills the same buffers and flushes at the same count.
FLUSH_ROWS = 4096
_TYPECODES = {(1, False): "B", (1, True): "b", (2, False): "H", (2, True): "h"}
_LITTLE = sys.byteorder == "little"
# Times above this are seconds since 1970 (a logger's wall clock), not seconds since the capture began.
EPOCH_MIN = 1e9
# The findings the summary tells through the figures (flags, missing replies, bad bytes), not as rule lines.
_TOLD = frozenset({"S001", "S002", "S003", "S004", "Q009", "B002", "F001", "F002"})
_MAX_LINES = 8
_SEV_RANK = {"error": 0, "warning": 1, "info": 2}


def _where(model: Any, names: tuple[str, ...], address: int, n: int) -> list[tuple[Any, int]]:
    """(register, offset in the payload) of each of ``names`` that ``n`` bytes at ``address`` hold whole."""
    out = []
    for name in names:
        try:
            reg = model.register(name)
        except KeyError:
            continue
        start = reg.address - address
        if start >= 0 and start + reg.size <= n and (reg.size, reg.signed) in _TYPECODES:
            out.append((reg, start))
    return out


def _column(block: bytes, off: int, stride: int, reg: Any) -> memoryview:
    """The values of ``reg`` at ``off`` in every ``stride``-byte row of ``block``, as a typed view."""
    code = _TYPECODES[reg.size, reg.signed]
    if reg.size == 1:
        return memoryview(block[off::stride]).cast(code)
    lo, hi = block[off::stride], block[off + 1::stride]
    buf = bytearray(2 * len(lo))
    buf[0::2], buf[1::2] = (lo, hi) if _LITTLE else (hi, lo)
    return memoryview(buf).cast(code)


class Frames(bytes):
    """Several frames of a buffer's size in one bytes object, followed in the buffer by an empty
    bytes for each frame after its first: the buffer still holds one item per row, so it is flushed
    after the same rows (a Block's rows, rs30x_sniff.sinks.stats, are buffered so without a bytes object each)."""

    __slots__ = ()

    @classmethod
    def rows(cls, block: bytes, size: int) -> list[bytes]:
        """The buffer items of ``block``, whole frames of ``size`` bytes."""
        n = len(block) // size
        return [cls(block), *(b"",) * (n - 1)] if n else []


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
    """A 1- or 2-byte register's raw values at byte ``at`` of every row (_column's values)."""
    if reg.size == 1:
        col = mat[:, at]
        return col.view(np.int8) if reg.signed else col
    col = mat[:, at].astype(np.uint16) | mat[:, at + 1].astype(np.uint16) << 8
    return col.view(np.int16) if reg.signed else col


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
    """Fed by CaptureStats per intact packet: keeps the raw packets, the flags, the findings per servo.

    The column form (CaptureStats over Blocks) uses the public buffer interface: the buffers
    ``returns``, ``writes`` and ``long_writes`` (shape key -> [model, raw frames]), ``open_buffer``
    to start one, ``flush_short`` / ``flush_long`` to reduce one (with a FrameRun's rows read in
    place), at ``FLUSH_ROWS`` frames a buffer, as the record form does.
    """

    def __init__(self) -> None:
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

    # ---- feeding (per record: keep it cheap) -------------------------------------------------
    def returned(self, rec: Any, ev: Any, sid: int) -> None:
        """An intact return packet from ``sid``."""
        data = ev[9]
        if data:
            key = (sid, ev[6], len(data))
            b = self.returns.get(key)
            if b is None or b[0] is not rec.model:
                b = self.open_buffer(self.returns, key, rec.model)
            rows = b[1]
            rows.append(ev[1])
            if len(rows) >= FLUSH_ROWS:
                self.flush_short(key, b, True)
        flags = ev[5]
        if flags:
            self._flags(sid, flags, ev)

    def written(self, rec: Any, ev: Any, sid: int) -> None:
        """An intact short packet to ``sid`` carrying data."""
        key = (sid, ev[6], len(ev[9]))
        b = self.writes.get(key)
        if b is None or b[0] is not rec.model:
            b = self.open_buffer(self.writes, key, rec.model)
        b[1].append(ev[1])
        if len(b[1]) >= FLUSH_ROWS:
            self.flush_short(key, b, False)

    def long_written(self, rec: Any, ev: Any) -> None:
        """An intact long packet."""
        records = ev[8]
        vm = rec.vid_models
        if vm is not None:
            # Servos of mixed models in one packet: each record on its own, in its servo's model.
            for m, (vid, data) in zip(vm, records):
                for reg, off in _where(m, WRITTEN, ev[5], len(data)):
                    self.servo(vid).take(reg, _column(data, off, len(data), reg))
            return
        key = (ev[5], ev[6], len(records))
        b = self.long_writes.get(key)
        if b is None or b[0] is not rec.model:
            b = self.open_buffer(self.long_writes, key, rec.model)
        b[1].append(ev[1])
        if len(b[1]) >= FLUSH_ROWS:
            self.flush_long(key, b)

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
                    h.flags[name] = [1, ev[2], ev[0]]
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
        data starts at byte 7 (header, ID, flags, address, length, count); the buffered ones, then
        ``rows`` of FrameRun ``run`` (if any), read in place."""
        raws, b[1] = b[1], []
        h, where = self.short_target(key, b[0], present)
        if not where:
            return
        mat = _frames(raws, run, rows, 8 + key[2])
        if len(mat):
            for reg, off in where:
                _take(h, reg, _register_column(mat, 7 + off, reg))

    def flush_long(self, key: tuple, b: list, run: Any = None, rows: np.ndarray | None = None) -> None:
        """Long packets of one shape: each of ``count`` records is a VID and ``length - 1`` bytes (the
        buffered frames, then ``rows`` of ``run``, as flush_short)."""
        raws, b[1] = b[1], []
        model = b[0]
        address, length, count = key
        where = _where(model, WRITTEN, address, length - 1)
        if not where or length < 2:
            return
        mat = _frames(raws, run, rows, 8 + length * count)
        if not len(mat):
            return
        for j in range(count):
            base = 7 + j * length
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


# ---- output ------------------------------------------------------------------------------------
def servo_health(h: ServoHealth | None, when: Any) -> dict[str, Any]:
    """One servo's health as JSON-ready data; ``when(t, offset)`` gives (t, wall)."""
    regs: dict[str, Any] = {}
    m = h.model if h is not None else None
    if h is not None:
        for name in (*PRESENT, *WRITTEN):
            if name not in h.lo:
                continue
            reg = (m or _any_model()).register(name)
            a, b = reg.convert(h.lo[name]), reg.convert(h.hi[name])
            regs[name] = {"min": min(a, b), "max": max(a, b), "unit": reg.unit, "count": h.samples[name]}
    flags = {}
    if h is not None:
        for name in FLAG_NAMES:
            seen = h.flags.get(name)
            if seen is not None:
                t, wall = when(seen[1], seen[2])
                flags[name] = {"count": seen[0], "first_t": t, "first_wall": wall}
    return {"model": None if m is None else m.name, "registers": regs, "flags": flags,
            "findings": dict(sorted(h.findings.items())) if h is not None else {}}


def _any_model() -> Any:
    from ..protocol.memmap import default_registry
    return default_registry().default


def timer(first_t: float | None, timed: bool, byte_s: float, anchor: float | None = None):
    """``when(t, offset)`` -> (capture time, ISO wall clock or None): the times ``lint`` and ``decode``
    print, and the wall clock where the capture has one (epoch times, or ``anchor``: the epoch time of
    capture time 0); an untimed capture is measured in line time, as its duration is."""
    epoch = anchor if anchor is not None else (0.0 if timed and first_t is not None and first_t > EPOCH_MIN else None)

    def when(t: float | None, offset: int) -> tuple[float | None, str | None]:
        if timed and t is not None and first_t is not None:
            wall = None
            if epoch is not None:
                try:
                    wall = (datetime.fromtimestamp(epoch + t, tz=timezone.utc).isoformat(timespec="milliseconds")
                            .replace("+00:00", "Z"))
                except (OverflowError, OSError, ValueError):
                    wall = None  # no calendar date: the capture time alone
            return round(t, 6), wall
        if not timed:
            return round(offset * byte_s, 6), None
        return None, None
    return when


def _at(t: float | None, wall: str | None) -> str:
    if t is None:
        return ""
    return f" at {t:.2f} s" + (f" [{wall.replace('T', ' ').replace('Z', ' UTC')}]" if wall else "")


def _times(n: int) -> str:
    return {1: "once", 2: "twice"}.get(n, f"{n} times")


def _ids(ids: list[int]) -> str:
    return ", ".join(map(str, ids[:6])) + (", ..." if len(ids) > 6 else "")


def _plural(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def what_happened(stats: Any, health: dict[str, dict], when: Any) -> list[dict[str, Any]]:
    """A handful of plain-language lines, most severe first: what a capture says went wrong."""
    items: list[dict[str, Any]] = []

    def say(sev: str, sid: int | None, text: str, tw: tuple = (None, None)) -> None:
        items.append({"severity": sev, "id": sid, "text": text, "t": tw[0], "wall": tw[1]})

    rec: HealthRecorder = stats.health
    servos = stats.servos
    refused: list[tuple[int, dict]] = []
    # Status flags the servos themselves reported (table 4.4): the hardware's own word on what happened.
    for sid in sorted(health, key=int):
        hv = health[sid]
        flags, regs, found = hv["flags"], hv["registers"], hv["findings"]
        peak = regs.get("present_temperature")
        peak_s = f"peak {peak['max']:g} {peak['unit'] or ''}".rstrip() if peak else ""
        lim = flags.get("temperature_limit")
        if lim:
            al = flags.get("temperature_alarm")
            why = ", ".join(x for x in (f"alarm from {al['first_t']:.2f} s" if al and al["first_t"] is not None
                                        else "", peak_s) if x)
            text = f"ID {sid} reached its temperature limit{_at(lim['first_t'], lim['first_wall'])}" + \
                (f" ({why})" if why else "")
            q = found.get("Q009", 0)
            text += (f" and was switched back on {_times(q)} (Q009)" if q else " and cut its torque")
            say("error", int(sid), text, (lim["first_t"], lim["first_wall"]))
        elif "temperature_alarm" in flags:
            al = flags["temperature_alarm"]
            say("warning", int(sid), f"ID {sid} came within 10 degC of its temperature limit"
                f"{_at(al['first_t'], al['first_wall'])}" + (f" ({peak_s})" if peak_s else ""),
                (al["first_t"], al["first_wall"]))
        fe = flags.get("flash_write_error")
        if fe:
            say("error", int(sid), f"ID {sid} reported a failed flash ROM write{_at(fe['first_t'], fe['first_wall'])}",
                (fe["first_t"], fe["first_wall"]))
        re_ = flags.get("received_packet_error")
        if re_:
            refused.append((int(sid), re_))
    # Packets the servos could not accept: one line, however many servos said so (one bad host, usually).
    if refused:
        n = sum(v["count"] for _, v in refused)
        first = min((v for _, v in refused), key=lambda v: (v["first_t"] is None, v["first_t"] or 0))
        ids = [sid for sid, _ in refused]
        who = f"ID {ids[0]}" if len(ids) == 1 else "IDs " + _ids(ids)
        say("warning", ids[0] if len(ids) == 1 else None,
            f"{who} flagged {_plural(n, 'packet')} {'it' if len(ids) == 1 else 'they'} could not accept "
            f"(status bit 1), first"
            f"{_at(first['first_t'], first['first_wall'])}", (first["first_t"], first["first_wall"]))
    # Replies that never came.
    for sid, st in sorted(servos.items()):
        if not st.missing:
            continue
        tw = when(*st.first_missing) if st.first_missing else (None, None)
        if st.returns + st.acks + st.nacks == 0:
            say("error", sid, f"ID {sid} never answered: {_plural(st.missing, 'request')} missing", tw)
        else:
            asked = st.missing + st.answered  # requests that asked for a reply, not the replies heard
            say("error", sid, f"ID {sid} left {st.missing} of {asked} requests unanswered, first{_at(*tw)}", tw)
    # Damaged traffic.
    if stats.bad_checksums:
        by_kind: dict[str, list] = {}
        for (kind, sid), n in stats.bad_by.items():
            k = by_kind.setdefault(kind, [0, set()])
            k[0] += n
            if sid is not None:
                k[1].add(sid)
        words = {"return": ("return", " from "), "short": ("request", " to "), "long": ("long packet", "")}
        parts = []
        for kind, (n, ids) in sorted(by_kind.items(), key=lambda kv: -kv[1][0]):
            word, prep = words.get(kind, (kind, ""))
            parts.append(_plural(n, word) + (f"{prep}ID{'s' if len(ids) > 1 else ''} {_ids(sorted(ids))}"
                                            if prep and ids else ""))
        sole = by_kind.get("return", [0, set()])[1]
        sid = next(iter(sole)) if len(by_kind) == 1 and len(sole) == 1 else None
        say("error", sid, "; ".join(parts) + " with a bad checksum", when(*stats.first_bad))
    if stats.garbage_bytes:
        say("warning", None, f"{_plural(stats.garbage_bytes, 'byte')} of garbage (no intact frame)",
            when(*stats.first_garbage))
    # What the linter found that the lines above do not already tell.
    for code, (n, t, off, sev, name, ids) in sorted(rec.codes.items(), key=lambda kv: (_SEV_RANK.get(kv[1][3], 3),
                                                                                       -kv[1][0])):
        if code in _TOLD or sev == "info":
            continue
        who = ""
        if ids:
            who = (" from ID " if len(ids) == 1 else " from IDs ") + _ids(sorted(ids))
        tw = when(t, off)
        sole = next(iter(ids)) if len(ids) == 1 else None
        say(sev, sole, f"{code} {name}: {_times(n)}{who}, first{_at(*tw)}", tw)
    items.sort(key=lambda it: _SEV_RANK[it["severity"]])  # stable: the order above ranks within a severity
    if len(items) > _MAX_LINES:
        rest = items[_MAX_LINES - 1:]
        items = items[:_MAX_LINES - 1]
        say(rest[0]["severity"], None, f"and {len(rest)} more: see the findings and the health table")
    if not items and not stats.bytes:
        say("warning", None, "nothing to tell: the capture holds no data")  # empty is no clean bill of health
    elif not items:
        answered = sum(st.returns + st.acks + st.nacks for st in servos.values())
        say("info", None, f"nothing wrong seen: {_plural(len(servos), 'servo')}, {answered} replies, none missing, "
            "no status flags, no damaged packets")
    # The bus load, last: a figure to know whether or not anything went wrong.
    peak = stats.load_peak
    if peak is not None:
        load, start = peak
        tw = when(start, 0)
        sev = "warning" if load >= 0.95 else "info"
        line = {"severity": sev, "id": None, "t": tw[0], "wall": tw[1],
                "text": f"the bus load peaked at {load * 100:.0f} % in the second from {tw[0]:.2f} s, "
                        f"{(stats.bus_load or 0) * 100:.0f} % on average"
                        + ("; little room for more traffic" if sev == "warning" else "")}
        if sev == "warning":
            k = next((i for i, it in enumerate(items) if it["severity"] == "info"), len(items))
            items.insert(k, line)
        else:
            items.append(line)
    return items
