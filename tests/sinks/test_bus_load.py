"""The bus-load windows (sinks/bus_load.py): one-second windows from a segment's first byte, fed per record
or per Block's columns alike, and the busiest of them."""

from __future__ import annotations

import random

import numpy as np
import pytest

from rs30x_sniff.protocol.wire import byte_time
from rs30x_sniff.sinks.bus_load import LOAD_WINDOW, LoadWindows, stalled

BAUD = 115200


def _state(w: LoadWindows) -> tuple:
    return w.start, w.end, w.bytes, list(w.closed)


def test_windows_roll_from_the_first_byte_and_skip_empty_seconds():
    w = LoadWindows(BAUD)
    w.add(0.25, 100)
    w.add(0.75, 100)
    w.add(1.30, 50)   # the second window, from 1.25
    w.add(4.00, 10)   # windows from 2.25 on were empty: none is counted for them
    assert list(w.closed) == [(pytest.approx(200 * byte_time(BAUD)), 0.25), (pytest.approx(50 * byte_time(BAUD)), 1.25)]
    assert (w.start, w.end, w.bytes) == (3.25, 3.25 + LOAD_WINDOW, 10)


def test_the_open_window_counts_once_it_spans_half_a_window():
    w = LoadWindows(BAUD)
    w.add(0.0, 1000)
    assert w.open_load(0.4) is None
    assert w.open_load(0.5) == pytest.approx(1000 * byte_time(BAUD) / 0.5)
    assert w.open_load(None) is None


def test_the_end_of_a_segment_closes_its_window_and_starts_afresh():
    w = LoadWindows(BAUD)
    w.add(10.0, 500)
    w.end_segment(10.8)
    assert list(w.closed) == [(pytest.approx(500 * byte_time(BAUD) / 0.8), 10.0)]
    assert (w.start, w.bytes) == (None, 0)
    w.add(0.1, 5)  # the clock restarted: a window of its own
    assert w.start == 0.1


def test_the_busiest_window_leaves_out_a_readers_stall():
    w = LoadWindows(BAUD)
    for t, n in ((0.0, 100), (1.0, 900), (2.0, 300), (2.9, 0)):
        w.add(t, n)
    assert w.busiest(2.9, []) == (pytest.approx(900 * byte_time(BAUD)), 1.0)
    stalls = [(1.2, 0.1, 500)]
    assert stalled(1.0, stalls) and not stalled(2.0, stalls)
    assert w.busiest(2.9, stalls)[1] == 2.0  # the open window (0.9 s of it): 300 bytes


@pytest.mark.parametrize("seed", range(20))
def test_the_column_form_is_the_record_form_row_by_row(seed):
    rng = random.Random(seed)
    by_record, by_rows = LoadWindows(BAUD), LoadWindows(BAUD)
    t = rng.random()
    for _ in range(rng.randint(1, 6)):  # Blocks, some with a clock stepping back inside
        n = rng.randint(1, 400)
        ts, sizes = [], []
        for _ in range(n):
            t += rng.choice((0.0002, 0.003, 0.02, 0.4, 1.7)) * (-1 if rng.random() < 0.02 else 1)
            ts.append(t)
            sizes.append(rng.randint(1, 70))
        for a, b in zip(ts, sizes):
            by_record.add(a, b)
        by_rows.add_rows(np.array(ts), np.array(sizes, dtype=np.int64))
        assert _state(by_rows) == _state(by_record)


def test_old_windows_fold_into_the_busiest_and_memory_stays_bounded():
    from rs30x_sniff.sinks.bus_load import HELD_WINDOWS
    rng = random.Random(4)
    sizes = [rng.randrange(1, 2000) for _ in range(3 * HELD_WINDOWS)]
    sizes[3], sizes[10] = 5000, 9000  # the busiest two, both long folded by the end; the second one stalled
    w = LoadWindows(BAUD)
    w.stalls.append((10.2, 0.5, 100))  # known before its window is folded
    for i, n in enumerate(sizes):
        w.add(float(i), n)
    assert len(w.closed) == HELD_WINDOWS  # however long the capture
    assert w.busiest(None) == (pytest.approx(5000 * byte_time(BAUD)), 3.0)
    w.stalls.clear()
    assert w.busiest(None) == (pytest.approx(5000 * byte_time(BAUD)), 3.0)  # folded: a stall is known by then
    w.add(float(len(sizes)) + 0.2, 11000)  # a new busiest, still held: a stall found now takes it out
    w.add(float(len(sizes)) + 1.5, 10)
    assert w.busiest(None)[1] == float(len(sizes))
    w.stalls.append((float(len(sizes)), 0.3, 11000))
    assert w.busiest(None) == (pytest.approx(5000 * byte_time(BAUD)), 3.0)
