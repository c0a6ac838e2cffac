"""The servos pane: one row per servo ID, its values, poll rate, latency and findings; a changed value flashes."""

from __future__ import annotations

from typing import Any, cast
from collections.abc import Callable, Hashable

from rich.style import Style
from rich.text import Text

from .line_table import LineTable
from .rows import clean
from .servos import SERVO_COLUMNS, ServoRow
from .store import Store

FLASH_SECONDS = 1.0  # how long a changed value stays highlighted
# A flash may end this much early: one lit by a port's batch then ends with the next batch, a second later, rather
# than costing a redraw of its own a tick after it (a live screen's redraws are most of its CPU).
FLASH_EARLY = 0.25
FLASH_STYLE = Style.parse("bold black on yellow")

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


class ServosPane(LineTable):
    """One row per servo; a value that changed shows highlighted for a moment. A batch redraws the rows
    whose values changed, nothing else (line_table)."""

    BORDER_TITLE = "servos"

    def __init__(self, clock: Callable[[], float], **kwargs) -> None:
        super().__init__([HEADINGS.get(c, c) for c in COLUMNS], **kwargs)
        self.clock = clock
        self._shown: dict[int, tuple[str, ...]] = {}      # what each servo's row shows
        self._changed: dict[tuple[int, int], float] = {}  # (ID, column) -> when it changed (a flash)

    @property
    def cursor_id(self) -> int | None:
        return cast("int | None", self.cursor_key)  # this table's rows are keyed by servo ID

    def get_cell(self, sid: int | str, column: str) -> Text:
        """The cell of servo ``sid`` in ``column`` as shown: its text, and its style while it flashes."""
        sid = int(sid)
        col = COLUMNS.index(column)
        return Text(self._shown[sid][col], self.cell_style(sid, col) or "")

    def cell_style(self, key: Hashable, col: int) -> Style | None:  # key: a servo ID
        return FLASH_STYLE if (key, col) in self._changed else None

    def reset(self) -> None:
        self._shown.clear()
        self._changed.clear()
        self.set_rows([])

    def update_from(self, store: Store, flash: bool = True) -> None:
        """Show the store's servo rows; a changed value flashes unless ``flash`` is False (a file
        loading: every value changes every batch)."""
        now = self.clock()
        shown = self._shown
        changed = self._changed
        for sid, row in store.servos.items():
            cells = servo_cells(store, row)
            old = shown.get(sid)
            if old == cells:
                continue
            shown[sid] = cells
            if flash and old is not None:
                for col, (a, b) in enumerate(zip(old, cells)):
                    if a != b and a != "-":
                        changed[(sid, col)] = now
        self.set_rows([(sid, shown[sid], None) for sid in sorted(shown)])

    def tick(self) -> None:
        """Let flashes expire."""
        now = self.clock()
        done = [k for k, at in self._changed.items() if now - at >= FLASH_SECONDS - FLASH_EARLY]
        for k in done:
            del self._changed[k]
        if done:
            self.refresh()
