"""Emulated servo against the manual: returns, ACK/NACK, flash and reboot, torque, limits, temperature."""

from __future__ import annotations

import pytest

from rs30x_sniff.decode.framing import decode_all
from rs30x_sniff.sim import Servo, SimBus
from rs30x_sniff.sim.servo import BOOT_TIME, FLASH_WRITE_TIME, Physics
from rs30x_sniff.protocol.wire import checksum, encode_command, encode_long, encode_read, encode_short
from tests.conftest import h


def request(servo: Servo, packet: bytes, t: float = 1.0):
    """Feed one request to a servo as its UART would see it; the reply bytes (or None) and delay."""
    (ev,) = decode_all([(packet, t)])
    r = servo.receive(ev, ev.t_end)
    return (None, None) if r is None else r


def reply_event(servo: Servo, packet: bytes, t: float = 1.0):
    data, _ = request(servo, packet, t)
    assert data is not None
    (ev,) = decode_all([(data, None)])
    return ev


def test_flag_09_poll_returns_42_to_59_with_the_manuals_layout():
    s = Servo("RS303MR", 1)
    s.pos = 900.0  # 90.0 deg
    ev = reply_event(s, h("FA AF 01 09 00 00 01 09"))  # the manual's poll (No. 42/43)
    assert ev.raw[:7] == h("FD DF 01 00 2A 12 01")
    assert ev.checksum_ok and len(ev.data) == 18
    assert ev.data[0:2] == h("84 03")  # present position 0x0384 = 90.0 deg
    fields = {f.name: f.value for f in s.model.decode(ev.address, ev.data, 1) if f.name}
    assert fields["present_position"] == 90.0
    assert fields["present_temperature"] == 25
    assert 7.2 <= fields["present_voltage"] <= 7.5
    assert fields["present_current"] > 0  # never 0, even with torque off (No. 48/49)


@pytest.mark.parametrize("flag,first,count", [(0x03, 0, 30), (0x05, 30, 30), (0x07, 20, 10), (0x0B, 30, 12)])
def test_return_modes_of_table_4_3(flag, first, count):
    ev = reply_event(Servo("RS304MD", 1), encode_short(1, flag))
    assert (ev.address, ev.length, len(ev.data)) == (first, count, count)
    if first == 0:
        assert ev.data[0:2] == h("40 30")  # RS304MD model number, low byte first (table 4.5)
        assert ev.data[2] == 0x03
        assert ev.data[4:8] == h("01 00 07 00")  # ID 1, normal, 115200, no delay (table 4.6)


def test_specified_read_of_the_manual():
    ev = reply_event(Servo(), h("FA AF 01 0F 2A 02 00 26"))
    assert (ev.address, ev.length) == (42, 2)


def test_ack_for_mode_0001_and_nack_for_a_bad_checksum():
    s = Servo()
    data, delay = request(s, encode_short(1, 0x01))
    assert data == b"\x07"
    assert delay == pytest.approx(100e-6, abs=11e-6)
    bad = bytearray(encode_short(1, 0x01, 35, b"\x50"))
    bad[-1] ^= 0xFF
    data, _ = request(s, bytes(bad))
    assert data == b"\x08"
    assert s.get("max_torque") == 100  # a packet that failed its checksum changes nothing
    # The next return reports the received-packet error once (table 4.4 bit 1).
    assert reply_event(s, encode_short(1, 0x09)).flags == 0x02
    assert reply_event(s, encode_short(1, 0x09)).flags == 0x00


def test_other_ids_and_broadcast_reads_get_no_reply():
    s = Servo(servo_id=3)
    assert request(s, encode_short(1, 0x09))[0] is None
    assert request(s, encode_short(255, 0x09))[0] is None  # every servo would answer at once
    request(s, encode_short(255, 0x00, 35, b"\x32"))
    assert s.get("max_torque") == 50  # a broadcast write still applies


def test_return_delay_is_100us_plus_50us_per_unit():
    s = Servo()
    request(s, h("FA AF 01 00 07 01 01 12 14"))  # return delay 18 (No. 7): 1 ms
    _, delay = request(s, encode_short(1, 0x09))
    assert delay == pytest.approx(1e-3, abs=11e-6)


def test_long_packet_of_the_manual_writes_each_vid():
    servos = [Servo(servo_id=i) for i in (1, 2, 3, 5)]
    for s in servos:
        s.mem[36] = 1
        assert request(s, h("FA AF 00 00 1E 03 03 01 64 00 02 64 00 05 F4 01 ED"))[0] is None
    assert [s.get("goal_position") for s in servos] == [10.0, 10.0, 0.0, 50.0]


