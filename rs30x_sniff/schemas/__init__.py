"""JSON Schemas of the MCAP channels and of a memory map, shipped as package data beside this module."""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path

# Files beside this module, as decoders/ is beside the package: read as paths (importlib.resources cost every
# start-up 3 ms).
_HERE = Path(__file__).resolve().parent
# Schema name (as registered in MCAP files) -> file in this package.
SCHEMA_FILES = {
    "rs30x.Raw": "raw.json",
    "rs30x.Packet": "packet.json",
    "rs30x.ServoState": "servo_state.json",
    "rs30x.Transaction": "transaction.json",
    "foxglove.Log": "foxglove_log.json",
}


@cache
def schema_bytes(name: str) -> bytes:
    """The schema's JSON text, as stored in an MCAP Schema record."""
    return (_HERE / SCHEMA_FILES[name]).read_bytes()


def schema(name: str) -> dict:
    """The schema as a dict (for validators)."""
    return json.loads(schema_bytes(name))


@cache
def memory_map_schema() -> dict:
    """The JSON Schema of a memory-map file (decoders/*.toml), checked as each map loads."""
    return json.loads((_HERE / "memory_map.json").read_bytes())
