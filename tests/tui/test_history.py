"""The monitor's history: Records in lists of CHUNK_RECORDS, Blocks whole, trimmed from the front."""

from __future__ import annotations

import pytest

from rs30x_sniff.tui import history as history_module
from rs30x_sniff.tui.history import History

from .helpers import FakeFinding, manual_records


@pytest.fixture
def small_chunks(monkeypatch):
    monkeypatch.setattr(history_module, "CHUNK_RECORDS", 4)


def test_records_fill_the_last_list_then_new_ones(small_chunks):
    recs = manual_records()[:11]
    held = History()
    held.append_records(recs[:3])
    held.append_records(recs[3:11])
    assert [len(s) for s in held.segments] == [4, 4, 3]
    assert held.starts == [0, 4, 8]
    assert (held.first_seq, held.end_seq, len(held)) == (0, 11, 11)
    assert [held.get(s) for s in range(11)] == recs
    assert held.get(11) is None and held.get(-1) is None
    assert [(seq, list(rows)) for seq, rows in held.rows(2, 9)] == \
        [(2, recs[2:4]), (4, recs[4:8]), (8, recs[8:9])]


def test_trim_tells_what_leaves(small_chunks):
    recs = manual_records()[:11]
    held = History()
    held.append_records(recs)
    gone = []
    held.trim(6, gone.append)
    assert gone == [recs[0:4], recs[4:6]]  # a whole list, then the rows cut from the next
    assert (held.first_seq, held.starts) == (6, [6, 8])
    assert held.get(5) is None and held.get(6) is recs[6]
    assert held.seq_of_offset(recs[7].offset) == 7
    assert held.seq_of_offset(recs[2].offset) is None


def every(seq: int) -> bool:
    return True


def test_finding_seq_asks_what_is_shown(small_chunks):
    recs = manual_records()
    for k, severity in ((4, "error"), (11, "warning"), (20, "info")):
        recs[k].findings.append(FakeFinding("X", "x", severity, "m", recs[k].offset))
    held = History()
    held.append_records(recs)
    assert held.finding_seq(None, True, "info", every) == 4
    assert held.finding_seq(4, True, "info", every) == 11
    assert held.finding_seq(None, False, "info", every) == 20
    assert held.finding_seq(None, True, "warning", lambda seq: seq != 4) == 11
    assert held.finding_seq(11, True, "warning", every) is None
    held.trim(12, lambda seg: None)
    assert held.finding_seq(None, False, "warning", every) is None
    assert History().finding_seq(None, True, "info", every) is None
