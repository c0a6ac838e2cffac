"""Memory maps as data: load decoders/*.toml and turn memory bytes into named, scaled fields."""

from __future__ import annotations

import os
import re
import struct
from collections.abc import Hashable, Mapping
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from types import MappingProxyType
from typing import Any

from ..schemas import memory_map_schema
from ..schemas.check import first_failure
from . import map_cache
from .codegen import values_function
from .wire import BAUD_RATES, MAX_READ_ADDRESS, RETURN_FLAG_BITS, RETURN_MODE_MASK, RETURN_MODE_TABLE

DEFAULT_MODEL = "RS303MR"
UNKNOWN = "unknown"  # a map's word for a model fact no source gives (model_number, top_speed_s_per_60deg)
# A map is data, never code: its names become filter terms, JSON keys, MCAP fields and the field names of
# generated plug-ins (sigrok, Logic 2, Wireshark), so they are checked as the map loads, by its schema
# (schemas/memory_map.json): a register is a snake_case word that is neither a filter key nor the label of an
# unnamed byte; a model, a word with - or _.
_REGISTER_NAME_SCHEMA = memory_map_schema()["$defs"]["register"]["properties"]["name"]
_NAME_SCHEMA = _REGISTER_NAME_SCHEMA["allOf"]
REGISTER_NAME = re.compile(_NAME_SCHEMA[0]["pattern"].strip("^$"))
RESERVED_NAMES = frozenset(_NAME_SCHEMA[1]["not"]["anyOf"][0]["enum"])  # the filter language's keys
# Entries a Model's cache holds before it starts afresh: its line templates go by header bytes, and a
# stream of odd headers would otherwise pile them up (what is dropped is made again when met).
MAX_CACHED = 4096


class ModelError(ValueError):
    """A memory-map file is wrong; the message names the file and the key."""


