"""Golden tests: every example of the manual decodes to what the manual says it means."""

import pytest

from rs30x_sniff.sources.captures import read_capture
from rs30x_sniff.decode.decoder import Decoder


@pytest.fixture(scope="module")
def records(manual_examples_path):
    dec = Decoder()
    out = []
    for data, t in read_capture(str(manual_examples_path)):
        out += dec.feed(data, t)
    return out + dec.close()


@pytest.fixture(scope="module")
def manual_examples_path():
    from tests.conftest import CAPTURES
    return CAPTURES / "manual-examples.hex"


def values(rec):
    return [(f.id, f.name, f.value) for f in rec.fields if f.name]


def by_raw(records, hexstr):
    raw = bytes.fromhex(hexstr)
    [rec] = [r for r in records if r.event.raw == raw]
    return rec


def test_every_example_is_an_intact_frame(records):
    assert all(r.event.checksum_ok for r in records)
    assert not [r for r in records if r.kind == "garbage"]
    assert len(records) == 24


@pytest.mark.parametrize("packet,expected", [
    ("FA AF 01 00 1E 02 01 84 03 9B", [(1, "goal_position", 90.0)]),
    ("FA AF 01 00 1E 02 01 7C FC 9C", [(1, "goal_position", -90.0)]),
    ("FA AF 01 00 1E 04 01 84 03 F4 01 68", [(1, "goal_position", 90.0), (1, "goal_time", 5.0)]),
    ("FA AF 01 00 1E 04 01 50 FB E8 03 5A", [(1, "goal_position", -120.0), (1, "goal_time", 10.0)]),
    ("FA AF 00 00 1E 03 03 01 64 00 02 64 00 05 F4 01 ED",
     [(1, "goal_position", 10.0), (2, "goal_position", 10.0), (5, "goal_position", 50.0)]),
    ("FA AF 01 00 04 01 01 05 00", [(1, "servo_id", 5)]),
    ("FA AF 01 00 05 01 01 01 05", [(1, "reverse", "reverse")]),
    ("FA AF 01 00 06 01 01 04 03", [(1, "baud_rate", 38400)]),
    ("FA AF 01 60 07 01 01 12 74", [(1, "return_delay", 1000)]),
    ("FA AF 01 00 08 02 01 E8 03 E1", [(1, "cw_angle_limit", 100.0)]),
    ("FA AF 01 00 1C 02 01 64 00 7A", [(1, "punch", 1.0)]),
    ("FA AF 01 00 18 06 01 03 03 14 14 64 00 7A",
     [(1, "cw_compliance_margin", 0.3), (1, "ccw_compliance_margin", 0.3), (1, "cw_compliance_slope", 20),
      (1, "ccw_compliance_slope", 20), (1, "punch", 1.0)]),
    ("FA AF 01 00 23 01 01 50 72", [(1, "max_torque", 80)]),
    ("FA AF 01 00 24 01 01 01 24", [(1, "torque_enable", "on")]),
    ("FA AF 01 00 24 01 01 00 25", [(1, "torque_enable", "off")]),
    ("FA AF 01 00 24 01 01 02 27", [(1, "torque_enable", "brake")]),
])
def test_write_examples(records, packet, expected):
    assert values(by_raw(records, packet)) == expected


def test_the_mistyped_ccw_limit_example_writes_reserved_bytes(records):
    rec = by_raw(records, "FA AF 01 00 10 02 01 18 FC F6")
    assert [(f.address, f.name, f.register.reserved) for f in rec.fields] == [(16, None, True), (17, None, True)]


def test_command_examples(records):
    assert by_raw(records, "FA AF 01 40 FF 00 00 BE").event.op == "flash"
    assert by_raw(records, "FA AF 01 20 FF 00 00 DE").event.op == "reboot"
    assert by_raw(records, "FA AF 01 10 FF FF 00 11").event.op == "initialize"
    assert by_raw(records, "FA AF 01 60 07 01 01 12 74").event.commands == ("flash", "reboot")


def test_read_and_return_examples(records):
    read = by_raw(records, "FA AF 01 0F 2A 02 00 26")
    assert read.event.read_range == (42, 2) and read.read_names == ["present_position"]
    poll = by_raw(records, "FA AF 01 09 00 00 01 09")
    assert poll.event.read_range == (42, 18)
    ret = poll.reply
    assert ret is not None and ret.request is poll
    assert values(ret) == [(1, "present_position", 90.0), (1, "present_time", 5.67), (1, "present_speed", 300),
                           (1, "present_current", 6), (1, "present_temperature", 45), (1, "present_voltage", 7.4)]
