"""Points of a register over time: the value a Record carries, and the values of a Block's rows from its columns."""

from __future__ import annotations

from typing import Any
from collections.abc import Iterable

import numpy as np

from ..decode.blocks import Block
from ..decode.frame_runs import LONG
from ..decode.pairing import Record
from ..protocol.events import LongPacket, ReturnPacket, ShortPacket
from ..protocol.wire import AT_DATA, VID_SIZE


def register_value(rec: Record, servo_id: int, name: str) -> Any:
    """The value of register ``name`` of ``servo_id`` that a record carries, if it carries all of it."""
    ev = rec.event
    model = rec.model
    if model is None or not ev.checksum_ok:
        return None
    if type(ev) is ReturnPacket or type(ev) is ShortPacket:
        if ev.id != servo_id or not ev.data:
            return None
        address, data = ev.address, ev.data
    elif type(ev) is LongPacket:
        for r in ev.records:
            if r.vid == servo_id:
                # rec.model is the bus default here; the register addresses the plot offers are the
                # same in every model's map (tables 4.5 and 4.6), so it finds the right bytes.
                address, data = ev.address, r.data
                break
        else:
            return None
    else:
        return None
    try:
        return model.register(name).value_in(address, data)
    except KeyError:
        return None


def _register_of(model: Any, name: str) -> Any:
    if model is None:
        return None
    try:
        return model.register(name)
    except KeyError:
        return None


def block_points(blk: Block, ids: Iterable[int], name: str, byte_seconds: float,
                 a: int = 0) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """For each servo of ``ids``: (times, values) of register ``name`` in rows ``a``.. of a Block, as
    register_value reads it from each row's record (a servo's returns and the writes to it, and its
    record of each long packet), in row order."""
    cols, run = blk.cols, blk.run
    kind, sid = cols["kind"][a:], cols["id"][a:]
    dlen = cols["data_len"][a:].astype(np.int64)
    address = cols["address"][a:].astype(np.int64)
    starts = run.starts[blk.lo + a:blk.hi]
    t0 = None if run.t0 is None else run.t0[blk.lo + a:blk.hi]
    arr = run.bytes_array
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    own = (kind != LONG) & (dlen > 0)
    long_rows = np.flatnonzero((kind == LONG) & (cols["length"][a:] > 0) & (dlen > 0))
    long_reg = _register_of(blk.default, name) if long_rows.size else None
    if long_reg is not None:
        # Long packets whose records hold the register: most write other registers (goal positions
        # while present_position is plotted), and then none is read.
        ln = cols["length"][a:][long_rows].astype(np.int64)
        reach = long_reg.address - address[long_rows]
        covers = (reach >= 0) & (reach + long_reg.size <= ln - VID_SIZE)
        if not covers.all():
            long_rows, ln = long_rows[covers], ln[covers]
        if not long_rows.size:
            long_reg = None
    for servo in ids:
        rows_parts, at_parts, regs = [], [], []
        rows = np.flatnonzero(own & (sid == servo))
        reg = _register_of(blk.models.get(servo), name) if rows.size else None
        if reg is not None:
            start = reg.address - address[rows]
            fits = (start >= 0) & (start + reg.size <= dlen[rows])
            rows_parts.append(rows[fits])
            at_parts.append(starts[rows[fits]] + AT_DATA + start[fits])
            regs.append(reg)
        if long_reg is not None:
            dl = dlen[long_rows]
            nrec = -(-dl // ln)
            width = int(nrec.max())
            j = np.arange(width)
            vid_at = starts[long_rows][:, None] + AT_DATA + j * ln[:, None]
            valid = j < nrec[:, None]
            hit = valid & (arr[np.minimum(vid_at, len(arr) - 1)] == servo)
            has = hit.any(axis=1)
            if has.any():
                first = hit.argmax(axis=1)[has]  # the first record for the servo, as register_value takes
                r = long_rows[has]
                lnr, dlr = ln[has], dl[has]
                data_len = np.minimum(lnr - VID_SIZE, dlr - first * lnr - VID_SIZE)
                start = long_reg.address - address[r]
                fits = (start >= 0) & (start + long_reg.size <= data_len)
                rows_parts.append(r[fits])
                at_parts.append(starts[r[fits]] + AT_DATA + first[fits] * lnr[fits] + VID_SIZE + start[fits])
                regs.append(long_reg)
        if not rows_parts:
            continue
        got_rows, got_vals = [], []
        for rws, at, reg in zip(rows_parts, at_parts, regs):
            if rws.size:
                # Register.raw_column and value_column: the one decoding of a register from columns.
                vals, ok = reg.value_column(reg.raw_column(arr, at))
                got_rows.append(rws[ok])
                got_vals.append(vals[ok])
        if not got_rows:
            continue
        rws = np.concatenate(got_rows)
        vals = np.concatenate(got_vals)
        if len(got_rows) > 1:
            order = np.argsort(rws, kind="stable")
            rws, vals = rws[order], vals[order]
        if not rws.size:
            continue
        times = t0[rws] if t0 is not None else (run.base + starts[rws]) * byte_seconds
        out[servo] = (times, vals)
    return out
