"""The monitor's own running figures since the last clear: counts by kind and severity, capture time, bus load."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import cast
import numpy as np

from ..decode.blocks import Block
from ..decode.frame_runs import LONG, RETURN, SHORT
from ..decode.framing import SEAM_BACK_S, SEAM_GAP_S
from ..decode.pairing import Record

LOAD_WINDOW = 1.0  # seconds of capture time the bus load is measured over
BLOCK_KINDS = ((SHORT, "short"), (LONG, "long"), (RETURN, "return"))  # a Block's kind codes, by name


@dataclass
class Stats:
    """Running counts since the last clear. Time segments are told by the times themselves (a clock
    running back or a long gap: rs30x_sniff.decode.framing's SEAM_BACK_S, SEAM_GAP_S)."""

    records: int = 0
    missing: int = 0       # requests whose reply never came
    kinds: Counter = field(default_factory=Counter)
    severities: Counter = field(default_factory=Counter)
    first_t: float | None = None
    last_t: float | None = None
    segment_t: float | None = None  # first time of the current time segment (rs30x_sniff.decode.framing.Seam)
    closed_span: float = 0.0        # seconds of the segments before it

    @property
    def packets(self) -> int:
        """Requests and returns (not ACK/NACK bytes or garbage)."""
        k = self.kinds
        return k["short"] + k["long"] + k["return"]

    @property
    def replies(self) -> int:
        """Returns, ACKs and NACKs."""
        k = self.kinds
        return k["return"] + k["ack"] + k["nack"]

    @property
    def garbage(self) -> int:
        return self.kinds["garbage"]

    @property
    def span(self) -> float | None:
        """Capture time from the first to the last timed record, added up over the time segments (None
        without timestamps)."""
        if self.first_t is None or self.last_t is None or self.segment_t is None:
            return None
        return self.closed_span + max(0.0, self.last_t - self.segment_t)

    def count_records(self, records: list[Record], loads: list) -> None:
        """Count Records; their (t, bytes) on the wire go to ``loads`` (as one list) when they are timed."""
        kinds = self.kinds
        timed: list[tuple[float, int]] = []
        load = timed.append
        # This loop runs on the screen's thread for every record: keep it lean.
        missing = 0
        first_t = self.first_t
        last_t = None
        # segment_t and last_t are None only while first_t is, and the loop reads them only after it set
        # first_t: typed as floats here rather than tested on every record
        seg_t, closed, prev_t = cast(float, self.segment_t), self.closed_span, cast(float, self.last_t)
        for rec in records:
            ev = rec.event
            kinds[ev.kind] += 1
            if rec.status == "missing":
                missing += 1
            t = ev.t_start
            if t is not None:
                if first_t is None:
                    first_t = seg_t = t
                elif t < prev_t - SEAM_BACK_S or t - prev_t > SEAM_GAP_S:
                    closed += max(0.0, prev_t - seg_t)  # a seam of the clock: spans add up, never run back
                    seg_t = t
                last_t = prev_t = t
                load((t, len(ev.raw)))
        self.missing += missing
        self.first_t = first_t
        self.segment_t, self.closed_span = seg_t, closed
        if last_t is not None:
            self.last_t = last_t
        if timed:
            loads.append(timed)

    def count_block(self, blk: Block, loads: list) -> None:
        """Count a Block's rows from its columns; its (times, sizes) go to ``loads`` when it is timed."""
        kinds = self.kinds
        counts = np.bincount(blk.cols["kind"], minlength=3).tolist()
        for code, name in BLOCK_KINDS:
            if counts[code]:
                kinds[name] += counts[code]
        t0 = blk.t0
        if t0 is not None:
            t = float(t0[0])
            last, seg = self.last_t, self.segment_t
            if self.first_t is None or last is None or seg is None:  # all three are set together
                self.first_t = self.segment_t = t
            elif t < last - SEAM_BACK_S or t - last > SEAM_GAP_S:  # a Block never spans a seam
                self.closed_span += max(0.0, last - seg)
                self.segment_t = t
            self.last_t = float(t0[-1])
            run = blk.run
            loads.append((t0, run.ends[blk.lo:blk.hi] - run.starts[blk.lo:blk.hi]))


def load_arrays(loads: list) -> tuple[np.ndarray, np.ndarray]:
    """The (t, bytes) of a batch's Records and Blocks, in order, as two arrays."""
    ts, ns = [], []
    for part in loads:
        if type(part) is list:
            ts.append(np.array([t for t, _ in part], dtype=float))
            ns.append(np.array([n for _, n in part], dtype=np.int64))
        else:
            ts.append(part[0])
            ns.append(part[1])
    if len(ts) == 1:
        return ts[0], ns[0]
    return np.concatenate(ts), np.concatenate(ns)
