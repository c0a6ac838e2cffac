"""The Line-API table under the servos and findings panes: rows drawn once until they change, a cursor kept by key."""

from __future__ import annotations

from textual.app import App, ComposeResult

from rs30x_sniff.tui.line_table import LineTable


class TableApp(App):
    def __init__(self) -> None:
        super().__init__()
        self.highlighted: list = []
        self.chosen: list = []

    def compose(self) -> ComposeResult:
        yield LineTable(("ID", "value"), id="t")

    def on_line_table_highlighted(self, event: LineTable.Highlighted) -> None:
        self.highlighted.append(event.key)

    def on_line_table_chosen(self, event: LineTable.Chosen) -> None:
        self.chosen.append(event.key)


def text(strip) -> str:
    return "".join(seg.text for seg in strip)


async def test_an_unchanged_row_is_not_drawn_again_and_a_changed_one_is():
    app = TableApp()
    async with app.run_test(size=(40, 10)) as pilot:
        table = app.query_one(LineTable)
        table.set_rows([(1, ("1", "10.0"), None), (2, ("2", "20.0"), None)])
        await pilot.pause()
        first, second = table.render_line(1), table.render_line(2)
        assert text(first).startswith(" 1  ") and "20.0" in text(second)
        table.set_rows([(1, ("1", "10.0"), None), (2, ("2", "25.0"), None)])
        assert table.render_line(1) is first  # the same drawn line, from the cache
        assert table.render_line(2) is not second and "25.0" in text(table.render_line(2))


async def test_the_cursor_stays_on_its_row_when_rows_come_before_it():
    app = TableApp()
    async with app.run_test(size=(40, 10)) as pilot:
        table = app.query_one(LineTable)
        table.set_rows([(5, ("5", "a"), None), (6, ("6", "b"), None)])
        await pilot.pause()
        assert table.cursor_key == 5 and app.highlighted == [5]
        table.focus()
        await pilot.press("down")
        assert table.cursor_key == 6
        table.set_rows([(4, ("4", "c"), None), (5, ("5", "a"), None), (6, ("6", "b"), None)])
        assert table.cursor_key == 6  # still on its row, now the third
        await pilot.press("enter")
        await pilot.pause()
        assert app.chosen == [6] and app.highlighted == [5, 6]


async def test_a_multi_line_cell_makes_its_row_taller_and_the_columns_fit_the_widest_line():
    app = TableApp()
    async with app.run_test(size=(40, 10)) as pilot:
        table = app.query_one(LineTable)
        table.set_rows([(1, ("1", "short\na longer line"), None), (2, ("2", "x"), None)])
        await pilot.pause()
        lines = [text(table.render_line(y)).rstrip() for y in range(4)]
        assert lines == [" ID  value", " 1   short", "     a longer line", " 2   x"]
        assert table.virtual_size.height == 4
