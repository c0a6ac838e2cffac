"""Memory maps as data: load decoders/*.toml and turn memory bytes into named, scaled fields."""

from __future__ import annotations

import os
import re
import struct
import tomllib
from collections.abc import Hashable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from .codegen import values_function
from .wire import MAX_READ_ADDRESS

ACCESS = ("read", "read-write", "reserved")
AREAS = ("invariable-rom", "variable-rom", "ram")
MODES = ("command", "pwm", "both")
_REGISTER_KEYS = {"name", "address", "size", "signed", "scale", "offset", "unit", "access", "area",
                  "default", "range", "mode", "enum", "table", "format", "description"}
_MODEL_KEYS = {"name", "model_number", "top_speed_s_per_60deg", "readable_to"}
DEFAULT_MODEL = "RS303MR"
# A map is data, never code: its names become filter terms, JSON keys, MCAP fields and the field names of
# generated plug-ins (sigrok, Logic 2, Wireshark), so they are checked as the map loads. A register is a
# snake_case word that is neither a filter key nor the label of an unnamed byte; a model, a word with - or _.
REGISTER_NAME = re.compile(r"[a-z][a-z0-9_]{0,47}")
MODEL_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,31}")
UNIT = re.compile(r"[A-Za-z%/°µ][A-Za-z0-9%/°µ._^-]{0,15}")
RESERVED_NAMES = frozenset({"id", "kind", "reg", "sev", "latency", "t"})  # the filter language's keys
_UNNAMED_LABEL = re.compile(r"(reserved|addr)_\d+")
TEXT_MAX = 500  # characters of a description or an enum label
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
            for k, v in self.enum.items():
                if v == value:
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


@dataclass(slots=True, eq=False)
class Model:
    """A servo model's memory map, loaded from one ``decoders/*.toml`` file.

    A model is equal only to itself (and hashes so): the caches below belong to it, and what other
    modules compile for a model (a filter's check, a line template) is kept by the model itself.
    """

    name: str
    model_number: int
    top_speed_s_per_60deg: float
    readable_to: int
    registers: tuple[Register, ...]
    source: str = ""
    _by_address: dict[int, Register] = field(default_factory=dict, repr=False)
    _by_name: dict[str, Register] = field(default_factory=dict, repr=False)
    _layouts: dict[tuple, Layout] = field(default_factory=dict, repr=False)
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
        key = (address, length, "names")
        names = self._layouts.get(key)
        if names is None:
            names = self._layouts[key] = tuple(reg.label for _, _, reg, _ in self.layout(address, length).parts)
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
        parts = []
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


def _text(source: str, where: str, value: Any, limit: int = TEXT_MAX) -> str:
    """A free-text value (a description, an enum label): a string of printable characters on one line.
    Plug-ins still escape it for their language; this keeps control bytes out of every report."""
    if not isinstance(value, str):
        raise _fail(source, where, "must be a string")
    if len(value) > limit:
        raise _fail(source, where, f"longer than {limit} characters")
    bad = next((c for c in value if not c.isprintable()), None)
    if bad is not None:
        raise _fail(source, where, f"holds the control character {bad!r}: one printable line")
    return value


def _register_name(source: str, where: str, name: Any) -> str:
    if not isinstance(name, str) or not REGISTER_NAME.fullmatch(name):
        raise _fail(source, where, f"{name!r} is no register name: lower-case letters, digits and _, "
                                   f"starting with a letter, at most 48 (present_temperature)")
    if name in RESERVED_NAMES or _UNNAMED_LABEL.fullmatch(name):
        raise _fail(source, where, f"{name!r} is taken (a filter key, or the label of an unnamed byte)")
    return name


def _int_keys(source: str, where: str, table: dict) -> dict[int, Any]:
    if not isinstance(table, dict):
        raise _fail(source, where, "must be a table of raw value = ...")
    try:
        return {int(k, 0): v for k, v in table.items()}
    except ValueError:
        raise _fail(source, where, "keys must be integers") from None