@dataclass(frozen=True, slots=True)
class Register:
    """One register of the memory map: where it is and how its raw value becomes a quantity."""

    name: str | None           # None for reserved and undocumented bytes
    address: int
    size: int = 1
    signed: bool = False
    scale: float = 1
    offset: float = 0
    unit: str | None = None
    access: str = "read"
    area: str = "ram"
    default: int | None = None
    range: tuple[int, int] | None = None
    mode: str = "both"
    enum: dict[int, str] | None = None
    table: dict[int, float] | None = None
    format: str | None = None
    description: str = ""
    source: str = ""           # where its facts come from when not the model's main source: a source key or a citation
    note: str = ""             # what the sources leave open: a conflict between them, "reserved per one header"
    # What other modules make from this register once and keep with it, by a key they choose (a tuple
    # or string starting with their tag): render's text and JSON of each raw value, the monitor's plot
    # values. Not part of the register's value: no init, repr or comparison.
    cache: dict[Hashable, Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def reserved(self) -> bool:
        return self.access == "reserved"

    @property
    def writable(self) -> bool:
        return self.access == "read-write"

    @property
    def label(self) -> str:
        """The name, or ``reserved_N`` / ``addr_N`` for unnamed bytes."""
        if self.name:
            return self.name
        return f"reserved_{self.address}" if self.reserved else f"addr_{self.address}"

    @property
    def divisor(self) -> int | None:
        """``round(1 / scale)`` when the scale is an exact decimal step (0.1, 0.01): values are then
        ``raw / divisor`` (900 / 10, not 900 * 0.1); None for any other scale, 1 included."""
        scale = self.scale
        if scale < 1 and abs(1 / scale - round(1 / scale)) < 1e-9:
            return round(1 / scale)
        return None

    def raw_int(self, raw: bytes) -> int:
        return int.from_bytes(raw, "little", signed=self.signed and len(raw) == self.size)

    def convert(self, raw_value: int) -> Any:
        """Engineering value of a raw register value (a label for enums, None for an unknown code)."""
        if self.enum is not None:
            return self.enum.get(raw_value, raw_value)
        if self.table is not None:
            return self.table.get(raw_value)
        scale = self.scale
        value: float
        if scale == 1:
            value = raw_value
        elif (divisor := self.divisor) is not None:
            value = raw_value / divisor
        else:
            value = raw_value * scale
        return value + self.offset if self.offset else value

    def value_of(self, raw_value: int, partial: str | None = None) -> Any:
        """The value a part of this register with ``raw_value`` has in a packet: :meth:`convert` for the
        whole of a named register, the raw value itself for one byte of a 2-byte one (``partial``) and
        for unnamed bytes. The reference form of Layout.values (which is generated: codegen)."""
        if partial or self.name is None:
            return raw_value
        return self.convert(raw_value)

    def raw_column(self, data: Any, at: Any, partial: str | None = None) -> Any:
        """The raw value :meth:`value_of` takes, for every row at once: this register's bytes (one byte of it
        with ``partial``) starting at ``at`` in the uint8 array ``data``, little-endian and signed as the
        register is, as int64. ``at`` is an index array, or an int into the first axis of a 2-D ``data``
        (``matrix.T``: a column of frame rows). The one place a column of bytes becomes register values
        (numpy is taken from the array: this module imports none). A table indexed by the unsigned raw
        value reads a signed raw value right too: numpy counts a negative index from the end."""
        size = 1 if partial else self.size
        signed = self.signed and not partial
        col = data[at]
        if size == 1:
            return (col.view("int8") if signed else col).astype("int64")
        if size == 2:
            col = col.astype("uint16") | data[at + 1].astype("uint16") << 8
            return (col.view("int16") if signed else col).astype("int64")
        col = col.astype("int64")
        for k in range(1, size):
            col |= data[at + k].astype("int64") << 8 * k
        if signed:
            col -= (col >= 1 << (8 * size - 1)) * (1 << 8 * size)
        return col

    def value_column(self, raw: Any) -> tuple[Any, Any]:
        """:meth:`value_of` of each raw value (:meth:`raw_column`'s): (the values as float64, whether each is
        a number: an enum's label or an unknown table code is not). For a 1- or 2-byte register each raw
        value is converted once, when first met, into tables kept in :attr:`cache`."""
        import numpy as np  # only where columns are read: the maps load without it

        if self.size > 2:
            got = [self.value_of(u) for u in raw.tolist()]
            ok_ = [isinstance(v, (int, float)) for v in got]
            return (np.array([float(v) if k else 0.0 for v, k in zip(got, ok_)], dtype=float),
                    np.array(ok_, dtype=bool))
        lut = self.cache.get("value column")
        if lut is None:
            n = 1 << 8 * self.size
            lut = self.cache["value column"] = (np.zeros(n), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool))
        values, ok, known = lut
        new = raw[~known[raw]]
        if new.size:
            convert = self.value_of
            for u in set(new.tolist()):
                v = convert(u)
                if isinstance(v, (int, float)):
                    values[u] = float(v)
                    ok[u] = True
                known[u] = True
        return values[raw], ok[raw]

    def value_in(self, address: int, data: bytes | bytearray) -> Any:
        """Engineering value of this register in ``data`` that starts at memory ``address``;
        None unless ``data`` holds all of the register."""
        start = self.address - address
        if start < 0 or start + self.size > len(data):
            return None
        return self.convert(int.from_bytes(data[start:start + self.size], "little", signed=self.signed))

    def to_raw(self, value: float) -> int:
        """Inverse of :meth:`convert` for scaled numbers (used by encoders and the simulator)."""
        if self.table is not None:
            for k, v in self.table.items():
                if v == value:
                    return k
            raise ValueError(f"{self.label}: no code for {value}")
        if self.enum is not None:
            for k, label in self.enum.items():
                if label == value:
                    return k
            return int(value)
        return round((value - self.offset) / self.scale)

    def encode(self, value: float) -> bytes:
        return self.to_raw(value).to_bytes(self.size, "little", signed=self.signed)


@dataclass(slots=True)
class Field:
    """A decoded piece of a packet: one register (or part of one) of one servo."""

    id: int | None
    address: int
    register: Register
    raw: bytes
    raw_value: int
    value: Any
    partial: str | None = None  # "low" / "high" when a packet carries one byte of a 2-byte register

    @property
    def name(self) -> str | None:
        return self.register.name

    @property
    def label(self) -> str:
        return self.register.label

    @property
    def unit(self) -> str | None:
        return None if self.partial else self.register.unit


