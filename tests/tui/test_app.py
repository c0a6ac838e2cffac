"""Pilot tests of the monitor: every key, the filter bar, the panes, and what reaches the terminal."""

from __future__ import annotations

import threading

import pytest

from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.tui.app import make_app
from rs30x_sniff.tui.detail import DetailPane, FieldTree
from rs30x_sniff.tui.header import StatusHeader
from rs30x_sniff.tui.help import HelpScreen
from rs30x_sniff.tui.panes import FindingsPane
from rs30x_sniff.tui.servos_pane import ServosPane
from rs30x_sniff.sources.feeds import FileSource
from rs30x_sniff.tui.timeline import Timeline
from rs30x_sniff.protocol.wire import encode_return, encode_short

from .helpers import MANUAL, SIZE, FrozenClock, GatedSource, wait_done


def manual_app(**kw):
    kw.setdefault("clock", FrozenClock())
    kw.setdefault("linter_factory", Linter)
    return make_app(FileSource(MANUAL), DecodeOptions(), **kw)


def header_text(app) -> str:
    return app.query_one(StatusHeader).render().plain


def timeline(app) -> Timeline:
    return app.query_one("#timeline", Timeline)


def selected(app):
    return app.store.get(timeline(app).cursor_seq)


async def test_opens_a_capture_and_follows_the_newest_row():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        tl = timeline(app)
        assert tl.row_count == 24 and tl.follow
        assert selected(app).kind == "return"
        assert app.query_one(DetailPane).rec is selected(app)
        head = header_text(app)
        assert "captures/manual-examples.hex" in head and "packets 24" in head and "done" in head
        assert "E3" in head and "W4" in head  # B002, P008, P009 errors; M002, Q002, 2x Q004 warnings


async def test_arrows_move_the_cursor_and_leave_follow_mode():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await pilot.press("up", "up")
        tl = timeline(app)
        assert not tl.follow and tl.cursor_seq == 21
        assert app.query_one(DetailPane).rec.offset == 210
        await pilot.press("home")
        assert tl.cursor_seq == 0
        await pilot.press("pagedown")
        assert tl.cursor_seq > 10
        await pilot.press("end")  # End resumes following
        assert tl.follow and tl.cursor_seq == 23


async def test_f_resumes_follow_after_scrolling_up():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await pilot.press("home")
        assert not timeline(app).follow
        await pilot.press("f")
        assert timeline(app).follow and timeline(app).cursor_seq == 23
        assert "not following" not in header_text(app)


@pytest.mark.parametrize("key", ["q", "ctrl+c"])
async def test_q_and_ctrl_c_quit(key):
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await pilot.press(key)
        await pilot.pause()
    assert app.return_code == 0 and not app.is_running


async def test_n_and_shift_n_walk_the_findings():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await pilot.press("home")
        offsets = []
        for _ in range(8):
            await pilot.press("n")
            offsets.append(selected(app).offset)
        # Findings sit on @34, @42, @59, @86, @105 and @139; past the last one the cursor stays put.
        assert offsets == [34, 42, 59, 86, 105, 139, 139, 139]
        await pilot.press("N", "N")
        assert selected(app).offset == 86


async def test_space_pauses_the_timeline_but_not_the_capture():
    gate = threading.Event()
    chunks = [(encode_short(1, 0, 30, bytes((i, 0))), i * 0.01) for i in range(40)]

    app = make_app(GatedSource(chunks, gate, (10,)), DecodeOptions(), clock=FrozenClock(), post_interval=0)
    async with app.run_test(size=SIZE) as pilot:
        for _ in range(100):
            await pilot.pause(0.02)
            if len(app.store) >= 10:
                break
        await pilot.press("space")
        assert timeline(app).paused_at is not None
        assert "PAUSED" in header_text(app)
        shown = timeline(app).row_count
        gate.set()
        await wait_done(pilot, app)
        assert len(app.store) == 40  # the capture went on
        assert timeline(app).row_count == shown  # the timeline did not
        assert "packets 40" in header_text(app)
        await pilot.press("space")
        assert timeline(app).row_count == 40 and "PAUSED" not in header_text(app)


async def test_c_clears_history_counts_findings_and_panes():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await pilot.press("c")
        assert len(app.store) == 0 and timeline(app).row_count == 0
        assert app.query_one(FindingsPane).row_count == 0
        assert app.query_one(ServosPane).row_count == 0
        assert app.query_one(DetailPane).rec is None
        assert "packets 0" in header_text(app) and "E0" in header_text(app)


async def test_question_mark_opens_help_and_escape_closes_it():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await pilot.press("question_mark")
        assert isinstance(app.screen, HelpScreen)
        await pilot.press("escape")
        assert not isinstance(app.screen, HelpScreen)
        await pilot.press("question_mark")
        await pilot.press("q")  # q closes help rather than quitting
        assert not isinstance(app.screen, HelpScreen) and app.is_running


