"""The ``rs30x-sniff`` command line: builds the parser from rs30x_sniff.commands and maps errors to exit codes."""

from __future__ import annotations

import argparse
import errno
import gc
import importlib
import math
import os
import re
import signal
import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any, NoReturn

from . import language
from .errors import CliError
from .version import __version__

# Subcommands, in the order `--help` lists them, with the one line `--help` gives each; each is a module
# rs30x_sniff.commands.<name> with add_parser(subparsers) and run(args) -> exit code. A command line imports the
# module of its own command only (issue 35: start-up), so the top-level --help reads these lines here; each equals
# the help= of its module's add_parser (tests/commands/test_startup.py).
SUMMARIES = {
    "decode": "decode a capture into named, scaled fields",
    "lint": "check captures against the rule catalog (exit 1 on findings)",
    "rules": "list the lint rules, or show one rule's documentation",
    "info": "summarize a capture: duration, packets, polls, latencies, bus load",
    "diff": "compare two captures: poll rates, latencies, missing replies, findings, load",
    "convert": "convert a capture into an MCAP log for Foxglove or a pcapng for Wireshark",
    "export": "write the raw bytes of an MCAP log back out as a capture",
    "table": "servo states, transactions or findings as CSV or Parquet",
    "record": "record a serial port to MCAP (a passive tap; never writes to the port)",
    "simulate": "a simulated servo bus: scenarios to a capture file or a port",
    "monitor": "watch the bus in a terminal UI",
    "serve": "stream the bus live to Foxglove (WebSocket server)",
    "plugin": "write a plug-in for sigrok/PulseView, Saleae Logic 2 or Wireshark",
}
COMMANDS = tuple(SUMMARIES)
# BLAS thread pools numpy would start at import: a command never multiplies large matrices, and the idle pool's
# threads cost 70-80 ms of CPU at start-up on another core (issue 35). Set unless the user set them.
ONE_THREAD = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


# The largest value of each command-only numeric option, checked for every command here (the settings'
# options, --gap-bytes, --reply-timeout and --baud, are bounded in settings.KEYS, from the command line and a
# config file alike). Each is far beyond any real use, so --help does not say it (it would read as a limit
# of the bus); a typo such as 1e308 gets one line, never an OverflowError deep in a command. An option with
# a real range says it in its own help (`decode --id`: 1-127, `simulate --baud`: table 4.7).
OPTION_MAX: dict[str, float] = {
    "--duration": 366 * 86400,  # seconds: a year of capture
    "--split-size": 1_000_000,  # MB: a terabyte per file
    "--speed": 1_000_000,       # replay speed: a day of capture in a tenth of a second
    "--history": 100_000_000,   # records the monitor keeps
    "--jobs": 1024,             # files linted at once
    "--seed": 2**64 - 1,        # the simulator's random seed
    "--baud": 1_000_000,        # simulate: bit/s (it takes the rates of table 4.7 only)
}
NUMBERS = (int, float)  # and options.duration: the types of a number option (--baud's own type also takes "auto")
ERROR = "rs30x-sniff: error: "  # the one prefix of an error line, argparse's own included
# Older spellings of a command, read as the one command they name (README.md, "One grammar"): `export --table KIND` is
# `table --of KIND`.
ALIASES = {("export", "--table"): ("table", "--of")}


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The whole parser, every command's module imported; given the command line ``argv``, a parser for it:
    the module of its command only (none for --help or --version), every other command a name and its line
    (SUMMARIES) for the top-level --help and the list of choices."""
    chosen = None if argv is None else chosen_command(argv)
    parser = CommandParser(
        prog="rs30x-sniff",
        description="Protocol analyzer and bus logger for the Futaba RS30x (RS303MR/RS304MD) servo bus.",
    )
    parser.add_argument("--version", action="version", version=f"rs30x-sniff {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=CommandParser)
    for name in COMMANDS:
        modname = f"{__package__}.commands.{name}"
        if argv is not None and name != chosen:
            sub.add_parser(name, help=SUMMARIES[name])  # never parsed: the command line names another
        elif spec_of(modname) is not None:
            importlib.import_module(modname).add_parser(sub)
    parser.commands = sub.choices  # name -> CommandParser
    return parser


def spec_of(module: str) -> object:
    """importlib's spec of ``module``, None where it is missing (importlib.util: imported for a command only)."""
    import importlib.util
    return importlib.util.find_spec(module)


