"""The memory maps and the protocol's constants as plain data for the plug-in generators, and the escapes
every string a plug-in embeds goes through (Python literals, Lua strings).

A plug-in never reads our TOML files or imports this package: it carries the maps as a literal made here.
The maps' names are checked as they load (rs30x_sniff.protocol.memmap: a register is a snake_case word), but a
generator must not depend on that: every string goes into generated code through :func:`py_literal` or
:func:`lua_string`, and names are only ever used as keys and strings, never as identifiers.
"""

from __future__ import annotations

import ast
import pprint
from typing import Any

from ..protocol import wire
from ..protocol.memmap import Model, ModelRegistry, default_registry
from ..version import __version__


def register_data(reg: Any) -> dict[str, Any]:
    """One register as plain data: what a plug-in needs to name, scale and label its bytes."""
    return {
        "name": reg.name,                  # None for a reserved or undocumented byte
        "label": reg.label,                # the name, or reserved_N / addr_N
        "address": reg.address,
        "size": reg.size,
        "signed": reg.signed,
        "scale": reg.scale,
        "offset": reg.offset,
        "unit": reg.unit,
        "access": reg.access,
        "enum": None if reg.enum is None else {int(k): str(v) for k, v in reg.enum.items()},
        "table": None if reg.table is None else {int(k): v for k, v in reg.table.items()},
        "format": reg.format,
        "description": reg.description,
    }


def model_data(model: Model, also_named: list[str] | None = None) -> dict[str, Any]:
    """One model as plain data. ``model_number`` is None for a model no return names (RS405CB, RS406CB: known
    only when the user names it); ``also_named`` lists the other names of the same map (RS406CB for RS405CB)."""
    return {
        "name": model.name,
        "also_named": list(also_named or ()),
        "model_number": model.model_number,
        "readable_to": model.readable_to,
        "registers": [register_data(r) for r in model.registers],
    }


def protocol_data() -> dict[str, Any]:
    """The wire's constants (rs30x_sniff.protocol.wire) a decoder of the bytes needs."""
    return {
        "request_header": list(wire.REQUEST_HEADER),
        "return_header": list(wire.RETURN_HEADER),
        "ack": wire.ACK,
        "nack": wire.NACK,
        "broadcast_id": wire.BROADCAST_ID,
        "long_packet_id": wire.LONG_PACKET_ID,
        "command_address": wire.COMMAND_ADDRESS,
        "header_size": wire.HEADER_SIZE,
        "sum_size": wire.SUM_SIZE,
        "vid_size": wire.VID_SIZE,
        "flag_reserved": wire.FLAG_RESERVED,
        "commands": [[bit, name] for bit, name in wire.COMMANDS],
        "return_mode_mask": wire.RETURN_MODE_MASK,
        "return_modes": {m.mode: {"name": m.name, "expect": None if m.expect is None else m.expect.kind,
                                  "range": None if m.expect is None or m.expect.range is None
                                  else list(m.expect.range)}
                         for m in wire.RETURN_MODE_TABLE.values()},
        "return_flag_bits": {bit: name for bit, name in wire.RETURN_FLAG_BITS.items()},
        "return_flags_reserved": wire.RETURN_FLAGS_RESERVED,
        "max_read_address": wire.MAX_READ_ADDRESS,
        "baud_rates": list(wire.BAUD_RATES),
    }


def plugin_maps(registry: ModelRegistry | None = None) -> dict[str, Any]:
    """Every model the registry holds ($RS30X_DECODERS included), the default first, and the protocol."""
    registry = registry or default_registry()
    default = registry.default
    # One entry per model the registry holds (RS406CB, which shares RS405CB's map, is a model of its own);
    # a name the registry gives a model besides its own (its key) is an alias of it, never a second copy.
    models: list[Model] = [default]
    aliases: dict[int, list[str]] = {id(default): []}
    for key, m in registry.models.items():
        if id(m) not in aliases:
            models.append(m)
            aliases[id(m)] = []
        names = aliases[id(m)]
        for name in (key, *getattr(m, "also_named", ())):
            if name.upper() != m.name.upper() and name.upper() not in (n.upper() for n in names):
                names.append(name)
    return {
        "generator": f"rs30x-sniff {__version__}",
        "default_model": default.name,
        "models": [model_data(m, aliases[id(m)]) for m in models],
        "protocol": protocol_data(),
    }


# ---- escapes ---------------------------------------------------------------------------------------------
def py_literal(data: Any) -> str:
    """``data`` (dicts, lists, strings, numbers, None, booleans) as Python literal source, readable and safe:
    ``ast.literal_eval`` of the text gives ``data`` back (checked here), so no string in it can be code."""
    text = pprint.pformat(data, indent=1, width=110, sort_dicts=False)
    if ast.literal_eval(text) != data:
        raise ValueError("the data does not survive as a Python literal")
    return text


def lua_string(text: str) -> str:
    """``text`` as a double-quoted Lua string literal: printable ASCII as it is, every other byte of its UTF-8
    (quotes, backslashes, newlines, brackets of long strings are plain here) as a decimal escape."""
    out = ['"']
    for b in text.encode("utf-8"):
        ch = chr(b)
        if 32 <= b < 127 and ch not in '"\\':
            out.append(ch)
        else:
            out.append(f"\\{b:03d}")
    out.append('"')
    return "".join(out)
