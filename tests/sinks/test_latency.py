"""The latency histogram (sinks/latency.py): the column form bins as the record form, and what it says."""

from __future__ import annotations

import random

import numpy as np

from rs30x_sniff.sinks.latency import LatencyHistogram


def test_the_column_form_bins_as_the_record_form():
    rng = random.Random(3)
    lat = [rng.choice((0.0001, 0.00015, 0.0002)) + rng.random() * 3e-6 for _ in range(500)]
    by_record, by_array = LatencyHistogram(), LatencyHistogram()
    for x in lat:
        by_record.add(x)
    by_array.add_array(np.array(lat[:200]))
    by_array.add_array(np.array(lat[200:]))
    assert by_array == by_record


def test_a_paired_reply_without_a_latency_is_unmeasured_only_when_timed():
    h = LatencyHistogram()
    h.add_paired(0.0002, True)
    h.add_paired(None, True)
    h.add_paired(None, False)
    assert (h.count, h.unmeasured) == (1, 1)
    d = h.as_dict()
    assert d["count"] == 1 and d["unmeasured"] == 1 and "F005" in d["absent"]
    assert h.as_dict("the times contradict the baud rate") == {
        "count": 0, "p50": None, "p95": None, "max": None, "unmeasured": 2,
        "absent": "the times contradict the baud rate"}


def test_late_latencies_share_coarse_bins_and_both_forms_agree():
    from rs30x_sniff.sinks.latency import COARSE_BITS, DENSE_US, LATENCY_BIN
    rng = random.Random(5)
    lat = [rng.random() * 0.2 for _ in range(3000)] + [0.0, 1e-7, (DENSE_US - 1) * LATENCY_BIN]
    by_record, by_array = LatencyHistogram(), LatencyHistogram()
    for x in lat:
        by_record.add(x)
    by_array.add_array(np.array(lat[:1000]))
    by_array.add_array(np.array(lat[1000:]))
    assert by_array == by_record and by_record.count == len(lat) and by_record.max == max(lat)
    for k in by_record.bins:  # a late bin keeps COARSE_BITS significant bits: under 0.013 % wide
        if k >= DENSE_US:
            width = 1 << (k.bit_length() - COARSE_BITS)
            assert k % width == 0 and width / k < 1.3e-4
    # every figure is within a bin's width of the exact nearest-rank percentile
    exact = sorted(lat)
    for p in (1, 50, 95, 99, 100):
        want = exact[max(1, -(-len(exact) * p // 100)) - 1]
        got = by_record.percentile(p)
        assert got <= want + LATENCY_BIN / 2 and want - got < max(LATENCY_BIN, want * 1.3e-4)


def test_memory_is_bounded_by_the_spread_not_the_count():
    # a live pty's jitter: a million latencies over 0-16 ms and a long tail take the same bins as ten thousand
    rng = np.random.default_rng(7)
    h = LatencyHistogram()
    for _ in range(100):
        h.add_array(np.concatenate([rng.uniform(0, 0.0164, 10_000), rng.uniform(0.0164, 0.05, 10)]))
    n_bins = len(h.bins)
    for _ in range(10):
        h.add_array(np.concatenate([rng.uniform(0, 0.0164, 10_000), rng.uniform(0.0164, 0.05, 10)]))
    assert h.count == 110 * 10_010
    from rs30x_sniff.sinks.latency import DENSE_US
    dense = sum(1 for k in h.bins if k < DENSE_US)
    assert dense <= DENSE_US and len(h.bins) - dense <= 2 * 8192  # two octaves past DENSE_US, coarse
    assert len(h.bins) < n_bins + 1000  # the late tail still finds new coarse bins, the dense part none


def test_merged_parts_are_the_whole():
    rng = random.Random(9)
    lat = [rng.random() * 0.03 for _ in range(500)]
    whole, a, b = LatencyHistogram(), LatencyHistogram(), LatencyHistogram()
    for i, x in enumerate(lat):
        whole.add(x)
        (a if i % 3 else b).add(x)
    b.add_paired(None, True)
    whole.add_paired(None, True)
    assert a + b == whole and (a + b).percentile(50) == whole.percentile(50)
