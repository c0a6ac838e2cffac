"""rs30x-sniff: protocol analyzer and bus logger for the Futaba RS30x command-type servo bus."""

from .decode.pairing import BusTracker, Record, ServoState
from .protocol.events import Ack, Event, Garbage, LongPacket, LongRecord, Nack, ReturnPacket, ShortPacket
from .decode.framing import FrameDecoder, decode_all
from .protocol.memmap import Field, Model, ModelError, ModelRegistry, Register, default_registry, load_model
from .decode.decoder import DecodeOptions, Decoder
from .sinks.pipeline import decode_records
from .lint import RULES, Finding, LintConfig, Linter

from .version import __version__

__all__ = [
    "Ack", "BusTracker", "DecodeOptions", "Decoder", "Event", "Field", "Finding", "FrameDecoder", "Garbage",
    "LintConfig", "Linter", "LongPacket", "LongRecord", "Model", "ModelError", "ModelRegistry", "Nack", "RULES",
    "Record", "Register",
    "ReturnPacket", "ServoState", "ShortPacket", "decode_all", "decode_records", "default_registry",
    "load_model", "__version__",
]
