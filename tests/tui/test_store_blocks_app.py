"""The monitor on a file loaded through the columnar path: the keys and views work as on Records."""

from __future__ import annotations

import sys
from pathlib import Path

from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.sources.captures import write_capture
from rs30x_sniff.sources.inputs import read_input
from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.tui.app import make_app
from rs30x_sniff.filters import parse_filter
from rs30x_sniff.sources.feeds import FileSource
from rs30x_sniff.tui.timeline import Timeline

from .helpers import SIZE, FrozenClock, wait_done

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from bench.traffic import hexapod_frames  # noqa: E402


def capture(tmp_path) -> str:
    """Bench traffic with a few faults among the clean stretches: a reply missing, bytes of noise."""
    frames = hexapod_frames(12_000)
    del frames[5003]  # a poll's return (frames 5001.. are a long packet and polls: see bench/traffic.py)
    frames.insert(8000, (b"\x00\x13\x37", frames[8000][1] - 0.0001))
    path = str(tmp_path / "faults.thex")
    write_capture(path, frames, "timestamped")
    return path


def record_path(path):
    dec = Decoder(DecodeOptions(), Linter())
    out = []
    for data, t in read_input(path, baud=115200, warn=None):
        out += dec.feed(data, t)
    return out + dec.close()


def app_of(path):
    return make_app(FileSource(path), DecodeOptions(), clock=FrozenClock(), linter_factory=Linter)


async def test_keys_and_views_on_a_file_of_blocks(tmp_path):
    path = capture(tmp_path)
    recs = record_path(path)
    with_findings = [i for i, r in enumerate(recs) if r.findings]
    assert with_findings
    app = app_of(path)
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        store = app.store
        assert any(type(s) is Block for s in store.held.segments)
        assert len(store) == len(recs) and store.stats.records == len(recs)
        tl = app.query_one("#timeline", Timeline)
        assert tl.row_count == len(recs) and tl.cursor_seq == len(recs) - 1
        assert app.detail.rec is store.get(len(recs) - 1)
        # n walks the findings as the record path's records have them.
        await pilot.press("home")
        walked = []
        for _ in range(len(with_findings) + 1):
            await pilot.press("n")
            walked.append(tl.cursor_seq)
        assert walked == with_findings + with_findings[-1:]
        # g goes from a request to its reply, both rows of a Block.
        seq = next(i for i in range(100, 2000) if recs[i].status == "answered")
        assert tl.select_seq(seq)
        await pilot.pause()
        await pilot.press("g")
        assert tl.cursor_seq == seq + 1 and app.detail.rec is store.get(seq + 1)
        assert store.get(seq + 1).request is store.get(seq)
        # A filter scans the Blocks' rows as Records.
        text = "id:5 kind:return latency>0.1ms"
        assert app.apply_filter(text)
        while store.filter_progress is not None:
            await pilot.pause(0.01)
        flt = parse_filter(text)
        assert list(store.view) == [i for i, r in enumerate(recs) if flt.matches(r)]
        # Every row as the record path has it (the ones built for the screen are kept).
        got = [store.get(i) for i in range(len(recs))]
        assert [(r.event, r.index, r.status, r.latency, [f.code for f in r.findings]) for r in got] == \
            [(r.event, r.index, r.status, r.latency, [f.code for f in r.findings]) for r in recs]