def test_id_change_is_immediate_and_needs_flash_to_survive_a_reboot():
    s = Servo()
    request(s, h("FA AF 01 00 04 01 01 05 00"))  # the manual's "set ID to 5"
    assert s.id == 5
    assert request(s, encode_short(1, 0x01))[0] is None
    assert request(s, encode_short(5, 0x01))[0] == b"\x07"
    request(s, encode_command(5, 0x20), t=2.0)  # reboot without flash: back to ID 1
    assert s.id == 1
    request(s, encode_short(1, 0, 4, b"\x05"), t=3.0)
    request(s, encode_command(5, 0x40), t=3.1)  # flash write
    request(s, encode_command(5, 0x20), t=3.2)
    assert s.id == 5


def test_baud_change_applies_only_after_flash_and_reboot():
    s = Servo()
    request(s, h("FA AF 01 00 06 01 01 04 03"), t=1.0)  # the manual's "set 38400 bps"
    assert s.get("baud_rate") == 38400 and s.baud == 115200  # still talks at the old rate
    request(s, encode_command(1, 0x20), t=2.0)  # reboot without flash: the old code comes back
    assert s.baud == 115200 and s.get("baud_rate") == 115200
    request(s, h("FA AF 01 00 06 01 01 04 03"), t=3.0)
    request(s, h("FA AF 01 40 FF 00 00 BE"), t=3.1)  # the manual's flash write
    assert s.baud == 115200
    request(s, h("FA AF 01 20 FF 00 00 DE"), t=3.2)  # the manual's reboot
    assert s.baud == 38400


def test_a_servo_at_another_baud_does_not_answer_on_the_bus():
    bus = SimBus(115200)
    s = bus.attach(Servo())
    host = [encode_short(1, 0, 6, b"\x04"), encode_command(1, 0x40)]
    for p in host:
        bus.send(p)
    bus.sleep(0.2)
    assert bus.send(encode_short(1, 0x01))  # still answers before the reboot
    bus.send(encode_command(1, 0x20))
    bus.sleep(0.5)
    assert s.baud == 38400
    assert bus.send(encode_short(1, 0x01)) == []


def test_servo_is_deaf_while_writing_flash_and_booting():
    s = Servo()
    request(s, encode_command(1, 0x40), t=1.0)
    assert request(s, encode_short(1, 0x01), t=1.0 + FLASH_WRITE_TIME / 2)[0] is None
    assert request(s, encode_short(1, 0x01), t=1.0 + FLASH_WRITE_TIME * 2)[0] == b"\x07"
    request(s, encode_command(1, 0x20), t=2.0)
    assert request(s, encode_short(1, 0x01), t=2.0 + BOOT_TIME / 2)[0] is None
    assert request(s, encode_short(1, 0x01), t=2.0 + BOOT_TIME * 2)[0] == b"\x07"


def test_flash_and_reboot_in_one_packet_is_refused():
    s = Servo()
    request(s, encode_short(1, 0, 4, b"\x09"))
    assert request(s, encode_command(9, 0x61), t=2.0)[0] == b"\x08"
    assert s.flash[0] == 1  # nothing was saved


def test_initialize_resets_rom_area_and_id_becomes_1():
    s = Servo(servo_id=7)
    request(s, encode_short(7, 0, 35, b"\x50"))
    request(s, encode_short(7, 0, 24, b"\x09\x09"))
    request(s, h("FA AF 07 10 FF FF 00") + bytes((checksum(h("07 10 FF FF 00")),)))
    assert s.id == 1 and s.get("cw_compliance_margin") == 0.2
    assert s.get("max_torque") == 80  # RAM is not part of the initialized area


def test_torque_on_rewrites_goal_and_goal_in_same_packet_does_not_move():
    s = Servo()
    s.pos = 300.0
    request(s, encode_short(1, 0, 30, h("84 03 00 00")), t=1.0)  # goal 90 deg with torque off
    s.advance(2.0)
    assert s.get("present_position") == 30.0  # no torque, no motion
    # Goal 90 deg and torque on in one packet (addresses 30-36): on, but it stays (No. 30/31).
    request(s, encode_short(1, 0, 30, h("84 03 00 00 00 64 01")), t=2.0)
    assert s.get("goal_position") == 30.0 and s.get("torque_enable") == "on"
    s.advance(3.0)
    assert s.get("present_position") == 30.0


