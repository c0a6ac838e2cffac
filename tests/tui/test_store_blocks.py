"""The monitor on the columnar path: CaptureStats and the Store fed Blocks answer as fed Records."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder, Step
from rs30x_sniff.sinks.pipeline import Sink, drive
from rs30x_sniff.sim import scenarios
from rs30x_sniff.sinks.stats import CaptureStats
from rs30x_sniff.tui.feed import split_block
from rs30x_sniff.filters import parse_filter
from rs30x_sniff.tui.plot_series import PLOT_POINTS, PLOT_REGISTERS
from rs30x_sniff.tui.store import Store

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from bench.traffic import hexapod_frames  # noqa: E402

SCENARIOS = list(scenarios.SCENARIOS)


class Keep(Sink):
    """Every step as the decoder gave it (Blocks and Records), with its findings."""

    takes_blocks = True

    def __init__(self) -> None:
        self.steps = []

    def batch(self, step) -> None:
        self.steps.append(step)


def capture(name: str) -> list:
    if name == "bench":
        return hexapod_frames(6000)
    if name == "bench-untimed":
        return [(d, None) for d, _ in hexapod_frames(3000)]
    return list(scenarios.run(name, duration=2.0))


def decoded(chunks, columnar: bool, lint: bool = True) -> tuple[list, Decoder]:
    keep = Keep()
    dec = drive(chunks, Decoder(DecodeOptions(), Linter() if lint else None, columnar=columnar), keep)
    return keep.steps, dec


CAPTURES = SCENARIOS + ["bench", "bench-untimed"]
NO_BLOCKS = {"setup", "silent-servo", "duplicate-id"}  # too irregular in 2 s for a clean stretch


@pytest.mark.parametrize("name", CAPTURES)
def test_capture_stats_count_a_block_as_its_records(name):
    chunks = capture(name)
    by_record, by_block = CaptureStats(115200), CaptureStats(115200)
    drive(chunks, Decoder(DecodeOptions(), Linter()), by_record)
    steps, _ = decoded(chunks, True)
    drive(chunks, Decoder(DecodeOptions(), Linter(), columnar=True), by_block)
    assert any(type(x) is Block for s in steps for x in s) == (name not in NO_BLOCKS)  # the columnar path was taken
    a, b = by_record.as_dict(), by_block.as_dict()
    assert a == b
    assert by_record.latency.bins == by_block.latency.bins
    assert {i: (h.model, h.lo, h.hi, h.samples, h.flags) for i, h in by_record.health.servos.items()} == \
        {i: (h.model, h.lo, h.hi, h.samples, h.flags) for i, h in by_block.health.servos.items()}


def test_capture_stats_of_a_block_fed_in_pieces():
    """The load windows and the health buffers' flushes fall inside Blocks as they do between records."""
    chunks = hexapod_frames(40_000)
    by_record = CaptureStats(115200)
    for rec in (r for s in decoded(chunks, False, lint=False)[0] for r in s):
        by_record.add(rec)
    by_block = CaptureStats(115200)
    for s in decoded(chunks, True, lint=False)[0]:
        by_block.batch(s)
    assert by_record.as_dict() == by_block.as_dict()


def test_capture_stats_of_servos_of_mixed_models():
    """A long packet to servos of two models: its health goes record by record, as on the record path."""
    chunks = hexapod_frames(6000)
    opts = DecodeOptions(models={4: "RS304MD", 7: "RS304MD"})
    by_record, by_block = CaptureStats(115200), CaptureStats(115200)
    drive(chunks, Decoder(opts, Linter()), by_record)
    keep = Keep()
    drive(chunks, Decoder(opts, Linter(), columnar=True), by_block, keep)
    assert any(type(x) is Block and x.vid_models is not None for s in keep.steps for x in s)
    assert by_record.as_dict() == by_block.as_dict()


# ---- the Store ---------------------------------------------------------------------------------------
FILTERS = ("id:3", "id:0", "kind:return", "kind:read", "kind:long", "latency>0.12ms", "reg:present_position",
           "present_position>0", "goal_position<0", "sev>=warning", "-id:1-6", "t>1", "READ")


def stores(name: str, history: int = 1_000_000, plot: int | None = None, split: bool = False,
           plot_points: int = PLOT_POINTS, plot_all: bool = False, together: bool = False):
    """Two Stores fed the same capture: the record path's Records and the columnar path's steps
    (``together``: every step in one batch, as a post gathers them while a file loads)."""
    chunks = capture(name)
    out = []
    for columnar in (False, True):
        steps, dec = decoded(chunks, columnar)
        if together:
            whole = Step(x for step in steps for x in step)
            whole.findings = [f for step in steps for f in step.findings]
            steps = [whole]
        stats = CaptureStats(115200)
        store = Store(history, plot_points=plot_points)
        if plot is not None:
            store.servos = {i: None for i in range(1, 19)} if plot_all else {plot: None}
            store.set_plot(plot, all_servos=plot_all)
        for step in steps:
            stats.batch(step)
            items = list(step)
            if split and columnar:  # Blocks cut as the feeder cuts them at max_batch
                items = [y for x in items for y in (_halves(x) if type(x) is Block else [x])]
            store.add(items, step.findings, capture_stats=stats.as_dict())
        out.append(store)
    return out


