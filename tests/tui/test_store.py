"""The monitor's store (no Textual): bounded history, counts, the filtered view, findings, load, plot, memory."""

from __future__ import annotations

import gc
import sys
import tracemalloc
from pathlib import Path

import pytest

from rs30x_sniff.sinks.stats import CaptureStats
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.filters import parse_filter
from rs30x_sniff.tui.plot_points import register_value
from rs30x_sniff.tui.servos import servo_snapshot
from rs30x_sniff.tui.store import Store
from rs30x_sniff.protocol.wire import encode_return, encode_short

from .helpers import FakeFinding, manual_records, records_of

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from bench.traffic import hexapod_frames  # noqa: E402


def test_counts_of_the_manual_examples():
    recs = manual_records()
    store = Store()
    store.add(recs, bytes_in=253)
    s = store.stats
    assert s.records == len(store) == 24
    assert s.packets == 24 and s.replies == 1 and s.missing == 1 and s.garbage == 0
    assert s.kinds == {"short": 22, "long": 1, "return": 1}
    assert store.bytes_seen == 253
    assert store.span is None and store.bus_load is None  # no timestamps in that capture


def test_history_is_bounded_and_seqs_stay_stable():
    recs = manual_records()
    store = Store(history=10)
    store.add(recs[:7])
    store.add(recs[7:])
    assert len(store) == 10
    assert store.first_seq == 14 and store.end_seq == 24
    assert store.get(13) is None
    assert store.get(14) is recs[14]
    assert store.get(23) is recs[23]
    assert store.stats.records == 24  # the counts cover everything seen, not only what is held
    assert store.seq_of_offset(recs[20].offset) == 20
    assert store.seq_of_offset(recs[2].offset) is None


def test_memory_estimate_follows_eviction():
    recs = manual_records()
    store = Store(history=5)
    store.add(recs[:5])
    held = store.memory
    store.add(recs[5:])
    assert len(store) == 5
    # Five of the last records weigh about what five of the first did (nothing leaks into the estimate).
    assert 0.5 * held < store.memory < 2 * held


def test_filter_view_is_kept_on_append_and_eviction():
    recs = manual_records()
    store = Store(history=12)
    store.set_filter(parse_filter("id:1 kind:write"))
    store.add(recs)
    seqs = [store.view_seq(i) for i in range(store.view_len())]
    assert seqs and all(s >= store.first_seq for s in seqs)
    assert all(store.get(s).offset in (139, 149, 159, 171, 183, 192, 201, 210) or store.get(s).event.data
               for s in seqs)
    assert [store.view_index(s) for s in seqs] == list(range(len(seqs)))
    # A record the filter hides has no row; the nearest row after it stands in.
    hidden = store.end_seq - 1  # the return
    assert store.view_index(hidden) is None
    assert store.view_nearest(hidden) == len(seqs) - 1


def test_stepwise_filter_scan_equals_one_shot_and_reports_progress():
    recs = manual_records()
    a, b = Store(), Store()
    a.add(recs)
    b.add(recs)
    a.set_filter(parse_filter("reg:goal_position"))
    b.begin_filter(parse_filter("reg:goal_position"))
    steps = 0
    assert b.filter_progress == 0.0
    while not b.filter_step(5):
        steps += 1
        assert 0 < b.filter_progress < 1
        b.add([])  # records may arrive between steps
    assert steps >= 4
    assert b.filter_progress is None
    assert list(a.view) == list(b.view) == [0, 5, 14, 15, 16, 17]


def test_records_arriving_during_a_scan_are_not_counted_twice():
    recs = manual_records()
    store = Store()
    store.add(recs[:10])
    store.begin_filter(parse_filter("kind:write"))
    store.filter_step(3)
    store.add(recs[10:])
    while not store.filter_step(3):
        pass
    view = list(store.view)
    assert view == sorted(set(view))
    assert view == [i for i, r in enumerate(recs) if r.kind == "short" and r.event.op == "write"]


def test_clearing_the_filter_shows_everything():
    store = Store()
    store.add(manual_records())
    store.set_filter(parse_filter("kind:return"))
    assert store.view_len() == 1
    store.set_filter(None)
    assert store.view_len() == 24 and store.view_seq(23) == 23 and store.view_seq(24) is None


def test_view_len_before_a_pause_point():
    store = Store()
    store.add(manual_records())
    assert store.view_len(before=10) == 10
    store.set_filter(parse_filter("kind:read"))
    assert store.view_len(before=10) == 1 and store.view_len(before=30) == 2


