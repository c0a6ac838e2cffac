"""The command line's option groups, built once: each command takes the groups that apply to it."""

# One grammar (issue 33 §2-3): a duration option takes language.py's durations (50ms, 10min, 2h; a bare number
# is seconds), an ID option language.py's ID ranges, and every command names its output format --format.

from __future__ import annotations

import argparse

from .. import language
from ..render.times import HELP as TIME_FORMAT_HELP, TIME_FORMATS
from ..sources.captures import input_formats
from ..sources.timebase import TIME_REFS
from ..sources.timeunit import UNITS as TIME_UNITS

SERVO_IDS = "1-127, table 4.6 No. 4; 255 is the broadcast"


def duration(text: str) -> float:
    """A duration option's value in seconds (``50ms``, ``1.5``, ``10min``, ``2h``); finite and positive."""
    try:
        return language.parse_duration(text)
    except language.LanguageError as e:
        raise argparse.ArgumentTypeError(str(e)) from None  # "50x: expected a duration ...": the value first


def servo_ids(text: str) -> tuple[int, ...]:
    """An ID option's value: servo IDs and ranges (``3``, ``1-6,9``) as language.py reads them, each a servo's
    own ID (1-127) or the broadcast (255)."""
    try:
        ids = language.parse_id_range(text, high=0xFFFF)  # a number read, so that 999 is said not to be an ID
    except language.LanguageError as e:
        why = f"not a servo ID ({SERVO_IDS})" if str(e).startswith("IDs run from") else str(e)
        raise argparse.ArgumentTypeError(f"{text}: {why}") from None
    bad = [i for i in ids if not (1 <= i <= 127 or i == 255)]
    if bad:
        raise argparse.ArgumentTypeError(f"{text}: not a servo ID ({SERVO_IDS})" if len(ids) == 1 else
                                         f"{text}: {bad[0]} is not a servo ID ({SERVO_IDS})")
    return ids


def baud_arg(text: str) -> int | str:
    """--baud's value: a number, or ``auto``."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a baud rate (a number, or auto)") from None


def add_format_option(p: argparse.ArgumentParser, choices: tuple[str, ...], help: str, *, default: str | None = None,
                      aliases: tuple[str, ...] = ()) -> None:
    """--format, the output format of every command; ``aliases`` (an older name such as ``convert --to``) are
    read as --format and left out of --help."""
    p.add_argument("--format", choices=choices, default=default, help=help)
    for alias in aliases:
        p.add_argument(alias, dest="format", choices=choices, default=default, help=argparse.SUPPRESS)


def add_bus_options(p: argparse.ArgumentParser) -> None:
    """--model, --baud and the timing knobs of decoding: what the bus is."""
    p.add_argument("--model", action="append", default=[], metavar="[ID=]MODEL",
                   help="servo model for every ID (a memory map's name: RS303MR, RS304MD, RS301CR, RS204MD, "
                        "RS405CB, ...) or for one ID (3=RS304MD); repeatable")
    p.add_argument("--baud", type=baud_arg, default=None, metavar="BPS|auto",
                   help="bus baud rate, one of table 4.7's (460800 too, where a model has it), or auto: a port is "
                        "tried at each rate, a capture goes by its metadata or timestamps (default: what the capture "
                        "shows, else 115200)")
    p.add_argument("--baud-any", action="store_true", default=None,
                   help="accept a --baud that is not one of the manual's rates")
    p.add_argument("--gap-bytes", type=float, default=None, metavar="N",
                   help="idle byte times inside a frame that end it as truncated (default 20; 0 turns it off)")
    p.add_argument("--reply-timeout", type=duration, default=None, metavar="TIME",
                   help="time after a request before its reply counts as missing (50ms, 0.05; default 50ms)")


def add_input_options(p: argparse.ArgumentParser, *, channel: bool = True) -> None:
    """How a capture is read: its format, its times, and (``channel``) a logic capture's channel."""
    p.add_argument("--input-format", choices=input_formats(), default=None,
                   help="capture format, when the extension and content do not tell")
    p.add_argument("--time-ref", choices=TIME_REFS, default=None,
                   help="what a timestamped hex capture's times mark: each line's first byte, or its arrival "
                        "(the end of its last byte, as serial loggers stamp reads); default: told by the content")
    p.add_argument("--time-unit", choices=TIME_UNITS, default=None,
                   help="the unit of a timestamped hex capture's times (counted from its start or from the epoch); "
                        "default: told by the content, else s")
    if channel:
        p.add_argument("--channel", default=None, metavar="NAME|INDEX",
                       help="a logic capture's channel to decode (.sr): its name (D0, RX) or its index from 0 "
                            "(default: the only channel, else the first that toggles)")


def add_decode_options(p: argparse.ArgumentParser, *, channel: bool = True) -> None:
    """The bus and the input: every command that decodes a capture."""
    add_bus_options(p)
    add_input_options(p, channel=channel)


def add_live_options(p: argparse.ArgumentParser, *, help: str | None = None) -> None:
    """--duration, for commands whose INPUT may be a serial port (a device or a pyserial URL)."""
    p.add_argument("--duration", type=duration, default=None, metavar="TIME",
                   help=help or "when INPUT is a serial port: stop after TIME (30s, 10min, 2h; default: run until "
                                "Ctrl-C)")


def add_config_options(p: argparse.ArgumentParser) -> None:
    """--config and --isolated: which settings file is read."""
    p.add_argument("--config", metavar="FILE",
                   help="settings file (default: the nearest rs30x-sniff.toml or pyproject.toml [tool.rs30x-sniff])")
    p.add_argument("--isolated", action="store_true", help="ignore configuration files")


def add_lint_selection(p: argparse.ArgumentParser) -> None:
    """--select / --ignore and the settings file options (every command that lints)."""
    p.add_argument("--select", action="append", default=None, metavar="RULES",
                   help="only these rules: codes, prefixes (Q, B00) or names, comma-separated; repeatable")
    p.add_argument("--ignore", action="append", default=None, metavar="RULES",
                   help="skip these rules (same forms as --select); repeatable")
    add_config_options(p)


def add_lint_options(p: argparse.ArgumentParser, *, no_lint: str = "do not run the linter") -> None:
    """The linter's rule selection, as `lint` takes it, and --no-lint."""
    add_lint_selection(p)
    p.add_argument("--no-lint", action="store_true", help=no_lint)


def add_time_format_option(p: argparse.ArgumentParser) -> None:
    """--time-format: how the text outputs and the monitor show times (one option, the same everywhere)."""
    p.add_argument("--time-format", choices=TIME_FORMATS, default=None, help=TIME_FORMAT_HELP)

