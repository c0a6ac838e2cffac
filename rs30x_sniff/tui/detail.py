"""The detail pane: the selected record's field tree and a hex dump that highlights the selected field's bytes."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.message import Message

from ..decode.pairing import Record
from ..protocol.events import Ack, Garbage, LongPacket, Nack, ReturnPacket, ShortPacket
from ..protocol.wire import (
    AT_ADDRESS, AT_COUNT, AT_DATA, AT_FLAG, AT_ID, AT_LENGTH, HEADER_SIZE, SUM_SIZE, VID_SIZE)
from ..render.records import format_value, kind_word
from ..render.times import ABSOLUTE, EPOCH, TimeForm, wall_text
from .field_tree import FieldTree, Node
from .rows import SEVERITY_STYLES, clean, kind_style, short_summary
from .text_lines import ScrollingText

HEX_PER_LINE = 16
EMPTY = "no packet selected"
DATE = len("2026-11-27 ")  # the date's characters before the time of day in render.times.wall_text


def time_label(t: float, times: TimeForm | None) -> str:
    """A record's time in the title, as --time-format shows it: seconds since the start (delta too: one record
    has no neighbour here) and the time of day where the capture has a wall clock, the date and time alone, or
    epoch seconds."""
    if times is None or times.origin is None:  # (not started)
        return f"t={t:.6f}s"
    shown, wall = times.shown, times.wall
    if shown == ABSOLUTE or shown == EPOCH:
        assert wall is not None  # a form with a date is shown only where the capture has a wall clock
        return wall_text(wall + t) if shown == ABSOLUTE else f"t={wall + t:.6f}s"
    since = f"t={t - times.origin:.6f}s"
    # The time of day beside it, without the date (the title must fit a narrow pane; absolute shows the date).
    return since if wall is None else f"{since} ({wall_text(wall + t)[DATE:]})"


def field_spans(rec: Record) -> list[tuple[int, int]]:
    """Where each of ``rec.fields`` sits in the raw frame, as (start, end) byte indexes."""
    ev = rec.event
    fields = rec.fields
    if type(ev) is ShortPacket or type(ev) is ReturnPacket:
        return [(AT_DATA + f.address - ev.address, AT_DATA + f.address - ev.address + len(f.raw)) for f in fields]
    if type(ev) is LongPacket and ev.count and fields:
        per = len(fields) // ev.count or 1  # every record of a long packet splits into the same fields
        out = []
        for i, f in enumerate(fields):
            start = AT_DATA + (i // per) * ev.length + VID_SIZE + f.address - ev.address
            out.append((start, start + len(f.raw)))
        return out
    return [(0, 0)] * len(fields)


def hex_dump(raw: bytes, span: tuple[int, int] | None = None) -> Text:
    """The frame's bytes, 16 to a line, with ``span`` (a field's bytes) in reverse video."""
    text = Text(no_wrap=True)
    for line in range(0, max(len(raw), 1), HEX_PER_LINE):
        if line:
            text.append("\n")
        text.append(f"{line:04X} ", "grey50")
        for i in range(line, min(line + HEX_PER_LINE, len(raw))):
            style = ""
            if i < AT_ID:  # the header bytes
                style = "grey62"
            elif span is not None and span[0] <= i < span[1]:
                style = "reverse bold"
            elif i == len(raw) - SUM_SIZE and len(raw) > HEADER_SIZE:
                style = "grey62"
            text.append(f"{raw[i]:02X}", style)
            if i + 1 < min(line + HEX_PER_LINE, len(raw)):
                text.append(" ", style if span is not None and span[0] <= i + 1 < span[1] else "")
    return text


_STATUS_LINES: dict[str | None, tuple[str, str]] = {
    "missing": ("no reply came", "red"),
    "unsolicited": ("unsolicited: no request asked for this", "yellow"),
    "unknown": ("the capture ended while its reply was still due", "grey70"),
    "request-unseen": ("answers a request sent before the capture began", "grey70"),
}


class HexView(ScrollingText, can_focus=False):
    """The frame's dump; a long one scrolls with the mouse, and Tab skips it (the tree drives what it shows)."""


