"""The monitor's two-line header: source, baud, models, time, counts, findings, bus load, recording, memory."""

from __future__ import annotations

from dataclasses import dataclass

from rich.text import Text
from textual.widgets import Static

from .rows import SEVERITY_MARKS, SEVERITY_STYLES, clean
from .store import Store


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


def status_text(store: Store, info: SessionInfo) -> Text:
    """The header's two lines as Text (every value from a file name or the wire goes through ``clean``)."""
    st = store.stats
    sep = (" │ ", "grey42")
    t = Text(no_wrap=True, overflow="ellipsis")
    t.append("rs30x-sniff ", "bold")
    t.append(f"{info.source_kind}: ", "grey70")
    t.append(clean(info.source), "bold cyan")
    t.append(*sep)
    t.append(f"{info.baud} bit/s")
    t.append(*sep)
    t.append("models ", "grey70")
    t.append(clean(info.models))
    t.append(*sep)
    span = store.span
    t.append("capture " if span is not None else "elapsed ", "grey70")
    t.append(_clock(span if span is not None else info.elapsed))
    t.append(*sep)
    if info.recording:
        t.append("● REC ", "bold red")
        t.append(clean(info.recording), "red")
    else:
        t.append("○ not recording", "grey62")
    t.append(*sep)
    state = info.state
    t.append(clean(state), "bold red" if state.startswith("error") else ("green" if state == "live" else "grey70"))
    if info.paused:
        t.append("  ⏸ PAUSED", "bold black on yellow")
    if not info.follow:
        t.append("  (not following: f)", "grey62")

    t.append("\n")
    t.append("bytes ", "grey70")
    t.append(f"{store.bytes_seen:,}")
    t.append(*sep)
    t.append("packets ", "grey70")
    t.append(f"{st.packets:,}")
    t.append(*sep)
    t.append("replies ", "grey70")
    t.append(f"{st.replies:,}")
    if st.missing:
        t.append(f" ({st.missing:,} missing)", "yellow")
    if st.garbage:
        t.append(*sep)
        t.append(f"garbage {st.garbage:,}", "yellow")
    t.append(*sep)
    t.append("findings ", "grey70")
    if not info.lint:
        t.append("(lint unavailable) ", "grey62")
    for k, sev in enumerate(("error", "warning", "info")):
        n = st.severities.get(sev, 0)
        t.append(f"{' ' if k else ''}{SEVERITY_MARKS[sev]}{n:,}", SEVERITY_STYLES[sev] if n else "grey50")
    t.append(*sep)
    load = store.bus_load
    t.append("load ", "grey70")
    t.append("-" if load is None else f"{load * 100:.1f}%", "bold red" if load is not None and load > 0.8 else "")
    t.append(*sep)
    t.append("mem ", "grey70")
    t.append(f"{store.memory_estimate() / 1e6:.1f} MB")
    t.append(f" ({_si(len(store))}/{_si(store.history)} rows)", "grey62")
    if info.filter_text:
        t.append(*sep)
        t.append("filter ", "grey70")
        t.append(clean(info.filter_text), "bold magenta")
        t.append(f" {store.view_len():,} shown", "grey70")
        if info.filter_progress is not None:
            t.append(f" scanning {info.filter_progress * 100:.0f}%", "yellow")
    return t


class StatusHeader(Static):
    """Two lines of status at the top of the screen."""

    DEFAULT_CSS = """
    StatusHeader { height: 2; background: $panel; color: $text; padding: 0 1; }
    """

    def show(self, store: Store, info: SessionInfo) -> None:
        # Two lines of fixed height: new text needs no layout of the screen (a tick would cost a full one).
        self.update(status_text(store, info), layout=False)