def test_findings_counts_and_next_previous():
    recs = manual_records()
    f1 = FakeFinding("B002", "missing-return", "error", "m", recs[4].offset, id=1)
    f2 = FakeFinding("M002", "write-reserved", "warning", "m", recs[11].offset, id=1)
    f3 = FakeFinding("X", "x", "info", "m", recs[20].offset, id=None)
    recs[4].findings.append(f1)
    recs[11].findings.append(f2)
    recs[20].findings.append(f3)
    store = Store()
    store.add(recs, findings=[f1, f2, f3])
    assert store.stats.severities == {"error": 1, "warning": 1, "info": 1}
    assert store.findings_by_id == {1: 2}
    assert store.finding_seq(None) == 4
    assert store.finding_seq(4) == 11
    assert store.finding_seq(11) == 20
    assert store.finding_seq(20) is None
    assert store.finding_seq(20, forward=False) == 11
    assert store.finding_seq(None, forward=False) == 20
    assert store.finding_seq(None, min_severity="warning") == 4
    assert store.finding_seq(4, min_severity="error") is None
    store.set_filter(parse_filter("-id:1"))
    assert store.finding_seq(None) is None  # every finding is on a row the filter hides


def test_clear_forgets_everything_but_keeps_counting_bytes_from_there():
    store = Store()
    store.add(manual_records(), findings=[FakeFinding("X", "x", "info", "m", 0)], bytes_in=253)
    gen = store.generation
    store.clear()
    assert len(store) == 0 and store.stats.records == 0 and store.findings_total == 0
    assert store.bytes_seen == 0 and store.generation == gen + 1
    store.add(manual_records()[:2], bytes_in=300)
    assert store.bytes_seen == 47 and store.first_seq == 0 and store.end_seq == 2


def test_bus_load_of_the_hexapod_traffic():
    frames = hexapod_frames(2000)
    recs = records_of(frames)
    store = Store()
    store.add(recs)
    # Busy time of the last second of capture, counted from the frames themselves.
    last = frames[-1][1]
    window = [(d, t) for d, t in frames[:-1] if t >= last - 1.0]
    busy = sum(len(d) for d, _ in window) * 10 / 115200
    assert store.bus_load == pytest.approx(busy / (last - window[0][1]), rel=1e-6)
    assert 0.3 < store.bus_load < 1.0
    assert store.span == pytest.approx(frames[-1][1] - frames[0][1])


def test_servo_rows_and_poll_rate():
    frames = hexapod_frames(700)
    dec = Decoder(DecodeOptions())
    recs = []
    for data, t in frames:
        recs += dec.feed(data, t)
    recs += dec.close()
    store = Store()
    stats = CaptureStats(115200)
    for rec in recs:
        stats.add(rec)
    store.add(recs, servos=servo_snapshot(dec.bus), capture_stats=stats.as_dict())
    assert sorted(store.servos) == list(range(1, 19))
    row = store.servos[1]
    assert row.values["present_position"] is not None and row.units["present_position"] == "deg"
    assert row.requests >= 5 and row.latency_p50 is not None and row.latency_p95 >= row.latency_p50
    # Polls are round-robin, 3 a cycle of 20 ms over 18 servos: 150/18 a second each.
    assert store.poll_rate(row) == pytest.approx(150 / 18, rel=0.15)


def test_plot_series_of_a_register():
    chunks = []
    t = 0.0
    for k, pos in enumerate((100, 200, -300)):
        chunks.append((encode_short(2, 0x09, 0, b"", length=0, count=1), t))
        data = pos.to_bytes(2, "little", signed=True) + bytes(16)
        chunks.append((encode_return(2, 42, data), t + 0.001))
        t += 0.02
    recs = records_of(chunks)
    store = Store()
    store.set_plot(2)
    store.add(recs[:2])
    store.add(recs[2:])
    assert list(store.plot) == [10.0, 20.0, -30.0]
    store.set_plot(2, "present_voltage")
    assert list(store.plot) == [0.0, 0.0, 0.0]
    store.set_plot(2, "present_position")  # refilled from the history
    assert list(store.plot) == [10.0, 20.0, -30.0]
    store.set_plot(3)
    assert list(store.plot) == []
    assert register_value(recs[1], 2, "present_position") == 10.0
    assert register_value(recs[1], 3, "present_position") is None
    assert register_value(recs[0], 2, "present_position") is None


def test_a_large_capture_stays_within_the_history_and_its_memory():
    """200,000 frames of hexapod traffic through a 15,000-record store: memory stays bounded."""
    frames = hexapod_frames(200_000)
    history = 15_000
    store = Store(history=history)
    dec = Decoder(DecodeOptions())

    def feed(part):
        for i in range(0, len(part), 5000):
            batch = []
            for data, t in part[i:i + 5000]:
                batch += dec.feed(data, t)
            store.add(batch, servos=servo_snapshot(dec.bus))
            assert len(store) <= history

    feed(frames[:180_000])
    # Trace only the last 20,000 frames (tracing is slow): every record the store holds by then was
    # allocated while tracing, so the traced total covers the whole held history.
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        feed(frames[180_000:])
        store.add(dec.close())
        gc.collect()
        held = tracemalloc.get_traced_memory()[0] - base
    finally:
        tracemalloc.stop()
    assert len(store) == history
    assert store.stats.records == 200_000
    # The header's estimate is close to what is really held (within a factor of two either way) ...
    assert 0.5 * held < store.memory_estimate() < 2.0 * held
    # ... and the history is bounded in absolute terms: well under a kilobyte a record.
    assert held < history * 1024
