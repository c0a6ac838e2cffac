"""The monitor application and the factory the CLI and the tests share to build it."""

from __future__ import annotations

import asyncio
import gc
import os
import signal
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast
from collections.abc import Callable, Iterable

from textual import on
from textual.app import App, ComposeResult, SystemCommand
from textual.binding import Binding
from textual.containers import Horizontal
from textual.message import Message
from textual.screen import Screen
from textual.widgets import Footer, Input, Label

from ..protocol.memmap import default_registry
from ..decode.decoder import DecodeOptions
from ..filters import FilterError, parse_filter
from ..render.times import ABSOLUTE, DEFAULT_TIME_FORMAT, DELTA, EPOCH, TimeForm
from .detail import DetailPane
from .feed import POST_INTERVAL, Batch, Feeder, default_linter
from ..sources.feeds import Feed
from ..sources.serial_tap import stop_signals
from .header import SessionInfo, StatusHeader
from .help import HelpScreen
from .panes import FindingsPane, PlotPane
from .rows import clean
from .servos_pane import ServosPane
from .plot_series import PLOT_REGISTERS
from .store import DEFAULT_HISTORY, Store
from .timeline import Timeline

FILTER_STEP = 20_000  # records a filter scan checks between screen updates
NARROW_WIDTH = 120    # columns under which the detail pane hides and the bottom panes take turns
WIDE_WIDTH = 160      # columns under which the findings and the plot take turns beside the servos
SHORT_HEIGHT = 32     # rows under which the bottom panes get fewer rows
BOTTOM_PANES = ("servos", "findings", "plot")
# The cyclic collector's thresholds while the monitor runs: a young collection every 50,000 allocations
# rather than 700 (drawing a screen allocates tens of thousands of objects a second, nearly all freed by
# reference counting before a collection would see them), a full one only after 100 of the middle
# generation's. Over 30 s of the hexapod at 230400 baud: 0.6 s of collections instead of 1.1 s with a
# freeze per batch, or 2.6 s with neither.
GC_THRESHOLDS = (50_000, 20, 100)


# What the header says of the times shown when they are not seconds since the capture's start.
_TIMES_SHOWN = {ABSOLUTE: "date and time", DELTA: "since the previous packet", EPOCH: "seconds since 1970"}


class BatchArrived(Message):
    """Records from the capture thread (posted from that thread; Textual queues it for the screen)."""

    def __init__(self, batch: Batch) -> None:
        super().__init__()
        self.batch = batch


@dataclass
class MonitorConfig:
    """Everything the factory needs besides the source (what the command line decides)."""

    options: DecodeOptions
    history: int = DEFAULT_HISTORY
    record_dir: str = "."
    clock: Callable[[], float] = time.monotonic   # elapsed time and value flashes (tests freeze it)
    wall: Callable[[], float] = time.time         # names recordings
    linter_factory: Callable[[], Any] = default_linter
    sink_factory: Callable[..., Any] | None = None
    post_interval: float = POST_INTERVAL
    tick_interval: float = 0.5
    time_format: str = DEFAULT_TIME_FORMAT        # how the timeline shows times (--time-format)
    time_anchor: float | None = None              # epoch seconds of capture time 0 (the simulator: when it started)


