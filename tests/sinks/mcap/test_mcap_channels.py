"""Every channel's messages validate against their own JSON Schemas; state, transactions and findings carry what they should."""

from __future__ import annotations

import json
from collections import Counter, defaultdict

import jsonschema
import pytest
from mcap.reader import make_reader

from rs30x_sniff.sinks.mcap.transactions import transaction_json
from rs30x_sniff.sinks.mcap.writer import McapSink
from rs30x_sniff.lint import Finding
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.schemas import SCHEMA_FILES, schema
from rs30x_sniff.protocol.wire import encode_return, encode_short

from .conftest import chunks_of, hexapod_frames, to_mcap


def read_all(path):
    with open(path, "rb") as f:
        return [(s, c, m) for s, c, m in make_reader(f).iter_messages()]


def test_shipped_schemas_are_valid_json_schemas():
    for name in SCHEMA_FILES:
        s = schema(name)
        jsonschema.validators.validator_for(s).check_schema(s)
        assert s["title"] == name


def test_every_message_validates_against_its_channel_schema(sample_capture, tmp_path):
    out = tmp_path / "x.mcap"
    chunks = chunks_of(sample_capture) + list(hexapod_frames(300))  # untimed, then timed: both shapes of t
    dec = Decoder()
    with McapSink(str(out), source="test", baud=115200, time_base="capture") as sink:
        for data, t in chunks:
            sink.raw(data, t)
            for rec in dec.feed(data, t):
                sink.record(rec)
        for rec in dec.close():
            sink.record(rec)
        sink.findings([Finding("F001", "checksum-mismatch", "error", "bad sum", 12, None, 3),
                       Finding("W002", "something", "warning", "odd", 40, 1.25, None),
                       Finding("I003", "note", "info", "fyi", 50, 2.5, 1)])
    validators = {}
    seen = Counter()
    for sch, ch, msg in read_all(out):
        assert sch.encoding == "jsonschema" and ch.message_encoding == "json"
        v = validators.get(sch.id)
        if v is None:
            s = json.loads(sch.data)
            v = validators[sch.id] = jsonschema.validators.validator_for(s)(s)
        obj = json.loads(msg.data)
        errors = list(v.iter_errors(obj))
        assert not errors, (ch.topic, obj, errors[0].message)
        seen[sch.name] += 1
    assert set(seen) == set(SCHEMA_FILES), seen


def test_the_schema_rejects_what_it_should():
    # The schemas are not trivially permissive: a packet without its raw bytes, a raw chunk with
    # a stray key, a log level out of range all fail.
    packet = jsonschema.Draft202012Validator(schema("rs30x.Packet"))
    assert not packet.is_valid({"type": "short", "offset": 0})
    raw = jsonschema.Draft202012Validator(schema("rs30x.Raw"))
    assert raw.is_valid({"offset": 0, "t": None, "length": 1, "data": "+g=="})
    assert not raw.is_valid({"offset": 0, "t": None, "length": 1, "data": "+g==", "x": 1})
    log = jsonschema.Draft202012Validator(schema("foxglove.Log"))
    good = {"timestamp": {"sec": 1, "nsec": 0}, "level": 4, "message": "m", "name": "n", "file": "f", "line": 3}
    assert log.is_valid(good)
    assert not log.is_valid({**good, "level": 9})


def test_servo_state_is_a_flat_object_of_latest_values(tmp_path):
    out = tmp_path / "h.mcap"
    to_mcap(hexapod_frames(200), out)
    states = defaultdict(list)
    for _, ch, msg in read_all(out):
        if ch.topic.startswith("/rs30x/servo/"):
            states[ch.topic].append((msg.log_time, json.loads(msg.data)))
    assert sorted(states) == sorted(f"/rs30x/servo/{i}/state" for i in range(1, 19))
    last = states["/rs30x/servo/3/state"][-1][1]
    assert last["id"] == 3 and last["model"] == "RS303MR"
    # Long packets set goals, polls return present values: all plottable numbers at the top level.
    for key in ("goal_position", "goal_time", "present_position", "present_current", "present_temperature",
                "present_voltage"):
        assert isinstance(last[key], (int, float)), key
    # Published whenever a packet changes the servo: every long packet and every return of ID 3.
    assert len(states["/rs30x/servo/3/state"]) > 20
    # Values persist between packets: a long packet's state still carries the last polled values.
    log_times = [lt for lt, _ in states["/rs30x/servo/3/state"]]
    assert log_times == sorted(log_times)


