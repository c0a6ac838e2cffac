"""The detail pane's field tree (Line API): keys, links, a tree of the same shape kept open, and no layout for a
record of another size that fits (the monitor shows a busy bus's newest record several times a second)."""

from __future__ import annotations

from rich.text import Text
from textual.app import App, ComposeResult

from rs30x_sniff.tui.field_tree import FieldTree, Node
from rs30x_sniff.tui.text_lines import ScrollingText


def record(title: str, fields: int, link: object = "request") -> Node:
    kids = [Node(Text(f"field {i}"), (i, i + 1), [Node(Text(f"about field {i}"))]) for i in range(fields)]
    return Node(Text(title), None, [Node(Text("header"), (0, 5), [Node(Text("id"), (2, 3))]),
                                    Node(Text(f"fields ({fields})"), None, kids, expand=True),
                                    Node(Text("-> request"), link)], expand=True)


class _Tree(App):
    def __init__(self) -> None:
        super().__init__()
        self.chosen: list = []
        self.lit: list = []

    def compose(self) -> ComposeResult:
        yield FieldTree(Node(Text("nothing")))
        yield ScrollingText(Text("00 01\n02"), id="text")

    def on_field_tree_chosen(self, message: FieldTree.Chosen) -> None:
        self.chosen.append(message.node.data)

    def on_field_tree_highlighted(self, message: FieldTree.Highlighted) -> None:
        self.lit.append(message.node.data)


def lines(tree: FieldTree) -> list[str]:
    return ["".join(s.text for s in tree.render_line(y)).rstrip() for y in range(tree.size.height)]


async def test_keys_open_close_and_follow_a_link():
    app = _Tree()
    chosen, lit = app.chosen, app.lit
    async with app.run_test(size=(40, 20)) as pilot:
        tree = app.query_one(FieldTree)
        tree.show(record("RETURN", 2))
        tree.focus()
        await pilot.pause()
        assert lines(tree)[:6] == ["▾ RETURN", "├ ▸ header", "├ ▾ fields (2)", "│ ├ ▸ field 0", "│ └ ▸ field 1",
                                   "└ -> request"]
        await pilot.press("down", "enter")  # open the header
        await pilot.pause()
        assert lines(tree)[1:3] == ["├ ▾ header", "│ └ id"]
        await pilot.press("down")
        await pilot.pause()
        assert lit[-1] == (2, 3)  # the id's bytes
        await pilot.press("left")  # a leaf: to its parent
        assert tree.cursor_line == 1
        await pilot.press("left")  # an open node: closes it
        await pilot.pause()
        assert lines(tree)[1] == "├ ▸ header"
        await pilot.press("right")
        await pilot.pause()
        assert lines(tree)[1] == "├ ▾ header"
        await pilot.press("end", "enter")
        await pilot.pause()
        assert chosen == ["request"]


async def test_a_tree_of_the_same_shape_keeps_its_open_nodes_and_cursor():
    app = _Tree()
    async with app.run_test(size=(40, 20)) as pilot:
        tree = app.query_one(FieldTree)
        tree.show(record("RETURN @1", 2))
        tree.focus()
        await pilot.press("down", "enter", "down")  # open the header, onto its id
        tree.show(record("RETURN @2", 2))
        await pilot.pause()
        assert lines(tree)[:3] == ["▾ RETURN @2", "├ ▾ header", "│ └ id"]
        assert tree.cursor_line == 2 and tree.cursor_node.data == (2, 3)
        tree.show(record("RETURN @3", 3))  # another shape: as it comes, the cursor on its title
        await pilot.pause()
        assert lines(tree)[1] == "├ ▸ header" and tree.cursor_line == 0


async def test_a_record_of_another_size_that_fits_asks_for_no_layout():
    app = _Tree()
    async with app.run_test(size=(40, 20)) as pilot:
        tree, text = app.query_one(FieldTree), app.query_one("#text", ScrollingText)
        tree.show(record("LONG", 5))
        text.update(Text("00\n01\n02"))
        await pilot.pause()
        layouts = []
        for widget in (tree, text):
            plain = widget.refresh

            def counted(*args, _plain=plain, **kwargs):
                layouts.append(kwargs.get("layout", False))
                return _plain(*args, **kwargs)

            widget.refresh = counted  # type: ignore[method-assign]
        tree.show(record("SHORT", 1))
        text.update(Text("00"))
        assert layouts and not any(layouts)
        # Taller than the pane: now it must scroll, and the screen is laid out again.
        tree.show(record("TALL", 30))
        assert any(layouts)
        await pilot.pause()
        assert tree.virtual_size.height == 34
