"""value_columns: a layout's numpy columns equal Layout.values / unpack_raw row by row, in value, type and bits."""

import math
from itertools import chain

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rs30x_sniff.protocol.memmap import Layout, default_registry, parse_model
from rs30x_sniff.decode.value_columns import raw_columns, value_columns, values_rows

MODELS = sorted(default_registry().models)
DTYPES = {np.dtype(np.int64), np.dtype(np.float64), np.dtype(object)}


def _width(layout):
    return layout.records * (layout.size + 1) if layout.records else layout.size


def _matrix(width, seed, random_rows=4):
    """Edge rows (all 00, all FF, all 7F, all 80, 7F/80 and 80/7F alternating), rows of small codes that
    hit the enums and tables, and random rows; fixed seed."""
    rng = np.random.default_rng(seed)
    alt = np.resize(np.array([0x7F, 0x80], dtype=np.uint8), width)
    edge = [np.full(width, b, dtype=np.uint8) for b in (0x00, 0xFF, 0x7F, 0x80)] + [alt, alt[::-1].copy()]
    small = rng.integers(0, 12, (2, width), dtype=np.uint8)
    rand = rng.integers(0, 256, (random_rows, width), dtype=np.uint8)
    return np.vstack(edge + [small, rand]).reshape(-1, width)


def _same(got, want, bits=True):
    """Lists of value tuples: equal, element by element of the same type, and (``bits``) floats bit for bit."""
    assert got == want
    assert list(map(type, chain.from_iterable(got))) == list(map(type, chain.from_iterable(want)))
    if bits:
        # repr tells every float64 apart, sign of zero included: bit-exact, not just ==. (Equal floats of
        # equal type can differ only in the sign of zero, which copysign shows too.)
        assert list(map(repr, chain.from_iterable(got))) == list(map(repr, chain.from_iterable(want)))
        floats = [(a, b) for a, b in zip(chain.from_iterable(got), chain.from_iterable(want)) if type(a) is float]
        assert [math.copysign(1.0, a) for a, _ in floats] == [math.copysign(1.0, b) for _, b in floats]


def _check(layout, matrix, full=True):
    """values_rows and raw_columns of ``matrix`` against Layout.values / unpack_raw, row by row; ``full``
    adds the bits of the floats and value_columns' own columns (dtypes, lengths, ``.item()``)."""
    rows = [bytes(r) for r in matrix]
    want = [layout.values(r) for r in rows]
    _same(values_rows(layout, matrix), want, full)
    raws = raw_columns(layout, matrix)
    assert {c.dtype for c in raws} <= {np.dtype(np.int64)} and {c.shape for c in raws} <= {(len(rows),)}
    want_raw = [layout.unpack_raw(r) for r in rows]
    assert (list(zip(*(c.tolist() for c in raws))) if raws else [()] * len(rows)) == want_raw
    if full:
        cols = value_columns(layout, matrix)
        assert len(cols) == len(want[0])
        assert all(c.ndim == 1 and c.shape[0] == len(rows) and c.dtype in DTYPES for c in cols)
        # .item() on the columns themselves, not only through tolist()
        _same([tuple(c.item(i) for c in cols) for i in range(len(rows))], want)


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("address", range(140))
def test_every_short_layout_of_the_map(name, address):
    """Every (address, length) a read or write of the map can have: address + length up to readable_to + 1.
    The full check on every layout up to 16 bytes (each register at each cut) and on the longest."""
    model = default_registry().get(name)
    end = model.readable_to + 1
    matrix = _matrix(end - address, seed=address, random_rows=2)
    for length in range(1, end - address + 1):
        # Layout itself, as Model.layout makes it, so the model's cache does not keep 10,000 of them.
        _check(Layout(model, address, length), np.ascontiguousarray(matrix[:, :length]),
               full=length <= 16 or address + length == end)


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("length", range(1, 9))
def test_long_layouts(name, length):
    """Long packets: count records of VID + length - 1 bytes, at addresses 0-69."""
    model = default_registry().get(name)
    for count in range(1, 5):
        matrix = _matrix(count * length, seed=100 * length + count, random_rows=3)
        for address in range(70):  # the documented map (0-59) and past its end
            _check(model.long_layout(address, length, count), matrix)


