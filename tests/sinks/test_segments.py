"""Time segments (sinks/segments.py): seams passed where they take effect, spans added up over segments."""

from __future__ import annotations

import numpy as np
import pytest

from rs30x_sniff.decode.framing import SEAM_RESTART, Seam
from rs30x_sniff.sinks.segments import NO_SEAM, TimeSegments


def _seam(offset: int) -> Seam:
    return Seam(offset, SEAM_RESTART, None, 0.0)


def test_an_untimed_capture_has_no_span_and_one_segment():
    s = TimeSegments()
    assert s.span() is None and s.count() == 1 and not s.timed


def test_spans_add_up_over_segments():
    s = TimeSegments()
    s.add(5.0, 5.001)
    s.add(7.0, None)  # no end time: it ends where it starts
    s.expect([_seam(100)])
    assert s.next_seam == 100
    assert s.end_segment(100) == 7.0
    assert s.next_seam == NO_SEAM and len(s.seams) == 1
    s.add(0.5, 0.6)
    s.add(1.5, 1.6)
    assert s.span() == pytest.approx(2.0 + 1.1)
    assert s.first_t == 5.0 and s.count() == 2


def test_a_seam_before_any_time_closes_nothing():
    s = TimeSegments()
    s.expect([_seam(0), _seam(50)])
    assert s.end_segment(10) is None
    assert s.next_seam == 50 and len(s.seams) == 1


def test_the_column_form_is_the_record_form_of_each_row():
    t0 = np.array([1.0, 1.5, 1.2, 3.0])
    t1 = np.array([1.1, 2.9, 1.3, 3.05])
    by_rows, by_record = TimeSegments(), TimeSegments()
    by_rows.add_rows(t0, t1)
    for a, b in zip(t0.tolist(), t1.tolist()):
        by_record.add(a, b)
    assert vars(by_rows) == vars(by_record)
