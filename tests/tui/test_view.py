"""The filtered view: every held row without a filter; with one, a scan in steps and new rows as they come."""

from __future__ import annotations

from rs30x_sniff.filters import parse_filter
from rs30x_sniff.tui.history import History
from rs30x_sniff.tui.view import FilteredView

from .helpers import manual_records


def test_without_a_filter_every_held_row():
    recs = manual_records()
    held = History()
    held.append_records(recs)
    held.trim(5, lambda seg: None)
    view = FilteredView(held)
    assert view.count() == len(recs) - 5 and view.count(before=7) == 2
    assert view.seq(0) == 5 and view.seq(-1) is None and view.seq(len(recs)) is None
    assert view.index(4) is None and view.index(6) == 1
    assert view.shows(4) and view.nearest(0) == 0 and view.progress is None and view.nbytes == 0


def test_a_scan_in_steps_finds_what_one_pass_finds():
    recs = manual_records()
    flt = parse_filter("id:1 kind:write")
    held = History()
    held.append_records(recs[:20])
    view = FilteredView(held)
    view.begin(flt)
    assert not view.matching_new_rows and view.progress == 0.0
    steps = 0
    while not view.step(3):
        steps += 1
    assert steps == 6 and view.matching_new_rows
    view.add(held.end_seq, recs[20:])
    held.append_records(recs[20:])
    want = [i for i, r in enumerate(recs) if flt.matches(r)]
    assert list(view.seqs) == want
    assert all(view.index(s) == i for i, s in enumerate(want))
    assert not view.shows(next(i for i in range(len(recs)) if i not in want))
    held.trim(want[2], lambda seg: None)
    view.trim()
    assert list(view.seqs) == want[2:] and view.nbytes == 8 * len(want[2:])
