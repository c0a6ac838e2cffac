"""Widgets that show lines of Rich Text with the Line API, each line rendered once when it is set."""

from __future__ import annotations

from collections.abc import Iterable

from rich.text import Text
from textual.geometry import Size
from textual.scroll_view import ScrollView
from textual.strip import Strip
from textual.widget import Widget


def steady_size(view: ScrollView, width: int, height: int) -> None:
    """Give ``view`` the virtual size of content ``width`` x ``height`` cells, changed only where a scrollbar
    must come or go: any change of a virtual size lays out the whole screen, and the monitor's detail pane
    takes a record of another size several times a second."""
    fits = view.size.width - view.styles.scrollbar_size_vertical  # content that fits needs no wider a size
    size = Size(max(width, fits), max(height, view.size.height))
    if size != view.virtual_size:
        view.virtual_size = size


def _strips(widget: Widget, lines: list[Text]) -> list[Strip]:
    console = widget.app.console
    return [Strip(list(line.render(console)), line.cell_len) for line in lines]


class TextLines(Widget):
    """Lines of Text drawn with the Line API: each rendered to a Strip once, when set (a Static would take the
    Text through its content pipeline again at every redraw)."""

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self._strips: list[Strip] = []
        self._shown: list[tuple] = []  # what each line shows: its text, its style and its spans' styles

    def set_lines(self, lines: Iterable[Text]) -> None:
        """Render ``lines`` and draw them; lines equal to those shown cost no redraw (the header is told every
        tick, and a live screen's redraws are most of its CPU)."""
        lines = list(lines)
        # Text's own == leaves out the line's base style: the key holds it.
        shown = [(line.plain, line.style, line.spans) for line in lines]
        if shown == self._shown:
            return
        self._shown = shown
        self._strips = _strips(self, lines)
        self.refresh()

    def render_line(self, y: int) -> Strip:
        width = self.size.width
        base = self.rich_style
        if y >= len(self._strips):
            return Strip.blank(width, base)
        return self._strips[y].crop_extend(0, width, base).apply_style(base)


class ScrollingText(ScrollView):
    """A Text of several lines that scrolls, drawn with the Line API; a Text of another height costs the screen
    no new layout while it fits (``steady_size``)."""

    def __init__(self, text: Text | None = None, **kwargs) -> None:
        super().__init__(**kwargs)
        self.text = text if text is not None else Text("")
        self._strips: list[Strip] = []
        self._width = 0

    def on_mount(self) -> None:
        self.update(self.text)

    def update(self, text: Text) -> None:
        self.text = text
        lines = text.split("\n", allow_blank=True)
        self._strips = _strips(self, list(lines))
        self._width = max((line.cell_len for line in lines), default=0)
        steady_size(self, self._width, len(self._strips))
        self.refresh()

    def on_resize(self) -> None:
        steady_size(self, self._width, len(self._strips))

    def render_line(self, y: int) -> Strip:
        width = self.size.width
        base = self.rich_style
        scroll_x, scroll_y = self.scroll_offset
        y += scroll_y
        if y >= len(self._strips):
            return Strip.blank(width, base)
        return self._strips[y].crop_extend(scroll_x, scroll_x + width, base).apply_style(base)
