"""Scenarios: repeatable, healthy ones clean, each fault scenario shows the fault it is named for."""

from __future__ import annotations

from collections import Counter
from functools import lru_cache

import pytest

from rs30x_sniff.decode.decoder import Decoder, DecodeOptions
from rs30x_sniff.sim import SCENARIOS, Servo, SimBus, run
from rs30x_sniff.sim.bus import Transmission, _merge
from rs30x_sniff.protocol.wire import byte_time, encode_short

# Short runs keep the suite fast; long enough for every fault to show several times.
DURATIONS = {"hexapod": 3.0, "setup": None, "overheat": 8.0}


@lru_cache(maxsize=None)
def chunks_of(name: str, baud: int = 115200, seed: int = 0):
    return tuple(run(name, baud=baud, seed=seed, duration=DURATIONS.get(name, 2.5)))


def records_of(name: str, baud: int = 115200, linter=None):
    dec = Decoder(DecodeOptions(baud=baud), linter)
    recs = []
    for data, t in chunks_of(name, baud):
        recs += dec.feed(data, t)
    return recs + dec.close(), dec


def _linter(baud: int = 115200):
    from rs30x_sniff.lint import LintConfig, Linter  # a linter that fails to import fails these tests

    return Linter(LintConfig(baud=baud))


def test_same_seed_same_bytes_other_seed_other_bytes():
    a = list(run("noise", seed=5, duration=1.5))
    assert a == list(run("noise", seed=5, duration=1.5))
    assert a != list(run("noise", seed=6, duration=1.5))


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_chunks_are_in_time_order_and_never_overlap(name):
    chunks = chunks_of(name)
    bt = byte_time(115200)
    assert chunks
    for (a, ta), (b, tb) in zip(chunks, chunks[1:]):
        assert tb >= ta + len(a) * bt - 1e-12


@pytest.mark.parametrize("baud", [115200, 230400])
def test_hexapod_is_a_busy_healthy_bus(baud):
    recs, dec = records_of("hexapod", baud)
    kinds = Counter(r.kind for r in recs)
    assert set(kinds) == {"short", "long", "return"}
    assert all(r.event.checksum_ok for r in recs)
    assert all(r.status in (None, "answered", "paired") for r in recs)
    assert set(dec.bus.servos) == set(range(1, 19))
    # Goals at 50 Hz: long packets 20 ms apart.
    longs = [r.t for r in recs if r.kind == "long"]
    gaps = {round(b - a, 4) for a, b in zip(longs[3:], longs[4:])}
    assert gaps == {0.02}
    # Round-robin polls of 42-59 fill the rest of each cycle: the line is busy.
    polled = [r.id for r in recs if r.kind == "short" and r.event.flag == 0x09]
    assert polled[:20] == [*range(1, 19), 1, 2]
    busy = sum(len(d) for d, _ in chunks_of("hexapod", baud)) * byte_time(baud) / chunks_of("hexapod", baud)[-1][1]
    assert busy > 0.5
    # Coxa servos are RS304MD and the sniffer learned it from their model-number reads.
    assert dec.bus.servos[1].model.name == "RS304MD" and dec.bus.servos[2].model.name == "RS303MR"
    # The legs move: present positions differ from poll to poll.
    positions = {r.fields[0].value for r in recs if r.kind == "return" and r.event.address == 42 and r.id == 3}
    assert len(positions) > 10


def test_setup_session_provisions_three_servos():
    recs, dec = records_of("setup")
    ops = [(r.event.op, r.id) for r in recs if r.kind == "short"]
    assert ("flash", 10) in ops and ("reboot", 10) in ops and ("flash", 12) in ops
    assert all(r.status in (None, "answered", "paired") for r in recs)
    # After the reboot each servo answers at its new ID with its ID saved.
    for new_id in (10, 11, 12):
        assert dec.bus.servos[new_id].get("servo_id") == new_id
    assert dec.bus.servos[11].get("model_number") == 0x3040


