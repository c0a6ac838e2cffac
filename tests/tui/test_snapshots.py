"""Snapshots of the monitor at a fixed terminal size: the main screen, the detail pane, and the help.

Update them after an intended change with ``pytest tests/tui/test_snapshots.py --snapshot-update`` and
look at the SVGs under tests/tui/__snapshots__ before committing.
"""

from __future__ import annotations

import pytest

from rs30x_sniff.lint import Linter
from rs30x_sniff.pipeline import DecodeOptions
from rs30x_sniff.tui.app import make_app
from rs30x_sniff.tui.sources import FileSource

from .helpers import ROOT, SIZE, FrozenClock, wait_done


@pytest.fixture(autouse=True)
def _in_the_repository(monkeypatch):
    # The header shows the path as given: relative, so the snapshots do not depend on the checkout's place.
    monkeypatch.chdir(ROOT)


def manual_app():
    # A frozen clock: nothing in the header depends on when the test runs.
    return make_app(FileSource("captures/manual-examples.hex"), DecodeOptions(), clock=FrozenClock(),
                    linter_factory=Linter, tick_interval=3600)


async def loaded(pilot):
    await wait_done(pilot, pilot.app)


def test_main_screen(snap_compare):
    assert snap_compare(manual_app(), terminal_size=SIZE, run_before=loaded)


def test_detail_pane_with_a_field_selected(snap_compare):
    async def select_field(pilot):
        await loaded(pilot)
        # The long packet at @42: its second servo's goal_position bytes light up in the hex dump.
        await pilot.press("home", "down", "down", "down", "down", "down", "tab")
        await pilot.press("down", "down", "down", "down")
        await pilot.pause()

    assert snap_compare(manual_app(), terminal_size=SIZE, run_before=select_field)


def test_help_screen(snap_compare):
    assert snap_compare(manual_app(), terminal_size=SIZE, press=["question_mark"], run_before=loaded)
