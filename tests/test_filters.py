"""The filter language on values (registers, latency, capture time), checked against decode's JSON, and decode --filter."""

from __future__ import annotations

import json
import math

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.filters import FilterError, parse_filter
from rs30x_sniff.sources.captures import read_capture
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.protocol.wire import encode_long, encode_return
from tests.conftest import CAPTURES, h

SESSION = str(CAPTURES / "session-mixed.thex")


def decode(path=SESSION, **opts):
    dec = Decoder(DecodeOptions(**opts))
    out = []
    for data, t in read_capture(path):
        out += dec.feed(data, t)
    return out + dec.close()


@pytest.fixture(scope="module")
def recs():
    return decode()


@pytest.fixture(scope="module")
def objs(tmp_path_factory):
    """What `decode --format jsonl` says of every event of the session: the reference values."""
    out = tmp_path_factory.mktemp("jsonl") / "session.jsonl"
    assert main(["decode", SESSION, "--format", "jsonl", "-o", str(out)]) == 0
    return [o for o in map(json.loads, out.read_text().splitlines()) if o["type"] != "diagnostic"]


def offsets(recs, text):
    flt = parse_filter(text)
    return [r.offset for r in recs if flt.matches(r)]


def where(objs, test):
    return [o["offset"] for o in objs if test(o)]


def values(o, name):
    # A packet that failed its checksum carries no trustworthy value: the filter (like the plot) skips it.
    return [f["value"] for f in o["fields"] if f["name"] == name] if o["checksum_ok"] else []


# ---- registers ----------------------------------------------------------------------------------
def test_temperature_above_40_finds_exactly_those_returns(recs, objs):
    want = where(objs, lambda o: any(v > 40 for v in values(o, "present_temperature")))
    assert want and all(o["type"] == "return" for o in objs if o["offset"] in want)
    assert offsets(recs, "reg:present_temperature>40") == want
    assert offsets(recs, "present_temperature>40") == want  # no reg: needed
    assert offsets(recs, "present_temperature>40degC") == want  # the register's own unit may follow


@pytest.mark.parametrize("op, test", [
    (">", lambda v, x: v > x), (">=", lambda v, x: v >= x), ("<", lambda v, x: v < x),
    ("<=", lambda v, x: v <= x), ("=", lambda v, x: v == x), ("!=", lambda v, x: v != x),
])
@pytest.mark.parametrize("name, x", [("present_temperature", 38), ("present_temperature", 68),
                                     ("present_voltage", 7.36), ("present_position", 24.3)])
def test_every_comparison_agrees_with_the_json(recs, objs, op, test, name, x):
    want = where(objs, lambda o: any(test(v, x) for v in values(o, name)))
    assert offsets(recs, f"{name}{op}{x}") == want
    assert offsets(recs, f"reg:{name}{op}{x}") == want


def test_a_long_packet_matches_by_any_of_its_servos(recs, objs):
    want = where(objs, lambda o: o["type"] == "long" and any(v > 20 for v in values(o, "goal_position")))
    assert want
    assert offsets(recs, "kind:long goal_position>20") == want
    # Writes carry values too: a short write of goal_position is matched like a return.
    writes = where(objs, lambda o: o["type"] == "short" and any(v == 90 for v in values(o, "goal_position")))
    assert writes and set(writes) <= set(offsets(recs, "goal_position=90"))


def test_labels_hex_and_units(recs, objs):
    assert offsets(recs, "reverse=normal") == where(objs, lambda o: values(o, "reverse") == ["normal"])
    assert offsets(recs, "torque_enable=on") == where(objs, lambda o: values(o, "torque_enable") == ["on"])
    assert offsets(recs, "torque_enable=ON") == offsets(recs, "torque_enable=1")  # a label or its code
    assert offsets(recs, "model_number=0x3030") == where(objs, lambda o: values(o, "model_number") == [0x3030])
    delay = where(objs, lambda o: values(o, "return_delay") == [100])
    assert delay
    assert offsets(recs, "return_delay=100") == offsets(recs, "return_delay=100us") == delay
    assert offsets(recs, "return_delay=0.1ms") == delay  # a time register takes any time unit
    # What a summary prints can be pasted back as a term.
    assert offsets(recs, "warm_up_time=2.00s") == where(objs, lambda o: values(o, "warm_up_time") == [2.0])


