"""The drive loop leaves no reference cycles: what a step made is freed as the step ends, not at a full collection.

A cycle lives until the cyclic collector's rare full pass. A live recorder's columnar steps once each left one (a
lint view held by its rules' closures), with the step's Block, records and arrays behind it: half an hour of them
piled up between passes, and glibc and Python's allocators kept the pile's high-water mark as resident memory
(bench/live.py's hour of `record`). Here each form of the drive loop runs simulator traffic, as a live port hands
it over (arrival-stamped chunks, an empty one a second), with the collector off, and then nothing may be left for it.
"""

from __future__ import annotations

import gc
import io
from collections import Counter
from functools import cache

import pytest

from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.protocol.wire import byte_time
from rs30x_sniff.sim import run
from rs30x_sniff.sinks.blackbox import BlackBox, parse_trigger
from rs30x_sniff.sinks.lines import TextSink
from rs30x_sniff.sinks.mcap.writer import McapSink
from rs30x_sniff.sinks.pipeline import Pipeline
from rs30x_sniff.sinks.stats import CaptureStats
from rs30x_sniff.sources.feeds import ChunkSource
from rs30x_sniff.tui.feed import Feeder, default_linter

EPOCH = 1.79e9
BAUD = 230400


@cache
def live_chunks(scenario: str) -> tuple:
    """Each frame stamped when its last byte arrived, and an empty chunk after each second (a port's gather)."""
    out, second = [], 1.0
    for data, t in run(scenario, baud=BAUD, duration=6.0, seed=5):
        end = t + len(data) * byte_time(BAUD)
        if end >= second:
            out.append((b"", None))
            second += 1.0
        out.append((data, EPOCH + end))
    out.append((b"", None))
    return tuple(out)


def watched(chunks: tuple, found: Counter):
    """``chunks`` with the collector off: after the first second, what was made to start with (the decoder's
    and linter's own structures) is collected; after the last chunk's step, while they are all still in use, the
    types of what the collector would free are counted into ``found``: left by the steps. (Run the same traffic
    once before: a module imported on first use leaves its own cycles, once.)"""
    was = gc.isenabled()
    gc.disable()
    try:
        for i, chunk in enumerate(chunks):
            if i and chunks[i - 1] == (b"", None) and not found:
                gc.collect()
                found["started"] = 0
            yield chunk
        gc.set_debug(gc.DEBUG_SAVEALL)
        gc.collect()
        found.update(type(o).__name__ for o in gc.garbage)
    finally:
        gc.set_debug(0)
        gc.garbage.clear()
        if was:
            gc.enable()


@pytest.mark.parametrize("scenario", ["hexapod", "noise"])
@pytest.mark.parametrize("columnar", [True, False])
@pytest.mark.parametrize("decoded", [False, True])
def test_a_recording_run_leaves_no_cycles(scenario, columnar, decoded):
    def record(chunks) -> tuple[McapSink, CaptureStats]:
        sink = McapSink(io.BytesIO(), source="pty", baud=BAUD, time_base="wall", decoded=decoded)
        stats = CaptureStats(BAUD)
        Pipeline(Decoder(DecodeOptions(baud=BAUD), Linter(LintConfig(), keep_findings=False), columnar=columnar),
                 [stats, sink], group_bytes=BAUD // 10).run(chunks)
        sink.finish()
        return sink, stats

    record(iter(live_chunks(scenario)))  # first: what is imported or cached on first use
    found: Counter = Counter()
    sink, stats = record(watched(live_chunks(scenario), found))
    assert +found == Counter()
    assert "started" in found and sink.messages > 0 and stats.packets > 0  # the traffic went through


@pytest.mark.parametrize("columnar", [True, False])
def test_printed_lines_leave_no_cycles(columnar):
    def printed(chunks) -> str:
        out = io.StringIO()
        Pipeline(Decoder(DecodeOptions(baud=BAUD), Linter(LintConfig(), keep_findings=False), columnar=columnar),
                 [TextSink(out)], group_bytes=BAUD // 10).run(chunks)
        return out.getvalue()

    printed(iter(live_chunks("hexapod")))  # first: what is imported or cached on first use
    found: Counter = Counter()
    text = printed(watched(live_chunks("hexapod"), found))
    assert +found == Counter()
    assert "started" in found and text.count("\n") > 1000


@pytest.mark.parametrize("columnar", [True, False])
def test_a_black_box_run_leaves_no_cycles(columnar):
    codes = [r.code for r in Linter(LintConfig()).rules]

    def watch(chunks) -> list:
        saved: list = []
        box = BlackBox([parse_trigger(t, codes) for t in ("sev>=warning", "present_temperature>30")], 1.0, 1.0,
                       lambda ch, w, name: saved.append(name))
        Pipeline(Decoder(DecodeOptions(baud=BAUD), Linter(LintConfig(), keep_findings=False), columnar=columnar),
                 [box], group_bytes=BAUD // 10).run(chunks)
        return saved

    watch(iter(live_chunks("noise")))  # first: what is imported or cached on first use
    found: Counter = Counter()
    saved = watch(watched(live_chunks("noise"), found))
    assert +found == Counter()
    assert "started" in found and saved  # a trigger fired and a window was saved


class _Port(ChunkSource):
    """Chunks as a port hands them over: live, a gather at a time (each gather ended by an empty chunk)."""

    kind = "port"
    live = True
    batched = True
    time_base = "wall"


def test_the_monitors_feeder_leaves_no_cycles():
    def monitor(chunks) -> list:
        batches: list = []
        Feeder(_Port("pty", chunks), DecodeOptions(baud=BAUD), batches.append, linter=default_linter(),
               interval=0).run()
        return batches

    monitor(iter(live_chunks("noise")))  # first: what is imported or cached on first use
    found: Counter = Counter()
    batches = monitor(watched(live_chunks("noise"), found))
    assert +found == Counter()
    assert "started" in found and batches[-1].done and sum(len(b.findings) for b in batches)
