"""What a source of chunks declares: how its chunks come (live, streamed, batched) and the chunks themselves."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Protocol

from ..protocol.chunks import Chunk


class Pacing(Protocol):
    """How a source hands over its chunks; the drive loop chooses its path by it (sinks.pipeline.columnar_for).

    Every source says all three, as class attributes or properties (a checker holds them to it; nothing is
    checked at run time).
    """

    @property
    def live(self) -> bool:
        """Paced as it happens (a port, the monitor's replay, the simulator), not read as fast as it can be."""
        ...

    @property
    def streamed(self) -> bool:
        """Not a regular file (a pipe, a FIFO, a device): its bytes may still be arriving as they are read."""
        ...

    @property
    def batched(self) -> bool:
        """A live source that hands its chunks over in gathers, each ended by an empty chunk (a port)."""
        ...


class Source(Pacing, Protocol):
    """A capture or a port as the commands read it: (bytes, t) chunks, marked ones and gaps among them
    (rs30x_sniff.protocol.chunks), and how they come."""

    def __iter__(self) -> Iterator[Chunk]: ...


class TextCapture(Source, Protocol):
    """A hex or timestamped-hex capture read with its line index (read_input(..., locate=True))."""

    def locate(self, offset: int) -> tuple[int, int] | None:
        """The line and column where the byte at stream ``offset`` is written, or None."""
        ...


class ChunkReader(Source, Protocol):
    """A capture being read (rs30x_sniff.sources.inputs.read_input): a Source that is its own iterator, so
    ``next()`` takes its head before the rest is read."""

    def __next__(self) -> Chunk: ...
