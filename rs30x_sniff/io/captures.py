"""Capture files: detect the format, read them as (bytes, t) chunks, and write them back."""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import BinaryIO, Iterable, Iterator

Chunk = tuple[bytes, float | None]

BINARY, HEX, TIMESTAMPED, MCAP = "bin", "hex", "timestamped", "mcap"
FORMATS = (BINARY, HEX, TIMESTAMPED, MCAP)
_EXTENSIONS = {".bin": BINARY, ".raw": BINARY, ".mcap": MCAP}
_TEXT_EXTENSIONS = {".hex", ".txt", ".log", ".thex"}
MCAP_MAGIC = b"\x89MCAP0\r\n"
_READ_SIZE = 1 << 16
_HEX_TOKEN = re.compile(rb"^(?:[0-9a-fA-F]{2})+$")
_TIME_TOKEN = re.compile(rb"^[0-9]+\.[0-9]*$|^[0-9]*\.[0-9]+$")


class CaptureError(ValueError):
    """A capture cannot be read; the message is one line naming the file."""


def detect_format(path: str) -> str:
    """The format of a capture file: by extension, else by content."""
    if path == "-":
        return BINARY
    p = Path(path)
    ext = p.suffix.lower()
    if ext in _EXTENSIONS:
        return _EXTENSIONS[ext]
    with open_capture(path) as f:
        head = f.read(4096)
    if head.startswith(MCAP_MAGIC):
        return MCAP
    text_kind = _sniff_text(head)
    if text_kind:
        return text_kind
    if ext in _TEXT_EXTENSIONS:
        try:
            text = head.decode("ascii")
        except UnicodeDecodeError:
            raise CaptureError(f"{path}: not a hex capture (expected text like 'FA AF 01 ...')") from None
        # A text capture with a bad token: read it as its first line says, so the error names the line.
        first = next((ln.split("#", 1)[0].split() for ln in text.splitlines() if ln.split("#", 1)[0].split()), [])
        return TIMESTAMPED if first and _TIME_TOKEN.match(first[0].encode()) else HEX
    if b"\xfa\xaf" in head or b"\xfd\xdf" in head or not head:
        return BINARY
    raise CaptureError(f"{path}: unknown capture format (use --input-format {'|'.join(FORMATS)})")


def _sniff_text(head: bytes) -> str | None:
    """HEX or TIMESTAMPED when the first data lines of ``head`` look like one of them."""
    try:
        text = head.decode("ascii")
    except UnicodeDecodeError:
        return None
    lines = [ln.split(b"#", 1)[0].split() for ln in text.encode().splitlines()]
    lines = [ln for ln in lines if ln]
    if len(lines) > 1 and not head.endswith(b"\n"):
        lines = lines[:-1]  # the last line may be cut by the 4 KiB window
    if not lines:
        return HEX if text.strip() == "" or text.lstrip().startswith("#") else None
    if all(_TIME_TOKEN.match(ln[0]) and all(_HEX_TOKEN.match(t) for t in ln[1:]) for ln in lines):
        return TIMESTAMPED
    if all(all(_HEX_TOKEN.match(t) for t in ln) for ln in lines):
        return HEX
    return None


def read_capture(path: str, fmt: str | None = None) -> Iterator[Chunk]:
    """Stream a capture as (bytes, t) chunks; ``t`` is the capture time of the chunk's first byte."""
    fmt = fmt or detect_format(path)
    if fmt == BINARY:
        return _read_binary(path)
    if fmt == HEX:
        return _read_text(path, timestamped=False)
    if fmt == TIMESTAMPED:
        return _read_text(path, timestamped=True)
    if fmt == MCAP:
        from .mcap_source import read_mcap_raw  # imported lazily: only MCAP inputs need the mcap library
        return read_mcap_raw(path)
    raise CaptureError(f"{path}: unknown input format {fmt!r} (use one of {', '.join(FORMATS)})")


def open_capture(path: str) -> BinaryIO:
    """Open a capture for binary reading; failure is a one-line CaptureError naming the file."""
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


def _open(path: str) -> BinaryIO:
    return sys.stdin.buffer if path == "-" else open_capture(path)


def _read_binary(path: str) -> Iterator[Chunk]:
    f = _open(path)
    try:
        while True:
            block = f.read(_READ_SIZE)
            if not block:
                return
            yield bytes(block), None
    finally:
        if f is not sys.stdin.buffer:
            f.close()


def _read_text(path: str, timestamped: bool) -> Iterator[Chunk]:
    f = _open(path)
    pending = bytearray()  # untimed hex lines are merged into larger chunks
    try:
        time_ok = _TIME_TOKEN.match
        for lineno, line in enumerate(f, 1):
            body = line.partition(b"#")[0]
            t = None
            if timestamped:
                parts = body.split(None, 1)
                if not parts:
                    continue
                head = parts[0]
                body = parts[1] if len(parts) > 1 else b""
                if not time_ok(head) and not head.isdigit():
                    raise CaptureError(f"{path}:{lineno}: expected a time in seconds, got {_show(head)}")
                t = float(head)
            try:
                # fromhex skips the whitespace between bytes: one C call per line.
                data = bytes.fromhex(body.decode("ascii"))
            except (ValueError, UnicodeDecodeError):
                tokens = body.split()
                bad = next((tok for tok in tokens if not _HEX_TOKEN.match(tok)), tokens[0] if tokens else body)
                raise CaptureError(f"{path}:{lineno}: not a hex byte: {_show(bad)}") from None
            if timestamped:
                if data:
                    yield data, t
            else:
                pending += data
                if len(pending) >= _READ_SIZE:
                    yield bytes(pending), None
                    pending.clear()
        if pending:
            yield bytes(pending), None
    except UnicodeDecodeError:
        raise CaptureError(f"{path}: not a text capture") from None
    finally:
        if f is not sys.stdin.buffer:
            f.close()


def _show(token: bytes) -> str:
    return repr(token.decode("ascii", "replace")[:20])


# ---- writers -------------------------------------------------------------------------------------
def write_capture(path: str | Path, chunks: Iterable[Chunk], fmt: str) -> int:
    """Write chunks as a capture of ``fmt`` (bin, hex or timestamped); returns the bytes written."""
    total = 0
    if fmt == BINARY:
        with open(path, "wb") as f:
            for data, _ in chunks:
                f.write(data)
                total += len(data)
        return total
    if fmt not in (HEX, TIMESTAMPED):
        raise CaptureError(f"{path}: cannot write format {fmt!r}")
    with open(path, "w", encoding="ascii") as f:
        for data, t in chunks:
            if not data:
                continue
            hexs = data.hex(" ").upper()
            if fmt == TIMESTAMPED:
                f.write(f"{(t or 0.0):.6f} {hexs}\n")
            else:
                f.write(hexs + "\n")
            total += len(data)
    return total


def format_for_output(path: str, fmt: str | None) -> str:
    """The capture format to write ``path`` in: the explicit one, else by extension."""
    if fmt:
        return fmt
    ext = Path(path).suffix.lower()
    if ext in (".bin", ".raw"):
        return BINARY
    if ext == ".mcap":
        return MCAP
    return TIMESTAMPED if ext in (".thex", ".log") else HEX
