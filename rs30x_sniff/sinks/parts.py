"""`record`'s output files: one MCAP, or numbered parts split by size or time, the oldest deleted under --keep."""

from __future__ import annotations

import math
import os
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from collections.abc import Callable

from ..language import LanguageError, parse_duration, say_duration, split_number, unit_scale
from ..decode.decoder import Step
from ..errors import CliError
from .mcap.writer import McapSink
from .outputs import STDOUT, check_output, write_error
from .pipeline import Sink

FLUSH_INTERVAL = 1.0  # an idle bus still gets its open MCAP chunk written within about a second

SIZE_UNITS = {"b": 1, "kb": 10**3, "mb": 10**6, "gb": 10**9, "tb": 10**12,
              "kib": 2**10, "mib": 2**20, "gib": 2**30, "tib": 2**40}


MIN_SPLIT_SECONDS = 1.0  # a part a second at most: the open part's chunks are written about once a second
MIN_SPLIT_MB = 0.01     # 10 kB: a part must hold more than its own header, metadata and summary (~3 kB)


def parse_span(option: str, text: str, *, least: float | None = None, most: float | None = None) -> float:
    """Seconds of a duration in language.py's grammar (``90``, ``500ms``, ``10min``, ``2h``, ``1d``), within
    [least, most] where given; a one-line error otherwise."""
    try:
        seconds = parse_duration(text, what=option)
    except LanguageError as e:
        raise CliError(str(e)) from None
    if least is not None and seconds < least:
        raise CliError(f"{option} {text}: must be at least {say_duration(least)}")
    if most is not None and seconds > most:
        raise CliError(f"{option} {text}: must be at most {say_duration(most)}")
    return seconds


@dataclass(frozen=True)
class Keep:
    """What ``--keep`` holds on to: parts younger than ``seconds``, or the newest up to ``bytes`` in all."""

    text: str
    seconds: float | None = None
    bytes: int | None = None


def parse_keep(text: str) -> Keep:
    """``--keep 24h`` (an age: any duration of language.py's grammar but a bare number) or ``--keep 5GB`` (a size:
    B, kB, MB, GB, TB, KiB, MiB, GiB, TiB)."""
    got = split_number(text)
    unit = got[1].lower() if got else ""
    if got is not None and unit in SIZE_UNITS:
        size = got[0] * SIZE_UNITS[unit]
        if not (math.isfinite(size) and size >= 1):
            raise CliError(f"--keep {text}: must be a finite, positive size")
        return Keep(text, bytes=int(size))
    if got is not None and unit and unit_scale(unit) is not None:
        return Keep(text, seconds=parse_span("--keep", text))
    raise CliError(f"--keep {text}: expected an age (24h, 7d, 90min) or a size (500MB, 5GB)")


def retire(paths: list[Path], keep: Keep, now: float, reserve: int = 0,
           say: Callable[[str], None] | None = None) -> list[Path]:
    """Delete the oldest of ``paths`` (oldest first) while they hold more than ``keep.bytes`` with ``reserve``
    bytes more to come, or are older than ``keep.seconds`` by their last write (epoch ``now``); the ones
    deleted (or already gone). The newest is never older than its last write, and what is kept is a suffix."""
    sizes: list[os.stat_result | None] = []  # None: already gone
    for p in paths:
        try:
            sizes.append(p.stat())
        except OSError:
            sizes.append(None)
    total = reserve + sum(st.st_size for st in sizes if st is not None)
    gone: list[Path] = []
    for p, st in zip(paths, sizes):
        if st is not None and not ((keep.bytes is not None and total > keep.bytes)
                                   or (keep.seconds is not None and st.st_mtime < now - keep.seconds)):
            break
        gone.append(p)
        if st is None:
            continue
        try:
            os.unlink(p)
        except FileNotFoundError:
            pass
        total -= st.st_size
        if say is not None:
            say(f"rs30x-sniff: removed {p} (--keep {keep.text})")
    return gone


