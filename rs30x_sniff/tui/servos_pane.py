"""The servos pane: one row per servo ID, drawn with Textual's Line API from a plain table of strings."""

from __future__ import annotations

from typing import Any, Callable

from rich.cells import cell_len
from rich.segment import Segment
from rich.style import Style
from rich.text import Text
from textual.binding import Binding
from textual.events import Click
from textual.geometry import Size
from textual.message import Message
from textual.scroll_view import ScrollView
from textual.strip import Strip

from .rows import clean
from .servos import SERVO_COLUMNS, ServoRow
from .store import Store

FLASH_SECONDS = 1.0  # how long a changed value stays highlighted
FLASH_STYLE = Style.parse("bold black on yellow")
PADDING = 1  # blank cells either side of a value

_SHORT = {"torque_enable": "torque", "goal_position": "goal", "present_position": "pos", "present_speed": "speed",
          "present_current": "cur", "present_temperature": "temp", "present_voltage": "volt"}
# The headings carry the units (the same in every model's map), so the cells stay narrow.
HEADINGS = {"torque": "trq", "goal": "goal°", "pos": "pos°", "speed": "°/s", "cur": "mA", "temp": "°C",
            "volt": "V", "finds": "!"}
COLUMNS = ("ID", "model", *(_SHORT[c] for c in SERVO_COLUMNS), "poll/s", "p50ms", "p95ms", "finds")


def value_text(value: Any, unit: str | None = None) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        s = f"{value:.2f}" if unit == "V" else f"{value:.1f}"
    else:
        s = str(value)
    return clean(s)


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v * 1e3:.2f}"


def servo_cells(store: Store, row: ServoRow) -> tuple[str, ...]:
    """The pane's cells for one servo, in COLUMNS order."""
    values, units = row.values, row.units
    rate = store.poll_rate(row)
    return (str(row.id), clean(row.model),
            *(value_text(values.get(name), units.get(name)) for name in SERVO_COLUMNS),
            "-" if rate is None else f"{rate:.1f}", _ms(row.latency_p50), _ms(row.latency_p95),
            str(store.findings_by_id.get(row.id, 0)))


