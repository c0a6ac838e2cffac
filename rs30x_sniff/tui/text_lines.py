"""A widget that shows lines of Rich Text with the Line API, each line rendered once when it is set."""

from __future__ import annotations

from collections.abc import Iterable

from rich.text import Text
from textual.strip import Strip
from textual.widget import Widget


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
        console = self.app.console
        self._strips = [Strip(list(line.render(console)), line.cell_len) for line in lines]
        self.refresh()

    def render_line(self, y: int) -> Strip:
        width = self.size.width
        base = self.rich_style
        if y >= len(self._strips):
            return Strip.blank(width, base)
        return self._strips[y].crop_extend(0, width, base).apply_style(base)
