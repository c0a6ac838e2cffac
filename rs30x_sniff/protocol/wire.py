"""Wire constants and meanings of the RS30x protocol (flag tables 4.2-4.4), the XOR checksum, and encoders."""

from __future__ import annotations

from collections.abc import Mapping
from functools import reduce
from operator import xor
from types import MappingProxyType
from typing import NamedTuple

# Headers (manual, "Format of Packets"): requests start FA AF, returns FD DF.
REQUEST_HEADER = b"\xfa\xaf"
RETURN_HEADER = b"\xfd\xdf"
ACK = 0x07
NACK = 0x08
# The packet layout (manual, "Format of Packets"): header(2) ID Flag Address Length Count, then the
# data, then one Sum byte. A return packet has the same layout, its Flag byte holding the status flags.
AT_ID = 2
AT_FLAG = 3
AT_ADDRESS = 4
AT_LENGTH = 5
AT_COUNT = 6
HEADER_SIZE = 7  # the bytes before the data: header(2) ID flag address length count
AT_DATA = HEADER_SIZE
SUM_SIZE = 1     # the XOR Sum after the data
FRAME_OVERHEAD = HEADER_SIZE + SUM_SIZE  # a frame's length beyond its data
VID_SIZE = 1     # a long packet's record: its VID byte, then the data (Length = data + 1, "Long Packet")
REQUEST_FIRST = REQUEST_HEADER[0]  # 0xFA: the byte a request starts with
RETURN_FIRST = RETURN_HEADER[0]    # 0xFD: the byte a return packet starts with
BROADCAST_ID = 0xFF
LONG_PACKET_ID = 0x00
# A flash / reboot / initialize command is sent to Address FF with Length 0 and Count 0 (table 4.2 notes).
COMMAND_ADDRESS = 0xFF

# ---- request flags (table 4.2) -----------------------------------------------------------------
# This block and the tables below are the one place that knows what the flag bits mean: every other
# module asks these names and helpers instead of masking the flag itself.
FLAG_RESERVED = 0x80     # bit 7: "Set 0 to this bit always"
FLAG_WRITE_FLASH = 0x40  # bit 6: save No. 4-29 to flash ROM
FLAG_REBOOT = 0x20       # bit 5: reboot the servo
FLAG_INITIALIZE = 0x10   # bit 4: No. 4-29 back to their defaults
COMMAND_BITS = FLAG_WRITE_FLASH | FLAG_REBOOT | FLAG_INITIALIZE
RETURN_MODE_MASK = 0x0F  # bits 3-0: the return mode of table 4.3
# The command bits by name, in bit order (the order ShortPacket.commands lists them).
COMMANDS: tuple[tuple[int, str], ...] = (
    (FLAG_WRITE_FLASH, "flash"), (FLAG_REBOOT, "reboot"), (FLAG_INITIALIZE, "initialize"))

# ---- return modes (table 4.3) ------------------------------------------------------------------
class Expect(NamedTuple):
    """What a request expects back: nothing, one ACK/NACK byte, or a return packet of ``range``."""

    kind: str                             # "none", "ack" or "return"
    range: tuple[int, int] | None = None  # for "return": (first address, byte count)


class ReturnMode(NamedTuple):
    """One row of table 4.3."""

    mode: int
    name: str | None        # the JSON flag name (record_json "flags"); None for "no return packet"
    expect: Expect | None   # None for mode F: the request's own Address and Length say the range


RETURN_NONE = 0x0
RETURN_ACK = 0x1
RETURN_SPECIFIED = 0xF
_EXPECT_NONE = Expect("none")
_EXPECT_ACK = Expect("ack")


def _fixed(mode: int, first: int, count: int) -> ReturnMode:
    return ReturnMode(mode, f"return_{first}_{first + count - 1}", Expect("return", (first, count)))