async def test_tab_moves_between_panes():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        assert app.focused is timeline(app)
        seen = []
        for _ in range(4):
            await pilot.press("tab")
            seen.append(app.focused.id)
        assert seen == ["fields", "servos", "findings", "timeline"]
        await pilot.press("shift+tab")
        assert app.focused.id == "findings"


async def test_enter_on_a_finding_jumps_to_its_packet():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        findings = app.query_one(FindingsPane)
        findings.focus()
        await pilot.pause()
        # Newest first: the last finding the linter reported is on top.
        newest = list(app.store.findings)[-1]
        await pilot.press("enter")
        await pilot.pause()
        assert selected(app).offset == newest.offset
        assert app.focused is timeline(app)
        await pilot.press("tab", "tab", "tab", "down", "enter")
        await pilot.pause()
        assert selected(app).offset == list(app.store.findings)[-2].offset


async def test_g_goes_between_a_reply_and_its_request():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        assert selected(app).kind == "return"
        await pilot.press("g")
        await pilot.pause()
        assert selected(app).offset == 219
        await pilot.press("g")
        await pilot.pause()
        assert selected(app).offset == 227
        await pilot.press("home", "g")  # a write without a reply: nothing to go to
        await pilot.pause()
        assert selected(app).offset == 0


async def test_the_detail_tree_highlights_a_fields_bytes_and_follows_links():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        tree = app.query_one(FieldTree)
        tree.focus()
        await pilot.pause()
        # root, header, fields, present_position ...
        await pilot.press("down", "down", "down")
        await pilot.pause()
        hexw = app.query_one("#hex")
        content = hexw.text
        spans = [(content.plain[s.start:s.end], s.style) for s in content.spans if "reverse" in str(s.style)]
        assert [s for s, _ in spans] == ["84", " ", "03"]  # present_position's two bytes
        # The last node links to the request; enter follows it.
        await pilot.press("end", "enter")
        await pilot.pause()
        assert selected(app).offset == 219


async def test_p_cycles_the_plotted_register():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        assert app.store.plot_id == 1 and app.store.plot_register == "present_position"
        assert list(app.store.plot) == [90.0]
        await pilot.press("p")
        assert app.store.plot_register == "present_speed" and list(app.store.plot) == [300.0]
        app.query_one(ServosPane).focus()
        await pilot.press("down")  # the servos pane picks the plotted servo
        await pilot.pause()
        assert app.store.plot_id == 2


async def test_r_records_to_mcap_and_stops(tmp_path):
    from rs30x_sniff.sources.mcap_reader import read_mcap_raw

    gate = threading.Event()
    chunks = [(encode_short(1, 0, 30, bytes((i, 0))), i * 0.01) for i in range(30)]

    app = make_app(GatedSource(chunks, gate, (10, 20), rearm=True), DecodeOptions(), clock=FrozenClock(),
                   wall=lambda: 0.0, record_dir=str(tmp_path),
                   post_interval=0)
    async with app.run_test(size=SIZE) as pilot:
        for _ in range(100):
            await pilot.pause(0.02)
            if len(app.store) >= 10:
                break
        await pilot.press("r")
        assert "REC" in header_text(app)
        gate.set()  # chunks 10-19 go into the recording
        for _ in range(100):
            await pilot.pause(0.02)
            if len(app.store) >= 20:
                break
        await pilot.press("r")
        await pilot.pause(0.1)
        gate.set()
        await wait_done(pilot, app)
        assert "not recording" in header_text(app)
    files = list(tmp_path.glob("rs30x-*.mcap"))
    assert len(files) == 1
    data = b"".join(d for d, _ in read_mcap_raw(str(files[0])))
    assert data and len(data) % 10 == 0 and data in b"".join(d for d, _ in chunks[10:])


async def test_r_after_the_end_of_a_file_says_so():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await pilot.press("r")
        await pilot.pause()
        assert "not recording" in header_text(app)
        assert any("nothing more to record" in n.message for n in app._notifications)


async def test_the_command_palette_runs_monitor_commands():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await pilot.press("ctrl+p")
        await pilot.pause()
        from textual.command import CommandPalette
        from textual.widgets import Input
        palette = app.screen
        assert isinstance(palette, CommandPalette)
        palette.query_one(Input).value = "Plot present_voltage"
        for _ in range(20):  # the palette searches in the background
            await pilot.pause(0.05)
            if "present_voltage" in str(palette.query_one("CommandList").get_option_at_index(0).prompt):
                break
        await pilot.press("enter")
        await pilot.pause()
        assert app.store.plot_register == "present_voltage"
        assert list(app.store.plot) == [7.4]