def test_long_layout_of_vids_alone_gives_the_vids():
    """Length 1: no bytes after the VID, and Layout.values is then unpack itself, VIDs and all."""
    lay = default_registry().default.long_layout(30, 1, 3)
    m = np.array([[1, 2, 3], [0xFF, 0x80, 0x7F]], dtype=np.uint8)
    assert values_rows(lay, m) == [(1, 2, 3), (255, 128, 127)] == [lay.values(bytes(r)) for r in m]


def test_the_column_types():
    model = default_registry().default
    lay = model.layout(0, 60)
    kinds = {}
    for (_, _, reg, partial), c in zip(lay.parts, value_columns(lay, _matrix(60, 1))):
        kinds[reg.label] = c.dtype
    assert kinds["goal_position"] == np.float64 and kinds["present_temperature"] == np.int64
    assert kinds["baud_rate"] == object and kinds["reverse"] == object and kinds["return_delay"] == np.int64
    m = np.zeros((1, 60), dtype=np.uint8)
    m[0, 5], m[0, 6], m[0, 36] = 7, 200, 2  # reverse: unknown code; baud_rate: no such code; torque: brake
    row = values_rows(lay, m)[0]
    assert row == lay.values(bytes(m[0]))
    at = {reg.label: j for j, (_, _, reg, _) in enumerate(lay.parts)}
    assert (row[at["reverse"]], row[at["baud_rate"]], row[at["torque_enable"]]) == (7, None, "brake")
    assert type(row[at["reverse"]]) is int


def test_empty_matrix_and_empty_layout():
    model = default_registry().default
    lay = model.layout(30, 4)
    empty = np.zeros((0, 4), dtype=np.uint8)
    assert values_rows(lay, empty) == []
    assert all(c.shape == (0,) for c in value_columns(lay, empty) + raw_columns(lay, empty))
    nothing = model.layout(30, 0)
    assert values_rows(nothing, np.zeros((3, 0), dtype=np.uint8)) == [()] * 3 == [nothing.values(b"")] * 3


def test_non_contiguous_matrices():
    lay = default_registry().default.layout(30, 4)
    big = _matrix(9, 3)
    for m in (big[:, 2:6], np.asfortranarray(big[:, :4]), big[::2, 1:5]):
        _check(lay, m)


def test_wrong_matrices_are_refused():
    lay = default_registry().default.layout(30, 4)
    with pytest.raises(ValueError, match="4"):
        value_columns(lay, np.zeros((2, 5), dtype=np.uint8))
    with pytest.raises(TypeError):
        raw_columns(lay, np.zeros((2, 4), dtype=np.int16))
    with pytest.raises(TypeError):
        value_columns(lay, np.zeros(4, dtype=np.uint8))
    with pytest.raises(TypeError):
        value_columns(lay, b"\x00" * 4)


def test_the_plan_is_made_once_per_layout():
    lay = default_registry().default.long_layout(30, 5, 18)
    m = _matrix(_width(lay), 4)
    value_columns(lay, m)
    plan = lay._columns
    assert plan is not None
    value_columns(lay, m)
    assert lay._columns is plan


def _layouts():
    model = default_registry().default
    other = default_registry().get("RS304MD")
    return [model.layout(0, 60), model.layout(42, 18), model.layout(55, 20), model.long_layout(30, 5, 18),
            model.long_layout(3, 4, 2), other.layout(0, 140), other.long_layout(58, 7, 3)]


@settings(max_examples=60, deadline=None)
@given(st.integers(0, len(_layouts()) - 1), st.data())
def test_random_rows(which, data):
    lay = _layouts()[which]
    width = _width(lay)
    rows = data.draw(st.lists(st.binary(min_size=width, max_size=width), min_size=1, max_size=8))
    m = np.frombuffer(b"".join(rows), dtype=np.uint8).reshape(len(rows), width)
    _check(lay, m)


