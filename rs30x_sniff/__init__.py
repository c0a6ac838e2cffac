"""rs30x-sniff: protocol analyzer and bus logger for the Futaba RS30x command-type servo bus."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from .version import __version__

# Each public name -> the module that defines it, imported on first use (PEP 562): `import rs30x_sniff` and the
# command line's start-up (`--help`, `rules`) load none of numpy and the decoder until a name is asked for.
_WHERE = {
    "BusTracker": "decode.pairing", "Record": "decode.pairing", "ServoState": "decode.pairing",
    "Ack": "protocol.events", "Event": "protocol.events", "Garbage": "protocol.events",
    "LongPacket": "protocol.events", "LongRecord": "protocol.events", "Nack": "protocol.events",
    "ReturnPacket": "protocol.events", "ShortPacket": "protocol.events",
    "FrameDecoder": "decode.framing", "decode_all": "decode.framing",
    "Field": "protocol.memmap", "Model": "protocol.memmap", "ModelError": "protocol.memmap",
    "ModelRegistry": "protocol.memmap", "Register": "protocol.memmap", "default_registry": "protocol.memmap",
    "load_model": "protocol.memmap",
    "DecodeOptions": "decode.decoder", "Decoder": "decode.decoder",
    "decode_records": "sinks.pipeline",
    "RULES": "lint", "Finding": "lint", "LintConfig": "lint", "Linter": "lint",
}

if TYPE_CHECKING:  # the checker reads the names where they are defined
    from .decode.pairing import BusTracker, Record, ServoState
    from .protocol.events import Ack, Event, Garbage, LongPacket, LongRecord, Nack, ReturnPacket, ShortPacket
    from .decode.framing import FrameDecoder, decode_all
    from .protocol.memmap import Field, Model, ModelError, ModelRegistry, Register, default_registry, load_model
    from .decode.decoder import DecodeOptions, Decoder
    from .sinks.pipeline import decode_records
    from .lint import RULES, Finding, LintConfig, Linter

__all__ = [
    "Ack", "BusTracker", "DecodeOptions", "Decoder", "Event", "Field", "Finding", "FrameDecoder", "Garbage",
    "LintConfig", "Linter", "LongPacket", "LongRecord", "Model", "ModelError", "ModelRegistry", "Nack", "RULES",
    "Record", "Register",
    "ReturnPacket", "ServoState", "ShortPacket", "decode_all", "decode_records", "default_registry",
    "load_model", "__version__",
]


def __getattr__(name: str) -> object:
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{where}", __name__), name)
    globals()[name] = value  # once: the next lookup finds it without this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_WHERE})
