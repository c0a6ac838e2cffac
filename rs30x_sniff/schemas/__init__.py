"""JSON Schemas of the MCAP channels, shipped as package data and loaded with importlib.resources."""

from __future__ import annotations

import json
from functools import cache
from importlib.resources import files

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
    return files(__package__).joinpath(SCHEMA_FILES[name]).read_bytes()


def schema(name: str) -> dict:
    """The schema as a dict (for validators)."""
    return json.loads(schema_bytes(name))


@cache
def memory_map_schema() -> dict:
    """The JSON Schema of a memory-map file (decoders/*.toml), checked as each map loads."""
    return json.loads(files(__package__).joinpath("memory_map.json").read_bytes())