def test_requests_for_a_register_carry_no_value(recs):
    flt = parse_filter("present_temperature>=-1000")
    assert all(r.kind == "return" for r in recs if flt.matches(r))
    assert any(r.kind == "short" for r in recs if parse_filter("reg:present_temperature").matches(r))


def test_a_bad_checksum_carries_no_values():
    good = encode_return(1, 50, h("45 00"))  # present_temperature = 69
    bad = good[:-1] + bytes([good[-1] ^ 0xFF])
    recs = [r for r in decode_chunks([good, bad]) if r.kind == "return"]
    assert [r.event.checksum_ok for r in recs] == [True, False]
    assert [r.event.checksum_ok for r in recs if parse_filter("present_temperature=69").matches(r)] == [True]


def test_each_servo_of_a_mixed_bus_by_its_own_model():
    goals = encode_long(30, [(7, h("58 02 0D 00")), (8, h("20 03 0D 00"))])  # 60.0 and 80.0 deg
    [rec] = decode_chunks([goals], models={7: "RS304MD"})
    assert rec.vid_models is not None
    assert parse_filter("goal_position=60").matches(rec) and parse_filter("goal_position=80").matches(rec)
    assert not parse_filter("goal_position>80").matches(rec)


def test_a_comparison_decodes_only_its_register():
    recs = decode()  # fresh: no other test has looked at their fields
    flt = parse_filter("present_temperature>40")
    hits = [r for r in recs if flt.matches(r)]
    assert hits and all(r._values is None and r._fields is None for r in recs)


# ---- latency and time ---------------------------------------------------------------------------
def test_latency_in_every_unit(recs, objs):
    want = where(objs, lambda o: o["latency_s"] is not None and o["latency_s"] > 0.001)
    assert want
    for text in ("latency>1ms", "latency>0.001", "latency>1000us", "latency>0.001s"):
        assert offsets(recs, text) == want, text
    fast = where(objs, lambda o: o["latency_s"] is not None and o["latency_s"] <= 0.000120)
    assert offsets(recs, "latency<=120us") == fast


@pytest.mark.parametrize("text, lo, hi", [
    ("t:1.5-3.0", 1.5, 3.0), ("t:1.5-", 1.5, math.inf), ("t:-1", -math.inf, 1.0), ("t=2-2.2", 2.0, 2.2),
    ("t>2.5", 2.5 + 1e-12, math.inf), ("t<=1", -math.inf, 1.0),
])
def test_time_ranges_and_comparisons(recs, objs, text, lo, hi):
    want = where(objs, lambda o: o["t"] is not None and lo <= o["t"] <= hi)
    assert want
    assert offsets(recs, text) == want


# ---- combinations and negation -------------------------------------------------------------------
def test_new_terms_combine_and_negate(recs, objs):
    hot = offsets(recs, "present_temperature>40")
    returns = offsets(recs, "kind:return")
    assert offsets(recs, "kind:return -present_temperature>40") == [o for o in returns if o not in hot]
    assert offsets(recs, "kind:return !reg:present_temperature>40") == [o for o in returns if o not in hot]
    slow = offsets(recs, "latency>1ms")
    assert offsets(recs, "kind:return !latency>1ms") == [o for o in returns if o not in slow]
    early = offsets(recs, "t:-2")
    assert offsets(recs, "-t:-2") == [r.offset for r in recs if r.offset not in early]
    servo3 = where(objs, lambda o: o["id"] == 3 and any(v > 40 for v in values(o, "present_temperature")))
    assert offsets(recs, "id:3 present_temperature>40 t:2-3") == [o for o in servo3 if o in offsets(recs, "t:2-3")]
    assert offsets(recs, "id:5 present_temperature>40") == []


