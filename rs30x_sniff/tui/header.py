"""The monitor's two-line header: source, baud, models, time, counts, findings, bus load, recording, memory."""

from __future__ import annotations

from dataclasses import dataclass

from rich.cells import cell_len
from rich.text import Text

from .rows import SEVERITY_MARKS, SEVERITY_STYLES, clean
from .store import Store
from .text_lines import TextLines


@dataclass
class SessionInfo:
    """What the header says about the session besides the store's counts."""

    source: str = ""
    source_kind: str = "file"
    baud: int = 115200
    models: str = ""
    elapsed: float = 0.0          # seconds since the source started (wall clock, injected)
    state: str = "reading"        # "reading", "live", "done", "error: ..."
    paused: bool = False
    follow: bool = True
    recording: str | None = None
    lint: bool = True
    filter_text: str = ""
    filter_progress: float | None = None
    times: str = ""               # how the timeline shows times, when not seconds since the start (--time-format)
    times_fallback: bool = False  # the form asked for cannot be shown (no wall clock): said in yellow


def _si(n: float) -> str:
    for unit in ("", "k", "M", "G"):
        if abs(n) < 1000:
            return f"{n:.0f}{unit}" if unit == "" else f"{n:.1f}{unit}"
        n /= 1000
    return f"{n:.1f}T"


def _clock(s: float) -> str:
    s = max(0.0, s)
    h, rem = divmod(int(s), 3600)
    m, sec = divmod(rem, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m}:{sec:02d}.{int((s % 1) * 10)}"


_SEP = (" │ ", "grey42")


class _Field:
    """One field of a header line: whole or not at all (a number is never cut); ``rank`` says which go
    first when the line is too long (the highest), and a ``shrink`` field (a name, not a number) may
    instead lose the middle of its ``name`` to an ellipsis."""

    def __init__(self, rank: int, *parts: tuple[str, str], shrink: int | None = None) -> None:
        self.rank = rank
        self.parts = list(parts)
        self.shrink = shrink  # index of the part that may be shortened

    @property
    def width(self) -> int:
        return sum(cell_len(p) for p, _ in self.parts)

    def shorten(self, by: int) -> bool:
        """Take ``by`` cells out of the shrinkable part (an ellipsis in their place); False if it cannot."""
        if self.shrink is None:
            return False
        text, style = self.parts[self.shrink]
        keep = len(text) - by - 1
        if keep < 6:
            return False
        head = keep // 3  # a path's end (the file name) says more than its start
        self.parts[self.shrink] = (text[:head] + "…" + text[len(text) - (keep - head):], style)
        return True


def _fit(fields: list[_Field], width: int | None) -> list[_Field]:
    """The fields that fit in ``width`` cells with their separators: the highest ranks are left out
    first; then the fields of rank 0, which always show, have their names shortened."""
    fields = list(fields)
    if width is None:
        return fields

    def over() -> int:
        return sum(f.width for f in fields) + cell_len(_SEP[0]) * (len(fields) - 1) - width

    while width is not None and over() > 0:
        droppable = [f for f in fields if f.rank > 0]
        if droppable:
            fields.remove(max(reversed(droppable), key=lambda f: f.rank))  # ties: the rightmost goes
        elif not any(f.shorten(over()) for f in fields):
            break  # the line ends in an ellipsis (status_text)
    return fields


def _line(fields: list[_Field], width: int | None) -> Text:
    t = Text(no_wrap=True, overflow="ellipsis")
    for k, f in enumerate(_fit(fields, width)):
        if k:
            t.append(*_SEP)
        for text, style in f.parts:
            t.append(text, style)
    if width is not None and t.cell_len > width:
        t.truncate(width, overflow="ellipsis")
    return t