def test_every_raw_value_of_every_register():
    """Each register alone, at every bit pattern (65,536 for a 2-byte one): bit-exact floats everywhere,
    not only at the sampled rows. Registers that convert alike (in any model) are checked once."""
    seen = set()
    for name in MODELS:
        model = default_registry().get(name)
        for reg in model.registers:
            sig = (reg.size, reg.signed, reg.name is None, reg.scale, type(reg.scale), reg.offset,
                   type(reg.offset), None if reg.enum is None else tuple(reg.enum.items()),
                   None if reg.table is None else tuple(reg.table.items()))
            if sig in seen:
                continue
            seen.add(sig)
            patterns = np.arange(1 << (8 * reg.size), dtype=np.uint32)
            matrix = np.stack([(patterns >> (8 * i)).astype(np.uint8) for i in range(reg.size)], axis=1)
            lay = model.layout(reg.address, reg.size)
            rows = list(map(bytes, matrix))
            _same(values_rows(lay, matrix), [lay.values(r) for r in rows])
            assert list(zip(*(c.tolist() for c in raw_columns(lay, matrix)))) == [lay.unpack_raw(r) for r in rows]

def _synthetic():
    """A memory map with every kind of conversion memmap compiles, including look-alikes that must not
    share a group: an offset of 1 and of 1.0, a factor of 2 and of 2.0."""
    regs = [
        {"name": "half", "address": 0, "scale": 0.5},                            # r / 2
        {"name": "odd", "address": 1, "size": 2, "signed": True, "scale": 2.5},  # r * 2.5
        {"name": "twice", "address": 3, "scale": 2},                             # r * 2, an int
        {"name": "twice_f", "address": 4, "scale": 2.0},                         # r * 2.0, a float
        {"name": "plus", "address": 5, "offset": 1},                             # 1 + r, an int
        {"name": "plus_f", "address": 6, "offset": 1.0},                         # 1.0 + r, a float
        {"name": "third", "address": 7, "scale": 0.3, "offset": -4},             # -4 + r * 0.3
        {"name": "tenth", "address": 8, "size": 2, "signed": True, "scale": 0.1, "offset": 0.25},
        {"name": "unit", "address": 10, "scale": 1.0},                           # r: scale == 1
        {"name": "mode", "address": 11, "size": 2, "signed": True, "enum": {"-1": "back", "0": "off", "300": 7}},
        {"name": "rate", "address": 13, "size": 2, "table": {"0": 1.5, "65535": 9, "256": 2.0}},
        {"name": "sb", "address": 15, "signed": True, "enum": {"-128": "min", "127": "max", "1000": "never"}},
        {"name": "twice_b", "address": 16, "scale": 2},                          # grouped with "twice"
        {"name": "plus_b", "address": 17, "offset": 1.0},                        # grouped with "plus_f"
        {"address": 18, "access": "reserved", "signed": True},                   # unnamed: raw, signed
        {"name": "neg", "address": 19, "signed": True, "scale": 0.01, "offset": -0.0},
    ]
    return parse_model({"model": {"name": "SYNTH", "model_number": 1, "top_speed_s_per_60deg": 0.1,
                                  "readable_to": 30}, "register": regs})


def test_every_kind_of_conversion():
    model = _synthetic()
    rng = np.random.default_rng(7)
    for address in range(21):
        for length in range(1, 22 - address):
            _check(model.layout(address, length), _matrix(length, address))
    for length in range(1, 9):
        for count in (1, 3):
            for address in range(22 - length):
                _check(model.long_layout(address, length, count), _matrix(count * length, length))
    for reg in model.registers:  # every bit pattern of each register
        patterns = np.arange(1 << (8 * reg.size), dtype=np.uint32)
        m = np.stack([(patterns >> (8 * i)).astype(np.uint8) for i in range(reg.size)], axis=1)
        lay = model.layout(reg.address, reg.size)
        _same(values_rows(lay, m), [lay.values(r) for r in map(bytes, m)])
    lay = model.layout(0, 21)
    m = rng.integers(0, 256, (5000, 21), dtype=np.uint8)
    _same(values_rows(lay, m), [lay.values(r) for r in map(bytes, m)])
