"""Columnar decoding: a layout's raw and engineering values for many packets at once, one numpy column each."""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..protocol.memmap import Layout, Register

__all__ = ["raw_columns", "value_columns", "values_rows"]


class _Group(NamedTuple):
    """Columns decoded together: the parts of one shape (size, signed) and conversion, at byte offsets
    ``offsets`` of a row, landing at ``positions`` of the output. One np.take and one conversion per
    group, not per column, keeps the numpy calls per layout few (a long packet's 18 goal positions are
    one group) and cuts the passes over the matrix; each column is a row of the group's block."""

    size: int              # 1 or 2 bytes, little-endian
    signed: bool           # struct's "b" / "h"
    kind: str              # "raw", "lut", "div", "mul" or "add"
    arg: Any               # lut: object array indexed by the unsigned bit pattern; div: divisor; mul: factor
    add: Any               # the register's offset, added last when truthy (as the compiled expression does)
    offsets: np.ndarray    # the byte offsets, 2 per part for 2-byte parts (low, high), for np.take
    positions: tuple[int, ...]


class _Plan(NamedTuple):
    width: int
    raw: tuple[_Group, ...]
    n_raw: int
    values: tuple[_Group, ...]
    n_values: int


# LUTs by (id of the enum/table dict, is enum, size, signed); the dict is kept so its id stays unique.
_LUTS: dict[tuple[int, bool, int, bool], tuple[dict, np.ndarray]] = {}
_RAW = ("raw", None, 0)  # (kind, arg, add) of a part whose value is its raw integer


def _lut(mapping: dict, is_enum: bool, size: int, signed: bool) -> np.ndarray:
    """Object array of ``E.get(r, r)`` (enums) or ``T.get(r)`` (tables) for every raw value, indexed by the
    raw value's unsigned bit pattern so a column maps with one fancy index and no int64 conversion."""
    key = (id(mapping), is_enum, size, signed)
    hit = _LUTS.get(key)
    if hit is not None and hit[0] is mapping:
        return hit[1]
    bits = 8 * size
    raw = np.arange(1 << bits, dtype=np.int64)
    if signed:
        raw = np.where(raw >= 1 << (bits - 1), raw - (1 << bits), raw)
    # astype(object) makes Python ints, the same objects E.get(r, r) hands back for unknown codes.
    lut = raw.astype(object) if is_enum else np.full(1 << bits, None, dtype=object)
    lo, hi = int(raw.min()), int(raw.max())
    for k, v in mapping.items():
        if type(k) is int and lo <= k <= hi:
            lut[k & ((1 << bits) - 1)] = v  # element assignment stores v as is (never broadcast)
    _LUTS[key] = (mapping, lut)
    return lut


def _conversion(reg: Register, signed: bool) -> tuple:
    """(kind, arg, add) of a whole, named register: a mirror of ``memmap._conversion``, the same
    operation on the same operand types, so float64 results are bit-identical to Python's (int / int
    and int * float round once, as numpy's true_divide and multiply of float64 do)."""
    if reg.enum is not None:
        return ("lut", _lut(reg.enum, True, reg.size, signed), 0)
    if reg.table is not None:
        return ("lut", _lut(reg.table, False, reg.size, signed), 0)
    scale, off = reg.scale, reg.offset
    if scale == 1:
        return ("add", None, off) if off else _RAW
    divisor = reg.divisor
    if divisor is not None:
        return ("div", divisor, off)
    return ("mul", scale, off)


def _plan(layout: Layout) -> _Plan:
    """The layout's plan, made once and kept on the layout (Layout._columns)."""
    plan = layout._columns
    if plan is not None:
        return plan
    records = layout.records
    stride = layout.size + (1 if records else 0)
    raw_specs: list[tuple] = []    # (size, signed, kind, arg, add) of each group
    value_specs: list[tuple] = []
    raw_index: dict[tuple, int] = {}  # group key -> index in the specs
    value_index: dict[tuple, int] = {}
    # One record's parts: (start, size, raw group, value group), with the struct codes of
    # Layout.__init__ (a partial byte is always "B") and the raw value itself for partial and unnamed
    # parts. The value group's key tells conversions apart by type too (an add of 1 and of 1.0, or a
    # factor of 2 and 2.0, compare equal but make int and float columns) and a LUT by identity.
    parts = []
    for start, size, reg, partial in layout.parts:
        signed = reg.signed and not partial
        kind, arg, add = conv = _RAW if partial or reg.name is None else _conversion(reg, signed)
        key = (size, signed, kind, id(arg) if kind == "lut" else (type(arg), arg, type(add), add))
        r = raw_index.get((size, signed))
        if r is None:
            r = raw_index[(size, signed)] = len(raw_specs)
            raw_specs.append((size, signed) + _RAW)
        v = value_index.get(key)
        if v is None:
            v = value_index[key] = len(value_specs)
            value_specs.append((size, signed) + conv)
        parts.append((start, size, r, v))
    vid = None
    if records:  # the VID: in unpack_raw, never in values
        vid = raw_index.get((1, False))
        if vid is None:
            vid = raw_index[(1, False)] = len(raw_specs)
            raw_specs.append((1, False) + _RAW)
    raw_offsets: list[list[int]] = [[] for _ in raw_specs]
    raw_positions: list[list[int]] = [[] for _ in raw_specs]
    value_offsets: list[list[int]] = [[] for _ in value_specs]
    value_positions: list[list[int]] = [[] for _ in value_specs]
    n_raw = n_values = 0
    for rec in range(max(records, 1)):
        base = rec * stride
        if vid is not None:
            raw_offsets[vid].append(base)
            raw_positions[vid].append(n_raw)
            n_raw += 1
            base += 1
        for start, size, r, v in parts:
            offset = base + start
            pair = (offset, offset + 1) if size == 2 else (offset,)
            raw_offsets[r] += pair
            raw_positions[r].append(n_raw)
            value_offsets[v] += pair
            value_positions[v].append(n_values)
            n_raw += 1
            n_values += 1
    raw_groups = _groups(raw_specs, raw_offsets, raw_positions)
    if layout.values is layout.unpack_raw:
        # Layout uses unpack itself when no part converts; for a long layout with no bytes after the
        # VID (length 1) that means values are the VIDs, so mirror it rather than the usual rule.
        plan = _Plan(stride * max(records, 1), raw_groups, n_raw, raw_groups, n_raw)
    else:
        plan = _Plan(stride * max(records, 1), raw_groups, n_raw,
                     _groups(value_specs, value_offsets, value_positions), n_values)
    layout._columns = plan
    return plan


