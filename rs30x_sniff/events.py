"""Frozen, slotted event records the frame decoder yields: packets, ACK/NACK bytes and garbage runs."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from .wire import (
    FLAG_INITIALIZE,
    FLAG_REBOOT,
    FLAG_WRITE_FLASH,
    RETURN_ACK,
    RETURN_MODE_MASK,
    RETURN_MODE_RANGES,
    RETURN_SPECIFIED,
    return_flag_names,
)

# Why a run of bytes was skipped (Garbage.reason).
NOISE = "noise"            # no frame header anywhere in the run
BAD_HEADER = "bad-header"  # a header whose length cannot be a real frame
TRUNCATED = "truncated"    # a frame cut short: by an idle gap, by a frame starting inside it, or by end of input


@dataclass(frozen=True, slots=True)
class Event:
    """Common to every event: where it sits in the byte stream and when it was on the wire."""

    kind: ClassVar[str] = "event"
    offset: int
    raw: bytes
    t_start: float | None
    t_end: float | None

    @property
    def checksum_ok(self) -> bool:
        return True

    @property
    def end_offset(self) -> int:
        return self.offset + len(self.raw)


@dataclass(frozen=True, slots=True)
class ShortPacket(Event):
    """An ``FA AF`` request to one servo (or to all with ID 255)."""

    kind: ClassVar[str] = "short"
    id: int
    flag: int
    address: int
    length: int
    count: int
    data: bytes
    checksum_ok: bool  # type: ignore[misc]

    @property
    def return_mode(self) -> int:
        return self.flag & RETURN_MODE_MASK

    @property
    def commands(self) -> tuple[str, ...]:
        """The flash / reboot / initialize bits set in the flag (table 4.2)."""
        f = self.flag
        return tuple(
            name for bit, name in ((FLAG_WRITE_FLASH, "flash"), (FLAG_REBOOT, "reboot"), (FLAG_INITIALIZE, "initialize"))
            if f & bit
        )

    @property
    def read_range(self) -> tuple[int, int] | None:
        """(address, length) of the memory this request asks to be returned, if any."""
        mode = self.flag & RETURN_MODE_MASK
        if mode == RETURN_SPECIFIED:
            return (self.address, self.length)
        return RETURN_MODE_RANGES.get(mode)

    @property
    def wants_ack(self) -> bool:
        return self.flag & RETURN_MODE_MASK == RETURN_ACK

    @property
    def op(self) -> str:
        """What the packet does, as one word: write, read, write+read, flash, reboot, ping, ..."""
        cmds = self.commands
        if cmds:
            return "+".join(cmds)
        reads = self.read_range is not None
        if self.data:
            return "write+read" if reads else ("write+ack" if self.wants_ack else "write")
        if reads:
            return "read"
        return "ping" if self.wants_ack else "empty"


@dataclass(frozen=True, slots=True)
class LongRecord:
    """One servo's share of a long packet."""

    vid: int
    data: bytes


@dataclass(frozen=True, slots=True)
class LongPacket(Event):
    """An ``FA AF`` packet with ID 0 writing the same address range to several servos."""

    kind: ClassVar[str] = "long"
    flag: int
    address: int
    length: int
    count: int
    records: tuple[LongRecord, ...]
    checksum_ok: bool  # type: ignore[misc]

    id: ClassVar[int] = 0

    @property
    def data(self) -> bytes:
        return self.raw[7:-1]


@dataclass(frozen=True, slots=True)
class ReturnPacket(Event):
    """An ``FD DF`` packet from a servo: memory it was asked for, and its status flags."""

    kind: ClassVar[str] = "return"
    id: int
    flags: int
    address: int
    length: int
    count: int
    data: bytes
    checksum_ok: bool  # type: ignore[misc]

    @property
    def flag_names(self) -> tuple[str, ...]:
        return return_flag_names(self.flags)


@dataclass(frozen=True, slots=True)
class Ack(Event):
    """The single byte 07 a servo sends when a request asked for ACK/NACK (table 4.3, mode 0001)."""

    kind: ClassVar[str] = "ack"


@dataclass(frozen=True, slots=True)
class Nack(Event):
    """The single byte 08: the servo refused or did not understand the request."""

    kind: ClassVar[str] = "nack"


@dataclass(frozen=True, slots=True)
class Garbage(Event):
    """A run of bytes that is no intact frame, with the reason it was skipped."""

    kind: ClassVar[str] = "garbage"
    reason: str


Packet = ShortPacket | LongPacket | ReturnPacket
Reply = ReturnPacket | Ack | Nack
AnyEvent = ShortPacket | LongPacket | ReturnPacket | Ack | Nack | Garbage
