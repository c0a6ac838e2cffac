"""`record --trigger`: the black box's options and the modes they belong to (its windows: sinks/windows.py)."""

from __future__ import annotations

import argparse
import re

from ..sinks.blackbox import Trigger, TriggerError, parse_trigger
from .common import CliError

PRE, POST = "60s", "10s"  # --pre and --post unless given
# The options of the black box alone, and those of recording the whole bus: each is refused in the other mode.
TRIGGER_ONLY = {"pre": "--pre", "post": "--post", "max_saves": "--max-saves"}
WHOLE_BUS_ONLY = {"split_size": "--split-size", "split_time": "--split-time", "print_lines": "--print",
                  "foxglove": "--foxglove"}
_MAX_SAVES = re.compile(r"\s*(\d+)\s*(?:/\s*h(?:our)?)?\s*")


def add_trigger_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--trigger", action="append", default=None, metavar="EXPR",
                   help="black box: keep the last --pre of the bus, and save [t - pre, t + post] around each time "
                        "EXPR fires, to the folder -o DIR/ (a filter such as 'present_temperature>70', "
                        "'sev>=error', 'id:3 latency>5ms', or a rule code such as S001); repeatable")
    p.add_argument("--pre", default=None, metavar="TIME",
                   help=f"with --trigger: the bus kept before a fire ({PRE}; --pre and --post at most 10min together)")
    p.add_argument("--post", default=None, metavar="TIME", help=f"with --trigger: the bus kept after a fire ({POST})")
    p.add_argument("--max-saves", default=None, metavar="N/h",
                   help="with --trigger: at most N windows saved in any hour (a storm of fires is counted, not saved)")


def check_mode(args: argparse.Namespace) -> None:
    """No option of one mode given to the other (one line): a --pre without --trigger would do nothing."""
    if args.trigger:
        for dest, option in WHOLE_BUS_ONLY.items():
            if getattr(args, dest, None):
                raise CliError(f"{option}: not with --trigger (the black box saves windows, not the whole bus)")
        return
    for dest, option in TRIGGER_ONLY.items():
        if getattr(args, dest, None) is not None:
            raise CliError(f"{option}: only with --trigger (it shapes the windows a trigger saves)")


def parse_max_saves(text: str | None) -> int | None:
    if text is None:
        return None
    m = _MAX_SAVES.fullmatch(text)
    if m is None or int(m.group(1)) < 1:
        raise CliError(f"--max-saves {text}: expected a count per hour, such as 6/h")
    return int(m.group(1))


def triggers_of(texts: list[str], codes: list[str]) -> list[Trigger]:
    try:
        return [parse_trigger(t, codes) for t in texts]
    except TriggerError as e:
        raise CliError(str(e)) from None