# ---- the filter bar -----------------------------------------------------------------------------------
async def type_filter(pilot, text, keys=False):
    await pilot.press("slash")
    inp = pilot.app.query_one("#filter-input")
    inp.value = ""
    if keys:
        for ch in text:
            await pilot.press({" ": "space", "/": "slash", "?": "question_mark"}.get(ch, ch))
    else:
        inp.value = text
    await pilot.press("enter")
    for _ in range(20):
        await pilot.pause()
        if pilot.app.store.filter_progress is None:
            break


async def test_slash_filters_the_timeline():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await type_filter(pilot, "id:1 kind:read")
        tl = timeline(app)
        assert tl.row_count == 2
        assert [app.store.get(app.store.view_seq(i)).offset for i in range(2)] == [34, 219]
        assert not app.query_one("#filter-bar").display
        assert app.focused is tl
        assert "filter: id:1 kind:read 2 shown" in header_text(app)
        await type_filter(pilot, "")  # an empty filter shows everything again
        assert tl.row_count == 24 and "filter" not in header_text(app)


async def test_typing_q_in_the_filter_does_not_quit():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await type_filter(pilot, "torque zq", keys=True)
        assert app.is_running
        assert app.info.filter_text == "torque zq"
        assert timeline(app).row_count == 0  # no row has both words


@pytest.mark.parametrize("text, reason", [
    ("ids:3", "unknown filter key 'ids'"),
    ("sev>=fatal", "unknown severity"),
    ("reg:nope", "no such register"),
])
async def test_an_invalid_filter_says_why_and_stays_open(text, reason):
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await type_filter(pilot, text)
        assert app.query_one("#filter-bar").display
        assert reason in str(app.query_one("#filter-error").render())
        assert app.focused.id == "filter-input"
        assert timeline(app).row_count == 24  # the old view is untouched
        await pilot.press("escape")
        assert not app.query_one("#filter-bar").display and app.focused is timeline(app)


async def test_sev_filter_and_next_finding_together():
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        await type_filter(pilot, "sev>=error")
        assert timeline(app).row_count == 2  # B002 at @34, P008 and P009 at @86
        await pilot.press("home", "n")
        assert selected(app).offset == 86


# ---- what reaches the terminal ------------------------------------------------------------------------
async def test_markup_and_control_characters_from_names_are_shown_not_obeyed(tmp_path):
    p = tmp_path / "[bold red]x\x1b[2J.hex"
    p.write_bytes(b"FA AF 01 00 24 01 01 01 24\n")
    app = make_app(FileSource(str(p)), DecodeOptions(), clock=FrozenClock())
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        plain = header_text(app)
        assert "[bold red]x\\x1b[2J.hex" in plain
        assert "\x1b" not in plain


async def test_garbage_bytes_are_shown_as_hex():
    from rs30x_sniff.tui.rows import row_text

    from .helpers import records_of
    recs = records_of([(b"[red]\x1b[2J\x07x", None)])
    text = row_text(recs[0], None).plain
    assert "\x1b" not in text and "[red]" not in text
    assert "5B 72 65 64 5D 1B" in text


async def test_changed_servo_values_flash_briefly():
    clock = FrozenClock(100.0)
    chunks = []
    for k, pos in enumerate((100, 200)):
        chunks.append((encode_short(3, 0x09, 0, b"", length=0, count=1), k * 1.0))
        chunks.append((encode_return(3, 42, pos.to_bytes(2, "little") + bytes(16)), k * 1.0 + 0.001))
    gate = threading.Event()

    app = make_app(GatedSource(chunks, gate, (2,)), DecodeOptions(), clock=clock, post_interval=0, tick_interval=60)
    async with app.run_test(size=SIZE) as pilot:
        for _ in range(100):
            await pilot.pause(0.02)
            if 3 in app.store.servos and app.store.servos[3].values["present_position"] is not None:
                break
        pane = app.query_one(ServosPane)
        assert pane.get_cell("3", "pos").plain == "10.0" and not pane.get_cell("3", "pos").style
        gate.set()
        await wait_done(pilot, app)
        cell = pane.get_cell("3", "pos")
        assert cell.plain == "20.0" and "yellow" in str(cell.style)
        assert not pane.get_cell("3", "volt").style  # unchanged values stay plain
        clock.t += 0.5
        pane.tick()
        assert "yellow" in str(pane.get_cell("3", "pos").style)  # half a second on: still lit
        clock.t += 0.3
        pane.tick()  # a port's next batch comes a second on, give or take: its redraw ends the flash
        assert not pane.get_cell("3", "pos").style


