"""The protocol-meaning tables of wire.py against the manual's tables 4.2-4.4."""

import pytest

from rs30x_sniff.protocol import wire
from rs30x_sniff.protocol.wire import Expect


@pytest.mark.parametrize(("mode", "expect"), [
    (0x0, Expect("none")),                    # 0000 no return packet
    (0x1, Expect("ack")),                     # 0001 ACK/NACK
    (0x3, Expect("return", (0, 30))),         # 0011 No. 00-29
    (0x5, Expect("return", (30, 30))),        # 0101 No. 30-59
    (0x7, Expect("return", (20, 10))),        # 0111 No. 20-29
    (0x9, Expect("return", (42, 18))),        # 1001 No. 42-59
    (0xB, Expect("return", (30, 12))),        # 1011 No. 30-41
    (0xF, Expect("return", (0x2A, 2))),       # 1111 the request's own Address and Length
])
def test_every_return_mode_of_table_4_3_expects_its_reply(mode, expect):
    assert wire.expects(mode, 0x2A, 2) == expect
    # The command bits (table 4.2) do not change what comes back.
    for bits in (0, wire.FLAG_WRITE_FLASH, wire.FLAG_REBOOT, wire.FLAG_INITIALIZE, wire.FLAG_RESERVED):
        assert wire.expects(bits | mode, 0x2A, 2) == expect
        assert wire.return_mode(bits | mode) == mode
        assert wire.FLAG_WANTS_REPLY[bits | mode] == (expect.kind != "none")
        assert wire.FLAG_WANTS_ACK[bits | mode] == (expect.kind == "ack")
        assert wire.read_range(bits | mode, 0x2A, 2) == expect.range


def test_the_table_holds_exactly_the_modes_of_table_4_3():
    assert sorted(wire.RETURN_MODE_TABLE) == [0x0, 0x1, 0x3, 0x5, 0x7, 0x9, 0xB, 0xF]
    assert wire.RETURN_MODES == frozenset(wire.RETURN_MODE_TABLE)
    assert all(wire.is_defined_mode(m) for m in wire.RETURN_MODES)


@pytest.mark.parametrize("mode", [m for m in range(16) if m not in (0x0, 0x1, 0x3, 0x5, 0x7, 0x9, 0xB, 0xF)])
def test_an_undefined_mode_expects_nothing_to_wait_for(mode):
    assert not wire.is_defined_mode(mode)
    assert wire.expects(mode, 0x2A, 2) == Expect("none")
    assert not wire.FLAG_WANTS_REPLY[mode]
    assert wire.request_flag_names(mode) == [f"return_mode_{mode:04b}"]


def test_request_flag_bits_of_table_4_2():
    assert (wire.FLAG_RESERVED, wire.FLAG_WRITE_FLASH, wire.FLAG_REBOOT, wire.FLAG_INITIALIZE) == (0x80, 0x40, 0x20, 0x10)
    assert wire.COMMAND_BITS == 0x70
    assert wire.RETURN_MODE_MASK == 0x0F
    assert wire.command_names(0x40) == ("flash",)
    assert wire.command_names(0x20) == ("reboot",)
    assert wire.command_names(0x10) == ("initialize",)
    assert wire.command_names(0x7F) == ("flash", "reboot", "initialize")
    assert wire.command_names(0x8F) == ()
    assert [f for f in range(256) if wire.is_command(f)] == [f for f in range(256) if f & 0x70]


def test_request_flag_names():
    assert wire.request_flag_names(0x00) == []
    assert wire.request_flag_names(0x01) == ["return_ack"]
    assert wire.request_flag_names(0x0F) == ["return_specified"]
    assert wire.request_flag_names(0x09) == ["return_42_59"]
    assert wire.request_flag_names(0xC3) == ["flash", "reserved_bit7", "return_0_29"]


def test_return_flag_bits_of_table_4_4():
    assert wire.RETURN_FLAG_BITS == {0x80: "temperature_limit", 0x20: "temperature_alarm",
                                     0x08: "flash_write_error", 0x02: "received_packet_error"}
    assert wire.RETURN_FLAGS_RESERVED == 0x55
    assert wire.RETURN_FLAGS_RESERVED & sum(wire.RETURN_FLAG_BITS) == 0
    assert wire.RETURN_FLAGS_RESERVED | sum(wire.RETURN_FLAG_BITS) == 0xFF
    assert wire.return_flag_names(0xA2) == ("temperature_limit", "temperature_alarm", "received_packet_error")