def test_state_tracks_writes_and_broadcasts(tmp_path):
    out = tmp_path / "w.mcap"
    frames = [encode_short(2, 0, 0x1E, (900).to_bytes(2, "little", signed=True)),  # goal 90.0 deg
              encode_short(255, 0, 0x24, b"\x01"),                                 # torque on, all servos
              encode_short(2, 0, 0x1E, b"\x00\x00")[:-1] + b"\x00"]               # bad checksum: ignored
    to_mcap([(f, None) for f in frames], out)
    states = [json.loads(m.data) for _, c, m in read_all(out) if c.topic == "/rs30x/servo/2/state"]
    assert states[0]["goal_position"] == pytest.approx(90.0)
    assert states[-1]["torque_enable"] == "on" and states[-1]["goal_position"] == pytest.approx(90.0)
    assert len(states) == 2


def test_transactions_pair_requests_with_replies(tmp_path):
    out = tmp_path / "t.mcap"
    req = encode_short(1, 0x09, 0, b"", length=0, count=1)
    ret = encode_return(1, 42, bytes(18))
    lost = encode_short(4, 0x09, 0, b"", length=0, count=1)
    req_end = 1.0 + len(req) * 10 / 115200
    to_mcap([(req, 1.0), (ret, req_end + 0.0003), (lost, 1.5), (req, 2.0)], out)
    tx = [json.loads(m.data) for _, c, m in read_all(out) if c.topic == "/rs30x/transactions"]
    # The last poll is still within its reply time when the capture ends: unknown, not missing.
    assert [(x["id"], x["status"]) for x in tx] == [(1, "answered"), (4, "missing"), (1, "unknown")]
    assert tx[0]["reply_type"] == "return" and tx[0]["latency_s"] == pytest.approx(0.0003)
    assert tx[0]["read"][0] == "present_position"
    assert tx[1]["reply_offset"] is None and tx[1]["latency_s"] is None


def test_findings_are_foxglove_logs(tmp_path):
    out = tmp_path / "f.mcap"
    with McapSink(str(out), source="cap.hex", baud=115200, time_base="synthetic") as sink:
        sink.raw(bytes(100), None)
        sink.findings([Finding("F001", "checksum-mismatch", "error", "sum is 1C, expected 1D", 25, None, 3),
                       Finding("W101", "slow-reply", "warning", "late", 50, 1.5, None)])
    logs = [(m.log_time, json.loads(m.data)) for _, c, m in read_all(out) if c.topic == "/rs30x/diagnostics"]
    (t0, a), (t1, b) = logs
    assert a["level"] == 4 and b["level"] == 3
    assert a["name"] == "F001 checksum-mismatch" and a["file"] == "cap.hex" and a["line"] == 25
    assert "3" in a["message"] and "expected 1D" in a["message"]
    # No capture time: the synthetic time of byte 25; with one: that time.
    assert t0 == round(25 * 10 / 115200 * 1e9) and a["timestamp"]["nsec"] == t0
    assert t1 == 1_500_000_000 and b["timestamp"] == {"sec": 1, "nsec": 500_000_000}


def test_transaction_json_of_a_missing_ack():
    dec = Decoder()
    recs = dec.feed(encode_short(7, 0x01, 0x24, b"\x01") + encode_short(8, 0, 0x24, b"\x01"), None) + dec.close()
    tx = transaction_json(recs[0])
    assert tx["expects"] == "ack" and tx["status"] == "missing" and tx["reply_type"] is None
