"""Text for the monitor's rows and labels, as rich Text objects: wire data is never read as markup or control codes."""

from __future__ import annotations

import re

from rich.text import Text

from ..decode.pairing import Record
from ..render.records import bad_sum, direction, kind_word, summary
from ..filters import SEVERITY_RANK
from ..render.times import ABSOLUTE, DELTA, EPOCH, RELATIVE, TimeForm

# Control characters (C0, DEL, C1) shown as \xNN, so nothing from a file name or the wire can move
# the cursor or change the terminal's state.
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def clean(s: str) -> str:
    """``s`` with control characters escaped (Text objects already keep markup from being interpreted)."""
    return _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", s)


KIND_STYLES = {
    "WRITE": "cyan", "WRITE+ACK": "cyan", "WRITE+READ": "cyan", "READ": "dodger_blue1", "PING": "dodger_blue1",
    "NOP": "grey62", "LONG": "magenta", "RETURN": "green", "ACK": "green", "NACK": "bold red",
    "GARBAGE": "yellow", "FLASH": "bold magenta", "REBOOT": "bold magenta", "INIT": "bold magenta",
}
SEVERITY_STYLES = {"error": "bold red", "warning": "yellow", "info": "dodger_blue1"}
SEVERITY_MARKS = {"error": "E", "warning": "W", "info": "i"}
ARROWS = {"host": "→", "servo": "←", "?": "?"}

# A narrow terminal (80 columns) keeps time, direction, ID, kind and the summary: delta and latency go.
COMPACT_BELOW = 110  # timeline widths under this many cells use the compact columns
# The time column by --time-format (render.times): its heading and width. A compact timeline shows the time of
# day without its date (the detail pane has both).
TIME_COLUMN = {RELATIVE: ("time(s)", 11), DELTA: ("dt(s)", 11), EPOCH: ("epoch(s)", 17), ABSOLUTE: ("date time", 26)}
COMPACT_DAY = 11  # characters of "2026-11-27 " left out of a compact timeline's absolute time


def time_column(times: TimeForm | None, compact: bool = False) -> tuple[str, int]:
    """The time column's heading and width for the form shown (the default: seconds of capture time)."""
    if times is None:
        return TIME_COLUMN[RELATIVE]
    head, width = TIME_COLUMN[times.shown]
    if compact and times.shown == ABSOLUTE:
        return "time of day", width - COMPACT_DAY
    return head, width


def columns(times: TimeForm | None = None, compact: bool = False) -> str:
    """The timeline's heading row (``compact``: time, direction, ID, kind and summary alone)."""
    head, width = time_column(times, compact)
    if compact:
        return f"  {head:>{width}} {'dir':^3} {'ID':>3} {'kind':<12} summary"
    return f"  {head:>{width}} {'delta(ms)':>10} {'dir':^3} {'ID':>3} {'kind':<12} {'latency':>9} summary"


def time_cell(t: float, prev_t: float | None, times: TimeForm | None, compact: bool = False) -> str:
    """A row's time as the form shows it, in the column's width."""
    _, width = time_column(times, compact)
    if times is None or not times.started:
        return f"{t:{width}.6f}"
    v = times.value(t, prev_t)
    if type(v) is str:
        v = v.strip()
        if compact and times.shown == ABSOLUTE and len(v) > COMPACT_DAY:
            v = v[COMPACT_DAY:]
        return f"{v:>{width}}"
    return f"{v:{width}.6f}"


def worst_severity(rec: Record) -> str | None:
    """The most severe finding of a record, if it has any."""
    if not rec.findings:
        return None
    return max((f.severity for f in rec.findings), key=lambda s: SEVERITY_RANK.get(s, 0))


def kind_style(word: str) -> str:
    """The colour of a kind word (FLASH+REBOOT takes FLASH's)."""
    base = word.split("(")[0].split("!")[0]
    return KIND_STYLES.get(base) or KIND_STYLES.get(base.split("+")[0], "white")


def short_summary(rec: Record) -> str:
    """The summary without what the timeline has columns for (kind word, ID, latency)."""
    # keep=False: rows are rendered on sight; keeping every row's fields would grow without bound.
    return clean(summary(rec, bare=True, keep=False))


def row_text(rec: Record, prev_t: float | None, compact: bool = False, times: TimeForm | None = None) -> Text:
    """One timeline row: severity mark, time, delta, direction, ID, kind, latency, summary (``compact``:
    without delta and latency, for narrow terminals; ``times``: how the time is shown, --time-format)."""
    text = Text(no_wrap=True, overflow="ellipsis")
    for piece, style in row_pieces(rec, prev_t, compact, times):
        text.append(piece, style)
    return text


def row_pieces(rec: Record, prev_t: float | None, compact: bool = False,
               times: TimeForm | None = None) -> list[tuple[str, str]]:
    """row_text's pieces as (text, style) pairs: the timeline draws them as segments without a Text."""
    ev = rec.event
    out: list[tuple[str, str]] = []
    add = out.append
    sev = worst_severity(rec)
    add((SEVERITY_MARKS.get(sev, " "), SEVERITY_STYLES.get(sev, "")) if sev else (" ", ""))
    t = ev.t_start
    if t is not None:
        add((" " + time_cell(t, prev_t, times, compact), "grey70"))
        if not compact:
            # No delta where the clock went back (a restart, F010): no duration is known there.
            delta = f"{(t - prev_t) * 1e3:+10.3f}" if prev_t is not None and t >= prev_t else " " * 10
            add((f" {delta}", "grey50"))
    else:
        width = time_column(times, compact)[1]
        add((f" {'@' + str(ev.offset):>{width}}" + ("" if compact else f" {'':10}"), "grey50"))
    who = direction(rec)
    add((f" {ARROWS[who]:^3}", "bold" if who == "host" else ""))
    sid = rec.id
    add((f" {sid if sid is not None else '-':>3}", "bold"))
    word = kind_word(rec)
    bad = bad_sum(rec)
    if bad:
        word += "!SUM"
    add((f" {word:<12}", "bold red" if bad else kind_style(word)))
    if compact:
        if rec.status == "missing":
            add((" no reply", "red"))
    elif rec.latency is not None:
        add((f" {rec.latency * 1e3:7.3f}ms", "grey70"))
    elif rec.status == "missing":
        add((" no reply ", "red"))
    else:
        add((" " * 10, ""))
    add((" " + short_summary(rec), "red" if sev == "error" else ""))
    return out
