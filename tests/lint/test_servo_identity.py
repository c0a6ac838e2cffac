"""The linter follows a servo across an ID change, knows a write that changes nothing, and names unknown models."""

from __future__ import annotations

from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.protocol.wire import (
    FLAG_REBOOT, FLAG_WRITE_FLASH, encode_command, encode_long, encode_read, encode_return, encode_short)

BAUD_7_TO_1 = encode_short(1, 0, 0x06, b"\x07")   # baud_rate 115200 (table 4.7)
ID_1_TO_2 = encode_short(1, 0, 0x04, b"\x02")     # servo_id (table 4.6 No. 4)


def lint(*frames: bytes, **options) -> Linter:
    linter = Linter()
    dec = Decoder(DecodeOptions(**options), linter)
    dec.feed(b"".join(frames))
    dec.close()
    return linter


def codes(linter: Linter) -> list[str]:
    return [f.code for f in linter.findings]


def rom(servo_id: int, baud: int = 7) -> bytes:
    """A return of addresses 0-29 (model number 0x3030, the servo's ID and baud rate among them)."""
    data = bytearray(30)
    data[0:2] = b"\x30\x30"
    data[4], data[6] = servo_id, baud
    return encode_return(servo_id, 0, bytes(data))


# ---- across an ID change ----------------------------------------------------------------------
def test_provisioning_under_the_new_id_is_clean():
    """What client libraries do: baud, new ID, then flash and reboot under the new ID."""
    linter = lint(BAUD_7_TO_1, ID_1_TO_2, encode_command(2, FLAG_WRITE_FLASH), encode_command(2, FLAG_REBOOT))
    assert codes(linter) == []
    assert 1 not in linter.servos and linter.servos[2].baud == 7


def test_provisioning_with_acks_and_a_read_back_is_clean():
    ack = b"\x07"
    linter = lint(encode_read(1, 0, 30), rom(1, baud=4),
                  encode_short(1, 0x01, 0x06, b"\x07"), ack, encode_short(1, 0x01, 0x04, b"\x02"), ack,
                  encode_command(2, FLAG_WRITE_FLASH | 0x01), ack, encode_command(2, FLAG_REBOOT),
                  encode_read(2, 0, 30), rom(2))
    assert codes(linter) == []


def test_not_rebooted_under_the_new_id_still_says_q001():
    linter = lint(BAUD_7_TO_1, ID_1_TO_2, encode_command(2, FLAG_WRITE_FLASH))
    assert codes(linter) == ["Q001"]
    f = linter.findings[0]
    assert f.offset == 0 and f.id == 1
    assert f.message.startswith("baud_rate code 7 written to ID 1 (now ID 2) but it was flashed but the servo was "
                                "never rebooted")


def test_flash_and_reboot_to_the_old_id_reach_nobody():
    linter = lint(BAUD_7_TO_1, ID_1_TO_2, encode_command(1, FLAG_WRITE_FLASH), encode_command(1, FLAG_REBOOT))
    assert sorted(codes(linter)) == ["Q001", "Q002"]


def test_q002_follows_a_servo_renumbered_twice():
    id_2_to_3 = encode_short(2, 0, 0x04, b"\x03")
    assert codes(lint(ID_1_TO_2, id_2_to_3, encode_command(3, FLAG_WRITE_FLASH))) == []
    linter = lint(ID_1_TO_2, id_2_to_3, encode_command(2, FLAG_WRITE_FLASH))
    assert [f.message.split(":")[0] for f in linter.findings] == ["ID 1 changed to 3 but no flash write to ID 3 followed"]
    # Back to the ID in its flash ROM: nothing to persist.
    assert codes(lint(ID_1_TO_2, encode_short(2, 0, 0x04, b"\x01"))) == []


def test_torque_and_angle_limits_follow_the_servo():
    torque_off = encode_short(1, 0, 0x24, b"\x00")
    cw_100 = encode_short(1, 0, 0x08, (1000).to_bytes(2, "little"))
    goal_120 = encode_short(2, 0, 0x1E, (1200).to_bytes(2, "little"))
    linter = lint(torque_off, cw_100, ID_1_TO_2, goal_120)
    assert sorted(codes(linter)) == ["Q002", "Q004", "Q006"]
    assert {f.id for f in linter.findings if f.code != "Q002"} == {2}