class MonitorApp(App):
    """The bus on one screen. Messages go up (batches from the capture thread, selections from panes);
    attributes go down (the app tells each pane what to show)."""

    CSS_PATH = "app.tcss"
    TITLE = "rs30x-sniff monitor"
    BINDINGS = [
        Binding("q", "quit", "Quit"),
        # Ctrl-C quits, as in cantools' and python-can's monitors (Textual would only say "press ctrl+q").
        Binding("ctrl+c", "quit", "Quit", show=False, priority=True),
        Binding("space", "toggle_pause", "Pause"),
        Binding("slash", "open_filter", "Filter"),
        Binding("n", "next_finding", "Next finding"),
        Binding("N", "prev_finding", "Prev finding", key_display="N"),
        Binding("f", "follow", "Follow"),
        Binding("end", "follow", "Follow", show=False),
        Binding("c", "clear", "Clear"),
        Binding("r", "toggle_record", "Record"),
        Binding("g", "goto_pair", "Pair"),
        Binding("p", "next_plot", "Plot"),
        Binding("a", "plot_all", "All servos", show=False),
        Binding("z", "plot_zoom(0.5)", "Zoom in", show=False),
        Binding("Z", "plot_zoom(2.0)", "Zoom out", show=False, key_display="Z"),
        Binding("left_square_bracket", "plot_pan(-0.25)", "Pan back", show=False, key_display="["),
        Binding("right_square_bracket", "plot_pan(0.25)", "Pan on", show=False, key_display="]"),
        Binding("0", "plot_reset", "Whole plot", show=False),
        Binding("d", "toggle_detail", "Detail"),
        Binding("b", "next_pane", "Pane"),
        Binding("question_mark", "help", "Help", key_display="?"),
    ]

    def __init__(self, source: Feed, config: MonitorConfig) -> None:
        super().__init__()
        self.source = source
        self.config = config
        opts = config.options
        self.store = Store(config.history, baud=opts.baud)
        self.linter = config.linter_factory()
        self.feeder = Feeder(source, opts, self._post_batch, linter=self.linter, interval=config.post_interval,
                             clock=config.clock, sink_factory=config.sink_factory)
        self.info = SessionInfo(source=source.name, source_kind=source.kind, baud=opts.baud,
                                models=self._models_text(), lint=self.linter is not None)
        self.times = TimeForm(config.time_format, config.time_anchor)
        self.info.times = _TIMES_SHOWN.get(config.time_format, "")
        self.started = config.clock()
        self.done = False
        self.batches = 0
        self._gc_thresholds: tuple[int, int, int] | None = None  # the process's, restored at unmount
        self._redraws = 0     # redraws of the panes for batches (_refresh_views)
        self._ticked_at = -1  # _redraws at the last tick
        self._redrawn_at: float | None = None  # config.clock() at the last redraw for a batch
        # The record the detail pane was given as the timeline followed (its seq, and its findings then): the
        # Selected message the same move queues behind the batch shows it again only if a finding came since.
        self._followed: tuple[int, int] | None = None
        self._filter_task: asyncio.Task | None = None
        # The first bottom pane's class from the start: added at the first resize instead, it would
        # restyle every widget once more before the first frame.
        self.add_class(f"-bottom-{BOTTOM_PANES[0]}")

    def _models_text(self) -> str:
        opts = self.config.options
        reg = opts.registry or default_registry()
        default = reg.get(opts.default_model).name if opts.default_model else reg.default.name
        per_id = ", ".join(f"{i}={m}" for i, m in sorted(opts.models.items()))
        if self.store.servos:
            # What the bus says: each servo's model, configured or learned from its model number.
            seen = Counter(row.model for row in self.store.servos.values())
            return " ".join(f"{m}×{n}" for m, n in sorted(seen.items()))
        return default + (f", {per_id}" if per_id else "")

    # ---- layout ---------------------------------------------------------------------------------------
    def compose(self) -> ComposeResult:
        # The app keeps its widgets by reference: a query would search whatever screen is on top (help).
        self.status = StatusHeader(id="status")
        self.timeline = Timeline(self.store, self.times, id="timeline")
        self.detail = DetailPane(self.times, id="detail")
        self.servos = ServosPane(self.config.clock, id="servos")
        self.findings = FindingsPane(id="findings")
        self.plot = PlotPane(id="plot")
        self.filter_bar = Horizontal(id="filter-bar")
        self.filter_input = Input(placeholder="id:1-6 kind:return reg:goal_position sev>=warning text",
                                  id="filter-input")
        self.filter_error = Label("", id="filter-error")
        yield self.status
        with Horizontal(id="main"):
            yield self.timeline
            yield self.detail
        with Horizontal(id="bottom"):
            yield self.servos
            yield self.findings
            yield self.plot
        with self.filter_bar:
            yield Label("filter:", id="filter-label")
            yield self.filter_input
            yield self.filter_error
        yield Footer()

    def on_mount(self) -> None:
        self.timeline.border_title = "timeline"
        self.detail.border_title = "detail"
        self.plot.border_title = "plot"
        self.timeline.focus()
        self._refresh_header()
        self.run_worker(self.feeder.run, thread=True, name="capture", group="capture", exit_on_error=False)
        self.set_interval(self.config.tick_interval, self._tick)
        self._quit_on_signals()
        self._gc_thresholds = gc.get_threshold()
        gc.set_threshold(*GC_THRESHOLDS)

    def on_unmount(self) -> None:
        if self._gc_thresholds is not None:
            gc.set_threshold(*self._gc_thresholds)

    def _quit_on_signals(self) -> None:
        """SIGTERM and SIGHUP quit as `q` does: the recording is finished and the terminal restored (SIGHUP not when
        it started ignored: `nohup` asked the run to outlive its terminal)."""
        try:
            loop = asyncio.get_running_loop()
            loop.add_signal_handler(signal.SIGTERM, lambda: asyncio.ensure_future(self.action_quit()))
            if hasattr(signal, "SIGHUP") and signal.SIGHUP in stop_signals():
                loop.add_signal_handler(signal.SIGHUP, lambda: asyncio.ensure_future(self._hang_up()))
        except (NotImplementedError, RuntimeError, ValueError):
            pass  # not the main thread, or a platform without loop signal handlers: the default applies

    async def _hang_up(self) -> None:
        """SIGHUP: quit as `q` does; if the terminal itself is gone (a closed ssh session, a killed tmux), there
        is no screen to restore, and Textual waits for ever on writes it cannot make: the recording is finished,
        then the process ends at once, exit 0."""
        try:
            if sys.__stdout__ is not None:  # None: started without one, nothing to reset
                os.write(sys.__stdout__.fileno(), b"\x1b[0m")  # a reset of attributes: harmless on a live terminal
        except (OSError, AttributeError, ValueError):
            self.feeder.stop()
            for _ in range(100):
                if not self.feeder.running:
                    break
                await asyncio.sleep(0.05)
            os._exit(0)
        await self.action_quit()

    # ---- capture thread -> screen ---------------------------------------------------------------------
    def _post_batch(self, batch: Batch) -> None:
        # Called on the capture thread; post_message is the thread-safe way in.
        self.post_message(BatchArrived(batch))

    def on_batch_arrived(self, message: BatchArrived) -> None:
        if not self.status.is_attached:
            return  # shutting down: the widgets are gone
        b = message.batch
        store = self.store
        if not self.times.started:
            self.times.start_with(b.records)  # the capture's first time: before any of its rows is drawn
            if self.times.note:
                self.info.times, self.info.times_fallback = "since start (no wall clock)", True
                self.notify(clean(self.times.note), timeout=6)
        # No gc.freeze of the store's rows: over an hour of the hexapod at 230400 baud it saved no CPU and made the
        # collector's pauses longer in sum and more often over 0.5 s (bench/gc_freeze.py): GC_THRESHOLDS alone rules it.
        store.add(b.records, b.findings, b.servos, b.bytes_in, b.stats)
        self.batches += 1
        self.info.recording = b.recording
        if b.note:
            self.notify(clean(b.note), timeout=4)
        if b.done:
            self.done = True
            self.info.state = f"error: {b.error}" if b.error else "done"
            if b.error:
                self.notify(clean(b.error), severity="error", timeout=10)
        elif self.source.kind in ("port", "simulator"):
            self.info.state = "live"
        elif self.source.kind == "replay":
            self.info.state = "replaying"
        if b.more:
            return  # the rest of the post follows at once: one redraw, after it
        if store.plot_id is None and store.servos:
            store.set_plot(min(store.servos))
        self._refresh_views(new_findings=bool(b.findings))

    def _refresh_views(self, new_findings: bool = False) -> None:
        timeline = self.timeline
        if new_findings:
            timeline.invalidate()  # a finding can land on a row already drawn
        timeline.sync()
        if timeline.follow:
            # Show the newest record now rather than after the next batch (the Selected message queues behind it).
            seq = timeline.cursor_seq
            rec = self.store.get(seq) if seq is not None else None
            self.detail.show(rec)
            self._followed = (seq, len(rec.findings)) if seq is not None and rec is not None else None
        self.servos.update_from(self.store, flash=self.done or self.source.kind != "file")
        self.servos.tick()  # flashes due to end go now, in this redraw, rather than in a tick's own
        self.findings.update_from(self.store)
        self.plot.update_from(self.store)
        self._refresh_header()
        self._redraws += 1
        self._redrawn_at = self.config.clock()

    def _refresh_header(self) -> None:
        self.info.models = self._models_text()
        self.info.elapsed = self.config.clock() - self.started
        self.info.filter_progress = self.store.filter_progress
        self.status.show(self.store, self.info)

    def _tick(self) -> None:
        # The header's clock and the flashes between batches: while batches come (one came since the last
        # tick), each redraw does this already, and a tick of its own would cost a redraw more.
        seen, self._ticked_at = self._ticked_at, self._redraws
        if not self.status.is_attached or self._redraws != seen:
            return
        if not self.done and not batch_overdue(self.config.clock(), self._redrawn_at, self.config.post_interval,
                                               self.config.tick_interval):
            return
        self._refresh_header()
        self.servos.tick()

    # ---- selection ------------------------------------------------------------------------------------
    @on(Timeline.Selected)
    def _on_selected(self, message: Timeline.Selected) -> None:
        rec = self.store.get(message.seq) if message.seq is not None else None
        followed, self._followed = self._followed, None
        if rec is not None and followed == (message.seq, len(rec.findings)):
            return  # the record the batch's redraw showed already, as it is
        self.detail.show(rec)

    @on(Timeline.FollowChanged)
    def _on_follow_changed(self, message: Timeline.FollowChanged) -> None:
        self.info.follow = message.follow
        self._refresh_header()

    @on(DetailPane.Jump)
    def _on_jump(self, message: DetailPane.Jump) -> None:
        seq = self.store.seq_of(message.rec)
        self._show_seq(seq, "that packet is no longer in the history")

    @on(FindingsPane.JumpTo)
    def _on_jump_to_finding(self, message: FindingsPane.JumpTo) -> None:
        seq = self.store.seq_of_offset(message.finding.offset)
        self._show_seq(seq, f"the packet at @{message.finding.offset} is no longer in the history")

    @on(ServosPane.Highlighted, "#servos")
    def _on_servo_highlighted(self, event: ServosPane.Highlighted) -> None:
        sid = cast("int | None", event.key)  # the servos pane's rows are keyed by servo ID
        if sid != self.store.plot_id:
            self.store.set_plot(sid)
            self.plot.update_from(self.store)

    def _show_seq(self, seq: int | None, gone: str) -> bool:
        timeline = self.timeline
        if seq is None:
            self.notify(gone, severity="warning")
            return False
        if timeline.paused_at is not None and seq >= timeline.paused_at:
            timeline.paused_at = self.store.end_seq  # show the paused view up to now, to reach it
            timeline.sync()
        if not timeline.select_seq(seq):
            self.notify("that packet is hidden by the filter", severity="warning")
            return False
        timeline.focus()
        return True

    # ---- actions --------------------------------------------------------------------------------------
    async def action_quit(self) -> None:
        self.feeder.stop()
        # Give the capture thread a moment to finish a recording, so the MCAP file is complete.
        for _ in range(60):
            if not self.feeder.running:
                break
            await asyncio.sleep(0.05)
        self.exit()

    def action_toggle_pause(self) -> None:
        timeline = self.timeline
        if timeline.paused_at is None:
            timeline.paused_at = self.store.end_seq
            self.info.paused = True
        else:
            timeline.paused_at = None
            self.info.paused = False
        timeline.sync()
        self._refresh_header()

    def action_follow(self) -> None:
        timeline = self.timeline
        timeline.follow = True
        timeline.sync()
        timeline.focus()

    def action_next_finding(self) -> None:
        self._step_finding(True)

    def action_prev_finding(self) -> None:
        self._step_finding(False)

    def _step_finding(self, forward: bool) -> None:
        timeline = self.timeline
        seq = self.store.finding_seq(timeline.cursor_seq, forward)
        if timeline.paused_at is not None and seq is not None and seq >= timeline.paused_at:
            seq = None
        if seq is None:
            self.notify("no further finding" if forward else "no earlier finding", timeout=2)
            return
        self._show_seq(seq, "")

    def action_clear(self) -> None:
        self.store.clear()
        self.feeder.clear_stats()
        self.servos.reset()
        self.detail.show(None)
        self._followed = None
        self.info.filter_text = ""
        self._refresh_views()
        self.findings.update_from(self.store)

    def action_toggle_record(self) -> None:
        feeder = self.feeder
        if feeder.recording or self.info.recording:
            feeder.stop_recording()
            self.notify("stopping the recording", timeout=2)
            return
        if self.done or feeder.finished:
            self.notify("the source has ended: nothing more to record", severity="warning")
            return
        stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(self.config.wall()))
        path = str(Path(self.config.record_dir) / f"rs30x-{stamp}.mcap")
        feeder.start_recording(path)
        self.info.recording = path
        self._refresh_header()

    def action_goto_pair(self) -> None:
        if not self.detail.goto_pair():
            self.notify("this packet has no reply or request", timeout=2)

    # ---- a layout for the terminal's size -------------------------------------------------------------
    def on_resize(self, event) -> None:
        self._fit(event.size.width, event.size.height)

    def _fit(self, width: int, height: int) -> None:
        """Under 120 columns the detail pane hides behind `d` and one bottom pane shows at a time (`b`
        cycles them); under 160 the findings and the plot take turns beside the servos (`b`); under 32
        rows the bottom panes get fewer rows (app.tcss)."""
        self.set_class(width < NARROW_WIDTH, "-narrow")
        self.set_class(NARROW_WIDTH <= width < WIDE_WIDTH, "-medium")
        self.set_class(height < SHORT_HEIGHT, "-short")
        if not any(self.has_class(f"-bottom-{p}") for p in BOTTOM_PANES):
            self.add_class(f"-bottom-{BOTTOM_PANES[0]}")

    def action_toggle_detail(self) -> None:
        if not self.has_class("-narrow"):
            self.notify("the detail pane is always shown at this width", timeout=2)
            return
        self.toggle_class("-with-detail")
        if self.has_class("-with-detail"):
            self._followed = None
            self.detail.show(self.store.get(self.timeline.cursor_seq) if self.timeline.cursor_seq is not None
                             else None)

    def action_next_pane(self) -> None:
        if self.has_class("-medium"):
            self.toggle_class("-side-plot")  # the servos stay; findings and the plot take turns
            return
        if not self.has_class("-narrow"):
            self.notify("every pane is shown at this width", timeout=2)
            return
        now = next((k for k, p in enumerate(BOTTOM_PANES) if self.has_class(f"-bottom-{p}")), 0)
        self.remove_class(f"-bottom-{BOTTOM_PANES[now]}")
        self.add_class(f"-bottom-{BOTTOM_PANES[(now + 1) % len(BOTTOM_PANES)]}")

    def action_plot_all(self) -> None:
        store = self.store
        store.set_plot(store.plot_id, all_servos=not store.plot_all)
        self.plot.update_from(store)

    def action_plot_zoom(self, factor: float) -> None:
        self.plot.zoom(self.store, factor)
        self.plot.update_from(self.store)

    def action_plot_pan(self, fraction: float) -> None:
        self.plot.pan(self.store, fraction)
        self.plot.update_from(self.store)

    def action_plot_reset(self) -> None:
        self.plot.reset()
        self.plot.update_from(self.store)

    def action_next_plot(self) -> None:
        store = self.store
        i = PLOT_REGISTERS.index(store.plot_register) if store.plot_register in PLOT_REGISTERS else -1
        store.set_plot(store.plot_id, PLOT_REGISTERS[(i + 1) % len(PLOT_REGISTERS)])
        self.plot.update_from(store)

    def action_help(self) -> None:
        if not isinstance(self.screen, HelpScreen):
            self.push_screen(HelpScreen())

    # ---- filter ---------------------------------------------------------------------------------------
    def action_open_filter(self) -> None:
        bar = self.filter_bar
        bar.display = True
        inp = self.filter_input
        inp.value = self.info.filter_text
        self.filter_error.update("")
        inp.focus()

    def _close_filter(self) -> None:
        self.filter_bar.display = False
        self.timeline.focus()

    @on(Input.Submitted, "#filter-input")
    def _on_filter_submitted(self, event: Input.Submitted) -> None:
        self.apply_filter(event.value)

    def apply_filter(self, text: str) -> bool:
        """Parse and apply a filter; on a parse error keep the bar open with the reason shown."""
        try:
            flt = parse_filter(text, self.config.options.registry)
        except FilterError as e:
            self.filter_bar.display = True
            self.filter_error.update(clean(str(e)))
            return False
        self.info.filter_text = flt.text if flt else ""
        self.store.begin_filter(flt)
        if self._filter_task is not None:
            self._filter_task.cancel()
        self._filter_task = asyncio.ensure_future(self._scan_filter())
        self._close_filter()
        self.timeline.invalidate()
        return True

    async def _scan_filter(self) -> None:
        # A long history is scanned in steps so the screen stays responsive (the header shows progress).
        store = self.store
        while not store.filter_step(FILTER_STEP):
            self._refresh_views()
            await asyncio.sleep(0)
        self._refresh_views()

    def on_key(self, event) -> None:
        if event.key == "escape" and self.filter_bar.display:
            event.stop()
            self._close_filter()

    # ---- command palette ------------------------------------------------------------------------------
    def get_system_commands(self, screen: Screen) -> Iterable[SystemCommand]:
        yield from super().get_system_commands(screen)
        yield SystemCommand("Pause / resume", "Freeze the timeline (the capture goes on)", self.action_toggle_pause)
        yield SystemCommand("Follow", "Stick to the newest packet", self.action_follow)
        yield SystemCommand("Filter", "Filter the timeline", self.action_open_filter)
        yield SystemCommand("Clear filter", "Show every packet", lambda: self.apply_filter(""))
        yield SystemCommand("Next finding", "Go to the next packet with a finding", self.action_next_finding)
        yield SystemCommand("Clear", "Forget the history, counts and findings", self.action_clear)
        yield SystemCommand("Record", "Start or stop recording to MCAP", self.action_toggle_record)
        for name in PLOT_REGISTERS:
            yield SystemCommand(f"Plot {name}", f"Plot {name} of the selected servo",
                                lambda name=name: self._plot(name))

    def _plot(self, name: str) -> None:
        self.store.set_plot(self.store.plot_id, name)
        self.plot.update_from(self.store)


def batch_overdue(now: float, redrawn_at: float | None, post_interval: float, tick_interval: float) -> bool:
    """Whether a tick should redraw the header and end flashes itself: not while a live source's next batch is due
    within a tick, as its redraw will do it (a tick just before would cost the screen a redraw of its own, and on
    a live port the redraws are most of the monitor's CPU)."""
    return redrawn_at is None or now - redrawn_at >= post_interval + tick_interval


def make_app(source: Feed, options: DecodeOptions | None = None, **config: Any) -> MonitorApp:
    """The monitor for ``source``: what ``rs30x-sniff monitor`` runs and what the tests drive."""
    return MonitorApp(source, MonitorConfig(options or DecodeOptions(), **config))
