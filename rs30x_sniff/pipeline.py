"""The one-way flow of the core: (bytes, t) chunks -> frame events -> paired, annotated records."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable, Iterator

from .bus import DEFAULT_REPLY_TIMEOUT, BusTracker, Record
from .framing import DEFAULT_GAP_BYTES, FrameDecoder
from .memmap import ModelRegistry, default_registry
from .wire import DEFAULT_BAUD


@dataclass
class DecodeOptions:
    """Everything that changes how bytes are decoded (from the command line or a config file)."""

    baud: int = DEFAULT_BAUD
    default_model: str | None = None
    models: dict[int, str] = field(default_factory=dict)  # per-ID model names
    gap_bytes: float | None = DEFAULT_GAP_BYTES
    reply_timeout: float = DEFAULT_REPLY_TIMEOUT
    registry: ModelRegistry | None = None


class Decoder:
    """Frame decoder, bus tracker and (optionally) linter in one object: feed chunks, get records.

    Still sans-IO. A linter, if given, sees every record before it is returned, so the record's
    ``findings`` already hold what the linter could tell at that point; findings that only the end
    of input reveals are in the list :meth:`close` leaves in ``late_findings`` (and, like every
    finding, at the end of ``linter.findings``).
    """

    def __init__(self, options: DecodeOptions | None = None, linter: Any = None) -> None:
        o = self.options = options or DecodeOptions()
        self.frames = FrameDecoder(o.baud, gap_bytes=o.gap_bytes)
        self.bus = BusTracker(o.registry or default_registry(), o.models, o.reply_timeout, o.default_model)
        self.linter = linter
        self.bytes_in = 0
        self.late_findings: list = []

    def feed(self, data: bytes, t: float | None = None) -> list[Record]:
        self.bytes_in += len(data)
        out = self.bus.feed_many(self.frames.feed(data, t), [])
        if self.linter is not None and out:
            lint = self.linter.feed
            for rec in out:
                lint(rec)
        return out

    def close(self) -> list[Record]:
        out = self.bus.feed_many(self.frames.close(), [])
        out += self.bus.close()
        if self.linter is not None:
            for rec in out:
                self.linter.feed(rec)
            self.late_findings = self.linter.close()
        return out


def decode_records(chunks: Iterable[tuple[bytes, float | None]], options: DecodeOptions | None = None,
                   decoder: Decoder | None = None) -> Iterator[Record]:
    """Stream records from chunks."""
    dec = decoder or Decoder(options)
    for data, t in chunks:
        yield from dec.feed(data, t)
    yield from dec.close()
