"""The ``rs30x-sniff`` command line: builds the parser from rs30x_sniff.commands and maps errors to exit codes."""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys

from . import __version__
from .commands.common import CliError
from .io.captures import CaptureError
from .memmap import ModelError

# Subcommands, in the order `--help` lists them; each is a module rs30x_sniff.commands.<name>
# with add_parser(subparsers) and run(args) -> exit code.
COMMANDS = ("decode", "lint", "rules", "info", "convert", "export", "record", "simulate", "monitor")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rs30x-sniff",
        description="Protocol analyzer and bus logger for the Futaba RS30x (RS303MR/RS304MD) servo bus.",
    )
    parser.add_argument("--version", action="version", version=f"rs30x-sniff {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        modname = f"{__package__}.commands.{name}"
        if importlib.util.find_spec(modname) is None:
            continue
        importlib.import_module(modname).add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "run", None):
        parser.print_help()
        return 2
    try:
        return int(args.run(args) or 0)
    except (CliError, CaptureError, ModelError) as e:
        print(f"rs30x-sniff: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # The reader of our output went away (e.g. `| head`): not an error for a CLI.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
