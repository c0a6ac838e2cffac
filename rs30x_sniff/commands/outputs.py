"""Output files that never replace an input or an existing file unasked, and never stay half-written."""

from __future__ import annotations

import argparse
import os
import stat
import sys
import tempfile
from contextlib import contextmanager
from typing import IO, Iterable, Iterator

from ..io.captures import BINARY, TIMESTAMPED
from .common import CliError

STDOUT = "-"


def add_output_options(p: argparse.ArgumentParser, *, required: bool = False, what: str = "OUT") -> None:
    """-o/--output (``-`` is stdout) and --force, the same for every command that writes a file."""
    p.add_argument("-o", "--output", required=required, metavar=what,
                   help="write to OUT (- for stdout)" if required else "write to OUT instead of stdout")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")


def check_output(path: str, force: bool, inputs: tuple[str, ...] = ()) -> None:
    """Refuse a directory, any input, and (without --force) an existing file; ``-`` is stdout."""
    if path == STDOUT:
        return
    if os.path.isdir(path):
        raise CliError(f"{path}: is a directory")
    if not os.path.lexists(path) or _is_special(path):
        return  # a device or a pipe (/dev/null, a FIFO) is written to, never replaced
    for i in inputs:
        if i and i != STDOUT:
            try:
                same = os.path.samefile(i, path)
            except OSError:
                same = False
            if same:
                raise CliError(f"{path}: is the input file; write to another file")
    if not force:
        raise CliError(f"{path}: already exists (use --force to replace it)")


@contextmanager
def output_path(path: str, *, force: bool = False, inputs: tuple[str, ...] = (),
                keep_on_stop: bool = False) -> Iterator[str]:
    """A temporary file beside ``path`` to write; it replaces ``path`` only when the block ends well.

    On an error nothing is left behind (the destination keeps whatever it held). A stop by the user
    (Ctrl-C, SIGTERM, SIGHUP) keeps what was written when ``keep_on_stop``: a finalized MCAP log of a
    stopped conversion is data, not a failed run.
    """
    check_output(path, force, inputs)
    if _is_special(path):
        # A character device or FIFO (/dev/null, /dev/stdout, a named pipe) is written in place: a
        # temporary file renamed over it would replace the device node itself.
        yield path
        return
    folder = os.path.dirname(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{os.path.basename(path)}.", suffix=".part")
    except OSError as e:
        raise CliError(f"{path}: cannot write: {e.strerror}") from None
    os.close(fd)
    try:
        yield tmp
    except KeyboardInterrupt:
        if keep_on_stop:
            os.replace(tmp, path)
        else:
            _discard(tmp)
        raise
    except BaseException:
        _discard(tmp)
        raise
    try:
        os.replace(tmp, path)
    except OSError as e:
        _discard(tmp)
        raise CliError(f"{path}: cannot write: {e.strerror}") from None


@contextmanager
def output_stream(path: str | None, *, force: bool = False, inputs: tuple[str, ...] = ()) -> Iterator[IO[str]]:
    """stdout (no path, or ``-``), or a text file written through :func:`output_path`."""
    if not path or path == STDOUT:
        yield sys.stdout
        return
    with output_path(path, force=force, inputs=inputs) as tmp:
        try:
            f = open(tmp, "w", encoding="utf-8")
        except OSError as e:
            raise CliError(f"{path}: cannot write: {e.strerror}") from None
        with f:
            yield f


def write_stream(out: IO[bytes], chunks: Iterable[tuple[bytes, float | None]], fmt: str) -> int:
    """Write chunks to a binary stream (stdout) as a capture of ``fmt``; returns the bytes written."""
    total = 0
    for data, t in chunks:
        if not data:
            continue
        if fmt == BINARY:
            out.write(data)
        else:
            hexs = data.hex(" ").upper()
            out.write((f"{(t or 0.0):.6f} {hexs}\n" if fmt == TIMESTAMPED else hexs + "\n").encode())
        total += len(data)
    out.flush()
    return total


def report_end(summary: str, stopped: str | None) -> int:
    """The last line of a command that wrote a file: its summary, and how it was stopped (exit 130)."""
    if stopped:
        print(f"rs30x-sniff: stopped ({stopped}): {summary}", file=sys.stderr)
        return 130
    print(summary, file=sys.stderr)
    return 0


def _is_special(path: str) -> bool:
    """Whether ``path`` exists and is neither a regular file nor a directory (a device, a FIFO, a socket)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def _discard(tmp: str) -> None:
    try:
        os.unlink(tmp)
    except OSError:
        pass
