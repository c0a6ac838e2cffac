"""Q007's matrix lookup (lint.batch._before_rows: no sort) gives what the sorted lookup (_before) gives, on any
sets of values and any rows asked about, the rows x servos matrix of a long packet's VIDs among them."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from rs30x_sniff.lint.batch import UNKNOWN, _before, _before_rows, _last_per_servo

SERVOS = st.integers(1, 6)


@st.composite
def block(draw):
    """(rows in the Block, the sets per group, the shadow column before it, rows asked, servos asked)."""
    n_rows = draw(st.integers(1, 40))
    sets = []
    used: set[tuple[int, int]] = set()  # (order, servo): one value per point, as a Block sets them
    for _ in range(draw(st.integers(0, 4))):
        points = draw(st.lists(st.tuples(st.integers(0, n_rows - 1), st.integers(0, 300), SERVOS), max_size=30))
        points = [(r * 512 + sub, s) for r, sub, s in points if (r * 512 + sub, s) not in used]
        points = list(dict.fromkeys(points))
        used.update(points)
        sets.append((np.array([o for o, _ in points], dtype=np.int64), np.array([s for _, s in points], dtype=np.int64),
                     np.array(draw(st.lists(st.integers(-500, 500), min_size=len(points), max_size=len(points))),
                              dtype=np.int64)))
    column = np.full(256, UNKNOWN, dtype=np.int64)
    for s in draw(st.lists(SERVOS, max_size=3)):
        column[s] = draw(st.integers(-500, 500))
    if draw(st.booleans()):  # a grid: the same servos row after row
        vids = draw(st.lists(SERVOS, min_size=1, max_size=6, unique=True))
        asked = sorted(draw(st.sets(st.integers(0, n_rows - 1), min_size=1)))
        rows = np.repeat(np.array(asked, dtype=np.int64), len(vids))
        ids = np.tile(np.array(vids, dtype=np.int64), len(asked))
    else:
        pairs = draw(st.lists(st.tuples(st.integers(0, n_rows - 1), SERVOS), min_size=1, max_size=30))
        rows = np.array([r for r, _ in pairs], dtype=np.int64)
        ids = np.array([s for _, s in pairs], dtype=np.int64)
    return n_rows, sets, column, rows, ids


@settings(max_examples=300, deadline=None)
@given(block())
def test_matrix_lookup_equals_sorted_lookup(case):
    n_rows, sets, column, rows, ids = case
    got = _before_rows(sets, column, n_rows)(rows, ids)
    want = _before(sets, column)(rows * 512, ids)
    assert got is not None
    assert got.tolist() == want.tolist()


def test_two_values_at_one_point_go_the_general_way():
    """A return holding goal_position and present_position sets "pos" twice at one point: the matrix declines."""
    one = (np.array([512], dtype=np.int64), np.array([3], dtype=np.int64), np.array([10], dtype=np.int64))
    two = (np.array([512], dtype=np.int64), np.array([3], dtype=np.int64), np.array([20], dtype=np.int64))
    column = np.full(256, UNKNOWN, dtype=np.int64)
    assert _before_rows([one, two], column, 4)(np.array([2]), np.array([3])) is None
    assert _before_rows([one], column, 4)(np.array([2, 1]), np.array([3, 3])).tolist() == [10, UNKNOWN]


def _last_by_sort(sets) -> dict[int, int]:
    """The reference: sorted by servo and order (stable: of two at one point, the later set), each servo's last."""
    order = np.concatenate([s[0] for s in sets])
    ids = np.concatenate([s[1] for s in sets])
    vals = np.concatenate([s[2] for s in sets])
    k = np.lexsort((order, ids))
    ids, vals = ids[k], vals[k]
    last = np.flatnonzero(np.append(ids[1:] != ids[:-1], True))
    return dict(zip(ids[last].tolist(), vals[last].tolist()))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.lists(st.tuples(st.integers(0, 4000), SERVOS, st.integers(-500, 500)), min_size=1, max_size=20),
                min_size=1, max_size=4))
def test_last_per_servo_equals_the_sorted_way(groups):
    """Ties included (one point, two values): the later set wins, as the linter applies them."""
    sets = [tuple(np.array(col, dtype=np.int64) for col in zip(*g)) for g in groups]
    assert _last_per_servo(sets) == _last_by_sort(sets)
