"""At 80x24 (and in narrow panes) the monitor cuts no number without a mark, draws the plot at once,
fits its help and header, and shows an active filter."""

from __future__ import annotations

import re

import pytest

from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.tui.app import make_app
from rs30x_sniff.tui.header import SessionInfo, status_text
from rs30x_sniff.tui.panes import range_label
from rs30x_sniff.sources.feeds import FileSource
from rs30x_sniff.tui.store import Store

from .helpers import ROOT, FrozenClock, wait_done

SESSION = "captures/session-mixed.thex"


@pytest.fixture(autouse=True)
def _in_the_repository(monkeypatch):
    monkeypatch.chdir(ROOT)


def session_app():
    return make_app(FileSource(SESSION), DecodeOptions(), clock=FrozenClock(), linter_factory=Linter,
                    tick_interval=3600)


async def loaded(pilot):
    await wait_done(pilot, pilot.app)
    for _ in range(3):
        await pilot.pause(0.05)


async def test_header_fits_80_columns_and_shows_the_filter():
    app = session_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await loaded(pilot)
        assert app.apply_filter("id:3")
        await pilot.pause(0.1)
        header = str(app.status.render()).split("\n")
        width = app.status.content_region.width
        plain = status_text(app.store, app.info, width).plain.split("\n")
        shown = app.store.view_len()
    assert len(plain) == 2 and all(len(line) <= width for line in plain), plain
    # Each field is whole (the two lines on screen are the two lines made: nothing wrapped).
    assert [h.strip() for h in header] == [p.strip() for p in plain]
    assert "findings E4 W6 i0" in plain[1]
    assert f"filter: id:3 {shown:,} shown" in plain[1] and 0 < shown < 321


def test_header_leaves_out_whole_fields_never_part_of_a_number():
    store = Store(1000)
    info = SessionInfo(source="a/very/long/path/to/the/capture/session-2024-11-25-robot.thex",
                       models="RS303MR×6", elapsed=12.3, state="done", filter_text="present_position<-20")
    full = status_text(store, info).plain.split("\n")
    for width in range(20, 200, 7):
        lines = status_text(store, info, width).plain.split("\n")
        assert all(len(line) <= width for line in lines), (width, lines)
        for line, whole in zip(lines, full):
            fields = [f for f in line.split(" │ ")]
            # Every field but a shortened name is one of the full line's fields, as it is.
            assert all(f in whole.split(" │ ") or "…" in f for f in fields), (width, line)
        assert "filter: " in lines[1] or width < 40


async def test_help_fits_80_columns():
    app = session_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await loaded(pilot)
        await pilot.press("question_mark")
        await pilot.pause(0.1)
        box = app.screen.query_one("VerticalScroll")
        assert box.region.right <= 80 and box.region.bottom <= 24
        # The longest explanations wrap inside the box instead of running off its right side.
        assert box.virtual_size.width <= box.scrollable_content_region.width
        assert box.max_scroll_x == 0


async def test_plot_is_drawn_at_once_when_its_pane_appears():
    app = session_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await loaded(pilot)
        await pilot.press("b", "b")  # servos -> findings -> plot: the pane was hidden when the data came
        await pilot.pause(0.1)
        rows = str(app.plot.query_one("#plot-line").render()).split("\n")
        label = str(app.plot.query_one("#plot-range").render())
    columns = {x for row in rows for x, ch in enumerate(row) if ch != " "}
    assert len(columns) > 10, rows  # not one column squeezed at the left
    assert re.fullmatch(r"1\.00-2\.90 s \(all\)  -24\.4\.\.24\.9", label), label


async def test_timeline_marks_a_row_cut_at_its_edge():
    app = session_app()
    async with app.run_test(size=(120, 30)) as pilot:
        await loaded(pilot)
        await pilot.pause(0.1)
        tl = app.timeline
        visible = tl.scrollable_content_region.width
        rows = ["".join(seg.text for seg in tl.render_line(y))[:visible] for y in range(1, tl.size.height)]
    returns = [r for r in rows if "RETURN" in r and "present_position" in r]
    assert returns, rows
    for r in returns:
        # present_position=-24.9deg ... does not fit: never shown as "present_position=-2" and nothing more.
        assert r.endswith("…"), r
    assert all(r.endswith("…") or not r.rstrip().endswith(tuple("0123456789.-")) or len(r.rstrip()) < visible - 1
               for r in rows)


@pytest.mark.parametrize("width", [6, 10, 14, 20, 26, 40])
def test_range_label_keeps_its_numbers_whole(width):
    text = range_label(1.0, 2.9, "all", -24.87, 24.9, width)
    assert len(text) <= width
    if not text.endswith("…"):
        assert text.endswith("-24.87..24.9")
    assert text != "-25..2"