def parse_model(doc: dict[str, Any], source: str = "<memory map>") -> Model:
    """Build a Model from a parsed TOML document, checking every key."""
    unknown = set(doc) - {"model", "register"}
    if unknown:
        raise _fail(source, sorted(unknown)[0], "unknown key")
    head = doc.get("model")
    if not isinstance(head, dict):
        raise _fail(source, "model", "missing [model] table")
    for k in head:
        if k not in _MODEL_KEYS:
            raise _fail(source, f"model.{k}", "unknown key")
    for k in ("name", "model_number", "top_speed_s_per_60deg"):
        if k not in head:
            raise _fail(source, f"model.{k}", "missing")
    if not isinstance(head["name"], str) or not MODEL_NAME.fullmatch(head["name"]):
        raise _fail(source, "model.name", f"{head['name']!r} is no model name: letters, digits, - and _, "
                                          f"at most 32 (RS303MR)")
    number = head["model_number"]
    if not isinstance(number, int) or isinstance(number, bool) or not 0 <= number <= 0xFFFF:
        raise _fail(source, "model.model_number", "must be an integer 0-0xFFFF (address 0-1, table 4.5)")
    speed = head["top_speed_s_per_60deg"]
    if not isinstance(speed, (int, float)) or isinstance(speed, bool) or not 0 < speed < 100:
        raise _fail(source, "model.top_speed_s_per_60deg", "must be a positive number of seconds")
    readable = head.get("readable_to", MAX_READ_ADDRESS)
    if not isinstance(readable, int) or isinstance(readable, bool) or not 0 <= readable <= 255:
        raise _fail(source, "model.readable_to", "must be an integer 0-255")
    names: dict[str, str] = {}
    regs: list[Register] = []
    owner: dict[int, str] = {}
    for n, r in enumerate(doc.get("register", [])):
        if not isinstance(r, dict):
            raise _fail(source, f"register[{n}]", "must be a table")
        label = r.get("name") or (f"address {r['address']}" if "address" in r else "?")
        if "name" in r and not (isinstance(label, str) and REGISTER_NAME.fullmatch(label)):
            label = repr(label)[:60]  # a bad name is said as a literal, never printed as it is
        where = f"register[{n}] ({label})"
        for k in r:
            if k not in _REGISTER_KEYS:
                raise _fail(source, f"{where}.{k}", "unknown key")
        if "address" not in r:
            raise _fail(source, f"{where}.address", "missing")
        address, size = r["address"], r.get("size", 1)
        if not isinstance(address, int) or not 0 <= address <= 255:
            raise _fail(source, f"{where}.address", "must be an integer 0-255")
        if size not in (1, 2):
            raise _fail(source, f"{where}.size", "must be 1 or 2")
        access = r.get("access", "read")
        if access not in ACCESS:
            raise _fail(source, f"{where}.access", f"must be one of {', '.join(ACCESS)}")
        if access != "reserved" and not r.get("name"):
            raise _fail(source, f"{where}.name", "missing (only reserved registers may be unnamed)")
        if r.get("name"):
            name = _register_name(source, f"{where}.name", r["name"])
            if name in names:
                raise _fail(source, f"{where}.name", f"{name!r} names {names[name]} already")
            names[name] = f"register[{n}]"
        unit = r.get("unit")
        if unit is not None and (not isinstance(unit, str) or not UNIT.fullmatch(unit)):
            raise _fail(source, f"{where}.unit", f"{unit!r} is no unit: a word such as deg, degC, mA, deg/s, %")
        if r.get("format") not in (None, "hex"):
            raise _fail(source, f"{where}.format", "must be \"hex\" (or left out)")
        if "description" in r:
            _text(source, f"{where}.description", r["description"])
        if not isinstance(r.get("offset", 0), (int, float)) or isinstance(r.get("offset", 0), bool):
            raise _fail(source, f"{where}.offset", "must be a number")
        if r.get("area", "ram") not in AREAS:
            raise _fail(source, f"{where}.area", f"must be one of {', '.join(AREAS)}")
        if r.get("mode", "both") not in MODES:
            raise _fail(source, f"{where}.mode", f"must be one of {', '.join(MODES)}")
        signed = bool(r.get("signed", False))
        lo_ok = -(1 << (8 * size - 1)) if signed else 0
        hi_ok = (1 << (8 * size - 1)) - 1 if signed else (1 << 8 * size) - 1
        rng = r.get("range")
        if rng is not None:
            if (not isinstance(rng, list) or len(rng) != 2 or not all(isinstance(x, int) for x in rng)
                    or rng[0] > rng[1] or rng[0] < lo_ok or rng[1] > hi_ok):
                raise _fail(source, f"{where}.range", f"must be [min, max] with {lo_ok} <= min <= max <= {hi_ok}")
            rng = (rng[0], rng[1])
        default = r.get("default")
        if default is not None and not (isinstance(default, int) and lo_ok <= default <= hi_ok):
            raise _fail(source, f"{where}.default", f"must be an integer {lo_ok}-{hi_ok}")
        scale = r.get("scale", 1)
        if not isinstance(scale, (int, float)) or scale <= 0:
            raise _fail(source, f"{where}.scale", "must be a positive number")
        for a in range(address, address + size):
            if a in owner:
                raise _fail(source, f"{where}.address", f"overlaps {owner[a]} at address {a}")
            owner[a] = label
        enum = _int_keys(source, f"{where}.enum", r["enum"]) if "enum" in r else None
        table = _int_keys(source, f"{where}.table", r["table"]) if "table" in r else None
        for raw, text in (enum or {}).items():
            _text(source, f"{where}.enum.{raw}", text, 64)
        for raw, number in (table or {}).items():
            if not isinstance(number, (int, float)) or isinstance(number, bool):
                raise _fail(source, f"{where}.table.{raw}", "must be a number")
        regs.append(Register(
            r.get("name"), address, size, signed, scale, r.get("offset", 0), r.get("unit"), access,
            r.get("area", "ram"), default, rng, r.get("mode", "both"), enum, table, r.get("format"),
            r.get("description", ""),
        ))
    regs.sort(key=lambda reg: reg.address)
    return Model(head["name"], head["model_number"], float(head["top_speed_s_per_60deg"]),
                 head.get("readable_to", MAX_READ_ADDRESS), tuple(regs), source)


def load_model(path: str | Path) -> Model:
    """Load one memory-map file; a mistake raises ModelError naming the file and the key."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise ModelError(f"{path}: cannot read: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise ModelError(f"{path}: not valid TOML: {e}") from None
    return parse_model(doc, str(path))


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
        self.models = {m.name.upper(): m for m in models}
        self.by_number = {m.model_number: m for m in models}

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
