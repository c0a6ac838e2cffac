"""Capture statistics (traffic, per-servo polls, latencies, bus load, health, what happened); pure, no I/O.

The one definition of these figures: ``info``, the MCAP metadata and the monitor all read them here.
CaptureStats counts what passes and hands each record or Block to the pieces that keep the rest, each
with its record form beside its column form: segments.py (time segments and durations), bus_load.py
(the load windows), servos.py (per-servo traffic and poll rates), latency.py, health.py.
"""

from __future__ import annotations

from collections import Counter
from operator import itemgetter
from typing import Any
from collections.abc import Iterable

import numpy as np

from ..decode.blocks import Block
from ..decode.decoder import Step
from ..decode.pairing import Record
from ..decode.frame_runs import LONG, RETURN, SHORT
from ..protocol.events import DATA, FLAG, ID, LONG_RECORDS, OFFSET, RAW, T_END, T_START, Ack, Garbage, LongPacket, \
    ReturnPacket, ShortPacket
from ..protocol.wire import BROADCAST_ID, FLAG_MODE_UNDEFINED, byte_time
from .bus_load import LOAD_WINDOW, LoadWindows, RecentLoad
from .health import FLUSH_ROWS, HealthRecorder
from .summary import servo_health, timer, what_happened
from .latency import LatencyHistogram, ServoLatencies
from .pipeline import Sink
from .segments import TimeSegments
from .servos import ServoStats, ServoTraffic

# Importers' names (RecentLoad: the live displays; FLUSH_ROWS: tests set it here and in health.py).
__all__ = ["CaptureStats", "FLUSH_ROWS", "LatencyHistogram", "RecentLoad", "ServoStats"]

# (flag, carries data) -> (op word, asks for a return): both follow from those two alone (table 4.2, 4.3).
_OPS: dict[tuple[int, bool], tuple[str, bool]] = {}


