"""What every capture reader shares: the error and the warning it reports, the default warning line, and
how a capture file is opened (rs30x_sniff.sources.captures and the MCAP reader both use them)."""

from __future__ import annotations

import os
import stat
import sys
from dataclasses import dataclass
from typing import BinaryIO


class CaptureError(ValueError):
    """A capture cannot be read; the message is one line naming the file (and the line, for text).

    ``line`` and ``column`` (1-based, or None) say where in a text capture the problem is.
    """

    def __init__(self, message: str, *, line: int | None = None, column: int | None = None) -> None:
        super().__init__(message)
        self.line = line
        self.column = column


@dataclass(frozen=True)
class CaptureWarning:
    """A problem the reader worked around: the capture is still read, up to ``offset`` bytes into the file.

    ``message`` is one line naming the file; ``offset`` is the file position where reading stopped
    (None if not one place) and ``lost_bytes`` how much of the file was not read.
    """

    path: str
    message: str
    offset: int | None = None
    lost_bytes: int = 0

    def __str__(self) -> str:
        return self.message


def stderr_warning(text: str) -> None:
    """The default ``warn`` callback: one line on stderr."""
    print(f"rs30x-sniff: warning: {text}", file=sys.stderr)


# Where stdin stood when first opened as a file: every later open reads it from there again.
_STDIN_START: list[int] = []


def open_capture(path: str) -> BinaryIO:
    """Open a capture for binary reading; failure is a one-line CaptureError naming the file.

    ``-`` is a copy of standard input's descriptor, at the offset stdin had when first opened here (so
    ``decode - < x.mcap`` can read and seek it as often as a file; a pipe is read once by its caller).
    """
    if path == "-":
        return _open_stdin()
    try:
        return open(path, "rb")
    except FileNotFoundError:
        if str(path).startswith("/dev/"):
            raise CaptureError(f"{path}: no such port (is the adapter plugged in?)") from None
        raise CaptureError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise CaptureError(f"{path}: is a directory, not a capture") from None
    except OSError as e:
        raise CaptureError(f"{path}: cannot read: {e.strerror}") from None


def _open_stdin() -> BinaryIO:
    # A file on stdin is opened anew (/proc/self/fd/0: a file position of its own), so that two readers of it
    # (a sample read ahead, then the capture) do not move each other's place as copies of one descriptor would.
    try:
        fd = sys.stdin.fileno()
        regular = stat.S_ISREG(os.fstat(fd).st_mode)
        if regular and not _STDIN_START:
            _STDIN_START.append(os.lseek(fd, 0, os.SEEK_CUR))
        own = f"/proc/self/fd/{fd}"
        f = open(own, "rb") if regular and os.path.exists(own) else os.fdopen(os.dup(fd), "rb")
    except (OSError, ValueError, AttributeError) as e:
        raise CaptureError(f"-: there is no standard input to read ({getattr(e, 'strerror', None) or e})") from None
    if regular:
        try:
            f.seek(_STDIN_START[0])
        except OSError as e:
            f.close()
            raise CaptureError(f"-: cannot read: {e.strerror}") from None
    return f
