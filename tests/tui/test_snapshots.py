"""Snapshots of the monitor: the main screen at 80x24, 120x30 and 160x48, panes, the detail pane, the help.

The SVGs are compared after the screenshot's id (a hash over the rendered segments, which carry per-run
handler metadata) is taken out, so the same screen always compares equal. After an intended change,
run ``RS30X_UPDATE_SNAPSHOTS=1 pytest tests/tui/test_snapshots.py`` and look at the SVGs under
tests/tui/__snapshots__/screens before committing.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.tui.app import make_app
from rs30x_sniff.sources.feeds import FileSource

from .helpers import ROOT, SIZE, FrozenClock, wait_done

SCREENS = Path(__file__).parent / "__snapshots__" / "screens"


@pytest.fixture(autouse=True)
def _in_the_repository(monkeypatch):
    # The header shows the path as given: relative, so the snapshots do not depend on the checkout's place.
    monkeypatch.chdir(ROOT)


def manual_app():
    # A frozen clock: nothing in the header depends on when the test runs.
    return make_app(FileSource("captures/manual-examples.hex"), DecodeOptions(), clock=FrozenClock(),
                    linter_factory=Linter, tick_interval=3600)


async def settled(pilot):
    """Loaded, and the layout done with its resize (the panes refill for their new widths)."""
    await wait_done(pilot, pilot.app)
    for _ in range(3):
        await pilot.pause(0.1)
    await pilot.wait_for_scheduled_animations()


def _normal(svg: str) -> str:
    return re.sub(r"terminal-\d+", "terminal", svg)


async def _compare(name: str, size: tuple[int, int], *keys: str) -> None:
    app = manual_app()
    async with app.run_test(size=size) as pilot:
        await settled(pilot)
        if keys:
            await pilot.press(*keys)
            await settled(pilot)
        svg = _normal(app.export_screenshot())
    path = SCREENS / f"{name}.svg"
    if os.environ.get("RS30X_UPDATE_SNAPSHOTS"):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(svg)
    assert path.exists(), f"no snapshot {path.name}: run with RS30X_UPDATE_SNAPSHOTS=1"
    assert svg == path.read_text(), f"{path.name} differs: look at it, then RS30X_UPDATE_SNAPSHOTS=1"


@pytest.mark.parametrize("size", [(80, 24), (120, 30), SIZE], ids=["80x24", "120x30", "160x48"])
async def test_main_screen_fits_common_terminal_sizes(size):
    """At 80x24 the timeline keeps time, direction, ID, kind and summary (the detail pane behind `d`, one
    bottom pane at a time); at 120x30 the findings and plot take turns beside the servos; at 160x48
    everything shows."""
    await _compare(f"main-{size[0]}x{size[1]}", size)


async def test_detail_pane_with_a_field_selected():
    # The long packet at @42: its second servo's goal_position bytes light up in the hex dump.
    await _compare("detail-field-160x48", SIZE, "home", "down", "down", "down", "down", "down", "tab",
                   "down", "down", "down", "down")


async def test_help_screen():
    await _compare("help-160x48", SIZE, "question_mark")


async def test_findings_wrap_at_80x24():
    await _compare("findings-80x24", (80, 24), "b")  # servos -> findings: messages wrap, never cut


async def test_detail_pane_at_80x24():
    await _compare("detail-80x24", (80, 24), "up", "up", "d")  # the detail pane in the timeline's place


async def test_plot_of_every_servo_zoomed():
    await _compare("plot-all-zoomed-160x48", SIZE, "a", "z")