def test_move_at_the_models_top_speed_and_stop_at_the_angle_limit():
    s = Servo("RS303MR")
    request(s, encode_short(1, 0, 36, b"\x01"), t=1.0)
    request(s, encode_short(1, 0, 8, (600).to_bytes(2, "little")), t=1.0)  # CW limit 60 deg
    request(s, h("FA AF 01 00 1E 02 01 84 03 9B"), t=1.0)  # the manual's "move to 90 deg", goal time 0
    full = 60 * 0.11 / 60  # 60 deg at 0.11 s per 60 deg
    s.advance(1.0 + full / 2)
    assert s.get("present_position") == pytest.approx(30.0, abs=1.0)
    assert s.get("present_speed") == pytest.approx(545, abs=2)
    s.advance(1.0 + full * 2)
    assert s.get("present_position") == 60.0  # stopped at the CW limit, not at 90
    assert s.get("present_speed") == 0


def test_goal_time_sets_a_slower_move_and_present_time():
    s = Servo()
    request(s, encode_short(1, 0, 36, b"\x01"), t=0.0)
    request(s, h("FA AF 01 00 1E 04 01 84 03 F4 01 68"), t=1.0)  # 90 deg in 5 s
    s.advance(3.5)
    assert s.get("present_position") == pytest.approx(45.0, abs=0.2)
    assert s.get("present_time") == pytest.approx(2.5, abs=0.01)
    s.advance(9.0)
    assert s.get("present_position") == 90.0
    assert s.get("present_time") == 5.0  # keeps the last value after the move


def test_brake_and_torque_off_stop_motion():
    s = Servo()
    request(s, encode_short(1, 0, 36, b"\x01"), t=0.0)
    request(s, encode_short(1, 0, 30, h("84 03 F4 01")), t=0.0)
    s.advance(1.0)
    request(s, encode_short(1, 0, 36, b"\x02"), t=1.0)
    pos = s.get("present_position")
    s.advance(3.0)
    assert s.get("present_position") == pos and s.get("torque_enable") == "brake"


def test_temperature_alarm_then_limit_then_brake_until_reboot():
    s = Servo(temperature=60.0, load=1.0, physics=Physics(thermal_tau_s=2.0))
    request(s, encode_short(1, 0, 36, b"\x01"), t=0.0)
    flags = []
    t = 0.0
    while t < 20:
        t += 0.1
        ev = reply_event(s, encode_short(1, 0x09), t=t)
        flags.append(ev.flags)
        if ev.flags & 0x80:
            break
    assert 0x20 in flags  # alarm first: 10 degC below the limit (No. 50/51)
    assert flags[-1] & 0x80 and s.get("torque_enable") == "brake"
    assert s.temp > 77  # the default limit 0x4D (table 4.6)
    request(s, encode_short(1, 0, 36, b"\x01"), t=t + 1)  # refused while latched
    assert s.get("torque_enable") == "brake"
    s.advance(t + 30)  # braked: it cools down, but the latch stays
    assert reply_event(s, encode_short(1, 0x09), t=t + 30).flags == 0x80
    request(s, encode_command(1, 0x20), t=t + 31)
    request(s, encode_short(1, 0, 36, b"\x01"), t=t + 32)
    assert s.get("torque_enable") == "on"


def test_current_and_voltage_respond_to_load():
    free, loaded = Servo(seed=1), Servo(seed=1, load=0.8)
    for s in (free, loaded):
        request(s, encode_short(1, 0, 36, b"\x01"), t=0.0)
        s.advance(1.0)
    assert loaded.get("present_current") > free.get("present_current") + 500
    assert loaded.get("present_voltage") < free.get("present_voltage")


def test_long_packet_reaches_servos_through_the_bus_and_polls_are_paced():
    bus = SimBus(115200, [Servo(servo_id=1), Servo(servo_id=2)])
    bus.send(encode_long(36, [(1, b"\x01"), (2, b"\x01")]))
    replies = bus.send(encode_read(2, 36, 1))
    assert len(replies) == 1 and replies[0].data[7] == 1
    chunks = bus.drain(final=True)
    assert [c[0][:2] for c in chunks] == [h("FA AF"), h("FA AF"), h("FD DF")]
    assert all(b[1] >= a[1] + len(a[0]) * bus.bt for a, b in zip(chunks, chunks[1:]))