def chosen_command(argv: list[str]) -> str | None:
    """The command ``argv`` names: its first word that is no option (the top level's own options take no value)."""
    word = next((a for a in argv if not a.startswith("-")), None)
    return word if word in SUMMARIES else None


class CommandParser(argparse.ArgumentParser):
    """A command's parser: it keeps each bounded option it is given (``numbers``: option, dest), so
    :func:`check_bounds` finds them without a list of its own, and says a usage error as one line with the
    one error prefix."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.numbers: list[tuple[str, str]] = []
        self.commands: Mapping[str, argparse.ArgumentParser] = {}  # the root's: name -> the command's parser
        self.set_defaults(command_parser=self)  # for main, to check the numbers of the command given

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:
        action = super().add_argument(*args, **kwargs)
        if is_number(kwargs.get("type")) and args and str(args[0]).startswith("-"):
            self.numbers.append((args[-1], action.dest))
        return action

    def error(self, message: str) -> NoReturn:
        # argparse says "argument --x: ..."; the option's name is enough ("--id 999: not a servo ID" where the
        # option's type names the value, as the commands' own checks do). The usage is a --help away.
        message = re.sub(r"^argument ([^:/ ]*)(?:/[^:]*)?: (?:([^: ]+): )?",
                         lambda m: f"{m[1]} {m[2]}: " if m[2] else f"{m[1]}: ", message)
        command = self.prog.removeprefix("rs30x-sniff").strip()
        where = f"{command}: " if command else ""
        self.exit(2, f"{ERROR}{where}{message} (see {self.prog} --help)\n")


def is_number(kind: object) -> bool:
    """Whether an option's type reads a number (NUMBERS, or a duration)."""
    if kind is None:
        return False
    from .commands.options import duration  # here: the command's module has imported it already
    return kind in NUMBERS or kind is duration


def user_errors() -> tuple[type[Exception], ...]:
    """The errors :func:`main` says in one line: CliError, and a capture's or a memory map's error where its
    module is loaded (one that was never imported raised nothing), so that --help loads neither."""
    found: list[type[Exception]] = [CliError]
    for module, name in (("rs30x_sniff.sources.base", "CaptureError"), ("rs30x_sniff.protocol.memmap", "ModelError")):
        loaded = sys.modules.get(module)
        if loaded is not None:
            found.append(getattr(loaded, name))
    return tuple(found)


def say_deprecations() -> None:
    """commands.common's, where a note waits: `plugin` and `rules` import none of the commands' common code."""
    if language.deprecation_notes:
        from .commands.common import say_deprecations as say
        say()


def one_thread_blas() -> None:
    """ONE_THREAD set to 1 where the user set nothing, before numpy is imported (build_parser imports it)."""
    for name in ONE_THREAD:
        os.environ.setdefault(name, "1")


# Whether modules_kept froze the collector's objects: once per process.
_frozen = {"done": False}


