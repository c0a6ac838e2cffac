"""The plotted series: a register's points per servo, grown batch by batch and refilled from the history."""

from __future__ import annotations

from collections import deque
from typing import Any
from collections.abc import Iterable

from ..decode.blocks import Block
from ..decode.pairing import Record
from ..protocol.events import LongPacket
from ..protocol.wire import byte_time
from .history import History
from .plot_points import block_points, register_value

PLOT_POINTS = 4096  # samples kept per plotted servo (drawn binned by time, so a long capture stays readable)
# Registers the plot can show, in the order `p` cycles through them.
PLOT_REGISTERS = ("present_position", "present_speed", "present_current", "present_temperature",
                  "present_voltage", "goal_position")
NOT_READ = object()  # a Block whose points newest_points has not read ahead


class PlottedSeries:
    """Register ``register`` of servo ``servo_id`` (and with ``all_servos`` of every servo beside it):
    (times, values) per servo, the newest ``points`` of each. A capture without times is plotted
    against line time (the byte's offset times a byte's time at ``baud``)."""

    def __init__(self, baud: int, points: int = PLOT_POINTS) -> None:
        self.byte_seconds = byte_time(baud)
        self.points = points
        self.servo_id: int | None = None
        self.register = PLOT_REGISTERS[0]
        self.all_servos = False
        self.series: dict[int, tuple[deque[float], deque[float]]] = {}  # servo -> (times, values)

    @property
    def values(self) -> deque[float]:
        """The plotted servo's values, oldest first."""
        pair = self.series.get(self.servo_id) if self.servo_id is not None else None
        return pair[1] if pair is not None else deque()

    def refill(self, history: History, servos: Iterable[int]) -> None:
        """The series of the plotted servo (and of ``servos`` beside it with ``all_servos``) from the held
        history, read from the newest row back until every servo has its points."""
        self.series = {}
        servo_id = self.servo_id
        if servo_id is None:
            return
        ids = [servo_id] + ([i for i in sorted(servos) if i != servo_id] if self.all_servos else [])
        found: dict[int, tuple[list[float], list[float]]] = {i: ([], []) for i in ids}  # newest first
        full: set[int] = set()
        byte_seconds = self.byte_seconds
        points = self.points
        register = self.register
        first_seq = history.first_seq
        for seg, start in history.newest_first():
            if type(seg) is Block:  # (else a list of Records; Block is final: narrowed both ways)
                hidden = max(0, first_seq - start)
                wanted = [i for i in ids if i not in full]
                for sid, (bts, bvs) in block_points(seg, wanted, register, byte_seconds, hidden).items():
                    fts, fvs = found[sid]
                    need = points - len(fvs)
                    fts += bts[::-1][:need].tolist()
                    fvs += bvs[::-1][:need].tolist()
                    if len(fvs) >= points:
                        full.add(sid)
                if len(full) == len(ids):
                    break
                continue
            for rec in reversed(seg):
                ev = rec.event
                one: int = getattr(ev, "id", -1)  # -1: no servo (ACK, NACK, garbage), never a key of found
                for sid in ids if type(ev) is LongPacket else ((one,) if one in found else ()):
                    if sid in full:
                        continue
                    v = register_value(rec, sid, register)
                    if isinstance(v, (int, float)):
                        ts, vs = found[sid]
                        ts.append(ev.offset * byte_seconds if ev.t_start is None else ev.t_start)
                        vs.append(float(v))
                        if len(vs) >= points:
                            full.add(sid)
                if len(full) == len(ids):
                    break
            if len(full) == len(ids):
                break
        for sid, (ts, vs) in found.items():
            self.series[sid] = (deque(reversed(ts), maxlen=points), deque(reversed(vs), maxlen=points))

    def add_records(self, records: Iterable[Record]) -> None:
        """The points new Records carry."""
        series, register = self.series, self.register
        byte_seconds = self.byte_seconds
        for rec in records:
            ev = rec.event
            if type(ev) is LongPacket:
                t = ev.t_start
                for sid, (ts, vs) in series.items():
                    v = register_value(rec, sid, register)
                    if isinstance(v, (int, float)):
                        ts.append(ev.offset * byte_seconds if t is None else t)
                        vs.append(float(v))
            else:
                one = getattr(ev, "id", -1)  # -1: no servo, never a key of series
                if one in series:
                    v = register_value(rec, one, register)
                    if isinstance(v, (int, float)):
                        ts, vs = series[one]
                        t = ev.t_start
                        ts.append(ev.offset * byte_seconds if t is None else t)
                        vs.append(float(v))

    def newest_points(self, items: list[Record | Block]) -> dict[Block, Any]:
        """The points of a batch's last Blocks, newest first, as far back as the plot keeps (``points``
        a servo): {a Block: its points, or None where none of them is kept}. A long load has far more
        points than the plot holds; Blocks before the newest run of Records are not looked at here
        (:meth:`add_block` reads them)."""
        want = {sid: self.points for sid in self.series}
        out: dict[Block, Any] = {}
        for x in reversed(items):
            if type(x) is not Block:
                break
            if not want:
                out[x] = None  # older than every point the plot keeps
                continue
            got = out[x] = block_points(x, list(want), self.register, self.byte_seconds)
            for sid, (_, vs) in got.items():
                want[sid] -= len(vs)
                if want[sid] <= 0:
                    del want[sid]
        return out

    def add_block(self, blk: Block, points: Any = NOT_READ) -> None:
        """The points of a new Block (``points``: as :meth:`newest_points` read them, None: none kept)."""
        if points is None:
            return
        if points is NOT_READ:
            points = block_points(blk, list(self.series), self.register, self.byte_seconds)
        keep = self.points
        for sid, (ts, vs) in points.items():
            pts = self.series[sid]
            pts[0].extend(ts[-keep:].tolist())
            pts[1].extend(vs[-keep:].tolist())
