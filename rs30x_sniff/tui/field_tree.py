"""The detail pane's field tree, drawn with the Line API: a record's nodes set whole, only the lines in sight drawn."""

from __future__ import annotations

from rich.text import Text
from textual.binding import Binding
from textual.events import Click
from textual.geometry import Region
from textual.message import Message
from textual.scroll_view import ScrollView
from textual.strip import Strip

from .line_table import CURSOR_BINDINGS, SettingsPerRender
from .text_lines import steady_size

ICON_OPEN, ICON_CLOSED = "▾ ", "▸ "
CROSS, LAST, VERTICAL, SPACE = "├ ", "└ ", "│ ", "  "  # a guide two cells deep, as Textual's Tree draws it


class Node:
    """A node of the tree: its label, its data (the pane's: a byte span, or a record to go to), its children
    (None: a leaf), whether it is open, and whether it may open at all."""

    __slots__ = ("label", "data", "children", "expand", "allow_expand")

    def __init__(self, label: Text, data: object = None, children: list[Node] | None = None, *,
                 expand: bool = False, allow_expand: bool = True) -> None:
        self.label, self.data, self.children = label, data, children
        self.expand, self.allow_expand = expand, allow_expand

    @property
    def opens(self) -> bool:
        return self.children is not None and self.allow_expand

    def shape(self) -> tuple:
        """What a tree of this node looks like apart from its labels and data."""
        kids = None if self.children is None else tuple(c.shape() for c in self.children)
        return (kids, self.expand, self.allow_expand)


def _keep_open(old: Node, new: Node) -> None:
    """Open or close ``new``'s nodes as ``old``'s (of the same shape) are now."""
    new.expand = old.expand
    for a, b in zip(old.children or (), new.children or ()):
        _keep_open(a, b)


class _Line:
    """A line of the tree: its node, the nodes above it (root first) and, for each level, whether the node of
    that level is its parent's last child (which guide it draws)."""

    __slots__ = ("node", "path", "lasts")

    def __init__(self, node: Node, path: tuple[Node, ...], lasts: tuple[bool, ...]) -> None:
        self.node, self.path, self.lasts = node, path, lasts


def _lines(root: Node) -> list[_Line]:
    out: list[_Line] = []

    def walk(node: Node, path: tuple[Node, ...], lasts: tuple[bool, ...]) -> None:
        out.append(_Line(node, path, lasts))
        if node.opens and node.expand:
            kids = node.children or []
            for i, child in enumerate(kids):
                walk(child, path + (node,), lasts + (i == len(kids) - 1,))

    walk(root, (), ())
    return out


class _NodeMessage(Message):
    """A message about ``node`` of the tree."""

    def __init__(self, node: Node) -> None:
        super().__init__()
        self.node = node


