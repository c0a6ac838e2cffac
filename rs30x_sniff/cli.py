"""The ``rs30x-sniff`` command line: builds the parser from rs30x_sniff.commands and maps errors to exit codes."""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import signal
import sys
import threading

from . import __version__
from .commands.common import CliError
from .io.captures import CaptureError
from .memmap import ModelError

# Subcommands, in the order `--help` lists them; each is a module rs30x_sniff.commands.<name>
# with add_parser(subparsers) and run(args) -> exit code.
COMMANDS = ("decode", "lint", "rules", "info", "convert", "export", "table", "record", "simulate", "monitor", "serve")


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


def _stop(signum: int, frame: object) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


def stop_on_hangup() -> dict:
    """SIGTERM and SIGHUP stop a command the way Ctrl-C does, so every output is finished or removed
    by the same code (a live capture and the monitor install their own handlers while they run).
    Returns the handlers replaced, for :func:`main` to put back."""
    saved: dict = {}
    if threading.current_thread() is not threading.main_thread():
        return saved
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None and signal.getsignal(sig) is signal.SIG_DFL:
            saved[sig] = signal.signal(sig, _stop)
    return saved


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "run", None):
        parser.print_help()
        return 2
    saved = stop_on_hangup()
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
    except OSError as e:
        # A disk that fills up, a file that vanishes: one line, never a traceback. (Outputs are written
        # beside their destination and renamed at the end, so nothing half-written is left.)
        where = f"{e.filename}: " if e.filename else ""
        print(f"rs30x-sniff: error: {where}{e.strerror or e}", file=sys.stderr)
        return 2
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
