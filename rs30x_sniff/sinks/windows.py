"""`record --trigger`'s saved windows: their folder, each a complete MCAP written afresh, the oldest retired."""

from __future__ import annotations

import os
import re
import signal
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from collections.abc import Callable

from ..decode.decoder import Decoder
from ..errors import CliError
from ..lint import Linter
from ..protocol.chunks import SourceGap
from ..sources.serial_tap import stop_signals
from .blackbox import Window, wall_time
from .mcap.writer import McapSink
from .parts import Keep, retire
from .pipeline import drive

WINDOW_FILE = re.compile(r"\d{4}-\d\d-\d\dT\d\d-\d\d-\d\d\.\d{3}Z-.+\.mcap")


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
                drive(chunks, Decoder(opts, Linter(lint_config, keep_findings=False), columnar=True), sink)
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
    saved = {sig: signal.signal(sig, lambda signum, frame: came.append(signum)) for sig in stop_signals()}
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