class DetailPane(Vertical):
    """Shows one record; ``Jump`` asks the app to select another (a reply's request, a request's reply)."""

    class Jump(Message):
        def __init__(self, rec: Record) -> None:
            super().__init__()
            self.rec = rec

    def __init__(self, times: TimeForm | None = None, **kwargs) -> None:
        super().__init__(**kwargs)
        self.rec: Record | None = None
        self.times = times  # how the title shows the record's time (--time-format)

    def compose(self) -> ComposeResult:
        tree = self.field_tree = FieldTree(Node(Text(EMPTY)), id="fields")
        self.hex_view = HexView(id="hex")
        yield tree
        yield self.hex_view

    def show(self, rec: Record | None) -> None:
        """Show ``rec`` (None: clear the pane); showing the same record again is free. A record of the same
        shape as the one shown (the newest, as the capture follows a busy bus) keeps the tree's open nodes and
        its cursor, and the screen needs no new layout, only the changed lines."""
        if (rec is self.rec and rec is not None) or not self.is_attached:
            return
        self.rec = rec
        tree = self.field_tree
        if rec is None:
            tree.show(Node(Text(EMPTY)))
            self._hex(Text(""))
            return
        ev = rec.event
        word = kind_word(rec)
        title = Text()
        title.append(word, kind_style(word))
        title.append(f" @{ev.offset} ({len(ev.raw)} bytes)", "grey70")
        if ev.t_start is not None:
            title.append(" " + time_label(ev.t_start, self.times), "grey70")
        nodes = self._header(rec) + self._fields(rec) + self._pair(rec)
        width = max(24, self.size.width - 8)  # the tree's guides and the border
        for f in rec.findings:
            # Whole, never cut: the message wraps onto the lines of an expanded node.
            nodes.append(Node(Text(f"! {f.code} {f.name}", SEVERITY_STYLES.get(f.severity, "")), None,
                              [Node(Text(piece)) for piece in textwrap.wrap(clean(f.message), width) or [""]],
                              expand=True))
        tree.show(Node(title, None, nodes, expand=True))
        data = tree.cursor_node.data  # the same field of a record of the same shape keeps its bytes lit
        self._hex(hex_dump(ev.raw, data if isinstance(data, tuple) else None))

    def _hex(self, dump: Text) -> None:
        self.hex_view.update(dump)

    def _header(self, rec: Record) -> list[Node]:
        ev = rec.event
        whole = (0, min(HEADER_SIZE, len(ev.raw)))
        if type(ev) is Garbage:
            return [Node(Text("header", "bold"), whole, [Node(Text(f"skipped: {ev.reason}"), (0, len(ev.raw)))])]
        if type(ev) is Ack or type(ev) is Nack:
            return [Node(Text(f"{'ACK' if ev.kind == 'ack' else 'NACK'} byte 0x{ev.raw[0]:02X}", "bold"), (0, 1),
                          allow_expand=False)]
        t = type(ev)
        flag = ev.flags if type(ev) is ReturnPacket else ev.flag
        items = [("header", 0, AT_ID, ev.raw[:AT_ID].hex(" ").upper()),
                 ("id", AT_ID, AT_FLAG, str(ev.raw[AT_ID])),
                 ("flags" if t is ReturnPacket else "flag", AT_FLAG, AT_ADDRESS,
                  f"0x{flag:02X}" + self._flag_text(rec)),
                 ("address", AT_ADDRESS, AT_LENGTH, str(ev.address)),
                 ("length", AT_LENGTH, AT_COUNT, str(ev.length)),
                 ("count", AT_COUNT, AT_DATA, str(ev.count)),
                 ("sum", len(ev.raw) - SUM_SIZE, len(ev.raw),
                  f"0x{ev.raw[-1]:02X}" + ("" if ev.checksum_ok else " (mismatch)"))]
        leaves = []
        for name, a, b, value in items:
            label = Text(f"{name:<10} {ev.raw[a:b].hex(' ').upper():<6} ")
            label.append(value, "red" if name == "sum" and not ev.checksum_ok else "")
            leaves.append(Node(label, (a, b)))
        return [Node(Text("header", "bold"), whole, leaves)]

    @staticmethod
    def _flag_text(rec: Record) -> str:
        ev = rec.event
        names: Sequence[str]
        if type(ev) is ReturnPacket:
            names = ev.flag_names
        elif type(ev) is ShortPacket:
            read = rec.read_range  # by the servo's model (return modes beyond table 4.3)
            names = list(ev.commands) + ([f"return {read[1]}B @{read[0]}"] if read else ["ack"] if ev.wants_ack else [])
        else:
            names = []
        return f" ({', '.join(names)})" if names else ""

    def _fields(self, rec: Record) -> list[Node]:
        fields = rec.fields
        if not fields:
            return []
        spans = field_spans(rec)
        long = type(rec.event) is LongPacket
        children = []
        for f, span in zip(fields, spans):
            label = Text()
            if long:
                label.append(f"[{f.id}] ", "magenta")
            label.append(f"{f.label:<22}", "bold" if f.name else "grey62")
            label.append(f" @{f.address:<3} {f.raw.hex(' ').upper():<6} ", "grey70")
            label.append(clean(format_value(f, with_unit=False)))
            if f.unit:
                label.append(f" {f.unit}", "grey70")
            desc = f.register.description
            children.append(Node(label, span, [Node(Text(clean(desc), "italic grey70"), span)] if desc else None))
        return [Node(Text(f"fields ({len(fields)})", "bold"), None, children, expand=True)]

    def _pair(self, rec: Record) -> list[Node]:
        other = rec.request if rec.is_reply else rec.reply
        if other is not None:
            arrow = "↰ request" if rec.is_reply else "↳ reply"
            label = Text(f"{arrow} @{other.offset} ", "bold underline")
            label.append(kind_word(other), kind_style(kind_word(other)))
            label.append(" " + short_summary(other)[:60])
            lat = rec.latency if rec.latency is not None else other.latency
            if lat is not None:
                label.append(f" ({lat * 1e3:.3f} ms)", "grey70")
            return [Node(label, other)]
        said = _STATUS_LINES.get(rec.status)
        return [Node(Text(*said))] if said else []

    # ---- events ---------------------------------------------------------------------------------------
    def on_field_tree_highlighted(self, event: FieldTree.Highlighted) -> None:
        event.stop()
        if self.rec is None:
            return
        data = event.node.data
        span = data if isinstance(data, tuple) else None
        self.hex_view.update(hex_dump(self.rec.event.raw, span))

    def on_field_tree_chosen(self, event: FieldTree.Chosen) -> None:
        event.stop()
        if isinstance(event.node.data, Record):
            self.post_message(self.Jump(event.node.data))

    def goto_pair(self) -> bool:
        """Ask to jump to the shown record's pair; False if it has none."""
        rec = self.rec
        other = None if rec is None else (rec.request if rec.is_reply else rec.reply)
        if other is None:
            return False
        self.post_message(self.Jump(other))
        return True