class Parts(Sink):
    """The recording's files: one MCAP, or numbered parts (OUT-001.mcap, ...) started after ``split_bytes``
    or ``split_seconds``; each part is finalized before the next opens. With ``keep``, the closed parts past
    its age or total size are deleted, oldest first, as a new one opens and as the open one grows (the open
    part never), and the numbers go on after the highest part already there (a restarted recorder adds to its
    folder). A size to keep also splits a part at half that size, so the open part and the newest closed one
    fit under it.

    A part ends at the first byte past its span or size, never on a quiet bus: no part is without bytes. A gap
    (the port lost and found again) goes in the open part, and the bytes after it too, so the part that holds
    the gap holds the bytes on both sides of it (a reader makes it the same seam again).

    ``make(path or stream, part number)`` opens an McapSink; ``clock`` (monotonic seconds) times the parts,
    ``wall`` (epoch seconds) ages them; ``say`` gets a line per deleted part (None: silent)."""

    def __init__(self, path: str, make: Callable[[Any, int], McapSink], *, split_bytes: int | None = None,
                 split_seconds: float | None = None, keep: Keep | None = None, force: bool = False,
                 clock: Callable[[], float] = time.monotonic, wall: Callable[[], float] = time.time,
                 say: Callable[[str], None] | None = None) -> None:
        self.base = Path(path)
        self.make = make
        if keep is not None and keep.bytes is not None and (split_bytes is not None or split_seconds is not None):
            split_bytes = max(1, min(split_bytes or keep.bytes, keep.bytes // 2))
        self.split_bytes, self.split_seconds = split_bytes, split_seconds
        self.after_gap = False  # a gap was written to the open part: its next bytes go there too
        self.keep, self.force = keep, force
        self.clock, self.wall, self.say = clock, wall, say
        self.numbered = split_bytes is not None or split_seconds is not None
        self.closed: list[Path] = self._existing() if keep is not None else []  # oldest first
        self.index = int(self.closed[-1].stem.rsplit("-", 1)[1]) if self.closed else 0
        self.paths: list[str] = []  # the parts this run wrote
        self.removed = 0
        self.dirty = False
        self.last_flush = clock()
        self.sink: McapSink = self._open()

    # ---- parts ----------------------------------------------------------------------------------------------
    def part_path(self, index: int) -> Path:
        return self.base.with_name(f"{self.base.stem}-{index:03d}{self.base.suffix or '.mcap'}")

    def _existing(self) -> list[Path]:
        """Parts of an earlier run in the folder, by number (what --keep counts and deletes first)."""
        suffix = self.base.suffix or ".mcap"
        pattern = re.compile(re.escape(self.base.stem) + r"-(\d{3,})" + re.escape(suffix))
        found = []
        folder = self.base.parent
        for p in folder.iterdir() if folder.is_dir() else ():
            m = pattern.fullmatch(p.name)
            if m and p.is_file():
                found.append((int(m.group(1)), p))
        return [p for _, p in sorted(found)]

    def _open(self) -> McapSink:
        if str(self.base) == STDOUT:
            # Streamed as it is recorded: the MCAP writer only appends, so a pipe takes it as a file does.
            name, path = "stdout", None
        elif not self.numbered:
            name = path = str(self.base)
        else:
            self.index += 1
            name = path = str(self.part_path(self.index))
        if path is not None:
            # Written in place, not renamed at the end: a recorder killed outright still leaves its log
            # under the name asked for (readable up to its last chunk). So the check comes first.
            check_output(path, self.force)
        try:
            sink = self.make(sys.stdout.buffer if path is None else path, self.index)
        except OSError as e:
            raise write_error(name, e, "nothing recorded") from None
        self.paths.append(name)
        self.opened = self.clock()
        return sink

    def _rotate(self) -> None:
        self.sink.finish()  # a part always ends finalized
        self.closed.append(Path(self.paths[-1]))
        self.sink = self._open()
        if self.keep is not None:
            self._retire()

    def _retire(self) -> None:
        """Delete closed parts past --keep, oldest first; the open part counts at the size it will reach
        (--split-size), so the folder stays under the limit until the next part opens."""
        assert self.keep is not None
        reserve = max(self.sink.bytes_written, self.split_bytes or 0)
        gone = retire(self.closed, self.keep, self.wall(), reserve, self.say)
        self.removed += len(gone)
        self.closed = [p for p in self.closed if p not in gone]

    # ---- as a sink -----------------------------------------------------------------------------------------
    def _due(self) -> bool:
        return self.numbered and ((self.split_bytes is not None and self.sink.bytes_written >= self.split_bytes)
                                  or (self.split_seconds is not None
                                      and self.clock() - self.opened >= self.split_seconds))

    def chunk(self, data: bytes, t: float | None, sender: str | None = None, error: str | None = None) -> None:
        if data and not self.after_gap and self._due():
            self._rotate()
        self.after_gap = self.after_gap and not data
        # Raw bytes go to the file before decoding: nothing received is ever lost to a decoder error.
        self.sink.chunk(data, t, sender, error)
        self.dirty = self.dirty or bool(data)
        self.idle()

    takes_blocks = True  # the MCAP sink takes a Block as it is

    def chunk_group(self, chunks: list[tuple[bytes, float | None]]) -> None:
        """A columnar group's chunks (a port's gather), in order with their records: a part due opens before the
        group (never mid-group, nor at the first bytes after a gap, which stay with it)."""
        if chunks and not self.after_gap and self._due():
            self._rotate()
        self.after_gap = self.after_gap and not chunks
        self.sink.chunk_group(chunks)
        self.dirty = True
        self.idle()

    def batch(self, step: Step) -> None:
        self.sink.batch(step)

    def gap(self, t: float, lost_at: float | None, note: str) -> None:
        """A gap in the port's bytes (rs30x_sniff.sources.reconnect): in the open part, with the bytes after it."""
        self.sink.gap(t, lost_at, note)
        self.after_gap = True

    def idle(self) -> None:
        now = self.clock()
        if self.dirty and now - self.last_flush >= FLUSH_INTERVAL:
            self.sink.flush()
            self.last_flush, self.dirty = now, False
            if self.keep is not None and self.keep.bytes is not None and self.closed:
                self._retire()  # the open part grew: the folder stays under the size to keep

    def close(self) -> None:
        self.sink.finish()

    def describe(self) -> str:
        """Where the recording went, short even after a week of parts."""
        if len(self.paths) <= 3:
            where = ", ".join(self.paths)
        else:
            where = f"{len(self.paths)} parts, {self.paths[0]} to {self.paths[-1]}"
        if self.removed:
            where += f" ({self.removed} older part{'s' if self.removed != 1 else ''} removed by --keep)"
        return where