class CaptureStats(Sink[Record | Block]):
    """Feed every record (and the findings), then read the figures or :meth:`as_dict`; as a sink of
    the drive loop it counts the bytes, records and findings that pass through.

    Times come from the records; a capture without timestamps is measured in line time: its
    byte count at the configured baud rate, as if the bus had never been idle. Where the capture's
    clock has seams (rs30x_sniff.decode.framing.Seam, handed over on the steps), durations add up over the
    time segments and rates and loads are taken within them. ``timing_unsupported`` (a reason) leaves
    out the figures that need the byte time to be right (latency, bus load): set when the timestamps
    contradict the baud rate.
    """

    takes_blocks = True  # a Block's rows are counted on its columns (add_block), as add() counts each

    def __init__(self, baud: int, ranges: bool = True) -> None:
        self.baud = baud
        self.bytes = 0
        self.bytes_in = 0  # bytes fed through chunk()
        self.records = 0
        self.by_kind: Counter = Counter()
        self.by_op: Counter = Counter()
        self.bad_checksums = 0
        self.garbage_bytes = 0
        self.bad_by: Counter = Counter()        # (kind, the ID it claims) of packets with a bad Sum
        self.first_bad: tuple[float | None, int] | None = None
        self.first_garbage: tuple[float | None, int] | None = None
        self._op_table = np.zeros(512, dtype=bool)  # flag * 2 + carries data -> reads (of _OPS seen)
        self.findings: Counter = Counter()
        self.finding_codes: Counter = Counter()
        self.segments = TimeSegments()
        self.load = LoadWindows(baud)
        self.per_servo = ServoTraffic()
        self.servos: dict[int, ServoStats] = self.per_servo.by_id
        self.latency = LatencyHistogram()
        self.servo_latency = ServoLatencies()  # the same replies, per servo
        # Per-servo register ranges (unless ``ranges`` is False: nothing reads them), status flags, findings.
        self.health = HealthRecorder(ranges)
        self.timing_unsupported: str | None = None
        self.wall_anchor: float | None = None  # epoch seconds of capture time 0, where the source says

    @property
    def stalls(self) -> list[tuple[float, float, int]]:
        """Where a live reader fell behind: (t, seconds, bytes) of bytes timed at the line rate, not as they
        came (rs30x_sniff.sources.serial_tap); no load is measured over them. The source's own list, set here."""
        return self.load.stalls

    @stalls.setter
    def stalls(self, stalls: list[tuple[float, float, int]]) -> None:
        self.load.stalls = stalls

    # ---- as a sink ---------------------------------------------------------------------------------
    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        self.bytes_in += len(data)

    def chunk_group(self, chunks: list[tuple[bytes, float | None]]) -> None:
        """A group of plain chunks at once (the drive loop's columnar path): one call, not one per chunk."""
        self.bytes_in += sum(map(len, map(itemgetter(0), chunks)))

    def batch(self, step: Step) -> None:
        if step.seams:
            self.segments.expect(step.seams)
        add = self.add
        for rec in step:
            if type(rec) is Block:
                self.add_block(rec)
            else:
                add(rec)
        if step.findings:
            self.add_findings(step.findings)

    def close(self) -> None:
        self.set_bytes(self.bytes_in)

    def servo(self, sid: int) -> ServoStats:
        return self.per_servo.servo(sid)

    # ---- the record form ---------------------------------------------------------------------------
    def add(self, rec: Record) -> None:
        # Per record on captures of millions of frames: events are read by index, not by property.
        ev = rec.event
        segments = self.segments
        if ev[OFFSET] >= segments.next_seam:
            self._end_segment(ev[OFFSET])
        self.records += 1
        t = type(ev)
        kind = t.kind
        self.by_kind[kind] += 1
        raw = ev[RAW]
        end_offset = ev[OFFSET] + len(raw)
        if end_offset > self.bytes:
            self.bytes = end_offset
        ts = ev[T_START]
        if ts is not None:
            segments.add(ts, ev[T_END])
            self.load.add(ts, len(raw))
        if t is Garbage:
            self.garbage_bytes += len(raw)
            if self.first_garbage is None:
                self.first_garbage = (ts, ev[OFFSET])
            return
        if not ev.checksum_ok:
            # Its ID, VIDs and op cannot be trusted: a bad checksum, not traffic of the servos it names.
            # The ID it claims is kept apart, as a hint for the summary ("bad returns from ID 3").
            self.bad_checksums += 1
            self.bad_by[kind, getattr(ev, "id", None)] += 1
            if self.first_bad is None:
                self.first_bad = (ts, ev[OFFSET])
            return
        if t is ShortPacket:
            data = ev[DATA]
            key = (ev[FLAG], bool(data))
            if FLAG_MODE_UNDEFINED[key[0]]:  # a mode some models define (0x0D): the servo's model says
                op = (rec.op or "", rec.read_range is not None)  # a short packet's record always has an op
            elif key in _OPS:
                op = _OPS[key]
            else:  # the op and whether it reads depend on the flag and on data being there
                assert type(ev) is ShortPacket  # (t is its type; told once per flag and data)
                op = _OPS[key] = (ev.op, ev.read_range is not None)
            self.by_op[op[0]] += 1
            sid = ev[ID]
            if sid != BROADCAST_ID:
                if self.per_servo.request(sid, op[1], rec.status, ts, ev[OFFSET]):
                    self.health.servo(sid).model = rec.model  # the model it is decoded as, even if it never answers
                if data:
                    self.health.written(rec, ev, sid)
        elif t is LongPacket:
            self.by_op["long-write"] += 1
            self.per_servo.long_write(ev[LONG_RECORDS])
            self.health.long_written(rec, ev)
        else:  # a reply: return, ACK or NACK
            sid = ev[ID] if t is ReturnPacket else rec.id
            if sid is not None:
                if t is ReturnPacket:
                    self.per_servo.returned(sid)
                    self.health.returned(rec, ev, sid)
                elif t is Ack:
                    self.per_servo.acked(sid)
                else:
                    self.per_servo.nacked(sid)
            if rec.status == "paired":
                lat = rec.latency
                self.latency.add_paired(lat, ts is not None)
                if lat is not None and sid is not None:
                    self.servo_latency.add(sid, lat)

    # ---- the column form ---------------------------------------------------------------------------
    def add_block(self, blk: Block) -> None:
        """Count a Block's rows (rs30x_sniff.decode.blocks) on its columns: the same figures as :meth:`add` of
        each of its records, in order. Every row is an intact short, long or return packet, and each
        request asking for a reply is followed by its (paired) return."""
        n = len(blk)
        if not n:
            return
        cols = blk.cols
        kind, sid, dlen = cols["kind"], cols["id"], cols["data_len"]
        run, lo, hi = blk.run, blk.lo, blk.hi
        starts, ends = run.starts[lo:hi], run.ends[lo:hi]
        if run.base + int(starts[0]) >= self.segments.next_seam:  # a Block never spans a seam (framing)
            self._end_segment(run.base + int(starts[0]))
        self.records += n
        counts = np.bincount(kind, minlength=3).tolist()
        by_kind = self.by_kind
        for code, name in ((SHORT, "short"), (LONG, "long"), (RETURN, "return")):
            if counts[code]:
                by_kind[name] += counts[code]
        end_offset = run.base + int(ends[-1])  # rows are in wire order
        if end_offset > self.bytes:
            self.bytes = end_offset
        t0, t1 = blk.t0, blk.t1
        if t0 is not None and t1 is not None:  # (a timed Block has both)
            self.segments.add_rows(t0, t1)
            self.load.add_rows(t0, ends - starts)
        is_short = kind == SHORT
        to_servo = is_short & (sid != BROADCAST_ID)
        is_return = kind == RETURN
        long_rows = np.flatnonzero(kind == LONG) if counts[LONG] else None
        reads = to_servo & self._reads(blk, is_short) if counts[SHORT] else to_servo
        health = self.health
        for i in self.per_servo.add_block(blk, to_servo, reads, is_return, long_rows):
            health.servo(i).model = blk.models[i]  # the model it is decoded as, even if it never answers
        if counts[SHORT]:
            writes = np.flatnonzero(to_servo & (dlen > 0))
            if writes.size:
                health.written_rows(blk, writes)
        if long_rows is not None:  # counts[LONG] rows
            self.by_op["long-write"] += counts[LONG]
            health.long_written_rows(blk, long_rows)
        if counts[RETURN]:
            health.returned_rows(blk, np.flatnonzero(is_return))
            got = blk.reply_latencies()
            if got is not None:
                # Every answered request's reply is paired; those read with their request have no latency.
                self.latency.unmeasured += int(np.count_nonzero(blk.answered)) - got[0].size
                if got[0].size:
                    self.latency.add_array(got[1])
                    self.servo_latency.add_arrays(sid[got[0]], got[1])  # a Block's replies are returns: their IDs

    def _reads(self, blk: Block, is_short: np.ndarray) -> np.ndarray:
        """The short packets of a Block counted by op; per row, whether its op asks for a return."""
        flag, dlen = blk.cols["flag"], blk.cols["data_len"]
        keys = flag.astype(np.intp) * 2 + (dlen > 0)
        by_key = np.bincount(keys[is_short], minlength=512)
        table = self._op_table
        for key in np.flatnonzero(by_key).tolist():
            op = _OPS.get((key >> 1, bool(key & 1)))
            if op is None:  # the op and whether it reads depend on the flag and on data being there
                ev = blk.run.event(blk.lo + int(np.flatnonzero(is_short & (keys == key))[0]))
                assert type(ev) is ShortPacket  # a row of kind SHORT
                op = _OPS[key >> 1, bool(key & 1)] = (ev.op, ev.read_range is not None)
            table[key] = op[1]
            self.by_op[op[0]] += int(by_key[key])
        return table[keys]

    def add_findings(self, findings: Iterable[Any]) -> None:
        findings = list(findings)
        for f in findings:
            self.findings[f.severity] += 1
            self.finding_codes[f"{f.code} {f.name}"] += 1
        self.health.findings(findings)

    def _end_segment(self, offset: int) -> None:
        """Close the time segment before the seam(s) at or before stream ``offset``: its span is added
        up, its last bus-load window and each servo's reads are closed, and the clock starts afresh."""
        last = self.segments.end_segment(offset)
        if last is not None:
            self.load.end_segment(last)
            self.per_servo.end_segment()

    def set_bytes(self, n: int) -> None:
        """The input's total byte count (the records may end before trailing bytes of a cut frame)."""
        self.bytes = max(self.bytes, n)

    # ---- figures ------------------------------------------------------------------------------
    @property
    def timed(self) -> bool:
        return self.segments.timed

    @property
    def first_t(self) -> float | None:
        """The capture's first time."""
        return self.segments.first_t

    @property
    def last_t(self) -> float | None:
        """The current time segment's last time."""
        return self.segments.last_t

    @property
    def seams(self) -> list:
        """Every seam of the capture's clock passed so far."""
        return self.segments.seams

    @property
    def unmeasured(self) -> int:
        """Paired replies whose times give no latency (pairing.reply_latency)."""
        return self.latency.unmeasured

    @property
    def line_time(self) -> float:
        """Seconds the captured bytes occupy the line at the baud rate (10 bits a byte)."""
        return self.bytes * byte_time(self.baud)

    @property
    def duration(self) -> float:
        """Seconds from the first to the last byte, added up over the time segments (line time for a
        capture without timestamps)."""
        span = self.segments.span()
        return self.line_time if span is None else span

    @property
    def bus_load(self) -> float | None:
        """Fraction of the capture's time the line was busy (None for an instant or untimed capture,
        or where the timestamps contradict the baud rate)."""
        if not self.timed or self.timing_unsupported:
            return None
        d = self.duration
        return min(1.0, self.line_time / d) if d > 0 else None

    @property
    def load_peak(self) -> tuple[float, float] | None:
        """(load, start time) of the busiest second of a timed capture (None for a shorter one).

        The last window counts over its own span once that is half a window (shorter, one packet
        would look like a full bus); none measured over a reader's stall counts; and no second is
        quieter than the whole capture's average says the busiest must be.
        """
        if not self.timed or self.timing_unsupported or self.duration < LOAD_WINDOW:
            return None
        best = self.load.busiest(self.last_t)
        avg = self.bus_load
        if avg is not None and self.first_t is not None and (best is None or avg > best[0]):
            best = (avg, self.first_t)
        return best

    def latency_dict(self) -> dict[str, Any]:
        """Reply latencies: count and percentiles, or none with the reason they cannot be given."""
        return self.latency.as_dict(self.timing_unsupported)

    def servos_dict(self) -> dict[str, Any]:
        """Per servo: its traffic (servos.py) and, where a reply of it had one, its reply latency."""
        out = self.per_servo.as_dict()
        # Replies whose times give no latency are counted for the bus only: where there are any, no
        # servo's percentiles are said to be whole.
        absent = self.timing_unsupported or self.latency_dict().get("absent")
        for key, row in out.items():
            lat = self.servo_latency.as_dict(int(key), self.timing_unsupported)
            if lat is not None:
                del lat["unmeasured"]
                if absent:
                    lat.update(p50=None, p95=None, max=None, absent=absent)
                row["latency_s"] = lat
        return out

    @property
    def packets(self) -> int:
        return self.records - self.by_kind["garbage"]

    def as_dict(self) -> dict[str, Any]:
        """Every figure as plain JSON-ready data (``info --format json``)."""
        return {
            "duration_s": self.duration,
            "timed": self.timed,
            "bytes": self.bytes,
            "baud": self.baud,
            "bus_load": self.bus_load,
            "records": self.records,
            "packets": self.packets,
            "by_type": dict(sorted(self.by_kind.items())),
            "by_op": dict(sorted(self.by_op.items())),
            "bad_checksums": self.bad_checksums,
            "garbage_bytes": self.garbage_bytes,
            "latency_s": self.latency_dict(),
            "segments": self.segments.count(),
            "reader_stalls": [{"t": t, "seconds": sec, "bytes": n} for t, sec, n in self.stalls],
            "timing_unsupported": self.timing_unsupported,
            "servos": self.servos_dict(),
            "findings": {sev: self.findings.get(sev, 0) for sev in ("error", "warning", "info")},
            "findings_by_rule": dict(self.finding_codes.most_common()),
            **self.health_dict(),
        }

    def health_dict(self) -> dict[str, Any]:
        """Per-servo health, the busiest second and the "what happened" lines (keys of :meth:`as_dict`)."""
        self.health.flush()
        when = timer(self.first_t, self.timed, byte_time(self.baud), self.wall_anchor)
        hs = self.health.servos
        # The servos of the traffic table, and any whose registers were seen; not IDs only a finding
        # named (a damaged packet's ID is no servo).
        ids = set(self.servos) | {sid for sid, h in hs.items() if h.lo or h.flags}
        health = {str(sid): servo_health(hs.get(sid), when) for sid in sorted(ids)}
        peak = self.load_peak
        t, wall = when(peak[1], 0) if peak else (None, None)
        return {
            "health": health,
            "bus_load_peak": None if peak is None else {"load": peak[0], "t": t, "wall": wall,
                                                        "window_s": LOAD_WINDOW},
            "what_happened": what_happened(self, health, when),
        }