@dataclass(frozen=True, slots=True)
class Source:
    """One source a map's facts come from (``[[source]]``): a key registers cite it by, its title, where it is."""

    key: str
    title: str
    where: str = ""


OVER_TEMPERATURE_RECOVERIES = ("reboot", "torque-enable")
# What brings a servo back from a temperature stop, said in words (lint's S001, info's "what happened").
RECOVERY_TEXT = {"reboot": "a reboot clears it", "torque-enable": "a torque_enable write clears it"}


def _manual_return_flags() -> Mapping[int, str]:
    return MappingProxyType(dict(RETURN_FLAG_BITS))


def _no_areas() -> Mapping[int, tuple[int, int]]:
    return MappingProxyType({})


@dataclass(frozen=True, slots=True)
class Behaviour:
    """How a model acts beyond its registers (``[behaviour]``); the defaults are the RS303MR manual's."""

    flash_and_reboot_together: bool = False       # flag 0x60 in one packet (the RS303MR manual: send them apart)
    invalid_baud_code_gives: int | None = None     # the rate an undefined baud code falls back to; None: unsaid
    over_temperature_recovery: str = "reboot"      # "reboot" | "torque-enable": what clears a temperature stop
    torque_off_only: tuple[str, ...] = ()          # registers a write changes only while torque is off
    # Return-packet status bit -> flag name (table 4.4 for the RS303MR).
    return_flags: Mapping[int, str] = field(default_factory=_manual_return_flags)
    # Return modes beyond table 4.3 -> (first address, byte count), as wire.Expect.range says a range.
    return_areas: Mapping[int, tuple[int, int]] = field(default_factory=_no_areas)
    voltage_accuracy_v: float | None = None        # +- volts of present_voltage; None: unsaid
    source: str = ""                               # where these facts come from (a source key or a citation)

    @property
    def recovers_by_torque_enable(self) -> bool:
        """Whether a torque_enable write clears a temperature stop (RS301CR/RS302CD p.20), not only a reboot."""
        return self.over_temperature_recovery == "torque-enable"

    @property
    def recovery(self) -> str:
        """What clears a temperature stop, in words (lint's S001, info's "what happened")."""
        return RECOVERY_TEXT[self.over_temperature_recovery]

    @property
    def reserved_flags(self) -> int:
        """The return-packet status bits this model leaves reserved: table 4.4's 6, 4, 2 and 0 for the RS303MR;
        bit 3 too where a manual has no flash-write-error bit (RS301CR/RS302CD)."""
        defined = 0
        for bit in self.return_flags:
            defined |= bit
        return 0xFF & ~defined


MANUAL_BEHAVIOUR = Behaviour()


def behaviour_of(model: Model | None) -> Behaviour:
    """A servo's model's behaviour, or the RS303MR manual's where no model is known (none configured or learned)."""
    return MANUAL_BEHAVIOUR if model is None else model.behaviour


