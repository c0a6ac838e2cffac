"""The monitor's register plot as text, with no Textual in it: a time axis, and each column's min and max."""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Sequence

from rich.text import Text

# One colour per servo plotted together (the first is the selected servo's).
COLOURS = ("green", "cyan", "magenta", "yellow", "dodger_blue1", "red", "white", "orange1")


@dataclass
class Window:
    """The time span shown: the whole series (``span`` None), or ``span`` seconds ending ``back`` seconds
    before the newest sample (0: following the newest)."""

    span: float | None = None
    back: float = 0.0

    def bounds(self, first: float, last: float) -> tuple[float, float]:
        if self.span is None:
            return first, last
        end = max(first, last - self.back)
        return max(first, end - self.span), end

    def zoom(self, factor: float, first: float, last: float) -> None:
        """Narrow (factor < 1) or widen the window around its end; wider than the data: the whole series."""
        t0, t1 = self.bounds(first, last)
        span = (t1 - t0) * factor
        self.span = None if span >= last - first else max(span, 1e-3)

    def pan(self, fraction: float, first: float, last: float) -> None:
        """Move the window by ``fraction`` of its span (negative: back in time)."""
        if self.span is None:
            return
        self.back = min(max(0.0, self.back - fraction * self.span), max(0.0, last - first - self.span))


def columns(times: Sequence[float], values: Sequence[float], t0: float, t1: float,
            width: int) -> list[tuple[float, float] | None]:
    """The (min, max) of the samples falling in each of ``width`` columns of [t0, t1] (None: no sample)."""
    out: list[list[float] | None] = [None] * width
    if width <= 0:
        return []
    scale = width / (t1 - t0) if t1 > t0 else 0.0  # every column spans the same time
    last = width - 1
    for t, v in zip(times, values):
        if t < t0 or t > t1:
            continue
        k = min(last, int((t - t0) * scale))
        cell = out[k]
        if cell is None:
            out[k] = [v, v]
        elif v < cell[0]:
            cell[0] = v
        elif v > cell[1]:
            cell[1] = v
    return [None if c is None else (c[0], c[1]) for c in out]


def render(series: Sequence[tuple[Sequence[float], Sequence[float]]], width: int, height: int,
           t0: float, t1: float) -> tuple[list[Text], float | None, float | None]:
    """Rows of text drawing each series' min-max envelope over [t0, t1]; also the value range shown.

    Each column spans (t1 - t0) / width seconds, so a long capture stays readable (a bar from the
    column's lowest to its highest value) instead of a squeezed sparkline. Later series draw over
    earlier ones; the first (the selected servo) is drawn last, on top.
    """
    cols = [columns(ts, vs, t0, t1, width) for ts, vs in series]
    lows = [c[0] for col in cols for c in col if c is not None]
    highs = [c[1] for col in cols for c in col if c is not None]
    if not lows or height <= 0:
        return [Text(" " * width) for _ in range(max(height, 0))], None, None
    vmin, vmax = min(lows), max(highs)
    span = vmax - vmin or 1.0
    grid: list[list[tuple[str, str]]] = [[(" ", "")] * width for _ in range(height)]
    for n in reversed(range(len(cols))):
        colour = COLOURS[n % len(COLOURS)]
        for x, c in enumerate(cols[n]):
            if c is None:
                continue
            top = int(round((vmax - c[1]) / span * (height - 1)))
            bottom = int(round((vmax - c[0]) / span * (height - 1)))
            for y in range(top, bottom + 1):
                grid[y][x] = ("█" if bottom > top else "▬", colour)
    lines = []
    for row in grid:
        # A run of like cells is one piece of text (a Text.append per cell was most of a redraw's cost).
        text = Text()
        run_ch, run_style, n = row[0][0], row[0][1], 0
        for ch, style in row:
            if ch == run_ch and style == run_style:
                n += 1
                continue
            text.append(run_ch * n, run_style)
            run_ch, run_style, n = ch, style, 1
        text.append(run_ch * n, run_style)
        lines.append(text)
    return lines, vmin, vmax
