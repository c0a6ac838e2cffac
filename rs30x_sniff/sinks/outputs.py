"""Output files that never replace an input or an existing file unasked, and never stay half-written."""

from __future__ import annotations

import errno
import os
import shutil
import stat
import sys
from contextlib import contextmanager
from typing import IO
from collections.abc import Callable, Iterable, Iterator

from ..sources.captures import BINARY, TIMESTAMPED
from ..errors import CliError

STDOUT = "-"


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


# Errors that only writing gives: an output hit them whatever else was going on.
_WRITE_ERRNOS = frozenset(getattr(errno, n) for n in ("ENOSPC", "EDQUOT", "EFBIG", "EROFS") if hasattr(errno, n))


class WriteError(CliError):
    """An output could not be written: one line naming it, how much of it was saved and in what state."""


def write_error(name: str, error: OSError, saved: str) -> WriteError:
    """The one line for a failed write to ``name`` (``saved``: what is left of the output, and in what state)."""
    why = error.strerror or str(error) or type(error).__name__
    return WriteError(f"{name}: cannot write: {why}; {saved}")


def is_write_error(error: OSError, *paths: str) -> bool:
    """Whether ``error`` came from writing (a full disk, a quota, a read-only file system) or names an output."""
    return error.errno in _WRITE_ERRNOS or (error.filename is not None and error.filename in paths)


def _create(folder: str, name: str, like: str | None) -> tuple[int, str]:
    """A new file in ``folder``, with the mode ``open()`` would give it: 0666 less the umask (os.open applies
    it), or the mode of ``like``, the file it will replace (as writing over it in place would keep)."""
    while True:
        tmp = os.path.join(folder, f".{name}.{os.urandom(4).hex()}.part")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666)
        except FileExistsError:
            continue
        break
    if like is not None:
        try:
            os.fchmod(fd, stat.S_IMODE(os.stat(like).st_mode))
        except OSError:
            pass  # the umask's mode, then
    return fd, tmp


@contextmanager
def output_path(path: str, *, force: bool = False, inputs: tuple[str, ...] = (),
                keep_on_stop: bool | Callable[[], bool] = False) -> Iterator[str]:
    """A temporary file to write, beside ``path``; it replaces ``path`` only when the block ends well.

    On an error nothing is left behind (the destination keeps whatever it held); a failed write (a full
    disk) is reported in one line that names ``path``. A stop by the user (Ctrl-C, SIGTERM, SIGHUP) keeps
    what was written when ``keep_on_stop`` (or when it returns True, asked at the stop: a stop before the
    writer began leaves nothing): a finalized MCAP log of a stopped conversion is data, not a failed run.
    ``-`` is stdout: the file is made in the temporary folder and copied to stdout when the block ends (a
    writer that can stream is better given :func:`output_binary`); never a file named ``-``.
    """
    check_output(path, force, inputs)
    if _is_special(path):
        # A character device or FIFO (/dev/null, /dev/full, a named pipe) is written in place: a
        # temporary file renamed over it would replace the device node itself.
        try:
            yield path
        except OSError as e:
            if is_write_error(e, path):
                raise write_error(path, e, f"{path} got an incomplete output") from None
            raise
        return
    to_stdout = path == STDOUT
    name = "stdout" if to_stdout else path
    if to_stdout:
        import tempfile  # here: only a whole file copied to stdout needs it (2 ms of every start-up)

        folder = tempfile.gettempdir()
    else:
        folder = os.path.dirname(os.path.abspath(path))
    replaced = path if not to_stdout and os.path.isfile(path) else None
    try:
        fd, tmp = _create(folder, "rs30x-sniff" if to_stdout else os.path.basename(path), replaced)
    except OSError as e:
        raise write_error(name, e, "nothing written") from None
    os.close(fd)
    unchanged = ("nothing written to stdout" if to_stdout else
                 f"nothing saved ({path} {'unchanged' if replaced else 'not created'})")
    try:
        yield tmp
    except KeyboardInterrupt:
        if keep_on_stop() if callable(keep_on_stop) else keep_on_stop:
            _finish(tmp, path, name, unchanged)
        else:
            _discard(tmp)
        raise
    except OSError as e:
        size = _size(tmp)
        _discard(tmp)
        if is_write_error(e, tmp):
            raise write_error(name, e, f"{size:,} bytes written, then removed: {unchanged}") from None
        raise
    except BaseException:
        _discard(tmp)
        raise
    _finish(tmp, path, name, unchanged)


def _finish(tmp: str, path: str, name: str, unchanged: str) -> None:
    """Put the finished temporary file in place: renamed over ``path``, or copied to stdout."""
    try:
        if path == STDOUT:
            out = sys.stdout.buffer
            sys.stdout.flush()  # text already printed goes first
            with open(tmp, "rb") as f:
                shutil.copyfileobj(f, out, 1 << 20)
            out.flush()
        else:
            os.replace(tmp, path)
    except BrokenPipeError:
        raise  # the reader went away: not an error (the CLI exits 0)
    except OSError as e:
        raise write_error(name, e, "the output is incomplete" if path == STDOUT else unchanged) from None
    finally:
        _discard(tmp)


@contextmanager
def output_binary(path: str, *, force: bool = False, inputs: tuple[str, ...] = (),
                  keep_on_stop: bool | Callable[[], bool] = False) -> Iterator[IO[bytes]]:
    """A binary file object to write OUT through, for a writer that only appends: stdout itself for
    ``-`` (streamed as it is written), else a file of :func:`output_path`."""
    if path != STDOUT:
        with output_path(path, force=force, inputs=inputs, keep_on_stop=keep_on_stop) as tmp:
            with open(tmp, "wb") as f:
                yield f
        return
    sys.stdout.flush()
    out = sys.stdout.buffer
    try:
        yield out
        out.flush()
    except BrokenPipeError:
        raise
    except OSError as e:
        if is_write_error(e) or e.filename is None:
            raise write_error("stdout", e, "the output is incomplete") from None
        raise


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
            raise write_error(path, e, "nothing saved") from None
        with f:
            yield f


def write_stream(out: IO[bytes], chunks: Iterable[tuple[bytes, float | None]], fmt: str) -> int:
    """Write chunks to a binary stream (stdout) as a capture of ``fmt``; returns the bytes written."""
    total = 0
    try:
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
    except BrokenPipeError:
        raise  # the reader went away: not an error (the CLI exits 0)
    except OSError as e:
        if e.filename is not None and not is_write_error(e):
            raise  # the input's error, not stdout's
        raise write_error("stdout", e, f"the output is incomplete ({total:,} capture bytes before the error)") from None
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


def _size(path: str) -> int:
    try:
        return os.path.getsize(path)
    except OSError:
        return 0


def _discard(tmp: str) -> None:
    try:
        os.unlink(tmp)
    except OSError:
        pass
