"""What a redraw costs on a live port: nothing is drawn again that would look the same (bench/live.py's monitor row)."""

from __future__ import annotations

from rich.text import Text
from textual.app import App, ComposeResult

from rs30x_sniff.tui.app import batch_overdue
from rs30x_sniff.tui.text_lines import TextLines


def test_a_tick_leaves_the_redraw_to_a_batch_that_is_due():
    # Batches a second apart, ticks every half second: the tick half a second after a batch, and the one
    # just before the next batch, wait for it; once a batch is a tick late (the line went quiet), ticks draw.
    assert batch_overdue(10.0, None, 1.0, 0.5)  # no batch yet: the header's clock runs on ticks
    assert not batch_overdue(10.5, 10.0, 1.0, 0.5)
    assert not batch_overdue(10.99, 10.0, 1.0, 0.5)
    assert not batch_overdue(11.4, 10.0, 1.0, 0.5)
    assert batch_overdue(11.5, 10.0, 1.0, 0.5)
    assert batch_overdue(30.0, 10.0, 1.0, 0.5)


class _Lines(App):
    def compose(self) -> ComposeResult:
        yield TextLines()


async def test_lines_equal_to_those_shown_are_not_drawn_again():
    app = _Lines()
    async with app.run_test(size=(40, 5)) as pilot:
        widget = app.query_one(TextLines)
        refreshes = []
        plain = widget.refresh

        def counted(*args, **kwargs):
            refreshes.append(1)
            return plain(*args, **kwargs)

        widget.refresh = counted  # type: ignore[method-assign]
        widget.set_lines([Text("live 12.0 s"), Text.assemble(("3 findings", "red"))])
        assert len(refreshes) == 1
        widget.set_lines([Text("live 12.0 s"), Text.assemble(("3 findings", "red"))])
        assert len(refreshes) == 1  # the same: no redraw
        widget.set_lines([Text("live 12.0 s"), Text.assemble(("3 findings", "yellow"))])
        assert len(refreshes) == 2  # a span's style changed
        widget.set_lines([Text("live 12.0 s", style="bold"), Text.assemble(("3 findings", "yellow"))])
        assert len(refreshes) == 3  # the line's own style changed (Text's == does not see it)
        widget.set_lines([Text("live 13.0 s", style="bold"), Text.assemble(("3 findings", "yellow"))])
        assert len(refreshes) == 4
        await pilot.pause()
        assert "live 13.0 s" in "".join(s.text for s in widget.render_line(0))