# ---- the parser's errors -------------------------------------------------------------------------
@pytest.mark.parametrize("text, reason", [
    ("presnt_temperature>40", "presnt_temperature>40: no register or filter key 'presnt_temperature'"),
    ("temperature>40", "(did you mean present_temperature, temperature_limit?)"),
    ("reg:temperature>40", "reg:temperature>40: no such register (did you mean"),
    ("present_temperature:40", "present_temperature is a register, not a key"),
    ("latency>1e999ms", "latency>1e999ms: '1e999ms' is not a finite number"),
    ("present_temperature>hot", "present_temperature>hot: 'hot' is not a number"),
    ("present_temperature>", "present_temperature>: needs a value"),
    ("present_temperature>40deg", "present_temperature is in degC, not deg"),
    ("servo_id>3V", "servo_id has no unit"),
    ("reverse>normal", "compare it with = or !="),
    ("reverse=sideways", "reverse is one of normal, reverse"),
    ("latency>1kg", "latency>1kg: unit 'kg' is not a time unit"),
    ("latency:1ms", "latency compares with"),
    ("latency>fast", "'fast' is not a number"),
    ("latency>", "latency> needs a value"),
    ("t:3", "t takes a range like t:1.5-3.0"),
    ("t:3-1", "t:3-1: range runs backwards"),
    ("t!=3", "t takes a range"),
    ("t:a-b", "'a' is not a number"),
    ("reply_to=@0", "quote free text"),
])
def test_errors_name_the_term(text, reason):
    with pytest.raises(FilterError) as e:
        parse_filter(text)
    assert reason in str(e.value)
    assert "\n" not in str(e.value)


def test_quoted_comparisons_are_free_text(recs):
    assert offsets(recs, '"reply_to=@0"') == [8]
    assert parse_filter('"present_temperature=68degC"').uses_text


# ---- findings apart from their record ------------------------------------------------------------
class F:
    def __init__(self, id, severity, t, code="Q001", name="baud-change-not-applied", message="m"):
        self.id, self.severity, self.t, self.code, self.name, self.message = id, severity, t, code, name, message


def test_a_finding_is_judged_by_id_sev_time_and_text():
    f = F(5, "warning", 3.2)
    assert parse_filter("id:5 sev>=warning t:3-").matches_finding(f)
    assert parse_filter("q001").matches_finding(f)
    assert not parse_filter("id:4").matches_finding(f)
    assert not parse_filter("sev:error").matches_finding(f)
    assert not parse_filter("t:-3").matches_finding(f)
    assert parse_filter("-id:4").matches_finding(f)
    # Terms about packets cannot judge a finding: a filter with one shows no finding apart from its record.
    for text in ("kind:short", "present_temperature>40", "latency>1ms", "id:5 reg:baud_rate"):
        assert not parse_filter(text).matches_finding(f), text


# ---- decode --filter -----------------------------------------------------------------------------
def test_decode_filter_text_and_jsonl(capsys, objs):
    want = where(objs, lambda o: any(v > 40 for v in values(o, "present_temperature")))
    assert main(["decode", SESSION, "--filter", "present_temperature>40"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [int(line.split("@")[1].split()[0]) for line in lines] == want
    assert all("present_temperature=68degC" in line for line in lines)
    assert main(["decode", SESSION, "--format", "jsonl", "--filter", "latency>1ms"]) == 0
    got = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [o["offset"] for o in got] == where(objs, lambda o: (o["latency_s"] or 0) > 0.001)


def test_decode_filter_with_id_and_late_findings(capsys, objs):
    assert main(["decode", SESSION, "--format", "jsonl", "--id", "3", "--filter", "sev>=warning"]) == 0
    got = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    records = [o for o in got if o["type"] != "diagnostic"]
    assert records and all(o["diagnostics"] for o in records)
    assert {o["offset"] for o in records} <= {o["offset"] for o in objs if o["diagnostics"]}
    assert not [o for o in got if o["type"] == "diagnostic"]  # the end-of-input Q001 is about ID 5
    assert main(["decode", SESSION, "--format", "jsonl", "--filter", "id:5 sev>=warning"]) == 0
    late = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(o["code"], o["id"]) for o in late if o["type"] == "diagnostic"] == [("Q001", 5)]
    assert main(["decode", SESSION, "--filter", "kind:short id:5"]) == 0
    assert " lint  " not in capsys.readouterr().out  # a term about packets says nothing of a finding


def test_decode_bad_filter_is_one_line_exit_2(capsys):
    assert main(["decode", SESSION, "--filter", "temperature>40"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--filter: temperature>40: no register or filter key" in err


def test_decode_empty_filter_shows_everything(capsys):
    assert main(["decode", SESSION, "--filter", ""]) == 0
    every = capsys.readouterr().out
    assert main(["decode", SESSION]) == 0
    assert capsys.readouterr().out == every


def decode_chunks(chunks, **opts):
    dec = Decoder(DecodeOptions(**opts))
    out = []
    for data in chunks:
        out += dec.feed(data, None)
    return out + dec.close()
