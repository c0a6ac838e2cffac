"""The bus tracker follows servos across ID changes; packets that fail their checksum create no servos."""

from __future__ import annotations

import json
import random
from pathlib import Path

from rs30x_sniff.cli import main
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.sinks.stats import CaptureStats
from rs30x_sniff.protocol.wire import encode_long, encode_read, encode_return, encode_short
from tests.conftest import h

ROOT = Path(__file__).resolve().parents[2]


def run(data: bytes, **opts):
    dec = Decoder(DecodeOptions(**opts))
    recs = dec.feed(data) + dec.close()
    return recs, dec.bus


def corrupt(frame: bytes) -> bytes:
    return frame[:-1] + bytes((frame[-1] ^ 0x5A,))


def test_the_shadow_moves_with_an_id_change():
    recs, bus = run(encode_short(1, 0, 30, h("84 03")) + encode_short(1, 0, 4, b"\x02") + encode_short(2, 0, 32, h("0A 00")))
    assert set(bus.servos) == {2}
    st = bus.servos[2]
    assert st.id == 2 and st.get("servo_id") == 2 and st.get("goal_position") == 90.0 and st.get("goal_time") == 0.1
    assert st.requests == 3


def test_a_learned_model_moves_with_an_id_change_and_the_old_id_forgets_it():
    data = encode_read(7, 0, 2) + encode_return(7, 0, h("40 30")) + encode_short(7, 0, 4, b"\x08")
    _, bus = run(data)
    assert bus.model_of(8).name == "RS304MD" and bus.servos[8].model.name == "RS304MD"
    assert bus.model_of(7).name == "RS303MR" and 7 not in bus.servos
    # A --model for the new ID still wins.
    _, bus = run(data, models={8: "RS303MR"})
    assert bus.servos[8].model.name == "RS303MR"


def test_a_long_packet_swaps_two_servos():
    data = (encode_short(1, 0, 30, h("84 03")) + encode_short(2, 0, 30, h("64 00"))
            + encode_long(4, [(1, b"\x02"), (2, b"\x01")]))
    _, bus = run(data)
    assert bus.servos[2].get("goal_position") == 90.0 and bus.servos[1].get("goal_position") == 10.0


def test_an_out_of_range_or_broadcast_id_write_moves_nothing():
    _, bus = run(encode_short(1, 0, 4, b"\x00") + encode_short(255, 0, 4, b"\x05"))
    assert set(bus.servos) == {1}


def test_corrupt_packets_create_no_servo_and_teach_no_model():
    data = (corrupt(encode_short(9, 0, 30, h("84 03"))) + corrupt(encode_long(30, [(10, h("00 00"))]))
            + encode_read(11, 0, 2) + corrupt(encode_return(11, 0, h("40 30"))))
    recs, bus = run(data)
    assert set(bus.servos) == {11}  # only the intact read
    assert bus.servos[11].returns == 0 and bus.model_of(11).name == "RS303MR"
    stats = CaptureStats(115200)
    for r in recs:
        stats.add(r)
    assert stats.bad_checksums == 3 and set(stats.servos) == {11}


def test_info_lists_no_phantom_servo_from_a_corrupt_long_packet(capsys):
    assert main(["info", str(ROOT / "captures" / "session-mixed.thex"), "--format", "json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert set(d["servos"]) == {str(i) for i in range(1, 7)}  # the corrupt long packet named VID 18
    assert d["bad_checksums"] >= 1
    assert {s["long_writes"] for s in d["servos"].values()} == {99}  # its records are not counted as writes


def test_random_bytes_create_almost_no_servos():
    data = random.Random(30).randbytes(2_000_000)
    recs, bus = run(data)
    claimed = {r.event.id for r in recs if r.kind in ("short", "return") and not r.event.checksum_ok}
    assert len(claimed) > 20  # the corrupt frames name many IDs ...
    assert len(bus.servos) <= 2  # ... none of which becomes a servo (an intact frame is 1 in 256)
    stats = CaptureStats(115200)
    for r in recs:
        stats.add(r)
    assert len(stats.servos) <= 2
