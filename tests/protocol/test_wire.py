"""The checksum and encoders against the manual's worked examples."""

from rs30x_sniff.protocol import wire
from tests.conftest import h


def test_checksum_example_of_the_manual():
    # "Sum" example: 01 XOR 00 XOR 1E XOR 02 XOR 01 XOR 00 XOR 00 = 1C
    assert wire.checksum(h("01 00 1E 02 01 00 00")) == 0x1C


def test_long_packet_checksum_example():
    assert wire.checksum(h("00 00 1E 03 03 01 64 00 02 64 00 05 F4 01")) == 0xED


def test_encoders_reproduce_manual_packets():
    assert wire.encode_short(1, 0, 0x1E, h("84 03")) == h("FA AF 01 00 1E 02 01 84 03 9B")
    assert wire.encode_command(1, wire.FLAG_WRITE_FLASH) == h("FA AF 01 40 FF 00 00 BE")
    assert wire.encode_command(1, wire.FLAG_REBOOT) == h("FA AF 01 20 FF 00 00 DE")
    assert wire.encode_read(1, 0x2A, 2) == h("FA AF 01 0F 2A 02 00 26")
    assert wire.encode_short(1, 0x09, 0, b"", length=0, count=1) == h("FA AF 01 09 00 00 01 09")
    assert wire.encode_long(0x1E, [(1, h("64 00")), (2, h("64 00")), (5, h("F4 01"))]) == h(
        "FA AF 00 00 1E 03 03 01 64 00 02 64 00 05 F4 01 ED")


def test_return_mode_ranges_follow_table_4_3():
    assert wire.RETURN_MODE_RANGES[0x3] == (0, 30)
    assert wire.RETURN_MODE_RANGES[0x5] == (30, 30)
    assert wire.RETURN_MODE_RANGES[0x7] == (20, 10)
    assert wire.RETURN_MODE_RANGES[0x9] == (42, 18)
    assert wire.RETURN_MODE_RANGES[0xB] == (30, 12)


def test_return_flag_names_follow_table_4_4():
    assert wire.return_flag_names(0xAA) == ("temperature_limit", "temperature_alarm", "flash_write_error",
                                            "received_packet_error")
    assert wire.return_flag_names(0) == ()
