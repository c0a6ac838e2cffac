"""The simulator speaks the family: each model answers with its number and acts as its map's [behaviour] says."""

from __future__ import annotations

import pytest

from rs30x_sniff.protocol.memmap import default_registry
from rs30x_sniff.sim import Servo
from rs30x_sniff.sim.servo import Physics
from rs30x_sniff.protocol.wire import encode_command, encode_read, encode_short
from tests.sim.test_servo import reply_event, request


@pytest.mark.parametrize("model, number", [("RS301CR", 0x3010), ("RS302CD", 0x3020), ("RS204MD", 0x2040),
                                           ("RS303MR", 0x3030), ("RS304MD", 0x3040)])
def test_each_model_answers_its_model_number(model, number):
    ev = reply_event(Servo(model, 1), encode_read(1, 0, 2))
    assert int.from_bytes(ev.data, "little") == number
    assert default_registry().by_number[number].name == model


@pytest.mark.parametrize("model, together", [("RS301CR", True), ("RS302CD", True), ("RS303MR", False),
                                             ("RS204MD", False)])
def test_flash_and_reboot_in_one_packet_only_where_the_manual_allows_it(model, together):
    s = Servo(model, 1)
    request(s, encode_short(1, 0, 7, b"\x05"), t=1.0)           # return delay: variable ROM (No. 7)
    reply = request(s, encode_short(1, 0x61, 0xFF, b"", length=0, count=0), t=2.0)[0]  # flag 0x60 + ACK bit
    if together:
        assert reply is None            # rebooted at once: no ACK
        request(s, encode_short(1, 0, 7, b"\x00"), t=3.0)  # RAM copy changed, the flash keeps 5
        s.reboot(4.0)
        assert s.mem[7] == 5
    else:
        assert reply == b"\x08"         # NACK: nothing saved
        s.reboot(4.0)
        assert s.mem[7] == 0


def test_rs301cr_takes_baud_code_0a_and_falls_back_to_115200_on_an_undefined_code():
    s = Servo("RS301CR", 1)
    request(s, encode_short(1, 0, 6, b"\x0A"), t=1.0)
    request(s, encode_command(1, 0x40), t=1.1)
    s.reboot(2.0)
    assert s.baud == 460800                 # 0x0A exists for the RS301CR (its manual p.19)
    request(s, encode_short(1, 0, 6, b"\x0C"), t=3.0)
    request(s, encode_command(1, 0x40), t=3.1)
    s.reboot(4.0)
    assert s.baud == 115200                 # an undefined code gives 115200 (p.19)


def test_rs303mr_refuses_an_undefined_baud_code():
    s = Servo("RS303MR", 1)
    request(s, encode_short(1, 0, 6, b"\x0A"), t=1.0)
    assert s.mem[6] == 7


@pytest.mark.parametrize("model, takes", [("RS204MD", False), ("RS303MR", True)])
def test_reverse_and_id_only_with_torque_off_on_the_rs204md(model, takes):
    s = Servo(model, 1)
    request(s, encode_short(1, 0, 36, b"\x01"), t=1.0)
    request(s, encode_short(1, 0, 5, b"\x01"), t=1.1)
    request(s, encode_short(1, 0, 4, b"\x09"), t=1.2)
    assert (s.mem[5], s.id) == ((1, 9) if takes else (0, 1))
    request(s, encode_short(s.id, 0, 36, b"\x00"), t=1.3)
    request(s, encode_short(s.id, 0, 5, b"\x01"), t=1.4)
    assert s.mem[5] == 1                    # torque off: taken by every model


def _overheated(model: str) -> tuple[Servo, float]:
    s = Servo(model, 1, temperature=60.0, load=1.0, physics=Physics(thermal_tau_s=2.0))
    request(s, encode_short(1, 0, 36, b"\x01"), t=0.0)
    t = 0.0
    while not s.temperature_latched:
        t += 0.1
        s.advance(t)
    s.load = 0.0
    s.advance(t + 30)                       # braked: it cools down
    return s, t + 30


@pytest.mark.parametrize("model, way", [("RS301CR", "torque-enable"), ("RS303MR", "reboot")])
def test_a_temperature_stop_clears_the_models_way(model, way):
    s, t = _overheated(model)
    request(s, encode_short(1, 0, 36, b"\x01"), t=t + 1)
    assert (s.get("torque_enable") == "on") == (way == "torque-enable")
    assert reply_event(s, encode_short(1, 0x09), t=t + 2).flags & 0x80 == (0 if way == "torque-enable" else 0x80)


@pytest.mark.parametrize("model, has", [("RS301CR", False), ("RS303MR", True)])
def test_the_flash_error_bit_only_where_the_model_has_one(model, has):
    s = Servo(model, 1)
    s.flash_error = True
    assert bool(reply_event(s, encode_short(1, 0x09)).flags & 0x08) == has