RETURN_MODE_TABLE: dict[int, ReturnMode] = {m.mode: m for m in (
    ReturnMode(RETURN_NONE, None, _EXPECT_NONE),        # 0000 no return packet
    ReturnMode(RETURN_ACK, "return_ack", _EXPECT_ACK),  # 0001 ACK/NACK
    _fixed(0x3, 0, 30),                                 # 0011 No. 00-29
    _fixed(0x5, 30, 30),                                # 0101 No. 30-59
    _fixed(0x7, 20, 10),                                # 0111 No. 20-29
    _fixed(0x9, 42, 18),                                # 1001 No. 42-59
    _fixed(0xB, 30, 12),                                # 1011 No. 30-41
    ReturnMode(RETURN_SPECIFIED, "return_specified", None),  # 1111 the specified address and length
)}
# Fixed ranges by mode: (first address, byte count).
RETURN_MODE_RANGES: dict[int, tuple[int, int]] = {
    m.mode: m.expect.range for m in RETURN_MODE_TABLE.values() if m.expect is not None and m.expect.range}
RETURN_MODES = frozenset(RETURN_MODE_TABLE)
MAX_READ_ADDRESS = 139  # "addresses No.00 to No.139" readable by flag 0F

# Per return mode (0-15) the Expect; None for mode F, which takes the request's range. A mode table
# 4.3 does not define asks for nothing the pairing can wait for, so it expects nothing.
EXPECT_BY_MODE: tuple[Expect | None, ...] = tuple(
    RETURN_MODE_TABLE[m].expect if m in RETURN_MODE_TABLE else _EXPECT_NONE for m in range(16))
# Per flag byte (0-255), for the hot paths (framing, bus pairing): one tuple index, no masking.
FLAG_WANTS_ACK: tuple[bool, ...] = tuple(f & RETURN_MODE_MASK == RETURN_ACK for f in range(256))
FLAG_WANTS_REPLY: tuple[bool, ...] = tuple(
    EXPECT_BY_MODE[f & RETURN_MODE_MASK] is not _EXPECT_NONE for f in range(256))
# Per flag byte: True where table 4.3 does not define its return mode. Another model's manual may (a map's
# [behaviour] return_areas: mode -> (first address, byte count)); only such a flag needs the servo's model.
FLAG_MODE_UNDEFINED: tuple[bool, ...] = tuple(f & RETURN_MODE_MASK not in RETURN_MODE_TABLE for f in range(256))
NO_AREAS: Mapping[int, tuple[int, int]] = MappingProxyType({})  # a model with no return mode beyond table 4.3
_COMMAND_NAMES: tuple[tuple[str, ...], ...] = tuple(
    tuple(name for bit, name in COMMANDS if f & bit) for f in range(256))


def return_mode(flag: int) -> int:
    """The return mode of a request's flag: bits 3-0 (table 4.3)."""
    return flag & RETURN_MODE_MASK


def is_defined_mode(flag: int) -> bool:
    """Whether the flag's return mode is one table 4.3 defines."""
    return flag & RETURN_MODE_MASK in RETURN_MODE_TABLE


def is_command(flag: int) -> bool:
    """Whether the flag sets a flash, reboot or initialize bit (table 4.2 bits 6-4)."""
    return flag & COMMAND_BITS != 0


def command_names(flag: int) -> tuple[str, ...]:
    """The commands a request flag sets, in bit order: "flash", "reboot", "initialize" (table 4.2)."""
    return _COMMAND_NAMES[flag & 0xFF]


def expects(flag: int, address: int = 0, length: int = 0, areas: Mapping[int, tuple[int, int]] = NO_AREAS) -> Expect:
    """What a short request with this flag (and, for mode F, this Address and Length) expects back; ``areas``:
    the return modes beyond table 4.3 its servo's model defines (memmap.Behaviour.return_areas)."""
    e = EXPECT_BY_MODE[flag & RETURN_MODE_MASK]
    if e is None:
        return Expect("return", (address, length))
    if areas and FLAG_MODE_UNDEFINED[flag & 0xFF]:
        area = areas.get(flag & RETURN_MODE_MASK)
        if area is not None:
            return Expect("return", area)
    return e


def read_range(flag: int, address: int = 0, length: int = 0,
               areas: Mapping[int, tuple[int, int]] = NO_AREAS) -> tuple[int, int] | None:
    """(first address, byte count) of the return packet the request asks for, if any (table 4.3, and
    ``areas`` as :func:`expects` takes them)."""
    return expects(flag, address, length, areas).range


