"""`record --trigger`: the black box's options, its folder, and the writing of each saved window as an MCAP."""

from __future__ import annotations

import argparse
import os
import re
import signal
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from collections.abc import Callable

from ..decode.decoder import Decoder
from ..lint import Linter
from ..protocol.chunks import SourceGap
from ..sinks.blackbox import Trigger, TriggerError, Window, parse_trigger, wall_time
from ..sinks.mcap.writer import McapSink
from ..sinks.pipeline import drive
from ..sources.serial_tap import STOP_SIGNALS
from .common import CliError
from ..sinks.parts import Keep, retire

PRE, POST = "60s", "10s"  # --pre and --post unless given
# The options of the black box alone, and those of recording the whole bus: each is refused in the other mode.
TRIGGER_ONLY = {"pre": "--pre", "post": "--post", "max_saves": "--max-saves"}
WHOLE_BUS_ONLY = {"split_size": "--split-size", "split_time": "--split-time", "print_lines": "--print",
                  "foxglove": "--foxglove"}
WINDOW_FILE = re.compile(r"\d{4}-\d\d-\d\dT\d\d-\d\d-\d\d\.\d{3}Z-.+\.mcap")
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


def window_folder(path: str, make: bool = False) -> Path:
    """The black box's folder: -o DIR/, checked (and with ``make``, made if missing: once the port is open, so
    a failed start leaves nothing behind). Saved windows are never replaced, so --force is not needed."""
    if path == "-":
        raise CliError("--trigger: windows are files in a folder: give -o DIR/, not - (stdout)")
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise CliError(f"{path}: with --trigger, -o names a folder for the saved windows (DIR/), not a file")
    if not folder.exists():
        if not path.endswith(("/", os.sep)):
            raise CliError(f"{path}: with --trigger, -o names a folder: end it with / to have it made")
        if not make:
            return folder
        try:
            folder.mkdir(parents=True)
        except OSError as e:
            raise CliError(f"{path}: cannot make the folder: {e.strerror or e}") from None
    return folder


def saved_windows(folder: Path) -> list[Path]:
    """The windows in ``folder``, oldest first (their names begin with the wall time of the first fire)."""
    return sorted(p for p in folder.iterdir() if WINDOW_FILE.fullmatch(p.name) and p.is_file())


def window_writer(folder: Path, *, opts: Any, lint_config: Any, source: str, metadata: Callable[[], dict],
                  keep: Keep | None, now: Callable[[], float], say: Callable[[str], None]) -> Callable:
    """The BlackBox's ``save``: the window's chunks decoded and linted afresh into a complete MCAP (raw bytes,
    decoded channels, findings, stats), written under a temporary name and renamed into ``folder``, then the
    oldest windows past ``keep`` deleted."""

    def save(chunks: list, w: Window, name: str) -> None:
        path = folder / name
        n = 2
        while path.exists():
            path = folder / f"{name[:-5]}-{n}.mcap"
            n += 1
        tmp = folder / f".{path.name}.part"
        meta = dict(metadata())
        meta.update({
            "trigger": w.first.text, "fired_at": _iso(w.first_t), "fires": str(len(w.fires)),
            "triggers_fired": ", ".join(sorted({text for _, text in w.fires})),
            "window_start": _iso(w.start), "window_end": _iso(w.end),
        })
        with held_signals():  # a stop asked for during the save comes after it: the window is written whole
            sink = McapSink(str(tmp), source=source, baud=opts.baud, time_base="wall", models=opts.models,
                            extra_metadata=meta)
            try:
                drive(chunks, Decoder(opts, Linter(lint_config), columnar=True), sink)
                os.replace(tmp, path)
            except BaseException:
                sink.finish()
                try:
                    os.unlink(tmp)
                except OSError:
                    pass
                raise
        size = path.stat().st_size
        say(f"rs30x-sniff: saved {path}: {w.first.text} at {_iso(w.first_t)}"
            f"{'' if len(w.fires) == 1 else f' ({len(w.fires)} fires)'}, {held_span(chunks, opts.baud)}, "
            f"{size:,} bytes")
        if keep is not None:
            others = [p for p in saved_windows(folder) if p != path]
            retire(others, keep, now(), size, say)

    return save


@contextmanager
def held_signals():
    """SIGINT, SIGTERM and SIGHUP wait until the block is done, then go to the handlers that were in place (in the
    main thread; elsewhere nothing is held)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []
    saved = {sig: signal.signal(sig, lambda signum, frame: came.append(signum)) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)
        for signum in came[:1]:
            handler = saved[signum]
            if callable(handler):
                handler(signum, None)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)


def held_span(chunks: list, baud: int) -> str:
    """What a window's file holds, as its line says it: from its first byte to the end of its last (the bus
    before and after it was quiet, so [start, end] asked for may be longer), and the port's losses in it."""
    timed = [c for c in chunks if c[0] and c[1] is not None]
    if not timed:
        return "no bytes of the bus"
    last = timed[-1]
    span = last[1] + len(last[0]) * 10 / baud - timed[0][1]  # 8N1: ten bit times a byte
    gaps = [c for c in chunks if type(c) is SourceGap and timed[0][1] <= c[1]]
    if not gaps:
        return f"{span:.1f} s of the bus"
    # The time without the port is no time of the bus: left out, and said.
    gone = sum(g[1] - g.lost_at for g in gaps if g.lost_at is not None and g.lost_at <= g[1])
    return (f"{max(0.0, span - gone):.1f} s of the bus (and {gone:.1f} s without the port: lost "
            f"{len(gaps)} time{'s' if len(gaps) != 1 else ''})")


_iso = wall_time  # the window's times in its metadata and lines, as a person reads them