def test_noise_scenario_has_garbage_between_intact_frames():
    recs, _ = records_of("noise")
    garbage = [r for r in recs if r.kind == "garbage"]
    assert len(garbage) >= 3 and all(r.event.reason == "noise" for r in garbage)
    assert all(r.event.checksum_ok for r in recs if r.kind != "garbage")


def test_silent_servo_requests_go_missing():
    recs, _ = records_of("silent-servo")
    missing = [r for r in recs if r.status == "missing"]
    assert missing and {r.id for r in missing} == {4}
    assert not any(r.kind == "return" and r.id == 4 for r in recs)


def test_duplicate_id_gives_two_returns_to_one_poll():
    recs, _ = records_of("duplicate-id")
    extra = [r for r in recs if r.status == "extra"]
    assert extra and {r.id for r in extra} == {2}
    assert all(r.event.checksum_ok for r in extra)  # they follow each other; they do not collide


def test_request_before_return():
    recs, _ = records_of("request-before-return")
    missing = [r for r in recs if r.status == "missing"]
    assert missing and {r.id for r in missing} == {5}
    for req in missing:
        nxt = recs[req.index + 1]
        assert nxt.is_request and nxt.t - req.event.t_end < 0.05  # the host did not wait
        late = recs[req.index + 2]
        assert late.kind == "return" and late.id == 5 and late.status == "unsolicited"


def test_bad_checksum_and_the_servo_reports_it():
    recs, _ = records_of("bad-checksum")
    bad = [r for r in recs if not r.event.checksum_ok]
    assert bad and all(r.kind == "short" for r in bad)
    flagged = [r for r in recs if r.kind == "return" and "received_packet_error" in r.event.flag_names]
    assert {r.id for r in flagged} == {r.id for r in bad}


def test_overheat_alarm_then_limit_and_torque_reenabled():
    recs, _ = records_of("overheat")
    flags = [r.event.flag_names for r in recs if r.kind == "return" and r.id == 2 and r.event.address == 42]
    first_alarm = next(i for i, f in enumerate(flags) if "temperature_alarm" in f)
    first_limit = next(i for i, f in enumerate(flags) if "temperature_limit" in f)
    assert first_alarm < first_limit
    after = [r for r in recs if r.kind == "long" and r.event.address == 36 and r.index > 0]
    assert len(after) >= 2  # the host turned torque on again after the limit
    assert not any(f for r in recs if r.kind == "return" and r.id != 2 for f in [r.event.flags])


def test_collision_ands_the_overlapping_bytes():
    bt = byte_time(115200)
    data, t = _merge([Transmission(0.0, b"\xff\xf0\x0f", "a"), Transmission(bt, b"\x3c\xff", "b")], bt)
    assert (data, t) == (b"\xff\x30\x0f", 0.0)
    # The host talks over a return: one chunk, the return with the host's byte on top.
    bus = SimBus(115200, [Servo()])
    bus.send(encode_short(1, 0x09))
    end = bus.t
    bus.send(b"\x00", at=end + 100e-6 + 3 * bt, wait=False)
    chunks = bus.drain(final=True)
    assert len(chunks) == 2
    data, t = chunks[1]
    assert t == pytest.approx(end + 100e-6, abs=11e-6)
    assert len(data) == 26 and data[:3] == b"\xfd\xdf\x01" and data[3] == 0


# ---- with the linter ---------------------------------------------------------------------------
@pytest.mark.parametrize("baud", [115200, 230400])
@pytest.mark.parametrize("name", [n for n, s in SCENARIOS.items() if not s.expects])
def test_healthy_scenarios_lint_clean(name, baud):
    linter = _linter(baud)
    records_of(name, baud, linter=linter)
    assert [f"{f.code} {f.message}" for f in linter.findings] == []


@pytest.mark.parametrize("name", [n for n, s in SCENARIOS.items() if s.expects])
def test_fault_scenarios_produce_their_findings(name):
    linter = _linter()
    records_of(name, linter=linter)
    codes = {f.code for f in linter.findings}
    assert set(SCENARIOS[name].expects) <= codes
