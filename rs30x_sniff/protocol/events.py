"""Immutable event records the frame decoder yields: packets, ACK/NACK bytes and garbage runs.

Events are tuple subclasses with named read-only attributes (frozen and slotted, like a frozen
``dataclass(slots=True)``, but about six times cheaper to build, which matters at 300,000 frames
a second). Two events are equal when their kind and every field are equal.
"""

from __future__ import annotations

from collections.abc import Mapping
from operator import itemgetter
from typing import Any, Literal, final

from .wire import (
    EXPECT_BY_MODE, FLAG_WANTS_ACK, RETURN_MODE_MASK, Expect, command_names, expects, read_range, return_flag_names,
    return_mode)

# Why a run of bytes was skipped (Garbage.reason).
NOISE = "noise"            # no frame header anywhere in the run
BAD_HEADER = "bad-header"  # a header whose length cannot be a real frame
TRUNCATED = "truncated"    # a frame cut short: by an idle gap, a frame starting inside it, or a flagged byte
# The edges of the capture itself, not faults on the wire: the tail of a frame whose start came before
# the capture (or a time segment) began, and a frame the capture's end (or a seam) cut off.
CAPTURE_START = "capture-start"
CAPTURE_END = "capture-end"
CAPTURE_EDGES = (CAPTURE_START, CAPTURE_END)

_COMMON = ("offset", "raw", "t_start", "t_end")


class Event(tuple):
    """Common to every event: where it sits in the byte stream and when it was on the wire."""

    __slots__ = ()
    kind: str = "event"
    _fields: tuple[str, ...] = _COMMON
    # The fields, declared for the type checker only (no class attribute, no cost): _with_fields makes each one
    # a property reading the tuple's item, which the checker cannot see.
    offset: int
    raw: bytes
    t_start: float | None
    t_end: float | None
    checksum_ok = True  # overridden by packets, which carry a Sum

    def __new__(cls, *args: Any, **kwargs: Any):
        if kwargs:
            names = cls._fields[len(args):]
            args = args + tuple(kwargs.pop(n) for n in names if n in kwargs)
            if kwargs:
                raise TypeError(f"{cls.__name__}: unexpected {', '.join(kwargs)}")
        if len(args) != len(cls._fields):
            raise TypeError(f"{cls.__name__} takes {len(cls._fields)} fields, got {len(args)}")
        return tuple.__new__(cls, args)

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and tuple.__eq__(self, other)

    def __ne__(self, other: object) -> bool:
        return not self == other

    __hash__ = tuple.__hash__

    def __repr__(self) -> str:
        inner = ", ".join(f"{n}={v!r}" for n, v in zip(self._fields, self))
        return f"{type(self).__name__}({inner})"

    def __getnewargs__(self):  # pickling (lint -j uses processes)
        return tuple(self)

    def _replace(self, **changes: Any):
        return type(self)(*(changes.pop(n, v) for n, v in zip(self._fields, self)))

    @property
    def end_offset(self) -> int:
        return self[0] + len(self[1])


def _with_fields(cls: type[Event], names: tuple[str, ...]) -> type[Event]:
    """Give an event class its ordered fields as read-only attributes."""
    cls._fields = names
    for k, name in enumerate(names):
        setattr(cls, name, property(itemgetter(k), doc=name))
    return cls


@final  # every kind of event is final: the checker narrows by `type(ev) is ShortPacket` both ways
class ShortPacket(Event):
    """An ``FA AF`` request to one servo (or to all with ID 255)."""

    __slots__ = ()
    kind: Literal["short"] = "short"
    id: int
    flag: int
    address: int
    length: int
    count: int  # type: ignore[assignment]  # the frame's Count field: it shadows tuple.count on purpose
    data: bytes
    checksum_ok: bool

    @property
    def return_mode(self) -> int:
        """Flag bits 3-0 (table 4.3)."""
        return return_mode(self[5])

    @property
    def commands(self) -> tuple[str, ...]:
        """The flash / reboot / initialize bits set in the flag (table 4.2)."""
        return command_names(self[5])

    @property
    def expects(self) -> Expect:
        """What the request expects back: nothing, an ACK/NACK byte, or a return of a range (table 4.3)."""
        return expects(self[5], self[6], self[7])

    @property
    def read_range(self) -> tuple[int, int] | None:
        """(address, length) of the memory this request asks to be returned, if any."""
        e = EXPECT_BY_MODE[self[5] & RETURN_MODE_MASK]  # wire.read_range, inlined: replies look here
        return (self[6], self[7]) if e is None else e.range

    # A servo whose model defines return modes beyond table 4.3 (``areas``: memmap.Behaviour.return_areas, a
    # mode -> (first address, byte count)) answers a request of such a mode: these forms say so.
    def expects_in(self, areas: Mapping[int, tuple[int, int]]) -> Expect:
        """:attr:`expects` of this request to a servo whose model defines ``areas``."""
        return expects(self[5], self[6], self[7], areas)

    def read_range_in(self, areas: Mapping[int, tuple[int, int]]) -> tuple[int, int] | None:
        """:attr:`read_range` of this request to a servo whose model defines ``areas``."""
        return read_range(self[5], self[6], self[7], areas)

    def op_in(self, areas: Mapping[int, tuple[int, int]]) -> str:
        """:attr:`op` of this request to a servo whose model defines ``areas``."""
        return self._op(self.read_range_in(areas) is not None)

    @property
    def wants_ack(self) -> bool:
        return FLAG_WANTS_ACK[self[5]]

    @property
    def op(self) -> str:
        """What the packet does, as one word: write, read, write+read, flash, reboot, ping, ..."""
        return self._op(self.read_range is not None)

    def _op(self, reads: bool) -> str:
        cmds = self.commands
        if cmds:
            return "+".join(cmds)
        if self[9]:
            return "write+read" if reads else ("write+ack" if self.wants_ack else "write")
        if reads:
            return "read"
        return "ping" if self.wants_ack else "empty"