@dataclass(slots=True, eq=False)
class Model:
    """A servo model's memory map, loaded from one ``decoders/*.toml`` file.

    A model is equal only to itself (and hashes so): the caches below belong to it, and what other
    modules compile for a model (a filter's check, a line template) is kept by the model itself.
    """

    name: str
    model_number: int | None            # None: no source gives it (RS405CB/RS406CB); known by --model only
    top_speed_s_per_60deg: float | None  # None: no source gives it
    readable_to: int
    registers: tuple[Register, ...]
    source: str = ""                    # the file it was loaded from
    sources: tuple[Source, ...] = ()    # where its facts come from ([[source]])
    behaviour: Behaviour = field(default_factory=Behaviour)
    also_named: tuple[str, ...] = ()    # other models sharing this map, each a Model of its own name
    _by_address: dict[int, Register] = field(default_factory=dict, repr=False)
    _by_name: dict[str, Register] = field(default_factory=dict, repr=False)
    _layouts: dict[tuple, Layout] = field(default_factory=dict, repr=False)
    _names: dict[tuple[int, int], tuple[str, ...]] = field(default_factory=dict, repr=False)  # names_in's
    # Line and message templates other modules compile for this model's packets (render's text and
    # JSON, the MCAP transactions), by a key they choose that starts with their tag; filled by keep.
    cache: dict[Hashable, Any] = field(default_factory=dict, repr=False)

    def keep(self, key: Hashable, value: Any) -> Any:
        """``value`` kept in ``cache`` under ``key``, and returned. Past MAX_CACHED entries the cache
        starts afresh (templates go by header bytes: a stream of odd ones would pile them up)."""
        cache = self.cache
        if len(cache) >= MAX_CACHED:
            cache.clear()
        cache[key] = value
        return value

    def renamed(self, name: str) -> Model:
        """This map under another model's name (one of ``also_named``): the same registers and behaviour,
        caches of its own (what other modules keep for a model may hold its name)."""
        return replace(self, name=name, also_named=(), _by_address={}, _by_name={}, _layouts={}, _names={},
                       cache={})

    def __post_init__(self) -> None:
        for reg in self.registers:
            for a in range(reg.address, reg.address + reg.size):
                self._by_address[a] = reg
            if reg.name:
                self._by_name[reg.name] = reg

    def register_at(self, address: int) -> Register:
        """The register covering ``address``; an unnamed one past the documented map."""
        reg = self._by_address.get(address)
        if reg is None:
            reg = self._by_address[address] = Register(None, address, access="read", area="undocumented",
                                                       mode="both")
        return reg

    def register(self, name: str) -> Register:
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(f"{self.name} has no register {name!r}") from None

    @property
    def names(self) -> list[str]:
        return list(self._by_name)

    def layout(self, address: int, length: int) -> Layout:
        """How ``length`` bytes at ``address`` split into fields, with a compiled decoder; cached."""
        key = (address, length)
        lay = self._layouts.get(key)
        if lay is None:
            lay = self._layouts[key] = Layout(self, address, length)
        return lay

    def long_layout(self, address: int, length: int, count: int) -> Layout:
        """The layout of a whole long packet's data (``count`` records of VID + ``length - 1`` bytes)."""
        key = (address, length, count, "long")
        lay = self._layouts.get(key)
        if lay is None:
            lay = self._layouts[key] = Layout(self, address, length - 1, count)
        return lay

    def decode(self, address: int, data: bytes, servo_id: int | None = None) -> list[Field]:
        """Named, scaled fields of ``data`` written to or read from ``address``."""
        lay = self.layout(address, len(data))
        return lay.fields(data, lay.values(data), servo_id)

    def names_in(self, address: int, length: int) -> list[str]:
        """Register labels a read of ``length`` bytes at ``address`` covers."""
        key = (address, length)
        names = self._names.get(key)
        if names is None:
            names = self._names[key] = tuple(reg.label for _, _, reg, _ in self.layout(address, length).parts)
        return list(names)