class FieldTree(SettingsPerRender, ScrollView, can_focus=True):
    """A tree of labelled nodes with a cursor. ``show`` sets a new tree: one of the same shape as the last keeps
    its open nodes and the cursor's line, and costs the screen no new layout (the monitor shows the newest
    record of a busy bus several times a second; Textual's Tree laid out the whole screen at each). Space
    pauses the monitor (as everywhere); enter opens or closes a node, or follows a link (``Chosen``)."""

    BINDINGS = [
        *CURSOR_BINDINGS,
        Binding("end", "last", "Last", show=False),
        Binding("enter", "choose", "Open or go", show=False),
        Binding("right", "open", "Open", show=False),
        Binding("left", "close", "Close", show=False),
        Binding("space", "app.toggle_pause", "Pause", show=False),
    ]
    COMPONENT_CLASSES = {"field-tree--guides", "field-tree--guides-selected", "field-tree--cursor"}
    # Textual's Tree's own look, so the pane reads as before.
    DEFAULT_CSS = """
    FieldTree {
        background: $surface;
        color: $foreground;
        & > .field-tree--guides {
            color: $surface-lighten-2;
        }
        & > .field-tree--guides-selected {
            color: $block-cursor-blurred-background;
        }
        & > .field-tree--cursor {
            text-style: $block-cursor-blurred-text-style;
            background: $block-cursor-blurred-background;
        }
        &:focus {
            background-tint: $foreground 5%;
            & > .field-tree--cursor {
                color: $block-cursor-foreground;
                background: $block-cursor-background;
                text-style: $block-cursor-text-style;
            }
            & > .field-tree--guides {
                color: $surface-lighten-3;
            }
            & > .field-tree--guides-selected {
                color: $block-cursor-background;
            }
        }
        &:light > .field-tree--guides {
            color: $surface-darken-1;
        }
    }
    FieldTree:ansi {
        color: ansi_default;
        & > .field-tree--guides {
            color: $ansi-background;
        }
    }
    """

    class Highlighted(_NodeMessage):
        """The cursor moved to ``node``."""

    class Chosen(_NodeMessage):
        """Enter was pressed on ``node`` (or it was clicked), a node that does not open: a link."""

    def __init__(self, root: Node, **kwargs) -> None:
        super().__init__(**kwargs)
        self.root = root
        self._shape = root.shape()  # as given, before a user opened or closed a node
        self._lines = _lines(root)
        self.cursor_line = 0
        self._cache: dict[tuple, Strip] = {}

    @property
    def cursor_node(self) -> Node:
        return self._lines[min(self.cursor_line, len(self._lines) - 1)].node

    def show(self, root: Node) -> None:
        """Show ``root``'s tree."""
        shape = root.shape()
        if shape == self._shape:
            _keep_open(self.root, root)
        else:
            self._shape = shape
            self.cursor_line = 0
            self.scroll_to(0, 0, animate=False)
        self.root = root
        self._relines()

    def _relines(self) -> None:
        self._lines = _lines(self.root)
        self.cursor_line = min(self.cursor_line, len(self._lines) - 1)
        self._cache.clear()
        self._fit()
        self.refresh()

    def _fit(self) -> None:
        steady_size(self, max((2 * len(line.path) + (2 if line.node.opens else 0) + line.node.label.cell_len
                               for line in self._lines), default=0), len(self._lines))

    def on_resize(self) -> None:
        self._cache.clear()
        self._fit()

    # ---- cursor ---------------------------------------------------------------------------------------
    def _go(self, line: int) -> None:
        line = max(0, min(len(self._lines) - 1, line))
        if line != self.cursor_line:
            self.cursor_line = line
            self._cache.clear()
            self.refresh()
            self.post_message(self.Highlighted(self._lines[line].node))
        self.scroll_to_region(Region(0, line, 1, 1), animate=False, immediate=True)

    def action_cursor(self, step: int) -> None:
        self._go(self.cursor_line + step)

    def action_page(self, direction: int) -> None:
        self._go(self.cursor_line + direction * max(1, self.scrollable_content_region.height - 1))

    def action_first(self) -> None:
        self._go(0)

    def action_last(self) -> None:
        self._go(len(self._lines) - 1)

    def action_choose(self) -> None:
        node = self.cursor_node
        if node.opens:
            node.expand = not node.expand
            self._relines()
        else:
            self.post_message(self.Chosen(node))

    def action_open(self) -> None:
        node = self.cursor_node
        if node.opens and not node.expand:
            node.expand = True
            self._relines()

    def action_close(self) -> None:
        """Close the cursor's node, or go to its parent."""
        node, line = self.cursor_node, self._lines[self.cursor_line]
        if node.opens and node.expand:
            node.expand = False
            self._relines()
        elif line.path:
            parent = line.path[-1]
            self._go(next(i for i, ln in enumerate(self._lines) if ln.node is parent))

    def on_click(self, event: Click) -> None:
        line = int(self.scroll_y) + event.y
        if 0 <= line < len(self._lines):
            self._go(line)
            self.action_choose()

    def on_focus(self) -> None:
        self._cache.clear()
        self.refresh()

    def on_blur(self) -> None:
        self._cache.clear()
        self.refresh()

    # ---- rendering ------------------------------------------------------------------------------------
    def render_settings(self) -> tuple:
        guides = self.get_component_rich_style("field-tree--guides", partial=True)
        return (self.size.width, int(self.scroll_x), int(self.scroll_y), self.rich_style, guides,
                guides + self.get_component_rich_style("field-tree--guides-selected", partial=True),
                self.get_component_rich_style("field-tree--cursor", partial=False), self.has_focus)

    def render_line(self, y: int) -> Strip:
        frame = self.settings()
        width, scroll_x, scroll_y, base = frame[:4]
        ly = y + scroll_y
        if ly >= len(self._lines):
            return Strip.blank(width, base)
        key = (ly, frame)
        strip = self._cache.get(key)
        if strip is None:
            strip = self._cache[key] = self._draw(self._lines[ly], ly == self.cursor_line, frame)
        return strip

    def _draw(self, line: _Line, cursor: bool, frame: tuple) -> Strip:
        width, scroll_x, _, base, guides, selected, cursor_style, focused = frame
        text = Text(style=base, no_wrap=True, end="")
        # Under the cursor's node (the tree focused), the guides take the cursor's colour.
        under = focused and self.cursor_node in line.path
        depth = len(line.lasts)
        for level, last in enumerate(line.lasts, 1):
            style = selected if focused and self.cursor_node in line.path[:level] else guides
            if level < depth:
                text.append(SPACE if last else VERTICAL, style)
            else:
                text.append(LAST if last else CROSS, selected if under else guides)
        node = line.node
        if node.opens:
            text.append(ICON_OPEN if node.expand else ICON_CLOSED)
        label = node.label.copy()
        if cursor:
            label.stylize(cursor_style)
        text.append_text(label)
        segments = list(text.render(self.app.console))
        return Strip(segments, text.cell_len).crop_extend(scroll_x, scroll_x + width, base)