def status_text(store: Store, info: SessionInfo, width: int | None = None) -> Text:
    """The header's two lines as Text, each fitted to ``width`` cells (None: no limit) by leaving
    whole fields out, least useful first, so no field is ever cut in the middle (every value from a
    file name or the wire goes through ``clean``)."""
    st = store.stats
    first: list[_Field] = [
        _Field(0, (f"{info.source_kind}: ", "grey70"), (clean(info.source), "bold cyan"), shrink=1),
        _Field(3, (f"{info.baud} bit/s", "")),
        _Field(5, ("models ", "grey70"), (clean(info.models), ""), shrink=1),
    ]
    span = store.span
    first.append(_Field(1, ("capture " if span is not None else "elapsed ", "grey70"),
                        (_clock(span if span is not None else info.elapsed), "")))
    if info.times:
        first.append(_Field(4, ("times ", "grey70"), (clean(info.times), "yellow" if info.times_fallback else "")))
    if info.recording:
        first.append(_Field(0, ("● REC ", "bold red"), (clean(info.recording), "red"), shrink=1))
    else:
        first.append(_Field(6, ("○ not recording", "grey62")))
    state = info.state
    first.append(_Field(0, (clean(state), "bold red" if state.startswith("error") else
                            ("green" if state == "live" else "grey70")), shrink=0))
    if info.paused:
        first.append(_Field(0, ("⏸ PAUSED", "bold black on yellow")))
    if not info.follow:
        first.append(_Field(2, ("not following: f", "grey62")))
    # The program's name goes first, and is the first to go.
    first.insert(0, _Field(7, ("rs30x-sniff", "bold")))

    second: list[_Field] = [
        _Field(3, ("bytes ", "grey70"), (f"{store.bytes_seen:,}", "")),
        _Field(1, ("packets ", "grey70"), (f"{st.packets:,}", "")),
    ]
    replies = _Field(2, ("replies ", "grey70"), (f"{st.replies:,}", ""))
    if st.missing:
        replies.parts.append((f" ({st.missing:,} missing)", "yellow"))
    second.append(replies)
    if st.garbage:
        second.append(_Field(2, (f"garbage {st.garbage:,}", "yellow")))
    found = _Field(0, ("findings ", "grey70"))
    if not info.lint:
        found.parts.append(("(lint unavailable) ", "grey62"))
    for k, sev in enumerate(("error", "warning", "info")):
        n = st.severities.get(sev, 0)
        found.parts.append((f"{' ' if k else ''}{SEVERITY_MARKS[sev]}{n:,}", SEVERITY_STYLES[sev] if n else "grey50"))
    second.append(found)
    load = store.bus_load
    second.append(_Field(4, ("load ", "grey70"), ("-" if load is None else f"{load * 100:.1f}%",
                                                  "bold red" if load is not None and load > 0.8 else "")))
    second.append(_Field(5, ("mem ", "grey70"), (f"{store.memory_estimate() / 1e6:.1f} MB", ""),
                         (f" ({_si(len(store))}/{_si(store.history)} rows)", "grey62")))
    if info.filter_text:
        # An active filter always shows: what it is and how many rows it lets through.
        flt = _Field(0, ("filter: ", "grey70"), (clean(info.filter_text), "bold magenta"),
                     (f" {store.view_len():,} shown", "grey70"), shrink=1)
        if info.filter_progress is not None:
            flt.parts.append((f" scanning {info.filter_progress * 100:.0f}%", "yellow"))
        second.append(flt)

    return Text("\n", no_wrap=True).join([_line(first, width), _line(second, width)])


class StatusHeader(TextLines):
    """Two lines of status at the top of the screen, drawn with the Line API (TextLines)."""

    DEFAULT_CSS = """
    StatusHeader { height: 2; background: $panel; color: $text; padding: 0 1; }
    """

    _last: tuple[Store, SessionInfo] | None = None

    def __init__(self, **kwargs) -> None:
        super().__init__(**kwargs)
        self._text = Text()

    def show(self, store: Store, info: SessionInfo) -> None:
        # Two lines of fixed height: new text needs no layout of the screen (a tick would cost a full one).
        self._last = (store, info)
        width = self.content_region.width
        text = status_text(store, info, width or None)
        if text.plain == self._text.plain and text.spans == self._text.spans:
            return  # the same two lines: nothing to draw
        self._text = text
        self.set_lines(text.split("\n"))

    def render(self) -> Text:
        return self._text

    def on_resize(self) -> None:
        if self._last is not None:
            self._text = Text()
            self.show(*self._last)