class Layout:
    """The fields of one (address, length) of a model, and a decoder compiled for them.

    ``values(data)`` turns the bytes into engineering values with one ``struct.unpack`` and one
    generated expression (codegen.values_function; its reference is Register.value_of of each part),
    which is what lets annotation keep up with a saturated bus; ``fields`` builds the Field objects
    from those values only when somebody looks at them. ``unpack_raw(data)`` gives the raw integers
    instead (one per part, VIDs included), for checks on raw values. With ``records`` > 0 it is a long
    packet's data: that many repeats of VID + ``length`` bytes. ``cache`` keeps what other modules make
    from the layout, by a key starting with their tag (render's JSON templates, the MCAP state plans).
    """

    __slots__ = ("parts", "size", "records", "values", "unpack_raw", "_named", "cache")

    def __init__(self, model: Model, address: int, length: int, records: int = 0) -> None:
        parts: list[tuple[int, int, Register, str | None]] = []
        a, end = address, address + length
        while a < end:
            reg = model.register_at(a)
            if a == reg.address and a + reg.size <= end:
                parts.append((a - address, reg.size, reg, None))
                a += reg.size
            else:
                parts.append((a - address, 1, reg, "low" if a == reg.address else "high"))
                a += 1
        self.parts = tuple(parts)
        self.size = length
        self.records = records
        codes = []
        for _ in range(max(records, 1)):
            if records:
                codes.append("B")  # the VID
            for _, size, reg, partial in parts:
                if partial or size == 1:
                    codes.append("b" if reg.signed and not partial else "B")
                else:
                    codes.append("h" if reg.signed else "H")
        self._named: tuple[tuple[int, str], ...] | None = None  # named_values' (part, name) pairs
        self.cache: dict[Hashable, Any] = {}  # what other modules make from this layout, by their key
        unpack = self.unpack_raw = struct.Struct("<" + "".join(codes)).unpack
        self.values = values_function([(reg, partial) for _, _, reg, partial in parts], records, unpack)

    def fields(self, data: bytes, values: tuple, servo_id: int | None = None) -> list[Field]:
        """Field objects for ``data`` and its already decoded ``values``."""
        out = []
        parts = self.parts
        if not self.records:
            for (start, size, reg, partial), v in zip(parts, values):
                raw = data[start:start + size]
                rv = raw[0] if partial else int.from_bytes(raw, "little", signed=reg.signed)
                out.append(Field(servo_id, reg.address if not partial else reg.address + (partial == "high"),
                                 reg, raw, rv, v, partial))
            return out
        stride = self.size + 1
        n = len(parts)
        for rec in range(self.records):
            base = rec * stride
            vid = data[base]
            for j, (start, size, reg, partial) in enumerate(parts):
                raw = data[base + 1 + start:base + 1 + start + size]
                rv = raw[0] if partial else int.from_bytes(raw, "little", signed=reg.signed)
                out.append(Field(vid, reg.address if not partial else reg.address + (partial == "high"),
                                 reg, raw, rv, values[rec * n + j], partial))
        return out

    def named_values(self, data: bytes, values: tuple, servo_id: int | None = None) -> list[tuple[Any, str, Any]]:
        """``(servo id, register name, value)`` of every whole, named register in ``data``: what the
        fields say, without building them (the servo-state channel and table read this per packet)."""
        named = self._named
        if named is None:
            named = self._named = tuple((j, reg.name) for j, (_, _, reg, partial) in enumerate(self.parts)
                                        if reg.name is not None and not partial)
        if not self.records:
            return [(servo_id, name, values[j]) for j, name in named]
        stride, n = self.size + 1, len(self.parts)
        out: list[tuple[Any, str, Any]] = []
        for rec in range(self.records):
            vid, base = data[rec * stride], rec * n
            out += [(vid, name, values[base + j]) for j, name in named]
        return out


class ByRaw(dict):
    """Something made from a part's raw value by ``make`` on first sight and kept (the first ``limit``
    of them, when given: a 2-byte register has 65,536 raw values)."""

    __slots__ = ("make", "limit")

    def __init__(self, make: Any, limit: int | None = None) -> None:
        super().__init__()
        self.make = make
        self.limit = limit

    def __missing__(self, raw: int) -> Any:
        made = self.make(raw)
        if self.limit is None or len(self) < self.limit:
            self[raw] = made
        return made


# ---- loading ------------------------------------------------------------------------------------
def _fail(source: str, where: str, msg: str) -> ModelError:
    return ModelError(f"{source}: {where}: {msg}")


def _printable(source: str, where: str, value: str) -> None:
    """A free-text value (a description, an enum label) on one printable line: plug-ins still escape it for
    their language; this keeps control bytes out of every report (Unicode's printable, which a schema's
    pattern cannot say)."""
    bad = next((c for c in value if not c.isprintable()), None)
    if bad is not None:
        raise _fail(source, where, f"holds the control character {bad!r}: one printable line")


def _int_keys(source: str, where: str, table: dict[str, Any]) -> dict[int, Any]:
    try:
        return {int(k, 0): v for k, v in table.items()}
    except ValueError:
        raise _fail(source, where, "keys must be integers") from None