def _groups(specs: list[tuple], offsets: list[list[int]], positions: list[list[int]]) -> tuple[_Group, ...]:
    return tuple(_Group(*spec, np.array(offs, dtype=np.intp), tuple(poss))
                 for spec, offs, poss in zip(specs, offsets, positions))


def _check(plan: _Plan, matrix: np.ndarray) -> np.ndarray:
    if not isinstance(matrix, np.ndarray) or matrix.dtype != np.uint8 or matrix.ndim != 2:
        raise TypeError("matrix must be a 2-D numpy uint8 array, one row per packet")
    if matrix.shape[1] != plan.width:
        raise ValueError(f"matrix rows are {matrix.shape[1]} bytes, the layout takes {plan.width}")
    return matrix


def _gather(m: np.ndarray, g: _Group) -> np.ndarray:
    """The group's raw values, (rows, parts), in the narrowest exact dtype: (u)int8 or (u)int16.
    np.take makes a C-ordered copy, so the 2-byte pairs can be reinterpreted in place."""
    block = np.take(m, g.offsets, axis=1)
    if g.size == 2:
        return block.view("<i2" if g.signed else "<u2")
    return block.view(np.int8) if g.signed else block


def _ints(m: np.ndarray, g: _Group) -> np.ndarray:
    """The group's raw values as int64, one C-contiguous row per part (so each column is contiguous)."""
    return _gather(m, g).T.astype(np.int64, order="C")


def _convert(m: np.ndarray, g: _Group) -> np.ndarray:
    kind, arg, add = g.kind, g.arg, g.add
    if kind == "lut":
        # Indexed by the unsigned bit pattern, so no int64 block is made; np.take's result is C-ordered.
        bits = np.take(m, g.offsets, axis=1)
        return np.take(arg, (bits.view("<u2") if g.size == 2 else bits).T)
    # The same operations, with the same operand types, as the compiled Python expression: every raw
    # value is an exact float64, and int / int, int * float and float + int round once in Python as
    # true division, multiplication and addition of the float64s do in numpy, so the bits agree.
    # Integer results (factor and offset ints) stay int64, as Python's ints stay ints.
    floats = kind == "div" or (kind == "mul" and type(arg) is float)
    block = _gather(m, g).T.astype(np.float64 if floats else np.int64, order="C")
    if kind == "div":
        block /= arg
    elif kind == "mul":
        block *= arg
    if add:
        if type(add) is float and block.dtype != np.float64:
            block = block.astype(np.float64)  # int + float is float(int) + float in Python
        block += add
    return block


def _columns(groups: tuple[_Group, ...], n: int, block_of: Any, m: np.ndarray) -> list[np.ndarray]:
    out: list[Any] = [None] * n
    for g in groups:
        for pos, col in zip(g.positions, block_of(m, g)):
            out[pos] = col
    return out


def raw_columns(layout: Layout, matrix: np.ndarray) -> list[np.ndarray]:
    """One int64 column per element of ``layout.unpack_raw(row)`` (VIDs included for long layouts),
    for ``matrix``: one row per packet, each row the bytes ``layout.values`` would be given."""
    plan = _plan(layout)
    return _columns(plan.raw, plan.n_raw, _ints, _check(plan, matrix))


def value_columns(layout: Layout, matrix: np.ndarray) -> list[np.ndarray]:
    """One column per element of ``layout.values(row)``: int64 for raw and integer-scaled parts, float64
    for scaled ones (bit-identical to the Python expression), object for enums and tables (str/int, or
    number/None), so each element's ``.item()`` equals the tuple's element and has its type.

    Columns of one conversion are rows of one 2-D block (views, each contiguous)."""
    plan = _plan(layout)
    return _columns(plan.values, plan.n_values, _convert, _check(plan, matrix))


def values_rows(layout: Layout, matrix: np.ndarray) -> list[tuple]:
    """``[layout.values(bytes(row)) for row in matrix]``, built from :func:`value_columns`."""
    cols = value_columns(layout, matrix)
    if not cols:
        return [()] * matrix.shape[0]
    # tolist() turns int64/float64 elements into Python int/float and leaves object elements as they are.
    return list(zip(*(c.tolist() for c in cols)))
