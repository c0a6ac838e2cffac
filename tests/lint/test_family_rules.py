"""Rules that follow each model's manual: the servo's model (learned from its model number) decides."""

from __future__ import annotations

from rs30x_sniff.protocol.wire import encode_command, encode_read, encode_return, encode_short

from .helpers import lint_chunks

POLL = encode_short(1, 0x09, 0, b"", length=0, count=1)
STATUS = bytes(18)


def _as(number: bytes, *frames: bytes):
    """Servo 1 answers ``number`` as its model number, then ``frames``: what the linter found."""
    chunks = [(f, None) for f in (encode_read(1, 0, 2), encode_return(1, 0, number), *frames)]
    return [(f.code, str(f.message)) for f in lint_chunks(chunks).findings]


RS301CR, RS303MR, RS204MD = bytes.fromhex("1030"), bytes.fromhex("3030"), bytes.fromhex("4020")


def test_the_reserved_status_bits_are_table_4_4s_without_a_model_and_bit_3_more_on_the_rs301cr():
    from rs30x_sniff.protocol.memmap import behaviour_of, default_registry
    from rs30x_sniff.protocol.wire import RETURN_FLAGS_RESERVED
    assert behaviour_of(None).reserved_flags == RETURN_FLAGS_RESERVED
    assert behaviour_of(default_registry().get("RS301CR")).reserved_flags == RETURN_FLAGS_RESERVED | 0x08


def test_bit_3_is_a_flash_error_on_the_rs303mr_and_reserved_on_the_rs301cr():
    assert [c for c, _ in _as(RS303MR, POLL, encode_return(1, 42, STATUS, 0x08))] == ["S003"]
    assert _as(RS301CR, POLL, encode_return(1, 42, STATUS, 0x08)) == [
        ("P013", "return flags 0x08 set reserved bit(s) 0x08")]


def test_s001_says_the_models_way_back():
    (rs303,) = _as(RS303MR, POLL, encode_return(1, 42, STATUS, 0x80))
    (rs301,) = _as(RS301CR, POLL, encode_return(1, 42, STATUS, 0x80))
    assert rs303 == ("S001", "ID 1 passed its temperature limit and cut torque (a reboot clears it)")
    assert rs301 == ("S001", "ID 1 passed its temperature limit and cut torque (a torque_enable write clears it)")


def test_q009_only_where_a_reboot_is_the_way_back_and_a_torque_write_ends_the_rs301crs_stop():
    hot = (POLL, encode_return(1, 42, STATUS, 0x80), encode_short(1, 0, 0x24, b"\x01"))
    assert [c for c, _ in _as(RS303MR, *hot)] == ["S001", "Q009"]
    assert [c for c, _ in _as(RS301CR, *hot)] == ["S001"]
    # After the RS301CR's torque write, a reboot-less torque on is fine: the stop was cleared.
    assert [c for c, _ in _as(RS301CR, *hot, encode_short(1, 0, 0x24, b"\x01"))] == ["S001"]


def test_p009_for_models_that_want_the_reboot_apart():
    assert [c for c, _ in _as(RS303MR, encode_command(1, 0x60))] == ["P009"]
    assert [c for c, _ in _as(RS204MD, encode_command(1, 0x60))] == ["P009"]
    assert _as(RS301CR, encode_command(1, 0x60)) == []


def test_q010_a_torque_off_only_register_written_with_torque_on():
    on = encode_short(1, 0, 0x24, b"\x01")
    found = _as(RS204MD, on, encode_short(1, 0, 0x05, b"\x01"))
    assert found == [("Q010", "reverse written to ID 1 (RS204MD) while its torque is on: the RS204MD takes it "
                               "only with torque off")]
    # servo_id too (the other rules still take the new ID as written: Q002 asks for its flash write).
    assert ("Q010", "servo_id written to ID 1 (RS204MD) while its torque is on: the RS204MD takes it only with "
                    "torque off") in _as(RS204MD, on, encode_short(1, 0, 0x04, b"\x02"))
    assert _as(RS303MR, on, encode_short(1, 0, 0x05, b"\x01")) == []
    assert _as(RS204MD, encode_short(1, 0, 0x24, b"\x00"), encode_short(1, 0, 0x05, b"\x01")) == []


def test_q010_in_a_long_packet_names_each_servo():
    from rs30x_sniff.protocol.wire import encode_long
    on = encode_long(0x24, [(1, b"\x01")])
    found = _as(RS204MD, on, encode_long(0x05, [(1, b"\x01")]))
    assert [c for c, _ in found] == ["Q010"]