def _label(r: dict[str, Any]) -> str:
    """How a register is named in a message: its name, else its address; a bad name as a literal, cut short
    (never printed as it is)."""
    label = r.get("name") or (f"address {r['address']}" if "address" in r else "?")
    if "name" in r and not (isinstance(label, str) and REGISTER_NAME.fullmatch(label)):
        label = repr(label)[:60]
    return label


def _where(doc: dict[str, Any], path: tuple[str | int, ...]) -> str:
    """A schema failure's place as the messages say it: model.name, register[3] (baud_rate).range, enum.0."""
    if len(path) >= 2 and path[0] == "register" and isinstance(path[1], int):
        reg = doc["register"][path[1]]
        head = f"register[{path[1]}]" + (f" ({_label(reg)})" if isinstance(reg, dict) else "")
        return ".".join((head, *map(str, path[2:])))
    if len(path) >= 2 and path[0] == "source" and isinstance(path[1], int):
        return ".".join((f"source[{path[1]}]", *map(str, path[2:])))
    return ".".join(map(str, path))


def parse_model(doc: dict[str, Any], source: str = "<memory map>", *, schema_checked: bool = False) -> Model:
    """Build a Model from a parsed TOML document: its shape checked by the schema (schemas/memory_map.json; not
    again when ``schema_checked``: a document that passed, as map_cache keeps it), then what the schema cannot
    say (a name given once, unnamed registers reserved, ranges and defaults within a register's size, no two
    registers on one address)."""
    failure = None if schema_checked else first_failure(doc, memory_map_schema())
    if failure is not None:
        path = failure.path
        if len(path) == 3 and path[0] == "register" and path[2] in _WITHIN_SIZE:
            # A range or default is said with the bounds its register's size gives (its size and signed,
            # before it in the schema, passed).
            raise _fail(source, _where(doc, path), _within_size(doc["register"][path[1]], str(path[2])))
        raise _fail(source, _where(doc, path), failure.message)
    head = doc["model"]
    sources = _sources(source, doc.get("source", []))
    names: dict[str, str] = {}
    owner: dict[int, str] = {}
    regs = [_register(source, n, r, names, owner) for n, r in enumerate(doc.get("register", []))]
    regs.sort(key=lambda reg: reg.address)
    number, speed = head["model_number"], head["top_speed_s_per_60deg"]
    also = tuple(head.get("also_named", ()))
    for n, other in enumerate(also):
        if other.upper() == head["name"].upper() or other.upper() in (o.upper() for o in also[:n]):
            raise _fail(source, f"model.also_named.{n}", f"{other!r} is named already")
    return Model(head["name"], None if number == UNKNOWN else number, None if speed == UNKNOWN else float(speed),
                 head.get("readable_to", MAX_READ_ADDRESS), tuple(regs), source, sources,
                 _behaviour(source, doc.get("behaviour", {}), names), also)


def _sources(source: str, tables: list[dict[str, Any]]) -> tuple[Source, ...]:
    """The [[source]] tables: each key given once, every text one printable line."""
    out: list[Source] = []
    for n, t in enumerate(tables):
        for key in ("key", "title", "where"):
            if key in t:
                _printable(source, f"source[{n}].{key}", t[key])
        if any(s.key == t["key"] for s in out):
            raise _fail(source, f"source[{n}].key", f"{t['key']!r} is given already")
        out.append(Source(t["key"], t["title"], t.get("where", "")))
    return tuple(out)


