"""The monitor shows --time-format: the timeline's time column, the detail title and the header, on a wall-clock
bus (a port's times) and on a capture timed from its start."""

from __future__ import annotations



from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.sim import run as simulate
from rs30x_sniff.tui.app import make_app
from rs30x_sniff.tui.detail import DetailPane
from rs30x_sniff.tui.header import StatusHeader
from rs30x_sniff.sources.feeds import ChunkSource, FileSource

from .helpers import ROOT, FrozenClock, wait_done

T0 = 1795832946.25  # 2026-11-28 02:29:06.25 UTC: a live port's wall-clock times
WIDE = (230, 30)    # the timeline's full columns (delta, latency)
NARROW = (100, 30)  # its compact columns



def wall_bus():
    return [(d, T0 + t) for d, t in simulate("bad-checksum", duration=0.5, seed=1)]


def rows(app) -> list[str]:
    tl = app.timeline
    width = tl.scrollable_content_region.width
    return ["".join(seg.text for seg in tl.render_line(y))[:width].rstrip() for y in range(0, 5)]


def title(app) -> str:
    return str(app.query_one(DetailPane).field_tree.root.label)


def header(app) -> str:
    return app.query_one(StatusHeader).render().plain


async def shown(mode: str, size=WIDE, chunks=None, **kw):
    app = make_app(ChunkSource("bus", chunks or wall_bus()), DecodeOptions(), clock=FrozenClock(),
                   tick_interval=3600, time_format=mode, **kw)
    async with app.run_test(size=size) as pilot:
        await wait_done(pilot, app)
        await pilot.press("home", "down")
        await pilot.pause()
        return rows(app), title(app), header(app)


async def test_relative_is_seconds_since_the_first_byte(utc):
    got, head, top = await shown("relative")
    assert got[0].split() == ["time(s)", "delta(ms)", "dir", "ID", "kind", "latency", "summary"]
    assert got[1].split()[:1] == ["0.000000"] and got[2].split()[:2] == ["0.000800", "+0.800"]
    assert "t=0.000800s (02:29:06.250850)" in head  # the time of day beside it: the bus has a wall clock
    assert "times " not in top  # the default says nothing


async def test_absolute_is_the_date_and_time_of_day(utc):
    got, head, top = await shown("absolute")
    assert got[0].split()[:2] == ["date", "time"]
    assert got[1].lstrip().startswith("2026-11-28 02:29:06.250050 ")
    assert got[0].index("time") + 4 == got[1].index("250050") + 6  # the heading right-aligned over the column
    assert "2026-11-28 02:29:06.250850" in head and "times date and time" in top
    narrow, _, _ = await shown("absolute", NARROW)
    assert narrow[0].split()[:3] == ["time", "of", "day"] and narrow[1].split()[0] == "02:29:06.250050"


async def test_epoch_is_whole_and_aligned(utc):
    got, head, top = await shown("epoch")
    assert got[1].split()[0] == "1795832946.250050"  # never cut: the column is as wide as the number
    assert got[0].index("epoch(s)") + 8 == got[1].index("250050") + 6
    assert "t=1795832946.250850s" in head and "times seconds since 1970" in top


async def test_delta_is_to_the_previous_packet(utc):
    got, head, _ = await shown("delta")
    assert got[0].split()[0] == "dt(s)"
    assert [r.split()[0] for r in got[1:4]] == ["0.000000", "0.000800", "0.000918"]
    assert "t=0.000800s" in head  # one record has no neighbour in the detail: since the start


async def test_without_a_wall_clock_the_header_says_so(monkeypatch):
    monkeypatch.chdir(ROOT)
    app = make_app(FileSource("captures/session-mixed.thex"), DecodeOptions(), clock=FrozenClock(),
                   tick_interval=3600, time_format="absolute")
    async with app.run_test(size=WIDE) as pilot:
        await wait_done(pilot, app)
        await pilot.press("home")
        await pilot.pause()
        got = rows(app)
        assert got[0].split()[0] == "time(s)" and got[1].split()[0] == "0.500000"  # its own times, no date
        assert "times since start (no wall clock)" in header(app)
        assert title(app).endswith("t=0.500000s")


async def test_the_simulator_is_anchored_at_its_start(utc):
    chunks = list(simulate("bad-checksum", duration=0.5, seed=1))  # times from 0, as the simulator gives them
    got, head, _ = await shown("absolute", chunks=chunks, time_anchor=T0)
    assert got[1].lstrip().startswith("2026-11-28 02:29:06.250050 ")
