"""Text for the monitor's rows and labels, as rich Text objects: wire data is never read as markup or control codes."""

from __future__ import annotations

import re

from rich.text import Text

from ..decode.pairing import Record
from ..render.records import bad_sum, direction, kind_word, summary
from ..filters import SEVERITY_RANK

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

COLUMNS = f"  {'time(s)':>11} {'delta(ms)':>10} {'dir':^3} {'ID':>3} {'kind':<12} {'latency':>9} summary"
# A narrow terminal (80 columns) keeps time, direction, ID, kind and the summary: delta and latency go.
COMPACT_COLUMNS = f"  {'time(s)':>11} {'dir':^3} {'ID':>3} {'kind':<12} summary"
COMPACT_BELOW = 110  # timeline widths under this many cells use the compact columns


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


def row_text(rec: Record, prev_t: float | None, compact: bool = False) -> Text:
    """One timeline row: severity mark, time, delta, direction, ID, kind, latency, summary (``compact``:
    without delta and latency, for narrow terminals)."""
    ev = rec.event
    text = Text(no_wrap=True, overflow="ellipsis")
    sev = worst_severity(rec)
    text.append(SEVERITY_MARKS.get(sev, " ") if sev else " ", SEVERITY_STYLES.get(sev, ""))
    t = ev.t_start
    if t is not None:
        text.append(f" {t:11.6f}", "grey70")
        if not compact:
            delta = f"{(t - prev_t) * 1e3:+10.3f}" if prev_t is not None else " " * 10
            text.append(f" {delta}", "grey50")
    else:
        text.append(f" {'@' + str(ev.offset):>11}" + ("" if compact else f" {'':10}"), "grey50")
    who = direction(rec)
    text.append(f" {ARROWS[who]:^3}", "bold" if who == "host" else "")
    sid = rec.id
    text.append(f" {sid if sid is not None else '-':>3}", "bold")
    word = kind_word(rec)
    bad = bad_sum(rec)
    if bad:
        word += "!SUM"
    text.append(f" {word:<12}", "bold red" if bad else kind_style(word))
    if compact:
        if rec.status == "missing":
            text.append(" no reply", "red")
    elif rec.latency is not None:
        text.append(f" {rec.latency * 1e3:7.3f}ms", "grey70")
    elif rec.status == "missing":
        text.append(" no reply ", "red")
    else:
        text.append(" " * 10)
    text.append(" " + short_summary(rec), "red" if sev == "error" else "")
    return text