def _behaviour(source: str, t: dict[str, Any], names: dict[str, str]) -> Behaviour:
    """The [behaviour] table the schema passed: register names that exist, one bit per flag, modes beyond
    table 4.3."""
    if "source" in t:
        _printable(source, "behaviour.source", t["source"])
    off = tuple(t.get("torque_off_only", ()))
    for n, name in enumerate(off):
        if name not in names:
            raise _fail(source, f"behaviour.torque_off_only.{n}", f"{name!r} names no register of this map")
    flags = None
    if "return_flags" in t:
        flags = _int_keys(source, "behaviour.return_flags", t["return_flags"])
        for bit in flags:
            if not (0 < bit < 256 and bit & (bit - 1) == 0):
                raise _fail(source, f"behaviour.return_flags.{bit:#x}", "must be one bit of the flag byte (0x01-0x80)")
    areas: dict[int, tuple[int, int]] = {}
    for mode, (first, last) in _int_keys(source, "behaviour.return_areas", t.get("return_areas", {})).items():
        where = f"behaviour.return_areas.{mode:#x}"
        if not 0 <= mode <= RETURN_MODE_MASK or mode in RETURN_MODE_TABLE:
            raise _fail(source, where, "must be a return mode 0x0-0xF that table 4.3 does not define")
        if not 0 <= first <= last <= MAX_READ_ADDRESS:
            raise _fail(source, where, f"must be [first, last] addresses with 0 <= first <= last <= {MAX_READ_ADDRESS}")
        areas[mode] = (first, last - first + 1)
    return Behaviour(
        t.get("flash_and_reboot_together", False), t.get("invalid_baud_code_gives"),
        t.get("over_temperature_recovery", "reboot"), off,
        _manual_return_flags() if flags is None else MappingProxyType(flags), MappingProxyType(areas),
        t.get("voltage_accuracy_v"), t.get("source", ""))


_WITHIN_SIZE = {"range": "must be [min, max] with {lo} <= min <= max <= {hi}",
                "default": "must be an integer {lo}-{hi}"}


