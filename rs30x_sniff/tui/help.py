"""The help screen: every key and the filter language, on one page."""

from __future__ import annotations

from rich.table import Table
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Static

KEYS = (
    ("q, ctrl+c", "quit (a recording in progress is finished first)"),
    ("space", "pause / resume the timeline (the capture, counts and recording go on)"),
    ("/", "filter the timeline (enter applies, escape closes, empty shows all)"),
    ("n / N", "next / previous packet with a finding"),
    ("f, End", "follow the newest packet (scrolling up stops following)"),
    ("c", "clear the history, counts and findings"),
    ("d", "narrow terminal: show the detail pane instead of the timeline, and back"),
    ("b", "under 160 columns: the next bottom pane (servos, findings, plot)"),
    ("r", "start / stop recording to an MCAP file"),
    ("g", "go to the selected packet's reply or request"),
    ("p", "plot the next register (the servo is the one selected in the servos pane)"),
    ("a", "plot every servo's value of the register beside the selected one, and back"),
    ("z / Z", "zoom the plot's time axis in / out"),
    ("[ / ]", "pan the plot back / on in time; 0 shows the whole series again"),
    ("tab / shift+tab", "move between panes"),
    ("enter", "in findings: show the packet; in the field tree: open a node or follow the link"),
    ("left / right", "in the field tree: close a node (on a closed one: go to its parent) / open it"),
    ("ctrl+p", "command palette"),
    ("?", "this help (escape closes)"),
)

FILTERS = (
    ("id:3  id:1-6  id:1,3,5", "packets to or from these servo IDs (a long packet: any of its IDs)"),
    ("kind:return", "by kind: short long return ack nack garbage, or write read ping flash reboot init "
                    "request reply"),
    ("reg:goal_position", "packets that write, read or return this register"),
    ("sev>=warning  sev:error", "packets with a finding of that severity (>=, >, <=, <, :)"),
    # Two examples on two lines: on one, the column would leave the text beside it no room at 80 columns.
    ("present_temperature>40\nreg:goal_position<=-30",
     "a register's value in engineering units (> >= < <= = !=; a long packet: any of its servos)"),
    ("latency>1ms  latency<=120us", "replies by their latency (s, ms, us)"),
    ("t:1.5-3.0  t:2-  t>2.5", "packets by capture time, in seconds"),
    ("word  \"two words\"", "free text anywhere in the row (case-insensitive)"),
    ("-term  !term", "exclude what the term matches"),
    ("id:1 kind:return", "terms combine: all must match"),
)


def _table(title: str, rows: tuple[tuple[str, str], ...]) -> Table:
    table = Table(title=title, title_justify="left", title_style="bold", show_header=False, box=None,
                  padding=(0, 2, 0, 0))
    table.add_column(style="bold cyan", no_wrap=True)
    table.add_column()
    for key, what in rows:
        table.add_row(Text(key), Text(what))
    return table


class HelpScreen(ModalScreen[None]):
    """Keys and filter syntax; any of escape, q or ? closes it."""

    BINDINGS = [
        Binding("escape", "dismiss", "Close"),
        Binding("q", "dismiss", "Close", show=False),
        Binding("question_mark", "dismiss", "Close", show=False),
    ]
    DEFAULT_CSS = """
    HelpScreen { align: center middle; }
    HelpScreen > VerticalScroll { width: 100; max-width: 100%; height: auto; max-height: 100%;
                                  border: thick $accent; background: $surface; padding: 0 1; }
    """

    def compose(self) -> ComposeResult:
        with VerticalScroll():
            yield Static(Text("rs30x-sniff monitor", "bold"))
            yield Static(_table("Keys", KEYS))
            yield Static(Text(""))
            yield Static(_table("Filter", FILTERS))
