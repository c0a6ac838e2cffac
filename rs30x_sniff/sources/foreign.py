"""Other tools' capture formats (logic analyzers' exports, serial loggers' logs): one registry the reader consults.

Each format module registers a :class:`ForeignFormat`; :mod:`rs30x_sniff.sources.captures` detects them by
content (or extension) after our own formats, and ``--input-format NAME`` forces one.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Any, BinaryIO
from collections.abc import Callable, Iterator

# The modules that register formats, imported on first use (each reader is a module of its own).
_MODULES = ("saleae", "sigrok", "serial_logs")


@dataclass
class ReadContext:
    """What a reader gets besides the open file: its name, the user's options, where to warn, what it found."""

    path: str
    options: dict[str, Any] = field(default_factory=dict)  # e.g. "channel", "baud" (None: find it)
    warn: Callable[[str], None] | None = None
    found: dict[str, Any] = field(default_factory=dict)    # what the reader learned (e.g. "baud", "baud_note")


@dataclass(frozen=True)
class ForeignFormat:
    """One foreign capture format.

    ``sniff(head)`` says whether the first 4 KiB of a file are this format (strictly: a false match
    hides the user's real format); ``read(stream, ctx)`` yields the file's chunks (``(bytes, t)`` pairs,
    or :class:`rs30x_sniff.protocol.chunks.Marked` ones saying who sent them or that the UART flagged them) and
    raises :class:`rs30x_sniff.sources.captures.CaptureError` with a one-line message (and line number) on
    bad input. ``time_ref`` says what its times mean: each chunk's first byte or its arrival
    (rs30x_sniff.sources.timebase FIRST/ARRIVAL). ``probe(path, options)`` (optional) returns settings the
    capture itself records, e.g. ``{"baud": 115200, "baud_note": "..."}``, before the file is read.
    """

    name: str
    description: str
    sniff: Callable[[bytes], bool]
    read: Callable[[BinaryIO, ReadContext], Iterator[Any]]
    time_ref: str
    extensions: tuple[str, ...] = ()
    needs_seek: bool = False
    channels: bool = False  # the capture holds several signals, picked with --channel (options["channel"])
    probe: Callable[[str, dict[str, Any]], dict[str, Any]] | None = None


_FORMATS: dict[str, ForeignFormat] = {}
_loaded = False


def register(fmt: ForeignFormat) -> ForeignFormat:
    """Add a format (called by each reader module at import)."""
    if fmt.name in _FORMATS:
        raise ValueError(f"input format {fmt.name!r} is registered twice")
    _FORMATS[fmt.name] = fmt
    return fmt


def _load() -> None:
    global _loaded
    if not _loaded:
        _loaded = True
        for name in _MODULES:
            try:
                importlib.import_module(f"{__package__}.{name}")
            except ModuleNotFoundError as e:
                if e.name != f"{__package__}.{name}":
                    raise


def formats() -> dict[str, ForeignFormat]:
    """Every registered foreign format, by name."""
    _load()
    return _FORMATS


def get(name: str | None) -> ForeignFormat | None:
    """The foreign format called ``name`` (None if there is none)."""
    return formats().get(name) if name else None


def by_extension(ext: str) -> ForeignFormat | None:
    """The foreign format a file extension (``.sr``) names, if one does."""
    for fmt in formats().values():
        if ext in fmt.extensions:
            return fmt
    return None


def sniff(head: bytes) -> ForeignFormat | None:
    """The foreign format the head of a file is in, if any."""
    for fmt in formats().values():
        if fmt.sniff(head):
            return fmt
    return None