def test_a_long_packet_may_swap_two_ids():
    cw_100 = encode_short(1, 0, 0x08, (1000).to_bytes(2, "little"))
    swap = encode_long(0x04, [(1, b"\x02"), (2, b"\x01")])
    goal = lambda sid: encode_short(sid, 0, 0x1E, (1200).to_bytes(2, "little"))  # noqa: E731
    linter = lint(cw_100, swap, goal(1), goal(2), encode_command(255, FLAG_WRITE_FLASH))
    assert [(f.code, f.id) for f in linter.findings] == [("Q006", 2)]


def test_an_out_of_range_id_moves_nothing():
    torque_off = encode_short(1, 0, 0x24, b"\x00")
    linter = lint(torque_off, encode_short(1, 0, 0x04, b"\x00"), encode_short(1, 0, 0x1E, b"\x84\x03"))
    assert sorted(codes(linter)) == ["M003", "Q002", "Q004"]  # servo 1 is still there, torque off


# ---- a write that changes nothing -------------------------------------------------------------------
def test_baud_write_of_the_rate_read_back_needs_no_reboot():
    assert codes(lint(encode_read(1, 0, 30), rom(1, baud=7), BAUD_7_TO_1)) == []
    assert codes(lint(encode_read(1, 6, 1), encode_return(1, 6, b"\x07"), BAUD_7_TO_1)) == []
    # A different rate than the one read back still needs its flash write and reboot.
    assert codes(lint(encode_read(1, 0, 30), rom(1, baud=4), BAUD_7_TO_1)) == ["Q001"]


def test_baud_write_repeated_after_it_was_applied_is_fine():
    flash, reboot = encode_command(1, FLAG_WRITE_FLASH), encode_command(1, FLAG_REBOOT)
    assert codes(lint(BAUD_7_TO_1, flash, reboot, BAUD_7_TO_1)) == []
    # Written again between flash and reboot: the reboot still applies the flashed rate.
    assert codes(lint(BAUD_7_TO_1, flash, BAUD_7_TO_1, reboot)) == []
    # An initialize resets RAM to the defaults: the rate in RAM is no longer known to be the one running.
    init = encode_short(1, 0x10, 0xFF, b"", length=0xFF, count=0)
    assert codes(lint(encode_read(1, 6, 1), encode_return(1, 6, b"\x07"), init, BAUD_7_TO_1)) == ["Q001"]


# ---- unknown model numbers (M005) --------------------------------------------------------------------
def test_unknown_model_number_named_once_with_the_map_used():
    ret = encode_return(1, 0, b"\x0c\x30")
    linter = lint(encode_read(1, 0, 2), ret, encode_read(1, 0, 2), ret)
    assert codes(linter) == ["M005"]
    msg = linter.findings[0].message
    assert "0x300C" in msg and "RS303MR map" in msg and linter.findings[0].severity == "info"
    chosen = lint(encode_read(1, 0, 2), ret, models={1: "RS304MD"})
    assert codes(chosen) == ["M005"] and "RS304MD map" in chosen.findings[0].message
    by_default = lint(encode_read(1, 0, 2), ret, default_model="RS304MD")
    assert "RS304MD map" in by_default.findings[0].message


def test_known_models_and_corrupt_returns_are_not_m005():
    known = [encode_read(1, 0, 2), encode_return(1, 0, b"\x40\x30"), encode_read(2, 0, 2), encode_return(2, 0, b"\x30\x30")]
    assert codes(lint(*known)) == []
    assert codes(lint(encode_read(3, 0, 2), encode_return(3, 0, b"\x40\x30"), models={3: "RS303MR"})) == []
    bad = bytearray(encode_return(1, 0, b"\x0c\x30"))
    bad[-1] ^= 0x55
    assert codes(lint(encode_read(1, 0, 2), bytes(bad))) == ["F001"]