def _raw_bounds(r: dict[str, Any]) -> tuple[int, int]:
    """The raw values a register's size and sign can hold."""
    bits = 8 * r.get("size", 1)
    return (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if r.get("signed", False) else (0, (1 << bits) - 1)


def _within_size(r: dict[str, Any], key: str) -> str:
    lo, hi = _raw_bounds(r)
    return _WITHIN_SIZE[key].format(lo=lo, hi=hi)


def _register(source: str, n: int, r: dict[str, Any], names: dict[str, str], owner: dict[int, str]) -> Register:
    """One [[register]] the schema passed, checked against itself and the registers before it."""
    label = _label(r)
    where = f"register[{n}] ({label})"
    address, size, signed, access = r["address"], r.get("size", 1), r.get("signed", False), r.get("access", "read")
    name = r.get("name")
    if name:
        if name in names:
            raise _fail(source, f"{where}.name", f"{name!r} names {names[name]} already")
        names[name] = f"register[{n}]"
    elif access != "reserved":
        raise _fail(source, f"{where}.name", "missing (only reserved registers may be unnamed)")
    if "description" in r:
        _printable(source, f"{where}.description", r["description"])
    lo_ok, hi_ok = _raw_bounds(r)
    rng = r.get("range")
    if rng is not None:
        if not lo_ok <= rng[0] <= rng[1] <= hi_ok:
            raise _fail(source, f"{where}.range", _within_size(r, "range"))
        rng = (rng[0], rng[1])
    default = r.get("default")
    if default is not None and not lo_ok <= default <= hi_ok:
        raise _fail(source, f"{where}.default", _within_size(r, "default"))
    for a in range(address, address + size):
        if a in owner:
            raise _fail(source, f"{where}.address", f"overlaps {owner[a]} at address {a}")
        owner[a] = label
    enum = _int_keys(source, f"{where}.enum", r["enum"]) if "enum" in r else None
    table = _int_keys(source, f"{where}.table", r["table"]) if "table" in r else None
    for raw, text in (enum or {}).items():
        _printable(source, f"{where}.enum.{raw}", text)
    for key in ("source", "note"):
        if key in r:
            _printable(source, f"{where}.{key}", r[key])
    return Register(name, address, size, signed, r.get("scale", 1), r.get("offset", 0), r.get("unit"), access,
                    r.get("area", "ram"), default, rng, r.get("mode", "both"), enum, table, r.get("format"),
                    r.get("description", ""), r.get("source", ""), r.get("note", ""))


def _names_pass(doc: dict[str, Any]) -> bool:
    """Whether a kept document's names pass the schema's patterns once more: the model's, its other names and the
    registers' become code (codegen) and file names, so they are checked on every load, cached or not (a document
    that fails is read and checked whole, and says why)."""
    schema = memory_map_schema()
    model = schema["properties"]["model"]["properties"]
    head = doc.get("model")
    if not isinstance(head, dict):
        return False
    names = [(head.get("name"), model["name"])]
    names += [(other, model["also_named"]["items"]) for other in head.get("also_named", ())]
    names += [(r.get("name"), _REGISTER_NAME_SCHEMA)
              for r in doc.get("register", ()) if isinstance(r, dict) and "name" in r]
    return all(first_failure(value, rule) is None for value, rule in names)


def load_model(path: str | Path) -> Model:
    """Load one memory-map file; a mistake raises ModelError naming the file and the key."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise ModelError(f"{path}: cannot read: {e.strerror}") from None
    kept = map_cache.get(raw)
    if kept is not None and _names_pass(kept):
        return parse_model(kept, str(path), schema_checked=True)
    import tomllib  # a map not kept yet (protocol.map_cache): most start-ups never parse TOML

    try:
        doc = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise ModelError(f"{path}: not UTF-8 text: {e.reason} at byte {e.start}") from None
    except tomllib.TOMLDecodeError as e:
        raise ModelError(f"{path}: not valid TOML: {e}") from None
    model = parse_model(doc, str(path))
    map_cache.keep(raw, doc)  # after every check passed
    return model


def decoders_dirs() -> list[Path]:
    """Where memory maps live: $RS30X_DECODERS, the installed copy, then the source tree's decoders/."""
    dirs = []
    env = os.environ.get("RS30X_DECODERS")
    if env:
        dirs += [Path(p) for p in env.split(os.pathsep) if p]
    package = Path(__file__).resolve().parent.parent  # rs30x_sniff/ (this module is in rs30x_sniff/protocol/)
    dirs += [package / "decoders", package.parent / "decoders"]
    return [d for d in dirs if d.is_dir()]


class ModelRegistry:
    """Every known model, by name and by model number."""

    def __init__(self, models: list[Model]) -> None:
        if not models:
            raise ModelError("no memory maps found (looked for decoders/*.toml)")
        # A map shared by several models (also_named) is a Model of each name, so --model and the output
        # say the one the user has.
        # say the one the user has (a map of that name of its own comes first).
        self.models: dict[str, Model] = {m.name.upper(): m for m in models}
        for m in models:
            for other in m.also_named:
                if other.upper() not in self.models:
                    self.models[other.upper()] = m.renamed(other)
        # A model no source gives a number for (None) is known by --model or the configuration only.
        self.by_number: dict[int, Model] = {m.model_number: m for m in models if m.model_number is not None}

    def get(self, name: str) -> Model:
        try:
            return self.models[name.upper()]
        except KeyError:
            raise ModelError(f"unknown model {name!r} (known: {', '.join(self.models)})") from None

    @property
    def default(self) -> Model:
        return self.models.get(DEFAULT_MODEL) or next(iter(self.models.values()))

    @classmethod
    def from_dirs(cls, dirs: list[Path]) -> ModelRegistry:
        seen: dict[str, Model] = {}
        for d in dirs:
            for p in sorted(d.glob("*.toml")):
                m = load_model(p)
                seen.setdefault(m.name.upper(), m)
        return cls(list(seen.values()))


@lru_cache(maxsize=1)
def default_registry() -> ModelRegistry:
    """The registry of the decoders found by :func:`decoders_dirs` (loaded once)."""
    return ModelRegistry.from_dirs(decoders_dirs())


def loaded_models() -> list[Model]:
    """The models of :func:`default_registry`, or none when a map fails to load: what is said of the models when the
    package is imported (a rule's doc, the rates a --baud may name) never fails there; the command that loads the
    maps reports a broken one in one line."""
    try:
        return list(default_registry().models.values())
    except ModelError:
        return []


@lru_cache(maxsize=1)
def bus_rates() -> tuple[int, ...]:
    """Every rate a servo of the family runs at: table 4.7's, and each memory map's baud_rate table (code 0x0A,
    460800, on the RS301CR, RS302CD and RS405CB): the rates a port scan tries and a typed --baud may name."""
    rates = set(BAUD_RATES)
    for m in loaded_models():
        table = m.register("baud_rate").table if "baud_rate" in m.names else None
        rates.update(int(r) for r in (table or {}).values())
    return tuple(sorted(rates))