_with_fields(ShortPacket, _COMMON + ("id", "flag", "address", "length", "count", "data", "checksum_ok"))


class LongRecord(tuple):
    """One servo's share of a long packet: its VID and its data bytes."""

    __slots__ = ()
    vid = property(itemgetter(0))
    data = property(itemgetter(1))

    def __new__(cls, vid: int, data: bytes):
        return tuple.__new__(cls, (vid, data))

    def __repr__(self) -> str:
        return f"LongRecord(vid={self[0]}, data={self[1]!r})"


@final
class LongPacket(Event):
    """An ``FA AF`` packet with ID 0 writing the same address range to several servos."""

    __slots__ = ()
    kind: Literal["long"] = "long"
    id = 0
    flag: int
    address: int
    length: int
    count: int  # type: ignore[assignment]  # the frame's Count field: it shadows tuple.count on purpose
    records: tuple[LongRecord, ...]
    checksum_ok: bool

    @property
    def data(self) -> bytes:
        return self[1][7:-1]


_with_fields(LongPacket, _COMMON + ("flag", "address", "length", "count", "records", "checksum_ok"))


@final
class ReturnPacket(Event):
    """An ``FD DF`` packet from a servo: memory it was asked for, and its status flags."""

    __slots__ = ()
    kind: Literal["return"] = "return"
    id: int
    flags: int
    address: int
    length: int
    count: int  # type: ignore[assignment]  # the frame's Count field: it shadows tuple.count on purpose
    data: bytes
    checksum_ok: bool

    @property
    def flag_names(self) -> tuple[str, ...]:
        return return_flag_names(self[5])


_with_fields(ReturnPacket, _COMMON + ("id", "flags", "address", "length", "count", "data", "checksum_ok"))


@final
class Ack(Event):
    """The single byte 07 a servo sends when a request asked for ACK/NACK (table 4.3, mode 0001)."""

    __slots__ = ()
    kind: Literal["ack"] = "ack"


_with_fields(Ack, _COMMON)


@final
class Nack(Event):
    """The single byte 08: the servo refused or did not understand the request."""

    __slots__ = ()
    kind: Literal["nack"] = "nack"


_with_fields(Nack, _COMMON)


@final
class Garbage(Event):
    """A run of bytes that is no intact frame, with the reason it was skipped."""

    __slots__ = ()
    kind: Literal["garbage"] = "garbage"
    checksum_ok = False
    reason: str


_with_fields(Garbage, _COMMON + ("reason",))

Packet = ShortPacket | LongPacket | ReturnPacket

# Field positions by name, for the hot paths that index an event (an index is about three times
# cheaper than a property). Short and return packets share theirs (FLAG is a return packet's flags);
# a long packet has no ID, so its fields sit one place earlier. tests/protocol/test_events.py holds
# them to the classes' _fields.
OFFSET, RAW, T_START, T_END = range(4)
ID, FLAG, ADDRESS, LENGTH, COUNT, DATA, CHECKSUM_OK = range(4, 11)
LONG_FLAG, LONG_ADDRESS, LONG_LENGTH, LONG_COUNT, LONG_RECORDS, LONG_CHECKSUM_OK = range(4, 10)
REASON = 4  # Garbage.reason
Reply = ReturnPacket | Ack | Nack
AnyEvent = ShortPacket | LongPacket | ReturnPacket | Ack | Nack | Garbage


def frame_event(off: int, raw: bytes, t0: float | None, t1: float | None, ok: bool) -> AnyEvent:
    """The event of one whole frame ``raw`` (FA AF or FD DF, header and Sum included) at stream ``off``."""
    sid, flag, address, length, count = raw[2], raw[3], raw[4], raw[5], raw[6]
    data = raw[7:-1]
    if raw[0] == 0xFD:
        return tuple.__new__(ReturnPacket, (off, raw, t0, t1, sid, flag, address, length, count, data, ok))
    if sid == 0:
        records = tuple([tuple.__new__(LongRecord, (data[k], data[k + 1:k + length]))
                         for k in range(0, len(data), length)]) if length else ()
        return tuple.__new__(LongPacket, (off, raw, t0, t1, flag, address, length, count, records, ok))
    return tuple.__new__(ShortPacket, (off, raw, t0, t1, sid, flag, address, length, count, data, ok))