@contextmanager
def modules_kept(frozen: bool) -> Iterator[None]:
    """The command's modules imported with the cyclic collector off, and (``frozen``: a process's own command
    line) what they made kept out of its later passes: it all lives until the process ends, yet numpy's and ours
    cost 60-odd collections, 15 ms of CPU at start-up (issue 35), and each later full pass would walk it again."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if frozen and not _frozen["done"]:
            # Once, and never for a library caller's main(argv): cyclic garbage of the moment is never freed.
            _frozen["done"] = True
            gc.freeze()
        if was:
            gc.enable()


def check_bounds(command: CommandParser, args: argparse.Namespace) -> None:
    """Each command-only number within OPTION_MAX (the settings check their own keys)."""
    for option, dest in command.numbers:
        limit = OPTION_MAX.get(option)
        values = getattr(args, dest, None)
        if limit is None or values is None:
            continue
        for v in values if isinstance(values, list) else (values,):
            # NaN and infinity are left to the command's own check, which says what the number must be.
            if isinstance(v, (int, float)) and math.isfinite(v) and v > limit:  # --baud auto: a word
                raise CliError(f"{option} {v:g}: must be at most {limit:g}")


def _stop(signum: int, frame: object) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


def stop_on_hangup() -> dict:
    """SIGTERM and SIGHUP stop a command the way Ctrl-C does, so every output is finished or removed
    by the same code (a live capture and the monitor install their own handlers while they run).
    Returns the handlers replaced, for :func:`main` to put back."""
    saved: dict = {}
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None and signal.getsignal(sig) is signal.SIG_DFL:
            try:
                saved[sig] = signal.signal(sig, _stop)
            except ValueError:  # not the main thread (a library caller's): it may set no handler
                break
    return saved


def interrupt_by_default() -> dict:
    """Ctrl-C (SIGINT) stops every command, whatever it inherited: a shell script starts a background
    job with SIGINT ignored, and Python keeps an ignored signal ignored (then `kill -INT` would not stop
    `serve`). The monitor and a live capture put their own handlers in while they run. Returns the
    handler replaced, for :func:`main` to put back."""
    try:
        return {signal.SIGINT: signal.signal(signal.SIGINT, signal.default_int_handler)}
    except ValueError:  # not the main thread: it may set no handler (threading would cost each start-up 1 ms)
        return {}


def _reader_gone() -> int:
    """The reader of our output went away (`| head`): not an error for a CLI. stdout is pointed at
    /dev/null, so the output still buffered is not written again (and fails again) at exit."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass
    return 0


def aliased(argv: list[str]) -> list[str]:
    """``argv`` with an older spelling of a command (:data:`ALIASES`) written as the command it names."""
    if not argv:
        return argv
    for (command, option), (to_command, to_option) in ALIASES.items():
        if argv[0] == command and any(a == option or a.startswith(option + "=") for a in argv[1:]):
            return [to_command, *(to_option + a[len(option):] if a == option or a.startswith(option + "=") else a
                                  for a in argv[1:])]
    return argv


def main(argv: list[str] | None = None) -> int:
    one_thread_blas()
    words = aliased(list(sys.argv[1:] if argv is None else argv))
    with modules_kept(frozen=argv is None):
        parser = build_parser(words)
    language.deprecation_notes.clear()  # this command's notes, not a former one's (a library caller's main)
    try:
        args = parser.parse_args(words)
    except SystemExit as e:  # a usage error (said in one line by CommandParser.error), --help or --version
        return e.code if isinstance(e.code, int) else 2
    if not getattr(args, "run", None):
        parser.print_help()
        return 2
    from . import allocator  # here: --help and a usage error need none of it
    allocator.keep_large_buffers()
    saved = {**interrupt_by_default(), **stop_on_hangup()}
    try:
        check_bounds(args.command_parser, args)
        code = int(args.run(args) or 0)
        say_deprecations()  # an old spelling read after the config (a --keep 5m): said once the command ends
        if sys.stdout is not None:
            sys.stdout.flush()  # here, not at exit: a reader gone or a full disk is reported like the rest
        return code
    except user_errors() as e:
        say_deprecations()
        print(f"{ERROR}{e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as e:
        # A command that keeps what it read says so in its own end line; one stopped before that (still waiting
        # for its input's first byte) still ends with one, as every other way out does.
        print(f"rs30x-sniff: stopped ({e or 'Ctrl-C'})", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return _reader_gone()
    except SystemExit as e:
        # A library that meets the closed pipe first ends the program itself (rich's console exits 1).
        if isinstance(e.__context__, BrokenPipeError):
            return _reader_gone()
        raise
    except OSError as e:
        # A file that vanishes, a disk that fills up under stdout: one line, never a traceback. (A
        # command's output files report their own write errors, with what was saved.)
        name = e.filename or ("stdout" if e.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG) else None)
        where = f"{name}: " if name else ""
        print(f"{ERROR}{where}{e.strerror or e}", file=sys.stderr)
        return 2
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
