"""A table drawn with Textual's Line API: rows of plain strings, only the lines in sight drawn, each from a cache.

It looks as Textual's DataTable (the same component styles, padding, widths, and a row cursor) but costs a
redraw of the rows that changed, not of every visible cell through Rich after any change: the monitor's
small panes take new values several times a second.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Hashable, Sequence

from rich.cells import cell_len
from rich.segment import Segment
from rich.style import Style
from textual.binding import Binding
from textual.events import Click
from textual.geometry import Region, Size
from textual.message import Message
from textual.scroll_view import ScrollView
from textual.strip import Strip

PADDING = 1  # blank cells either side of a value, as a DataTable's
_CACHE_LINES = 4096  # drawn lines kept; past this the cache starts afresh


def _width(text: str) -> int:
    return len(text) if text.isascii() else cell_len(text)


# The keys that move a cursor over rows, here and in the timeline (each says what its end key does).
CURSOR_BINDINGS = (
    Binding("up", "cursor(-1)", "Up", show=False),
    Binding("down", "cursor(1)", "Down", show=False),
    Binding("pageup", "page(-1)", "Page up", show=False),
    Binding("pagedown", "page(1)", "Page down", show=False),
    Binding("home", "first", "First", show=False),
)


class _RowMessage(Message):
    """A message about the row ``key`` of ``table``."""

    def __init__(self, table: LineTable, key: Hashable) -> None:
        super().__init__()
        self.table, self.key = table, key

    @property
    def control(self) -> LineTable:
        return self.table


class SettingsPerRender:
    """A Line-API widget's settings that every line of one render shares (sizes, scroll, styles), worked out once
    per render, as a widget's rich_style walks its ancestors' styles on every call: ``render_settings()`` makes
    them, ``settings()`` gives them to each line."""

    _shared: tuple | None = None

    def render_lines(self, crop: Region) -> list[Strip]:
        self._shared = self.render_settings()
        try:
            return super().render_lines(crop)  # type: ignore[misc]
        finally:
            self._shared = None

    def settings(self) -> tuple:
        return self._shared or self.render_settings()

    def render_settings(self) -> tuple:
        raise NotImplementedError


class LineTable(SettingsPerRender, ScrollView, can_focus=True):
    """Rows of cells (strings; a cell may hold several lines, its row is as tall as its tallest cell) under a
    heading row that stays in place. The cursor is a row's key, so it stays on its row when rows come and
    go; ``Highlighted`` says it moved, ``Chosen`` that enter was pressed on it."""

    BINDINGS = [
        *CURSOR_BINDINGS,
        Binding("end", "last", "Last", show=False),
        Binding("enter", "choose", "Go", show=False),
    ]
    COMPONENT_CLASSES = {"table--header", "table--cursor"}
    # DataTable's own look, so these panes read as the other tables do.
    DEFAULT_CSS = """
    LineTable {
        background: $surface;
        color: $foreground;
        &:focus {
            background-tint: $foreground 5%;
            & > .table--cursor {
                background: $block-cursor-background;
                color: $block-cursor-foreground;
                text-style: $block-cursor-text-style;
            }
            & > .table--header {
                background-tint: $foreground 5%;
            }
        }
        & > .table--header {
            text-style: bold;
            background: $panel;
            color: $foreground;
        }
        &:ansi > .table--header {
            background: ansi_bright_blue;
            color: ansi_default;
        }
        & > .table--cursor {
            background: $block-cursor-blurred-background;
            color: $block-cursor-blurred-foreground;
            text-style: $block-cursor-blurred-text-style;
        }
    }
    """

    class Highlighted(_RowMessage):
        """The cursor moved to the row ``key``."""

    class Chosen(_RowMessage):
        """Enter was pressed on the row ``key`` (or the cursor's row was clicked)."""

    def __init__(self, headings: Sequence[str], **kwargs) -> None:
        super().__init__(**kwargs)
        self.headings = tuple(headings)
        self._keys: list[Hashable] = []
        self._cells: dict[Hashable, tuple[tuple[str, ...], ...]] = {}  # key -> each cell's lines
        self._styles: dict[Hashable, tuple[Style | None, ...]] = {}     # key -> each cell's own style
        self._tops: list[int] = [0]           # each row's first line under the heading; then the total
        self._widths = [_width(h) for h in self.headings]
        self._cursor: Hashable | None = None
        self._cache: dict[tuple, Strip] = {}

    # ---- rows -----------------------------------------------------------------------------------------
    @property
    def row_count(self) -> int:
        return len(self._keys)

    @property
    def cursor_key(self) -> Hashable | None:
        return self._cursor

    def set_rows(self, rows: Sequence[tuple[Hashable, Sequence[str], Sequence[Style | None] | None]]) -> None:
        """Show ``rows`` (key, cells, each cell's style or None), in this order. Rows already shown keep
        their drawn lines if their cells did not change; the cursor stays on its row if it is still here,
        else goes to the first."""
        cells_of, styles_of = {}, {}
        keys = []
        for key, cells, styles in rows:
            keys.append(key)
            cells_of[key] = tuple(tuple(c.split("\n")) if "\n" in c else (c,) for c in cells)
            styles_of[key] = tuple(styles) if styles is not None else (None,) * len(cells)
        shape_changed = keys != self._keys or any(
            len(cells_of[k]) != len(self._cells.get(k, ())) or
            max(map(len, cells_of[k])) != max(map(len, self._cells[k])) for k in keys)
        self._keys, self._cells, self._styles = keys, cells_of, styles_of
        if shape_changed:
            tops = [0]
            for k in keys:
                tops.append(tops[-1] + max(map(len, cells_of[k]), default=1))
            self._tops = tops
        self._fit(shape_changed)
        if self._cursor not in cells_of:
            self._cursor = None
            if keys:
                self._move(keys[0])
        self.refresh()

    def _fit(self, resize: bool) -> None:
        widths = [_width(h) for h in self.headings]
        for cells in self._cells.values():
            for i, lines in enumerate(cells):
                for line in lines:
                    n = _width(line)
                    if n > widths[i]:
                        widths[i] = n
        if resize or widths != self._widths:
            self._widths = widths
            self.virtual_size = Size(self._table_width(), self._tops[-1] + 1)

    def _table_width(self) -> int:
        return sum(self._widths) + 2 * PADDING * len(self._widths)

    def cell_style(self, key: Hashable, col: int) -> Style | None:
        """The style of a cell's text (None: the row's); the panes add their own (a value's flash)."""
        return self._styles[key][col]

    # ---- cursor ---------------------------------------------------------------------------------------
    def _move(self, key: Hashable | None) -> None:
        if key != self._cursor:
            self._cursor = key
            if key is not None:
                self.post_message(self.Highlighted(self, key))
            self.refresh()

    def _row_of(self, key: Hashable | None) -> int | None:
        try:
            return self._keys.index(key) if key is not None else None
        except ValueError:
            return None

    def _go(self, row: int) -> None:
        if not self._keys:
            return
        row = max(0, min(len(self._keys) - 1, row))
        self._move(self._keys[row])
        top, bottom = self._tops[row], self._tops[row + 1]
        height = max(1, self.scrollable_content_region.height - 1)  # under the heading
        y = int(self.scroll_y)
        if top < y:
            self.scroll_to(y=top, animate=False)
        elif bottom > y + height:
            self.scroll_to(y=min(top, bottom - height), animate=False)

    def action_cursor(self, step: int) -> None:
        row = self._row_of(self._cursor)
        self._go(0 if row is None else row + step)

    def action_page(self, direction: int) -> None:
        row = self._row_of(self._cursor) or 0
        lines = max(1, self.scrollable_content_region.height - 2)
        target = bisect_right(self._tops, self._tops[row] + direction * lines) - 1
        self._go(target if target != row else row + direction)

    def action_first(self) -> None:
        self._go(0)

    def action_last(self) -> None:
        self._go(len(self._keys) - 1)

    def action_choose(self) -> None:
        if self._cursor is not None:
            self.post_message(self.Chosen(self, self._cursor))

    def on_click(self, event: Click) -> None:
        if event.y < 1:
            return
        line = int(self.scroll_y) + event.y - 1
        row = bisect_right(self._tops, line) - 1
        if 0 <= row < len(self._keys):
            chosen = self._keys[row] == self._cursor  # a click on the cursor's row chooses it, as in a DataTable
            self._go(row)
            if chosen:
                self.action_choose()

    def on_focus(self) -> None:
        self.refresh()  # the cursor and the background look different with the focus (the frame says so)

    def on_blur(self) -> None:
        self.refresh()

    # ---- rendering ------------------------------------------------------------------------------------
    def render_settings(self) -> tuple:
        base = self.rich_style
        return (self.size.width, int(self.scroll_x), base, self.get_component_rich_style("table--cursor"),
                self.get_component_styles("table--header").rich_style, tuple(self._widths))

    def render_line(self, y: int) -> Strip:
        frame = self.settings()
        width, scroll_x, base = frame[:3]
        if y == 0:
            line, key = 0, None
        else:
            ly = int(self.scroll_y) + y - 1
            if ly >= self._tops[-1]:
                return Strip.blank(width, base)
            row = bisect_right(self._tops, ly) - 1
            line = ly - self._tops[row]
            key = self._keys[row]
        cursor = key is not None and key == self._cursor
        styles = () if key is None else tuple(self.cell_style(key, c) for c in range(len(self.headings)))
        cells = None if key is None else self._cells[key]
        ck = (line, key, cells, styles, cursor, frame)  # not the row's place: rows move as others come
        strip = self._cache.get(ck)
        if strip is None:
            if len(self._cache) > _CACHE_LINES:
                self._cache.clear()
            strip = self._draw(line, cells, styles, cursor, frame)
            self._cache[ck] = strip
        return strip

    def _draw(self, line: int, cells: tuple | None, styles: tuple, cursor: bool, frame: tuple) -> Strip:
        """One line ``line`` of a row (``cells`` None: the heading), segment by segment as a DataTable draws it: each
        cell padded, its style carrying its column (as the table's meta does), the rest of the line in the
        row's style, the cursor's colour over a cell's own."""
        width, scroll_x, base, cursor_style, header_style, widths = frame
        texts: Sequence[str]
        if cells is None:
            row_style = header_style
            texts = self.headings
        else:
            row_style = base
            texts = [lines[line] if line < len(lines) else "" for lines in cells]
        component = cursor_style if cursor else Style()
        post = Style.from_color(color=component.color)
        pad = " " * PADDING
        segments: list[Segment] = []
        for col, (text, w) in enumerate(zip(texts, widths)):
            pre = row_style + Style.from_meta({"column": col}) + component
            outer = pre + post
            fill = " " * (w - _width(text))
            own = styles[col] if styles else None
            if own is not None and text:
                segments += [Segment(pad, outer), Segment(text, pre + own + post), Segment(fill + pad, outer)]
            else:
                segments.append(Segment(pad + text + fill + pad, outer))
        extend = row_style + component + Style.from_meta({"column": 0, "out_of_bounds": True})
        table = sum(widths) + 2 * PADDING * len(widths)
        rest = max(0, width - table)
        segments.append(Segment(" " * rest, extend))
        return Strip(segments, table + rest).crop_extend(scroll_x, scroll_x + width, base).simplify()
