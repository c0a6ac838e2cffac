"""Wire constants of the RS30x protocol, the XOR checksum, and packet encoders."""

from __future__ import annotations

from functools import reduce
from operator import xor

# Headers (manual, "Format of Packets"): requests start FA AF, returns FD DF.
REQUEST_HEADER = b"\xfa\xaf"
RETURN_HEADER = b"\xfd\xdf"
ACK = 0x07
NACK = 0x08
HEADER_SIZE = 7  # header(2) ID flag address length count
BROADCAST_ID = 0xFF
LONG_PACKET_ID = 0x00

# Flag bits of a request (table 4.2).
FLAG_RESERVED = 0x80
FLAG_WRITE_FLASH = 0x40
FLAG_REBOOT = 0x20
FLAG_INITIALIZE = 0x10
RETURN_MODE_MASK = 0x0F

# Return modes, flag bits 3-0 (table 4.3): mode -> (first address, byte count).
RETURN_NONE = 0x0
RETURN_ACK = 0x1
RETURN_SPECIFIED = 0xF
RETURN_MODE_RANGES: dict[int, tuple[int, int]] = {
    0x3: (0, 30),
    0x5: (30, 30),
    0x7: (20, 10),
    0x9: (42, 18),
    0xB: (30, 12),
}
RETURN_MODES = frozenset({RETURN_NONE, RETURN_ACK, RETURN_SPECIFIED, *RETURN_MODE_RANGES})
MAX_READ_ADDRESS = 139  # "addresses No.00 to No.139" readable by flag 0F

# Flags of a return packet (table 4.4): bit -> name.
RETURN_FLAG_BITS: dict[int, str] = {
    0x80: "temperature_limit",
    0x20: "temperature_alarm",
    0x08: "flash_write_error",
    0x02: "received_packet_error",
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
    return encode_short(servo_id, flag, 0xFF, b"", length=0, count=0)


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
