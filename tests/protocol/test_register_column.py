"""A register read from columns (Register.raw_column, value_column) is held to Register.value_of, per row."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from rs30x_sniff.protocol.memmap import Register, default_registry

REGISTERS = sorted({(m.name, r.address): r for m in default_registry().models.values() for r in m.registers}.items())


def _row_value(reg: Register, raw: bytes, partial: str | None) -> object:
    """What a record says: the bytes as value_of takes them (as Layout.values and Register.value_in read)."""
    return reg.value_of(int.from_bytes(raw, "little", signed=reg.signed and not partial), partial)


@pytest.mark.parametrize(("key", "reg"), REGISTERS, ids=[f"{m}:{a}" for (m, a), _ in REGISTERS])
def test_every_register_from_columns_is_value_of(key, reg: Register) -> None:
    rng = random.Random(f"{key}")
    rows = 400
    data = np.frombuffer(rng.randbytes(rows * 8), dtype=np.uint8)
    at = np.array(rng.sample(range(len(data) - 8), rows), dtype=np.int64)
    partials = [None] + (["low", "high"] if reg.size == 2 else [])
    for partial in partials:
        size = 1 if partial else reg.size
        raw = reg.raw_column(data, at, partial)
        assert raw.dtype == np.int64
        want = [_row_value(reg, data[p:p + size].tobytes(), partial) for p in at.tolist()]
        assert [reg.value_of(r, partial) for r in raw.tolist()] == want
    # value_column: the values as numbers, the rest (an enum's label, an unknown code) flagged.
    values, ok = reg.value_column(reg.raw_column(data, at))
    for v, k, w in zip(values.tolist(), ok.tolist(), (_row_value(reg, data[p:p + reg.size].tobytes(), None)
                                                        for p in at.tolist())):
        assert k == isinstance(w, (int, float))
        if k:
            assert v == float(w) or (math.isnan(v) and math.isnan(w))
    # The same column of a matrix of frame rows (matrix.T, a column index), as the health sink reads it.
    mat = data[:rows * 8].reshape(rows, 8)
    col = reg.raw_column(mat.T, 3)
    assert col.tolist() == [int.from_bytes(r[3:3 + reg.size].tobytes(), "little", signed=reg.signed) for r in mat]


def test_every_raw_value_of_a_two_byte_signed_register() -> None:
    """Every raw value, both signs: the table read by a signed raw value (a negative index) is the right one."""
    reg = next(r for _, r in REGISTERS if r.size == 2 and r.signed)
    raw16 = np.arange(1 << 16, dtype=np.int64)
    data = np.empty(2 << 16, dtype=np.uint8)
    data[0::2], data[1::2] = raw16 & 0xFF, raw16 >> 8
    raw = reg.raw_column(data, np.arange(0, 2 << 16, 2))
    assert raw.min() == -(1 << 15) and raw.max() == (1 << 15) - 1
    values, ok = reg.value_column(raw)
    assert ok.all() and values.tolist() == [float(reg.value_of(r)) for r in raw.tolist()]


def test_a_wider_register_from_columns() -> None:
    """Four bytes, signed (no bundled model has one): raw_column and value_column still agree with value_of."""
    reg = Register("wide", 0, size=4, signed=True, scale=0.5)
    data = np.frombuffer(bytes([0xFF, 0xFF, 0xFF, 0xFF, 1, 0, 0, 0x80, 2, 0, 0, 0]), dtype=np.uint8)
    at = np.array([0, 4, 8])
    raw = reg.raw_column(data, at)
    assert raw.tolist() == [-1, -(1 << 31) + 1, 2]
    values, ok = reg.value_column(raw)
    assert ok.all() and values.tolist() == [reg.value_of(r) for r in raw.tolist()]
