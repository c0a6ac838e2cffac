"""Request/reply pairing, latency, missing and unsolicited replies, model learning and shadow state."""

import pytest

from rs30x_sniff.decode.pairing import ANSWERED, EXTRA, MISSING, PAIRED, UNSOLICITED
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.protocol.wire import byte_time, encode_long, encode_read, encode_return, encode_short
from tests.conftest import h

POLL = encode_short(1, 0x09, 0, b"", length=0, count=1)
RET = encode_return(1, 42, h("84 03 37 02 2C 01 06 00 2D 00 E4 02") + bytes(6))


def run(chunks, **opts):
    dec = Decoder(DecodeOptions(**opts))
    out = []
    for data, t in chunks:
        out += dec.feed(data, t)
    return out + dec.close(), dec


def test_reply_pairs_with_its_request_and_latency_is_measured():
    bt = byte_time(115200)
    t_ret = len(POLL) * bt + 0.0001  # the default return delay: 100 us
    recs, _ = run([(POLL, 0.0), (RET, t_ret)])
    req, rep = recs
    assert req.status == ANSWERED and rep.status == PAIRED
    assert req.reply is rep and rep.request is req
    assert rep.latency == pytest.approx(0.0001)


def test_returns_decoded_by_what_they_carry_reads_by_what_they_ask():
    recs, _ = run([(encode_read(1, 42, 2) + encode_return(1, 42, h("84 03")), None)])
    assert recs[0].read_names == ["present_position"]
    assert [(f.name, f.value) for f in recs[1].fields] == [("present_position", 90.0)]


def test_missing_reply_and_unsolicited_reply():
    write = encode_short(1, 0, 30, h("84 03"))
    recs, _ = run([(POLL + write + RET, None)])
    assert [r.status for r in recs] == [MISSING, None, UNSOLICITED]
    assert recs[2].request is None


def test_reply_after_the_timeout_is_unsolicited():
    recs, _ = run([(POLL, 0.0), (RET, 1.0)], reply_timeout=0.05)
    assert [r.status for r in recs] == [MISSING, UNSOLICITED]


def test_two_replies_to_one_request():
    recs, _ = run([(POLL + RET + RET, None)])
    assert [r.status for r in recs] == [ANSWERED, PAIRED, EXTRA]
    assert recs[2].request is recs[0]


def test_ack_pairs_with_the_request_that_asked():
    ask = encode_short(4, 0x01, 36, b"\x01")
    recs, _ = run([(ask + b"\x07", None)])
    assert recs[0].status == ANSWERED and recs[1].kind == "ack" and recs[1].id == 4


def test_records_leave_in_wire_order():
    data = POLL + RET + encode_short(2, 0, 30, h("00 00")) + POLL + encode_long(30, [(1, h("00 00"))])
    recs, _ = run([(data, None)])
    assert [r.offset for r in recs] == sorted(r.offset for r in recs)
    assert [r.index for r in recs] == list(range(len(recs)))


def test_model_learned_from_a_return_of_addresses_0_and_1():
    ret304 = encode_return(7, 0, h("40 30 03"))
    recs, dec = run([(encode_read(7, 0, 3) + ret304 + encode_short(7, 0, 28, h("58 02")), None)])
    assert dec.bus.model_of(7).name == "RS304MD"
    assert recs[2].model.name == "RS304MD"
    assert dec.bus.model_of(8).name == "RS303MR"  # others keep the default


def test_configured_model_wins_over_learning():
    ret303 = encode_return(7, 0, h("30 30"))
    _, dec = run([(encode_read(7, 0, 2) + ret303, None)], models={7: "RS304MD"})
    assert dec.bus.model_of(7).name == "RS304MD"


def test_shadow_state_from_writes_long_packets_and_returns():
    data = (encode_short(1, 0, 30, h("84 03 F4 01")) + encode_long(30, [(2, h("64 00")), (5, h("F4 01"))])
            + POLL + RET)
    _, dec = run([(data, None)])
    s1, s5 = dec.bus.servos[1], dec.bus.servos[5]
    assert s1.get("goal_position") == 90.0 and s1.get("goal_time") == 5.0
    assert s1.get("present_voltage") == 7.4 and s1.get("present_current") == 6
    assert s5.get("goal_position") == 50.0 and s5.get("present_position") is None
    assert s1.values()["present_speed"] == 300


def test_corrupt_write_does_not_change_shadow_state():
    bad = bytearray(encode_short(1, 0, 30, h("84 03")))
    bad[-1] ^= 0xFF
    _, dec = run([(bytes(bad), None)])
    assert dec.bus.servos.get(1) is None or dec.bus.servos[1].get("goal_position") is None