async def test_a_large_capture_opens_with_a_bounded_history(tmp_path):
    import sys
    from pathlib import Path

    from rs30x_sniff.sources.captures import write_capture
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
    from bench.traffic import hexapod_frames

    p = tmp_path / "big.thex"
    write_capture(p, hexapod_frames(60_000), "timestamped")
    app = make_app(FileSource(str(p)), DecodeOptions(), clock=FrozenClock(), history=10_000)
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app, limit=60)
        assert app.store.stats.records == 60_000
        assert len(app.store) == 10_000 and timeline(app).row_count == 10_000
        assert app.store.first_seq == 50_000
        assert "10.0k/10.0k rows" in header_text(app)
        await pilot.press("home")
        assert timeline(app).cursor_seq == 50_000
        await type_filter(pilot, "id:7 kind:return")
        assert 0 < timeline(app).row_count < 1000


async def test_batches_arriving_under_the_help_screen_are_not_lost():
    gate = threading.Event()
    chunks = [(encode_short(1, 0, 30, bytes((i, 0))), i * 0.01) for i in range(20)]

    app = make_app(GatedSource(chunks, gate, (5,)), DecodeOptions(), clock=FrozenClock(), post_interval=0)
    async with app.run_test(size=SIZE) as pilot:
        await pilot.press("question_mark")
        assert isinstance(app.screen, HelpScreen)
        gate.set()
        await wait_done(pilot, app)
        await pilot.press("escape")
        assert len(app.store) == 20 and timeline(app).row_count == 20


async def test_the_mouse_wheel_scrolls_back_and_leaves_follow_mode(tmp_path):
    from rs30x_sniff.sources.captures import write_capture

    p = tmp_path / "many.thex"
    write_capture(p, [(encode_short(1, 0, 30, bytes((i % 256, 0))), i * 0.01) for i in range(300)], "timestamped")
    app = make_app(FileSource(str(p)), DecodeOptions(), clock=FrozenClock())
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        tl = timeline(app)
        bottom = tl.scroll_y
        assert tl.follow and bottom > 200
        from textual.events import MouseScrollUp
        for _ in range(3):  # what a wheel turn sends (Pilot has no helper for it)
            tl.post_message(MouseScrollUp(tl, 20, 5, 0, -1, 0, False, False, False))
        await pilot.pause()
        assert not tl.follow and tl.scroll_y < bottom
        await pilot.click(tl, offset=(20, 5))
        assert tl.cursor_seq == int(tl.scroll_y) + 4


async def test_a_narrow_terminal_swaps_panes_with_d_and_b():
    app = manual_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_done(pilot, app)
        assert app.has_class("-narrow") and not app.detail.display and app.timeline.display
        assert app.servos.display and not app.findings.display and not app.plot.display
        await pilot.press("b")
        assert app.findings.display and not app.servos.display
        await pilot.press("b", "b")
        assert app.servos.display
        await pilot.press("d")
        assert app.detail.display and not app.timeline.display
        await pilot.press("d")
        assert app.timeline.display and not app.detail.display
    app = manual_app()
    async with app.run_test(size=(160, 48)) as pilot:
        await wait_done(pilot, app)
        assert not app.has_class("-narrow")
        assert app.detail.display and app.servos.display and app.findings.display and app.plot.display


async def test_the_collector_thresholds_hold_while_the_monitor_runs_and_are_restored_after():
    import gc

    from rs30x_sniff.tui.app import GC_THRESHOLDS

    before = gc.get_threshold()
    app = manual_app()
    async with app.run_test(size=SIZE) as pilot:
        await wait_done(pilot, app)
        assert gc.get_threshold() == GC_THRESHOLDS
    assert gc.get_threshold() == before


async def test_the_timeline_grows_without_a_layout_and_its_scrollbar_and_scroll_keep_up():
    chunks = [(encode_short(1, 0, 30, bytes((i % 256, 0))), i * 0.01) for i in range(200)]
    gate = threading.Event()
    app = make_app(GatedSource(chunks, gate, (100,)), DecodeOptions(), clock=FrozenClock(), post_interval=0)
    async with app.run_test(size=SIZE) as pilot:
        for _ in range(100):
            await pilot.pause(0.02)
            if len(app.store) >= 100:
                break
        await pilot.pause(0.1)
        tl = timeline(app)
        assert tl.show_vertical_scrollbar  # the rows overflow the view: what follows moves only the thumb
        gate.set()
        await wait_done(pilot, app)
        await pilot.pause(0.1)
        assert tl.virtual_size.height == 201 == tl.vertical_scrollbar.window_virtual_size
        assert tl.scroll_y == tl.max_scroll_y > 0  # following: the newest row is in sight
        assert tl.cursor_seq == 199
        rows = ["".join(seg.text for seg in tl.render_line(y)) for y in range(1, tl.scrollable_content_region.height)]
        assert "1.990000" in rows[-1]  # the last line in sight is the newest packet's
