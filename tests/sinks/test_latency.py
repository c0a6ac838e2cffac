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
