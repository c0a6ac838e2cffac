"""The timeline: one row per record, drawn with Textual's Line API so only the visible rows are rendered."""

from __future__ import annotations

from rich.cells import cell_len
from rich.segment import Segment
from rich.style import Style
from textual.binding import Binding
from textual.events import Click, MouseScrollUp
from textual.geometry import Size
from textual.message import Message
from textual.reactive import reactive
from textual.scroll_view import ScrollView
from textual.strip import Strip

from ..render.times import TimeForm
from .line_table import CURSOR_BINDINGS, SettingsPerRender
from .rows import COMPACT_BELOW, columns, row_pieces
from .store import Store

ROW_WIDTH = 400  # virtual width: summaries of long packets run far to the right (scroll with shift+wheel)
_CACHE_ROWS = 512


class Timeline(SettingsPerRender, ScrollView, can_focus=True):
    """Rows come from the store's view (filtered or not); the cursor is kept as a record seq, so it
    stays on its record while old records are dropped or a filter changes."""

    BINDINGS = [*CURSOR_BINDINGS, Binding("end", "app.follow", "Follow", show=False)]
    COMPONENT_CLASSES = {"timeline--cursor", "timeline--header"}
    DEFAULT_CSS = """
    Timeline { background: $surface; }
    Timeline > .timeline--cursor { background: $boost; text-style: bold; }
    Timeline:focus > .timeline--cursor { background: $accent 40%; }
    Timeline > .timeline--header { color: $text-muted; text-style: bold; }
    """

    follow: reactive[bool] = reactive(True)

    class Selected(Message):
        """The cursor moved to another record (``seq`` None: nothing to show)."""

        def __init__(self, seq: int | None) -> None:
            super().__init__()
            self.seq = seq

    class FollowChanged(Message):
        def __init__(self, follow: bool) -> None:
            super().__init__()
            self.follow = follow

    def __init__(self, store: Store, times: TimeForm | None = None, **kwargs) -> None:
        super().__init__(**kwargs)
        self.store = store
        self.times = times  # how the time column shows times (--time-format); None: capture seconds
        self.cursor_seq: int | None = None
        self.paused_at: int | None = None  # while paused, rows from this seq on are not shown yet
        self._rows = 0
        self._top_seq: int | None = None
        self._generation = store.generation
        self._cache: dict[tuple, Strip] = {}
        self._syncing = False

    # ---- model -> view ------------------------------------------------------------------------------
    @property
    def row_count(self) -> int:
        return self._rows

    @property
    def cursor_row(self) -> int | None:
        if self.cursor_seq is None:
            return None
        return self.store.view_index(self.cursor_seq)

    def sync(self) -> None:
        """Catch up with the store: new rows, dropped rows, a new filter, a clear."""
        store = self.store
        if store.generation != self._generation:
            self._generation = store.generation
            self.cursor_seq = self._top_seq = None
            self._cache.clear()
            if self.paused_at is not None:
                self.paused_at = store.end_seq
        n = store.view_len(self.paused_at)
        self._rows = n
        self._syncing = True
        try:
            self._resize(Size(ROW_WIDTH, n + 1))  # + the column header row
            if self.follow:
                self._move_cursor(store.view_seq(n - 1) if n else None)
                self.scroll_to(y=max(0, n + 1 - self.scrollable_content_region.height), animate=False,
                               immediate=True, force=True)
            else:
                if self._top_seq is not None:
                    self.scroll_to(y=store.view_nearest(self._top_seq), animate=False, immediate=True, force=True)
                if self.cursor_seq is not None and store.view_index(self.cursor_seq) is None:
                    self._move_cursor(store.view_seq(store.view_nearest(self.cursor_seq)) if n else None)
        finally:
            self._syncing = False
        if len(self._cache) > _CACHE_ROWS:
            self._cache.clear()
        self.refresh()

    def _resize(self, size: Size) -> None:
        """A new virtual size. While the rows overflow the view before and after (the vertical scrollbar
        shown, and staying so), nothing on the screen moves but the scrollbar's thumb: the size is set
        without a layout of the screen (which, every batch, cost a layout and a second redraw of the
        scrollbars), and the scrollbar is told its new extent."""
        old = self.virtual_size
        if size == old:
            return
        view = self.scrollable_content_region.height
        if self.show_vertical_scrollbar and size.width == old.width and old.height > view and size.height > view:
            self.set_reactive(Timeline.virtual_size, size)
            self.vertical_scrollbar.window_virtual_size = size.height
        else:
            self.virtual_size = size

    def invalidate(self) -> None:
        """Redraw every row (findings or a filter changed what rows show)."""
        self._cache.clear()
        self.refresh()

    # ---- cursor ---------------------------------------------------------------------------------------
    def _move_cursor(self, seq: int | None) -> None:
        if seq != self.cursor_seq:
            self.cursor_seq = seq
            self.post_message(self.Selected(seq))
            self.refresh()

    def select_seq(self, seq: int) -> bool:
        """Put the cursor on record ``seq`` (leaving follow mode); False if it is not in the view."""
        row = self.store.view_index(seq)
        if row is None or (self.paused_at is not None and seq >= self.paused_at):
            return False
        self.follow = False
        self._move_cursor(seq)
        self._scroll_to_row(row, center=True)
        return True

    def _scroll_to_row(self, row: int, center: bool = False) -> None:
        """Scroll just enough to show ``row`` (a jump from afar puts it in the middle)."""
        height = max(1, self.scrollable_content_region.height - 1)
        top = int(self.scroll_y)
        if top <= row < top + height:
            pass
        elif center:
            top = max(0, row - height // 2)
        elif row < top:
            top = row
        else:
            top = row - height + 1
        self._syncing = True
        try:
            self.scroll_to(y=top, animate=False, immediate=True, force=True)
        finally:
            self._syncing = False
        self._top_seq = self.store.view_seq(top)
        self.refresh()

    def action_cursor(self, step: int) -> None:
        n = self._rows
        if not n:
            return
        row = self.cursor_row
        row = n - 1 if row is None else max(0, min(n - 1, row + step))
        self.follow = row == n - 1 and self.follow and step > 0
        self._move_cursor(self.store.view_seq(row))
        self._scroll_to_row(row)

    def action_page(self, direction: int) -> None:
        self.action_cursor(direction * max(1, self.scrollable_content_region.height - 2))

    def action_first(self) -> None:
        if self._rows:
            self.follow = False
            self._move_cursor(self.store.view_seq(0))
            self._scroll_to_row(0)

    def watch_follow(self, follow: bool) -> None:
        self.post_message(self.FollowChanged(follow))
        if follow:
            self.sync()

    def watch_scroll_y(self, old_value: float, new_value: float) -> None:
        super().watch_scroll_y(old_value, new_value)
        if not self._syncing:
            self._top_seq = self.store.view_seq(int(new_value))

    def on_mouse_scroll_up(self, event: MouseScrollUp) -> None:
        # Scrolling up means the user wants to look back: stop sticking to the newest row.
        self.follow = False

    def on_click(self, event: Click) -> None:
        row = int(self.scroll_y) + event.y - 1
        if 0 <= row < self._rows:
            self.follow = False
            self._move_cursor(self.store.view_seq(row))

    # ---- rendering ------------------------------------------------------------------------------------
    def render_settings(self) -> tuple:
        width = self.size.width
        base: Style = self.rich_style
        # The mark goes at the last cell in sight: the scrollbar covers the line's last cells.
        shown = min(width, self.scrollable_content_region.width) or width
        return (width, int(self.scroll_x), int(self.scroll_y), width < COMPACT_BELOW, base,
                base + self.get_component_rich_style("timeline--cursor"), shown, self.has_focus)

    def render_line(self, y: int) -> Strip:
        look = self.settings()
        width, scroll_x, scroll_y, compact, base, cursor_style, shown, focus = look
        if y == 0:
            header = Strip([Segment(columns(self.times, compact), self.get_component_rich_style("timeline--header"))])
            return header.crop_extend(scroll_x, scroll_x + width, base)
        row = scroll_y + y - 1
        store = self.store
        seq = store.view_seq(row) if row < self._rows else None
        rec = store.get(seq) if seq is not None else None
        if rec is None:
            return Strip.blank(width, base)
        cursor = seq == self.cursor_seq
        # A row is drawn again only when what it shows changes (a finding, its reply's latency or
        # status, the cursor) or the drawing's settings do (size, horizontal scroll, focus, styles).
        key = (seq, len(rec.findings), cursor, rec.latency, rec.status, look[:2], look[3:])
        cached = self._cache.get(key)
        if cached is None:
            assert seq is not None  # a record was found under it (above)
            prev = store.get(seq - 1)
            pieces = row_pieces(rec, prev.event.t_start if prev is not None else None, compact, self.times)
            style = cursor_style if cursor else base
            segments, length = _segments(pieces, style)
            view = _marked(segments, length, scroll_x, shown, style)
            if shown < width:
                view.append(Segment(" " * (width - shown), base))
            cached = self._cache[key] = Strip(view, max(width, shown))
        return cached


_STYLES: dict[str, Style] = {}


def _segments(pieces: list[tuple[str, str]], style: Style) -> tuple[list[Segment], int]:
    """A row's pieces as segments over ``style``, as Text.render would give them (a run of unstyled pieces
    is one segment, each styled piece its own), and the row's length in cells."""
    out: list[Segment] = []
    plain = ""
    length = 0
    for text, name in pieces:
        if not text:
            continue
        length += cell_len(text)
        if not name:
            plain += text
            continue
        if plain:
            out.append(Segment(plain, style))
            plain = ""
        parsed = _STYLES.get(name)
        if parsed is None:
            parsed = _STYLES[name] = Style.parse(name)
        out.append(Segment(text, style + parsed))
    if plain:
        out.append(Segment(plain, style))
    return out, length


def _crop(segments: list[Segment], start: int, end: int) -> list[Segment]:
    """The segments' cells ``start`` to ``end`` (fewer where they end sooner)."""
    out = []
    pos = 0
    for seg in segments:
        if pos >= end:
            break
        after = pos + cell_len(seg.text)
        if after > start:
            if pos < start:
                seg = seg.split_cells(start - pos)[1]
            if after > end:
                seg = seg.split_cells(end - max(pos, start))[0]
            out.append(seg)
        pos = after
    return out


def _marked(segments: list[Segment], length: int, x: int, width: int, style: Style) -> list[Segment]:
    """Cells ``x`` to ``x + width`` of a row ``length`` cells long (blank past its end), with an ellipsis
    at an edge the row runs past: a value cut at the edge of the view (``present_position=-2`` of -24.9)
    is never shown as if it were whole. Segment by segment, one Strip made at the end: a Strip is costly
    to make (each has caches of its own)."""
    view = _crop(segments, x, x + width)
    shown = min(width, max(0, length - x))
    if shown < width:
        view.append(Segment(" " * (width - shown), style))
    if width < 2:
        return view
    if length > x + width:
        view = _crop(view, 0, width - 1) + [Segment("…", style)]
    if x > 0 and length > x:
        view = [Segment("…", style)] + _crop(view, 1, width)
    return view
