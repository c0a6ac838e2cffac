"""A capture file opened as a source of first-byte-timed chunks: the one way every command reads a file."""

from __future__ import annotations

import itertools
from collections.abc import Callable

from .timebase import FIRST, SAMPLE_CHUNKS, TimedSource, TimeRef, judge
from . import foreign
from .captures import MCAP, TIMESTAMPED, read_capture, regular_file, stderr_warning
from .protocol import ChunkReader

RECORDED = TimeRef(FIRST, "each chunk's first byte, as the log records it")


def read_input(path: str, fmt: str | None = None, *, baud: int, time_ref: str | None = None,
               warn: Callable[[str], None] | None = stderr_warning,
               options: dict | None = None) -> ChunkReader:
    """The chunks of a capture file (or ``-``/a pipe), their times meaning each chunk's first byte.

    Timestamped hex from another tool's logger is often stamped at arrival (the end of the read):
    ``time_ref`` says so, or the content tells (rs30x_sniff.sources.timebase). A file is sampled by a read
    of its own first lines; a pipe cannot be read ahead, so its times are taken as first-byte times
    unless ``time_ref`` says otherwise. The source's ``time_ref`` says which reading and why.
    """
    src = read_capture(path, fmt, warn=warn, options=options)
    kind = getattr(src, "format", fmt)
    other = foreign.get(kind)
    if (options or {}).get("channel") is not None and not (other is not None and other.channels) and warn:
        warn(f"{path}: --channel is ignored: a {kind} capture holds one stream of bytes")
    if other is not None:
        # Another tool's format says what its times mean (a logic analyzer stamps each byte's start
        # bit, a serial logger each read's return); --time-ref still overrides it.
        if time_ref is None:
            return TimedSource(src, baud, other.time_ref,
                               TimeRef(other.time_ref, f"as the {other.name} format stamps them"))
        return TimedSource(src, baud, time_ref)
    if kind == TIMESTAMPED:
        if time_ref is None:
            judged = _judge_file(path, baud)
            return TimedSource(src, baud, judged.ref, judged)
        return TimedSource(src, baud, time_ref)
    if kind == MCAP:
        src.time_ref = RECORDED  # type: ignore[attr-defined]
    return src


def _judge_file(path: str, baud: int) -> TimeRef:
    if not regular_file(path):
        return TimeRef(FIRST, "each line's first byte (assumed: a pipe cannot be read ahead to tell; "
                              "--time-ref arrival if a logger stamped its reads)")
    sample = read_capture(path, TIMESTAMPED, warn=None)
    try:
        head = [c for c in itertools.islice(sample, SAMPLE_CHUNKS) if c[1] is not None]
    except Exception:  # noqa: BLE001 - a bad line: the main read reports it where it is
        head = []
    finally:
        sample.close()
    return judge(head, baud)
