"""Two of the small panes under the timeline: findings (newest first) and a register plot (servos_pane: the servos)."""

from __future__ import annotations

import textwrap
from itertools import islice
from typing import Any, cast

from rich.cells import cell_len
from rich.style import Style
from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.message import Message
from textual.widgets import Label

from .line_table import LineTable
from .rows import SEVERITY_MARKS, SEVERITY_STYLES, clean
from .plot import COLOURS, Window, render
from .store import Store
from .text_lines import TextLines

FINDINGS_SHOWN = 1000  # the pane lists the newest ones; the header counts them all
_SEVERITY_STYLES = {name: Style.parse(style) for name, style in SEVERITY_STYLES.items()}


class FindingsPane(LineTable):
    """Lint findings, newest first; enter asks the app to show the packet (``JumpTo``). New findings are
    put on top; the rows already shown keep their drawn lines (line_table), their wrapped messages too."""

    BORDER_TITLE = "findings"

    class JumpTo(Message):
        def __init__(self, finding: Any) -> None:
            super().__init__()
            self.finding = finding

    def __init__(self, **kwargs) -> None:
        super().__init__(("sev", "code", "ID", "message"), **kwargs)
        self._total = -1
        self._shown: dict[int, Any] = {}                  # row key (the finding's ordinal) -> finding
        self._wrapped: dict[int, tuple[Any, str]] = {}    # ordinal -> (finding, its message as wrapped)
        self._width = 0

    def on_resize(self) -> None:
        if self.size.width != self._width:
            self._width = self.size.width
            self._wrapped.clear()
            self._fill()

    def update_from(self, store: Store) -> None:
        if store.findings_total == self._total:
            return
        self._total = store.findings_total
        newest = store.findings_total
        self._shown = {newest - i: f for i, f in enumerate(islice(reversed(store.findings), FINDINGS_SHOWN))}
        self._fill()
        self.border_title = f"findings ({store.findings_total})"

    def _fill(self) -> None:
        # Messages wrap to the pane's width (a row grows to their lines) rather than being cut off.
        width = max(20, self.size.width - 22)  # sev, code, ID, the cell padding and a scrollbar
        wrapped = {}
        rows = []
        for key, f in self._shown.items():
            done = self._wrapped.get(key)
            if done is None or done[0] is not f:
                done = (f, "\n".join(textwrap.wrap(clean(f"{f.name}: {f.message}"), width)) or "-")
            wrapped[key] = done
            style = _SEVERITY_STYLES.get(f.severity)
            rows.append((key, (SEVERITY_MARKS.get(f.severity, "?"), f.code, "-" if f.id is None else str(f.id),
                               done[1]), (style, style, None, None)))
        self._wrapped = wrapped
        self.set_rows(rows)

    def on_line_table_chosen(self, event: LineTable.Chosen) -> None:
        event.stop()
        f = self._shown.get(cast(int, event.key))  # this table's rows are keyed by finding ordinal (_shown)
        if f is not None:
            self.post_message(self.JumpTo(f))


def range_label(t0: float, t1: float, shown: str, vmin: float | None, vmax: float | None, width: int) -> str:
    """The plot's time span and value range in ``width`` cells: the longest form that fits, down to
    the value range alone, then an ellipsis (a number is never cut without a mark)."""
    values = "" if vmin is None else f"{vmin:g}..{vmax:g}"
    forms = [f"{t0:.2f}-{t1:.2f} s ({shown})", f"{t0:.2f}-{t1:.2f} s", f"{t0:.3g}-{t1:.3g} s", ""]
    for times in forms:
        text = f"{times}  {values}" if times and values else times or values
        if cell_len(text) <= width:
            return text
    return values[:max(width - 1, 0)] + "…"


class PlotLines(TextLines):
    """The plot's rows, drawn with the Line API (TextLines)."""

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.rows: list[Text] = []

    def show(self, rows: list[Text]) -> None:
        self.rows = rows
        self.set_lines(rows)

    def render(self) -> Text:
        return Text("\n").join(self.rows)


class PlotPane(Vertical):
    """One register over time: the selected servo (and with `a` every servo), each column's min to max;
    `z`/`Z` zoom the time axis in and out, `[`/`]` pan, `0` shows it all again (following the newest)."""

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self.window = Window()
        self._shown: dict[str, tuple] = {}  # selector -> what its label shows
        self._store: Store | None = None    # drawn again at its new size when the pane is resized

    def compose(self) -> ComposeResult:
        yield Label(Text("plot: no servo yet"), id="plot-title")
        yield PlotLines(id="plot-line")
        yield Label(Text(""), id="plot-range")

    def bounds(self, store: Store) -> tuple[float, float] | None:
        times = [t for ts, _ in store.plot_series.values() if ts for t in (ts[0], ts[-1])]
        return (min(times), max(times)) if times else None

    def zoom(self, store: Store, factor: float) -> None:
        b = self.bounds(store)
        if b is not None:
            self.window.zoom(factor, *b)

    def pan(self, store: Store, fraction: float) -> None:
        b = self.bounds(store)
        if b is not None:
            self.window.pan(fraction, *b)

    def reset(self) -> None:
        self.window = Window()

    def on_resize(self) -> None:
        # A pane hidden at first (a narrow terminal shows one bottom pane at a time) has no size when
        # the data comes; it is drawn when it gets one, not at the next key that asks for a redraw.
        if self._store is not None:
            self.update_from(self._store)

    def update_from(self, store: Store) -> None:
        self._store = store
        title = Text("plot: ")
        if store.plot_id is None:
            title.append("no servo yet")
        else:
            ids = list(store.plot_series)
            for n, sid in enumerate(ids):
                title.append(f"{'' if n == 0 else ' '}{sid}", COLOURS[n % len(COLOURS)] + (" bold" if n == 0 else ""))
            title.append(" " + store.plot_register, "cyan")
        self._label("#plot-title", title)
        line = self.query_one("#plot-line", PlotLines)
        b = self.bounds(store)
        if b is None:
            line.show([])
            self._label("#plot-range", Text("no samples", "grey70"))
            return
        width, height = line.size.width, line.size.height
        if width <= 0 or height <= 0:
            return  # not laid out (hidden): drawn at its first resize
        t0, t1 = self.window.bounds(*b)
        rows, vmin, vmax = render(list(store.plot_series.values()), width, height, t0, t1)
        line.show(rows)
        shown = "all" if self.window.span is None else f"{t1 - t0:.3g} s"
        self._label("#plot-range", Text(range_label(t0, t1, shown, vmin, vmax, width), "grey70"))

    def _label(self, selector: str, text: Text) -> None:
        # A label's new text may wrap to another number of lines (a layout of the whole screen): only
        # a changed one is updated.
        # A label's new text of the same width on one line takes no layout either (its size is the same).
        key = (text.plain, str(text.style), tuple(text.spans))
        old = self._shown.get(selector)
        if old != key:
            self._shown[selector] = key
            same_size = old is not None and "\n" not in old[0] + key[0] and cell_len(old[0]) == cell_len(key[0])
            self.query_one(selector, Label).update(text, layout=not same_size)