class ServosPane(ScrollView, can_focus=True):
    """One row per servo; a value that changed shows highlighted for a moment.

    The rows are kept as strings; only the rows in sight are drawn, each from a cache keyed by what it
    shows, so a new batch redraws the rows whose values changed and nothing else (a DataTable renders
    every visible cell through Rich again after any change). It looks as the DataTable it replaced:
    the same component styles, the same padding and column widths."""

    BORDER_TITLE = "servos"
    BINDINGS = [
        Binding("up", "cursor(-1)", "Up", show=False),
        Binding("down", "cursor(1)", "Down", show=False),
        Binding("pageup", "page(-1)", "Page up", show=False),
        Binding("pagedown", "page(1)", "Page down", show=False),
        Binding("home", "first", "First", show=False),
        Binding("end", "last", "Last", show=False),
    ]
    COMPONENT_CLASSES = {"servos--header", "servos--cursor"}
    # DataTable's own look, so the pane reads as the other tables do.
    DEFAULT_CSS = """
    ServosPane {
        background: $surface;
        color: $foreground;
        &:focus {
            background-tint: $foreground 5%;
            & > .servos--cursor {
                background: $block-cursor-background;
                color: $block-cursor-foreground;
                text-style: $block-cursor-text-style;
            }
            & > .servos--header {
                background-tint: $foreground 5%;
            }
        }
        & > .servos--header {
            text-style: bold;
            background: $panel;
            color: $foreground;
        }
        &:ansi > .servos--header {
            background: ansi_bright_blue;
            color: ansi_default;
        }
        & > .servos--cursor {
            background: $block-cursor-blurred-background;
            color: $block-cursor-blurred-foreground;
            text-style: $block-cursor-blurred-text-style;
        }
    }
    """

    class Highlighted(Message):
        """The cursor moved to another servo."""

        def __init__(self, sid: int) -> None:
            super().__init__()
            self.sid = sid

    def __init__(self, clock: Callable[[], float], **kwargs) -> None:
        super().__init__(**kwargs)
        self.clock = clock
        self._ids: list[int] = []                       # the rows' servo IDs, in order
        self._cells: dict[int, tuple[str, ...]] = {}    # what each row shows
        self._changed: dict[tuple[int, int], float] = {}  # (ID, column) -> when it changed (a flash)
        self._widths = [cell_len(HEADINGS.get(c, c)) for c in COLUMNS]
        self._cursor: int | None = None                 # the ID under the cursor
        self._cache: dict[int, tuple[tuple, Strip]] = {}  # row index -> (what it showed, its strip)

    # ---- model -> view ------------------------------------------------------------------------------
    @property
    def row_count(self) -> int:
        return len(self._ids)

    @property
    def cursor_id(self) -> int | None:
        return self._cursor

    def get_cell(self, sid: int | str, column: str) -> Text:
        """The cell of servo ``sid`` in ``column`` as shown: its text, and its style while it flashes."""
        sid = int(sid)
        col = COLUMNS.index(column)
        at = self._changed.get((sid, col))
        flashing = at is not None and self.clock() - at < FLASH_SECONDS
        return Text(self._cells[sid][col], FLASH_STYLE if flashing else "")

    def reset(self) -> None:
        self._ids.clear()
        self._cells.clear()
        self._changed.clear()
        self._cursor = None
        self._widths = [cell_len(HEADINGS.get(c, c)) for c in COLUMNS]
        self._resize()

    def update_from(self, store: Store, flash: bool = True) -> None:
        """Show the store's servo rows; a changed value flashes unless ``flash`` is False (a file
        loading: every value changes every batch)."""
        now = self.clock()
        cells_of = self._cells
        changed = self._changed
        grown = False
        for sid, row in store.servos.items():
            cells = servo_cells(store, row)
            old = cells_of.get(sid)
            if old == cells:
                continue
            cells_of[sid] = cells
            if old is None:
                grown = True
            elif flash:
                for col, (a, b) in enumerate(zip(old, cells)):
                    if a != b and a != "-":
                        changed[(sid, col)] = now
        if grown:
            self._ids = sorted(cells_of)
        self._fit_widths()
        if self._cursor is None and self._ids:
            self._move(self._ids[0])
        if grown:
            self._resize()
        self.refresh()  # the cache keeps every row that did not change

    def tick(self) -> None:
        """Let flashes expire."""
        now = self.clock()
        done = [k for k, at in self._changed.items() if now - at >= FLASH_SECONDS]
        for k in done:
            del self._changed[k]
        if done:
            self.refresh()

    def _fit_widths(self) -> None:
        # As a DataTable's: each column as wide as its widest value or heading (a cell_len, values being
        # ASCII but a model name may not be).
        widths = [cell_len(HEADINGS.get(c, c)) for c in COLUMNS]
        for cells in self._cells.values():
            for i, c in enumerate(cells):
                n = len(c) if c.isascii() else cell_len(c)
                if n > widths[i]:
                    widths[i] = n
        if widths != self._widths:
            self._widths = widths
            self._resize()

    def _resize(self) -> None:
        self.virtual_size = Size(sum(self._widths) + 2 * PADDING * len(COLUMNS), len(self._ids) + 1)
        self._cache.clear()
        self.refresh()

    # ---- cursor ---------------------------------------------------------------------------------------
    def _move(self, sid: int | None) -> None:
        if sid != self._cursor:
            self._cursor = sid
            if sid is not None:
                self.post_message(self.Highlighted(sid))
            self.refresh()

    def _cursor_row(self) -> int | None:
        try:
            return self._ids.index(self._cursor) if self._cursor is not None else None
        except ValueError:
            return None

    def _go(self, row: int) -> None:
        if not self._ids:
            return
        row = max(0, min(len(self._ids) - 1, row))
        self._move(self._ids[row])
        height = max(1, self.scrollable_content_region.height - 1)  # under the heading
        top = int(self.scroll_y)
        if row < top:
            self.scroll_to(y=row, animate=False)
        elif row >= top + height:
            self.scroll_to(y=row - height + 1, animate=False)

    def action_cursor(self, step: int) -> None:
        row = self._cursor_row()
        self._go(0 if row is None else row + step)

    def action_page(self, direction: int) -> None:
        self.action_cursor(direction * max(1, self.scrollable_content_region.height - 2))

    def action_first(self) -> None:
        self._go(0)

    def action_last(self) -> None:
        self._go(len(self._ids) - 1)

    def on_click(self, event: Click) -> None:
        if event.y >= 1:
            row = int(self.scroll_y) + event.y - 1
            if row < len(self._ids):
                self._go(row)

    def on_focus(self) -> None:
        self._cache.clear()  # the cursor and the background look different with the focus

    def on_blur(self) -> None:
        self._cache.clear()

    # ---- rendering ------------------------------------------------------------------------------------
    def render_line(self, y: int) -> Strip:
        width = self.size.width
        scroll_x = int(self.scroll_x)
        base = self.rich_style
        if y == 0:
            row, sid = -1, None
        else:
            row = int(self.scroll_y) + y - 1
            if row >= len(self._ids):
                return Strip.blank(width, base)
            sid = self._ids[row]
        cursor = sid is not None and sid == self._cursor
        flashes = () if sid is None else tuple(
            col for col in range(len(COLUMNS)) if (sid, col) in self._changed)
        cells = None if sid is None else self._cells[sid]
        key = (sid, cells, cursor, flashes, base, width, scroll_x, tuple(self._widths))
        slot = y if y == 0 else row + 1
        cached = self._cache.get(slot)
        if cached is not None and cached[0] == key:
            return cached[1]
        strip = self._draw(row, cells, cursor, flashes, base).crop_extend(scroll_x, scroll_x + width, base)
        strip = strip.simplify()
        self._cache[slot] = (key, strip)
        return strip

    def _draw(self, row: int, cells: tuple[str, ...] | None, cursor: bool, flashes: tuple[int, ...],
              base: Style) -> Strip:
        """A whole row (or the heading, ``row`` -1), segment by segment as a DataTable draws it: each
        cell padded, its style carrying the cell's place (the table's meta), the rest of the line in the
        row's style."""
        if cells is None:
            row_style = self.get_component_styles("servos--header").rich_style
            texts = [HEADINGS.get(c, c) for c in COLUMNS]
        else:
            row_style = base
            texts = list(cells)
        component = self.get_component_rich_style("servos--cursor") if cursor else Style()
        post = Style.from_color(color=component.color)  # the cursor's colour wins, as in a DataTable
        pad = " " * PADDING
        segments: list[Segment] = []
        for col, (text, w) in enumerate(zip(texts, self._widths)):
            pre = row_style + Style.from_meta({"row": row, "column": col}) + component
            outer = pre + post
            fill = " " * (w - cell_len(text))
            if col in flashes:
                segments += [Segment(pad, outer), Segment(text, pre + FLASH_STYLE + post),
                             Segment(fill + pad, outer)]
            else:
                segments.append(Segment(pad + text + fill + pad, outer))
        extend = row_style + component + Style.from_meta({"row": row, "column": 0, "out_of_bounds": True})
        table = sum(self._widths) + 2 * PADDING * len(COLUMNS)
        rest = max(0, self.size.width - table)
        segments.append(Segment(" " * rest, extend))
        return Strip(segments, table + rest)
