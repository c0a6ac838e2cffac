"""record_json_text (per-layout templates) writes exactly what json.dumps(record_json(...)) writes."""

import json

import pytest

from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.sinks.pipeline import decode_records
from rs30x_sniff.render.records import record_json, record_json_text
from rs30x_sniff.sim.scenarios import SCENARIOS, run
from rs30x_sniff.protocol.wire import encode_long, encode_return, encode_short

_COMPACT = json.JSONEncoder(separators=(",", ":")).encode


def _records(name):
    return list(decode_records(run(name, duration=1.0, seed=3)))


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_templates_write_the_same_text_as_json_dumps(name):
    recs = _records(name)
    assert any(record_json(r)["fields"] for r in recs)
    ids = {r.id for r in recs if r.id}
    for rec in recs:
        assert record_json_text(rec) == json.dumps(record_json(rec))
        assert record_json_text(rec, compact=True) == _COMPACT(record_json(rec))
        only = {min(ids)} if ids else {1}
        assert record_json_text(rec, only) == json.dumps(record_json(rec, only))


def test_partial_registers_enums_and_mixed_models_long_packets():
    chunks = [
        (encode_short(1, 0, 0x1F, b"\x05"), None),                 # one byte of a 2-byte register: partial
        (encode_return(2, 0, bytes(30)), None),                     # model number, enums, reserved bytes
        (encode_long(0x1E, [(1, b"\x10\x00"), (2, b"\xf0\xff")]), None),
        (encode_short(1, 0, 0x24, b"\x02"), None),                  # torque_enable (an enum)
    ]
    recs = list(decode_records(chunks, DecodeOptions(models={2: "RS304MD"})))
    for rec in recs:
        for compact in (False, True):
            want = (_COMPACT if compact else json.dumps)(record_json(rec))
            assert record_json_text(rec, compact=compact) == want


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_named_values_are_what_the_fields_say(name):
    for rec in _records(name):
        want = [(f.id, f.register.name, f.value) for f in rec.fields if f.register.name is not None and not f.partial]
        assert rec.named_values() == want