def request_flag_names(flag: int) -> list[str]:
    """Names of what a short request's flag says: its commands, reserved_bit7, its return mode."""
    names = list(_COMMAND_NAMES[flag & 0xFF])
    if flag & FLAG_RESERVED:
        names.append("reserved_bit7")
    mode = flag & RETURN_MODE_MASK
    row = RETURN_MODE_TABLE.get(mode)
    if row is None:
        names.append(f"return_mode_{mode:04b}")
    elif row.name is not None:
        names.append(row.name)
    return names


# ---- return packet flags (table 4.4) -----------------------------------------------------------
RETURN_TEMPERATURE_LIMIT = 0x80   # bit 7: temperature limit passed, torque off
RETURN_TEMPERATURE_ALARM = 0x20   # bit 5: within 10 degC of the limit
RETURN_FLASH_WRITE_ERROR = 0x08   # bit 3: the last flash ROM write failed
RETURN_RECEIVED_ERROR = 0x02      # bit 1: a packet the servo could not accept
RETURN_FLAGS_RESERVED = 0x55      # bits 6, 4, 2, 0: always 0
# Status bit -> name.
RETURN_FLAG_BITS: dict[int, str] = {
    RETURN_TEMPERATURE_LIMIT: "temperature_limit",
    RETURN_TEMPERATURE_ALARM: "temperature_alarm",
    RETURN_FLASH_WRITE_ERROR: "flash_write_error",
    RETURN_RECEIVED_ERROR: "received_packet_error",
}

# Baud rate codes of register 6 (table 4.7).
BAUD_RATES: tuple[int, ...] = (9600, 14400, 19200, 28800, 38400, 57600, 76800, 115200, 153600, 230400)
DEFAULT_BAUD = 115200
BITS_PER_BYTE = 10  # 8N1: start + 8 data + stop


def byte_time(baud: int) -> float:
    """Seconds one byte occupies on the wire at ``baud`` (8N1)."""
    return BITS_PER_BYTE / baud


def checksum(data: bytes | bytearray | memoryview) -> int:
    """XOR of every byte: the Sum of a packet over ID through the last data byte."""
    return reduce(xor, data, 0)


def return_flag_names(flags: int) -> tuple[str, ...]:
    """Names of the status bits set in a return packet's flags."""
    return tuple(name for bit, name in RETURN_FLAG_BITS.items() if flags & bit)


def encode_short(
    servo_id: int, flag: int = 0, address: int = 0, data: bytes = b"", *, length: int | None = None,
    count: int | None = None,
) -> bytes:
    """A short packet. ``length``/``count`` default to len(data) and 1 (0 when there is no data)."""
    if length is None:
        length = len(data)
    if count is None:
        count = 1 if data else 0
    body = bytes((servo_id, flag, address, length, count)) + bytes(data)
    return REQUEST_HEADER + body + bytes((checksum(body),))


def encode_read(servo_id: int, address: int, length: int) -> bytes:
    """A flag-0F read of ``length`` bytes from ``address`` (count 0, no data)."""
    return encode_short(servo_id, RETURN_SPECIFIED, address, b"", length=length, count=0)


def encode_command(servo_id: int, flag: int) -> bytes:
    """A flash-write, reboot or initialize command: address FF, length 0, count 0."""
    return encode_short(servo_id, flag, COMMAND_ADDRESS, b"", length=0, count=0)


def encode_long(address: int, records: list[tuple[int, bytes]]) -> bytes:
    """A long packet writing the same address range to several servos (one ``(vid, data)`` each)."""
    if not records:
        raise ValueError("a long packet needs at least one record")
    size = len(records[0][1])
    if any(len(d) != size for _, d in records):
        raise ValueError("every record of a long packet carries the same number of bytes")
    payload = b"".join(bytes((vid,)) + bytes(d) for vid, d in records)
    body = bytes((LONG_PACKET_ID, 0, address, size + 1, len(records))) + payload
    return REQUEST_HEADER + body + bytes((checksum(body),))


def encode_return(servo_id: int, address: int, data: bytes, flags: int = 0) -> bytes:
    """A return packet from ``servo_id`` carrying ``data`` read from ``address``."""
    body = bytes((servo_id, flags, address, len(data), 1)) + bytes(data)
    return RETURN_HEADER + body + bytes((checksum(body),))