def _halves(blk):
    head, tail = split_block(blk, len(blk) // 2)
    return head + tail


def record_key(r):
    return (r.event, r.index, r.status, r.latency, r.model and r.model.name, r.request and r.request.index,
            r.reply and r.reply.index, tuple(f.code for f in r.findings))


def held(store):
    return [store.get(s) for s in range(store.first_seq, store.end_seq)]


BLOCKED = [n for n in CAPTURES if n not in NO_BLOCKS]


@pytest.mark.parametrize("name", BLOCKED)
def test_a_store_of_blocks_answers_as_a_store_of_records(name):
    a, b = stores(name)
    assert any(type(x) is Block for x in b.held.segments)
    assert (len(a), a.first_seq, a.end_seq) == (len(b), b.first_seq, b.end_seq)
    sa, sb = a.stats, b.stats
    assert (sa.records, sa.kinds, sa.missing, sa.severities, sa.first_t, sa.last_t) == \
        (sb.records, sb.kinds, sb.missing, sb.severities, sb.first_t, sb.last_t)
    assert (a.span, a.bus_load, a.average_load) == (b.span, b.bus_load, b.average_load)
    assert list(a.recent_load._items) == list(b.recent_load._items)
    # Filters and findings first: they make no Record a Block keeps (the linter's samples are kept).
    built = [len(x.made_rows) for x in b.held.segments if type(x) is Block]
    for text in FILTERS:
        flt = parse_filter(text)
        a.set_filter(flt)
        b.begin_filter(flt)
        while not b.filter_step(700):  # steps that end inside Blocks
            pass
        assert list(a.view) == list(b.view), text
        assert [len(x.made_rows) for x in b.held.segments if type(x) is Block] == built
        for sev in ("info", "warning", "error"):
            assert finding_walk(a, sev) == finding_walk(b, sev)
    a.set_filter(None)
    b.set_filter(None)
    for sev in ("info", "warning", "error"):
        assert finding_walk(a, sev) == finding_walk(b, sev)
    # Every row, as a Record.
    ra, rb = held(a), held(b)
    assert [record_key(r) for r in ra] == [record_key(r) for r in rb]
    assert all(b.get(s) is r for s, r in zip(range(b.first_seq, b.end_seq), rb))  # kept once built
    for r in ra[::7]:
        seq = a.seq_of_offset(r.offset)
        assert seq == b.seq_of_offset(r.offset) and seq is not None
        assert b.seq_of(b.get(seq)) == seq
        assert a.seq_of_offset(r.offset + 1) == b.seq_of_offset(r.offset + 1) is None
    # With the Records built, a filter reads them (and their findings).
    b.set_filter(parse_filter("sev>=info"))
    a.set_filter(parse_filter("sev>=info"))
    assert list(a.view) == list(b.view)
    assert finding_walk(a, "info") == finding_walk(b, "info")


def finding_walk(store, sev):
    """Every seq `n` and `N` stop at, from either end."""
    fwd, seq = [], None
    while (seq := store.finding_seq(seq, True, sev)) is not None:
        fwd.append(seq)
    back, seq = [], None
    while (seq := store.finding_seq(seq, False, sev)) is not None:
        back.append(seq)
    return fwd, back, store.finding_seq(store.end_seq // 2, True, sev), store.finding_seq(store.end_seq // 2, False, sev)


@pytest.mark.parametrize("name", ["bench", "bench-untimed", "hexapod", "overheat"])
def test_plot_series_of_blocks(name):
    for servo in (1, 4):
        a, b = stores(name, plot=servo)  # series grown batch by batch
        assert a.plot_series.keys() == b.plot_series.keys()
        for sid in a.plot_series:
            assert list(a.plot_series[sid][0]) == list(b.plot_series[sid][0])
            assert list(a.plot_series[sid][1]) == list(b.plot_series[sid][1])
        assert len(a.plot) > 5
        for register in PLOT_REGISTERS:  # and refilled from the history
            for store in (a, b):
                store.servos = {i: None for i in range(1, 19)}
                store.set_plot(servo, register, all_servos=register == "goal_position")
            assert {k: (list(t), list(v)) for k, (t, v) in a.plot_series.items()} == \
                {k: (list(t), list(v)) for k, (t, v) in b.plot_series.items()}, register


@pytest.mark.parametrize("together", [False, True])
@pytest.mark.parametrize("name", ["bench", "hexapod", "overheat"])
def test_plot_series_grown_past_what_it_keeps(name, together):
    # A batch with more points than the plot keeps reads only its newest Blocks: the same series.
    for points in (1, 7, 300):
        a, b = stores(name, plot=3, plot_points=points, plot_all=True, together=together)
        assert {k: (list(t), list(v)) for k, (t, v) in a.plot_series.items()} == \
            {k: (list(t), list(v)) for k, (t, v) in b.plot_series.items()}
        assert 0 < len(b.plot) <= points and (points > 100 or len(b.plot) == points)


def test_plot_points_are_bounded_in_blocks():
    a, b = stores("bench", plot=2)
    for store in (a, b):
        store.plot_points = 50
        store.set_plot(2, "goal_position", all_servos=True)
    assert len(b.plot) == 50
    assert {k: (list(t), list(v)) for k, (t, v) in a.plot_series.items()} == \
        {k: (list(t), list(v)) for k, (t, v) in b.plot_series.items()}


@pytest.mark.parametrize("history", [1, 333, 2500])
@pytest.mark.parametrize("name", ["bench", "overheat"])
def test_eviction_of_blocks(name, history):
    a, b = stores(name, history=history, split=True)
    assert (len(a), a.first_seq, a.end_seq) == (len(b), b.first_seq, b.end_seq) and len(b) == min(history, b.end_seq)
    assert b.get(b.first_seq - 1) is None
    first = a.get(a.first_seq).offset  # offsets before it are gone (or inside a frame): no seq
    for off in range(max(0, first - 200), first + 200):
        assert a.seq_of_offset(off) == b.seq_of_offset(off)
    for text in FILTERS[:6]:
        flt = parse_filter(text)
        a.set_filter(flt)
        b.set_filter(flt)
        assert list(a.view) == list(b.view), text
    for sev in ("info", "warning"):
        assert finding_walk(a, sev) == finding_walk(b, sev)
    a.set_filter(None)
    b.set_filter(None)
    for store in (a, b):
        store.servos = {i: None for i in range(1, 19)}
        store.set_plot(3, "present_position", all_servos=True)
    assert {k: (list(t), list(v)) for k, (t, v) in a.plot_series.items()} == \
        {k: (list(t), list(v)) for k, (t, v) in b.plot_series.items()}
    assert [record_key(r) for r in held(a)] == [record_key(r) for r in held(b)]
    # Held Records and Blocks weigh what they weigh: dropping them takes their weight off.
    assert b.memory > 0 and b.memory_estimate() > 0


def test_a_store_of_blocks_is_smaller():
    a, b = stores("bench")
    assert b.memory_estimate() < a.memory_estimate() / 3
    held(b)  # every row built: about the record path's weight again, plus the columns
    assert b.memory_estimate() > 0.8 * a.memory_estimate()


def test_adding_a_block_takes_no_python_work_per_row():
    """A Block goes into the store with a fixed number of operations (an untimed one: a timed one's
    rows of the last second also go to the recent load), whatever its length: the calls it makes are
    counted (a profile hook), never timed."""
    import sys

    steps, _ = decoded([(d, None) for d, _ in hexapod_frames(30_000)], True, lint=False)
    blocks = [x for s in steps for x in s if type(x) is Block]
    big = max(blocks, key=len)
    assert len(big) > 1000

    def calls(blk):
        store = Store()
        store.servos = {1: None}
        store.set_plot(1)
        store.add([blk])  # the first add of a kind may set things up
        n = 0

        def count(frame, event, arg):
            nonlocal n
            n += event in ("call", "c_call")

        sys.setprofile(count)
        try:
            store.add([blk])
        finally:
            sys.setprofile(None)
        return n

    small = _halves(big)[0]
    while len(small) > 100:
        small = _halves(small)[0]
    assert calls(big) <= calls(small) + 10, (calls(big), calls(small), len(big), len(small))


@pytest.mark.parametrize("rows", [1, 37, 500])
def test_capture_stats_flush_health_buffers_as_the_record_path(monkeypatch, rows):
    """The health recorder's buffers flushed every few rows: inside Blocks, across them, on numpy."""
    import rs30x_sniff.sinks.health
    import rs30x_sniff.sinks.stats

    monkeypatch.setattr(rs30x_sniff.sinks.health, "FLUSH_ROWS", rows)
    monkeypatch.setattr(rs30x_sniff.sinks.stats, "FLUSH_ROWS", rows)
    for name, opts in (("bench", DecodeOptions()), ("overheat", DecodeOptions()),
                       ("bench", DecodeOptions(models={4: "RS304MD"}))):
        chunks = capture(name)
        by_record, by_block = CaptureStats(115200), CaptureStats(115200)
        drive(chunks, Decoder(opts, Linter()), by_record)
        drive(chunks, Decoder(opts, Linter(), columnar=True), by_block)
        assert by_record.as_dict() == by_block.as_dict()
        assert {i: (h.model, h.lo, h.hi, h.samples) for i, h in by_record.health.servos.items()} == \
            {i: (h.model, h.lo, h.hi, h.samples) for i, h in by_block.health.servos.items()}


# ---- the feeder ---------------------------------------------------------------------------------------
def test_the_feeder_loads_a_file_as_blocks(tmp_path):
    from rs30x_sniff.sources.captures import write_capture
    from rs30x_sniff.tui.feed import Feeder, default_linter
    from rs30x_sniff.sources.feeds import FileSource

    frames = hexapod_frames(20_000)
    path = tmp_path / "t.thex"
    write_capture(path, frames, "timestamped")
    batches = []
    Feeder(FileSource(str(path)), DecodeOptions(), batches.append, linter=default_linter(), max_batch=3000).run()
    assert batches[-1].done and batches[-1].error is None
    assert all(sum(len(x) if type(x) is Block else 1 for x in b.records) <= 3000 + 1 for b in batches)
    items = [x for b in batches for x in b.records]
    assert sum(len(x) for x in items if type(x) is Block) > 15_000
    rows = [r for x in items for r in (x.rows(0, len(x)) if type(x) is Block else [x])]
    steps, _ = decoded(list(read_capture_of(path)), False)
    recs = [r for s in steps for r in s]
    assert [record_key(r) for r in rows] == [record_key(r) for r in recs]
    stats = CaptureStats(115200)
    drive(read_capture_of(path), Decoder(DecodeOptions(), Linter()), stats)
    # What the screen shows of info's figures (screen_figures), as info gives them for the same capture.
    whole = stats.as_dict()
    assert batches[-1].stats == {k: whole[k] for k in ("bus_load", "latency_s", "servos")}
    assert sorted(f.code for b in batches for f in b.findings) == sorted(f.code for s in steps for f in s.findings)


def read_capture_of(path):
    from rs30x_sniff.sources.inputs import read_input

    return read_input(str(path), baud=115200, warn=None)


def test_a_live_source_stays_record_by_record():
    from rs30x_sniff.tui.feed import Feeder
    from rs30x_sniff.sources.feeds import ChunkSource

    port = ChunkSource("port", hexapod_frames(2000))
    port.kind, port.live = "port", True  # chunks as a serial port hands them out
    batches = []
    Feeder(port, DecodeOptions(), batches.append).run()
    items = [x for b in batches for x in b.records]
    assert len(items) == 2000 and not any(type(x) is Block for x in items)


def test_recording_while_a_file_loads_gets_records(tmp_path):
    """A sink that takes Records (the `r` recording) sees every row as one, and a Block reaches the
    screen only once it has built them (no row is two objects)."""
    from rs30x_sniff.sources.captures import write_capture
    from rs30x_sniff.tui.feed import Feeder
    from rs30x_sniff.sources.feeds import FileSource

    path = tmp_path / "t.thex"
    write_capture(path, hexapod_frames(20_000), "timestamped")
    seen = []

    class FakeSink:
        def __init__(self, path, **kw):
            pass

        def chunk(self, data, t):
            pass

        def batch(self, step):
            assert not any(type(x) is Block for x in step)
            seen.extend(step)

        def finish(self):
            pass

    batches = []
    feeder = Feeder(FileSource(str(path)), DecodeOptions(), batches.append, sink_factory=FakeSink)
    feeder.start_recording(str(tmp_path / "x.mcap"))
    feeder.run()
    items = [x for b in batches for x in b.records]
    rows = [r for x in items for r in (x.records() if type(x) is Block else [x])]
    assert len(seen) == len(rows) == 20_000
    assert all(a is b for a, b in zip(seen, rows))


def test_the_memory_figure_of_blocks_is_what_they_hold():
    """Blocks and their runs, and the Records built of them as rows are shown: the header's figure is
    close to what tracemalloc sees held (within a factor of two), and far under the record path's."""
    import gc
    import tracemalloc

    frames = hexapod_frames(60_000)
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        store = Store()
        for step in decoded(frames, True)[0]:
            store.add(list(step), step.findings)
        gc.collect()
        held = tracemalloc.get_traced_memory()[0] - base
        assert 0.5 * held < store.memory_estimate() < 2 * held
        assert held < 60_000 * 150  # the record path holds ~700 bytes a row
        for seq in range(0, len(store), 3):
            store.get(seq)
        gc.collect()
        held = tracemalloc.get_traced_memory()[0] - base
        assert 0.5 * held < store.memory_estimate() < 2 * held
    finally:
        tracemalloc.stop()
