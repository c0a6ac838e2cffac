"""Figure checks (``[[expect]]``, issue 24): the language, its errors, and checks measured on the figures
``info`` computes (the same pipeline: settings, source, Decoder, CaptureStats)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rs30x_sniff.cli import build_parser, main
from rs30x_sniff.commands.common import make_linter, open_input, settings_for
from rs30x_sniff.commands.simulate import write_file
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.expect import (FAIL, NOT_CHECKABLE, PASS, ExpectError, evaluate, figures_doc, findings,
                                load_checks, parse_ids, select_checks)
from rs30x_sniff.lint.registry import Finding
from rs30x_sniff.protocol.wire import AT_FLAG, AT_ID
from rs30x_sniff.sim import scenarios
from rs30x_sniff.sim.bus import SimBus
from rs30x_sniff.sinks.pipeline import columnar_for, drive
from rs30x_sniff.sinks.stats import CaptureStats

CAPTURES = Path(__file__).resolve().parents[1] / "captures"


# ---- the figures, as info computes them ----------------------------------------------------------------------
def info_figures(path: str | Path, *options: str) -> tuple[dict, list[str] | None]:
    """(CaptureStats.as_dict(), the codes of the rules that ran) of ``path``, by info's own pieces."""
    path = str(path)
    args = build_parser().parse_args(["info", path, "--isolated", *options])
    settings = settings_for(args, path)
    opts = settings.decode_options()
    linter = make_linter(args, settings)
    source = open_input(path, None, settings)
    stats = CaptureStats(opts.baud)
    stats.timing_unsupported = getattr(settings, "timing_unsupported", None)
    drive(source, Decoder(opts, linter, columnar=columnar_for(source)), stats)
    return stats.as_dict(), None if linter is None else [r.code for r in linter.rules]


class HalfPollBus(SimBus):
    """A bus whose host spends every other poll of each servo idle: the time passes as if it polled, so the
    cycle holds as many turns as before, and each servo's poll period is twice the hexapod's."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.turns: dict[int, int] = {}

    def send(self, data: bytes, **kw):
        if len(data) == 8 and data[AT_FLAG] == scenarios.POLL_MODE:  # a poll (Host.poll)
            sid = data[AT_ID]
            self.turns[sid] = self.turns.get(sid, 0) + 1
            if self.turns[sid] % 2 == 0:
                self.sleep(8 * self.bt + scenarios.POLL_REPLY_BYTES * self.bt + 200e-6 + 2 * self.turnaround)
                return [None]  # "answered": the host goes on with its cycle
        return super().send(data, **kw)


@pytest.fixture(scope="module")
def hexapod(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("expect") / "h.thex"
    write_file(str(path), scenarios.run("hexapod"), "timestamped", 115200)
    return path


@pytest.fixture(scope="module")
def hexapod_half_polls(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("expect") / "half.thex"
    write_file(str(path), scenarios.run("hexapod", bus=HalfPollBus(115200)), "timestamped", 115200)
    return path


LEGS = {"code": "U101", "name": "legs-polled-fast", "severity": "error", "check": "poll_hz >= 5", "for": "id:1-6"}


# ---- the acceptance of the issue -------------------------------------------------------------------------------
def test_poll_hz_passes_on_the_hexapod(hexapod):
    info, rules = info_figures(hexapod)
    results = evaluate(load_checks([LEGS], "rs30x-sniff.toml"), info, rules)
    assert [r.id for r in results] == [1, 2, 3, 4, 5, 6]
    assert all(r.status == PASS for r in results), [r.message for r in results]
    assert results[0].message.startswith("ID 1: poll_hz 7.")
    assert findings(results, info["bytes"]) == []


def test_poll_hz_fails_with_the_measured_rate_when_the_poll_period_doubles(hexapod, hexapod_half_polls):
    before, _ = info_figures(hexapod)
    info, rules = info_figures(hexapod_half_polls)
    for sid in range(1, 7):  # the bus really polls each servo half as often
        assert info["servos"][str(sid)]["poll_rate_hz"] == pytest.approx(before["servos"][str(sid)]["poll_rate_hz"] / 2,
                                                                         rel=0.05)
    results = evaluate(load_checks([LEGS], "rs30x-sniff.toml"), info, rules)
    assert [r.status for r in results] == [FAIL] * 6
    for r in results:
        rate = info["servos"][str(r.id)]["poll_rate_hz"]
        assert r.message == f"ID {r.id}: poll_hz {rate:.3g} < 5"
    found = findings(results, info["bytes"], 9.5)
    assert found[2] == Finding("U101", "legs-polled-fast", "error", results[2].message, info["bytes"], 9.5, 3)


def test_the_figures_are_the_ones_info_prints(tmp_path):
    path = str(CAPTURES / "session-mixed.thex")
    info, _ = info_figures(path)
    out = tmp_path / "info.json"
    assert main(["info", path, "--isolated", "--format", "json", "-o", str(out)]) == 0
    printed = json.loads(out.read_text())
    assert {k: printed[k] for k in info} == json.loads(json.dumps(info))


# ---- measured figures on a real capture -------------------------------------------------------------------------
@pytest.fixture(scope="module")
def mixed() -> tuple[dict, list[str] | None]:
    return info_figures(CAPTURES / "session-mixed.thex")


def _one(entry: dict, info: dict, rules=None, **kw) -> list:
    return evaluate(load_checks([{"code": "U101", "name": "x", **entry}], "t.toml"), info, rules, **kw)


def test_a_servo_named_but_never_seen_is_not_checkable(mixed):
    info, rules = mixed
    results = _one({"check": "missing_replies == 0", "for": "id:6-7"}, info, rules)
    assert [(r.id, r.status, r.message) for r in results] == [
        (6, FAIL, "ID 6: missing_replies 1 != 0"), (7, NOT_CHECKABLE, "ID 7 not seen")]
    f = findings(results, 100, 3.0)
    assert [x.message for x in f] == ["ID 6: missing_replies 1 != 0", "not checkable: ID 7 not seen"]
    assert [x.id for x in f] == [6, 7]


def test_each_takes_every_servo_seen(mixed):
    info, rules = mixed
    results = _one({"check": "missing_replies == 0", "for": "each"}, info, rules)
    assert [r.id for r in results] == [1, 2, 3, 4, 5, 6]
    assert [r.id for r in results if r.status == FAIL] == [3, 6]


def test_units_convert_and_are_shown_as_written(mixed):
    info, rules = mixed
    p95 = info["latency_s"]["p95"]
    (r,) = _one({"check": "latency_p95 < 100 us"}, info, rules)
    assert r.status == FAIL and r.message == f"latency_p95 {p95 * 1e6:g} us >= 100 us"
    (r,) = _one({"check": "latency_p95 < 1"}, info, rules)  # a bare number: the figure's own unit (ms)
    assert r.status == PASS and r.message == f"latency_p95 {p95 * 1e3:g} < 1"
    (r,) = _one({"check": "bus_load <= 10 %"}, info, rules)
    assert r.status == FAIL and r.message == f"bus_load {info['bus_load'] * 100:.3g} % > 10 %"
    hot = max(h["registers"]["present_temperature"]["max"] for h in info["health"].values())
    (r,) = _one({"check": "max(present_temperature) < 60 degC"}, info, rules)
    assert r.status == (PASS if hot < 60 else FAIL) and str(hot).rstrip("0").rstrip(".") in r.message
    (r,) = _one({"check": "max(present_current) <= 0.3 A", "for": "id:1"}, info, rules)
    cur = info["health"]["1"]["registers"]["present_current"]["max"]
    assert r.status == (PASS if cur <= 300 else FAIL) and r.message == f"ID 1: max(present_current) {cur / 1e3:g} A " \
        f"{'<=' if cur <= 300 else '>'} 0.3 A"


def test_a_number_on_the_left_and_two_figures(mixed):
    info, rules = mixed
    (r,) = _one({"check": "5 <= poll_hz", "for": "id:5"}, info, rules)
    assert r.status == PASS and r.message.startswith("ID 5: poll_hz 10.1 >= 5")
    r3, r5 = _one({"check": "returns >= reads", "for": "id:3,5"}, info, rules)
    assert (r3.status, r3.message) == (FAIL, "ID 3: returns 17 < reads 18")
    assert r5.status == PASS


def test_and_reports_every_failing_comparison(mixed):
    info, rules = mixed
    (r,) = _one({"check": "missing_replies == 0 and poll_hz > 100 and returns > 0", "for": "id:3"}, info, rules)
    assert r.status == FAIL
    assert r.message.startswith("ID 3: missing_replies 1 != 0; poll_hz 6.98 <= 100")
    assert "returns" not in r.message


def test_a_shown_value_keeps_the_digits_its_outcome_needs():
    info = {"timed": True, "servos": {"1": {"poll_rate_hz": 4.99991, "reads": 50}}, "health": {}}
    (r,) = _one({"check": "poll_hz >= 5", "for": "id:1"}, info)
    assert r.status == FAIL and r.message == "ID 1: poll_hz 4.9999 < 5"  # never "5 < 5"


def test_unsolicited_replies_and_findings_need_the_linter(mixed):
    info, rules = mixed
    (r,) = _one({"check": "unsolicited_replies == 0 and findings == 0", "for": "id:1"}, info, None)
    assert r.status == NOT_CHECKABLE
    assert r.message == ("ID 1: unsolicited_replies not checkable: the capture was not linted; "
                         "findings not checkable: the capture was not linted")
    (r,) = _one({"check": "unsolicited_replies == 0"}, info, [c for c in rules if c != "B003"])
    assert (r.status, r.message) == (NOT_CHECKABLE, "unsolicited_replies not checkable: rule B003 did not run "
                                                    "(--select/--ignore)")
    (r,) = _one({"check": "findings <= 3"}, info, rules)
    total = sum(info["findings"].values())
    assert r.status == (PASS if total <= 3 else FAIL) and f"findings {total}" in r.message


def test_a_fail_beside_a_not_checkable_is_a_fail():
    info = {"timed": False, "servos": {"1": {"poll_rate_hz": None, "reads": 9, "missing": 2}}, "health": {}}
    (r,) = _one({"check": "missing_replies == 0 and poll_hz > 5", "for": "id:1"}, info)
    assert r.status == FAIL
    assert r.message == "ID 1: missing_replies 2 != 0; poll_hz not checkable: the capture has no timestamps"


# ---- not checkable: figures the capture cannot give -------------------------------------------------------------
def test_an_untimed_capture_gives_no_rate_load_or_latency(tmp_path):
    path = tmp_path / "h.hex"
    write_file(str(path), scenarios.run("hexapod", duration=2.0), "hex", 115200)
    info, rules = info_figures(path)
    assert info["timed"] is False
    checks = load_checks([
        {"code": "U101", "name": "rate", "check": "poll_hz >= 5", "for": "id:1"},
        {"code": "U102", "name": "load", "check": "bus_load < 50%"},
        {"code": "U103", "name": "lat", "check": "latency_p95 < 1 ms", "not_checkable": "warning"},
        {"code": "U104", "name": "peak", "check": "bus_load_peak < 90"},
        {"code": "U105", "name": "count", "check": "missing_replies == 0"},
    ], "t.toml")
    results = evaluate(checks, info, rules)
    assert [(r.status, r.message) for r in results] == [
        (NOT_CHECKABLE, "ID 1: poll_hz not checkable: the capture has no timestamps"),
        (NOT_CHECKABLE, "bus_load not checkable: the capture has no timestamps"),
        (NOT_CHECKABLE, "latency_p95 not checkable: the capture has no timestamps"),
        (NOT_CHECKABLE, "bus_load_peak not checkable: the capture has no timestamps"),
        (PASS, "missing_replies 0 == 0"),
    ]
    f = findings(results, info["bytes"])
    assert [(x.code, x.severity, x.message) for x in f][1:3] == [
        ("U102", "error", "not checkable: bus_load not checkable: the capture has no timestamps"),
        ("U103", "warning", "not checkable: latency_p95 not checkable: the capture has no timestamps")]
    assert all(x.offset == info["bytes"] and x.t is None for x in f)


def test_an_absent_latency_is_not_checkable():
    info = {"timed": True, "servos": {}, "health": {},
            "latency_s": {"count": 10, "p50": 1e-4, "p95": 2e-4, "max": 3e-4, "unmeasured": 2,
                          "absent": "2 replies stamped before their request ended (F005/F006): no latency"}}
    (r,) = _one({"check": "latency_p95 < 1 ms"}, info)
    assert r.status == NOT_CHECKABLE and r.message.endswith("(F005/F006): no latency")
    info["latency_s"] = {"count": 0, "p50": None, "p95": None, "max": None, "unmeasured": 0}
    (r,) = _one({"check": "latency_max < 1 ms"}, info)
    assert (r.status, r.message) == (NOT_CHECKABLE, "latency_max not checkable: no reply was paired with its request")


def test_flags_and_ranges_of_a_servo_that_never_answered_are_not_checkable():
    info = {"timed": True, "servos": {"4": {"requests": 9, "reads": 9, "returns": 0, "missing": 9}},
            "health": {"4": {"model": "RS303MR", "registers": {}, "flags": {}, "findings": {}}}}
    r1, r2 = evaluate(load_checks([
        {"code": "U101", "name": "a", "check": "temperature_alarm == 0", "for": "id:4"},
        {"code": "U102", "name": "b", "check": "max(present_temperature) < 60", "for": "id:4"}], "t.toml"), info)
    assert (r1.status, r1.message) == (NOT_CHECKABLE, "ID 4: temperature_alarm not checkable: ID 4 sent no return: "
                                                      "its status flags are unknown")
    assert (r2.status, r2.message) == (NOT_CHECKABLE, "ID 4: max(present_temperature) not checkable: ID 4 showed no "
                                                      "present_temperature in its returns")


# ---- mistakes in the configuration: one line, the file, the check, the key, the column -------------------------
@pytest.mark.parametrize("check, col, why", [
    ("pol_hz >= 5", 1, "unknown figure 'pol_hz' (did you mean poll_hz?)"),
    ("poll_hz >= 5 ms", 12, "poll_hz is a rate (Hz, kHz); 'ms' is a time (ns, us, ms, s, min, h, d)"),
    ("poll_hz >= 5 or missing_replies == 0", 14, "'or' is not part of the language: write two checks"),
    ("poll_hz >=", 11, "the check ends too soon"),
    ("poll_hz >= 5 and", 17, "the check ends too soon"),
    ("missing_replies > 2 ms", 19, "missing_replies is a count: no unit (2 ms)"),
    ("poll_hz >= 5xz", 13, "unknown unit 'xz'"),
    ("max(present_temp) < 60", 5, "max() of 'present_temp': not a register with a range in info (did you mean "
                                   "present_temperature?)"),
    ("present_temperature < 60", 1, "present_temperature is a register: write max(present_temperature)"),
    ("5 < 6", 1, "compares two numbers: one side must be a figure"),
    ("poll_hz > returns", 11, "poll_hz is a rate (Hz, kHz), returns is a count (no unit): they cannot be compared"),
    ("bus_load < 50%", 1, "bus_load is a figure of the whole bus (not measured per servo): check it "
                          "without 'for'"),
    ("poll_hz >= 5 # x", 14, "unexpected '#'"),
    ("", 1, "empty check"),
    ("poll_hz >= 1e999", 12, "1e999 is not a finite number"),
])
def test_a_bad_check_names_the_file_the_check_the_key_and_the_column(check, col, why):
    with pytest.raises(ExpectError) as e:
        load_checks([{"code": "U101", "name": "x", "check": "packets > 0"},
                     {"code": "U102", "name": "y", "check": check, "for": "id:1"}], "rs30x-sniff.toml")
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(f"rs30x-sniff.toml: [[expect]] #2 (U102): check = {check!r}: column {col}: {why}"), msg


def test_a_per_servo_figure_without_for():
    with pytest.raises(ExpectError, match=r"^t.toml: \[\[expect\]\] #1 \(U101\): check = 'poll_hz >= 5': column 1: "
                                          r"poll_hz is a figure of each servo: give the check for = \"id:...\""):
        load_checks([{"code": "U101", "name": "x", "check": "poll_hz >= 5"}], "t.toml")


@pytest.mark.parametrize("entry, why", [
    ({"code": "R101"}, "code = 'R101': expected U and three digits (U101)"),
    ({"code": "U1011"}, "code = 'U1011': expected U and three digits"),
    ({"name": "Legs Fast"}, "name = 'Legs Fast': expected lower-case words joined by '-'"),
    ({"severity": "fatal"}, "severity = 'fatal': expected one of info, warning, error"),
    ({"not_checkable": "pass"}, "not_checkable = 'pass': expected one of info, warning, error"),
    ({"for": "1-6"}, "for = '1-6': expected id:1-6,9 (the filter language's IDs) or \"each\""),
    ({"for": "id:6-1"}, "for = 'id:6-1': range 6-1 runs backwards"),
    ({"for": "id:300"}, "for = 'id:300': IDs run from 0 to 255"),
    ({"chek": "x"}, "unknown key 'chek' (did you mean check?)"),
    ({"check": 5}, "check = 5: expected a string"),
])
def test_a_bad_entry_names_its_key(entry, why):
    base = {"code": "U101", "name": "x", "check": "missing_replies == 0", "for": "id:1"}
    with pytest.raises(ExpectError) as e:
        load_checks([{**base, **entry}], "pyproject.toml")
    assert str(e.value).startswith("pyproject.toml: [[expect]] #1") and why in str(e.value), str(e.value)


def test_codes_and_names_are_unique():
    a = {"code": "U101", "name": "a", "check": "packets > 0"}
    with pytest.raises(ExpectError, match=r"#2 \(U101\): code = 'U101': already the code of \[\[expect\]\] #1"):
        load_checks([a, {**a, "name": "b"}], "t.toml")
    with pytest.raises(ExpectError, match=r"#2 \(U102\): name = 'a': already the name of \[\[expect\]\] #1"):
        load_checks([a, {**a, "code": "U102"}], "t.toml")


def test_parse_ids_is_the_filter_languages():
    assert parse_ids("id:1-3,9") == (1, 2, 3, 9)
    assert parse_ids("id:0x10") == (16,)
    assert parse_ids("each") == "each"


def test_the_language_is_documented():
    doc = (Path(__file__).resolve().parents[1] / "docs" / "checks.md").read_text()
    for name, *_ in figures_doc():
        assert f"`{name}`" in doc, name


def test_select_ignore_and_severity_take_the_checks_as_they_take_rules():
    checks = load_checks([{"code": "U101", "name": "legs-polled-fast", "check": "poll_hz >= 5", "for": "each"},
                          {"code": "U201", "name": "cool", "check": "max(present_temperature) < 60"}], "t.toml")
    assert [c.code for c in select_checks(checks)] == ["U101", "U201"]
    assert [c.code for c in select_checks(checks, ["U1"])] == ["U101"]
    assert [c.code for c in select_checks(checks, ["F", "B"])] == []
    assert [c.code for c in select_checks(checks, ["ALL"], ["cool"])] == ["U101"]
    (c,) = select_checks(checks, ["legs-polled-fast"], (), {"U101": "warning"})
    assert (c.severity, c.unknown_severity) == ("warning", "warning")


def test_a_bad_entry_is_a_configuration_error():
    from rs30x_sniff.lint.config import ConfigError
    with pytest.raises(ConfigError):
        load_checks([{"code": "U1"}], "t.toml")


def test_a_check_as_a_rule_of_the_registry():
    from rs30x_sniff.expect import as_rule
    (c,) = load_checks([{"code": "U101", "name": "legs-polled-fast", "check": "poll_hz >= 5", "for": "id:1-6",
                         "severity": "warning", "doc": "The gait needs fresh positions."}], "t.toml")
    r = as_rule(c)
    assert (r.code, r.name, r.severity, r.kinds, r.column) == ("U101", "legs-polled-fast", "warning", ("close",),
                                                                "silent")
    assert r.summary == "Figure check: poll_hz >= 5 (IDs 1, 2, 3, 4, 5, 6)."
    assert "The gait needs fresh positions." in r.doc
    assert r.check(None) is None


# ---- a servo's own latency ---------------------------------------------------------------------------------------
class OneSlowServoBus(SimBus):
    """A bus on which ID 3 answers after 8 steps of its return delay (No. 7: 50 us each), the others at once."""

    def attach(self, servo):
        if servo.mem[4] == 3:
            servo.mem[7] = 8
        return super().attach(servo)


@pytest.mark.parametrize("fmt", ["timestamped", "mcap"])
def test_a_servos_latency_is_its_own_replies(tmp_path, fmt):
    """Per-servo percentiles (info's servos.ID.latency_s) on the columnar path (a .thex) and the record path
    (an MCAP's raw channel is read as records too): the slow servo alone fails a per-servo check."""
    path = tmp_path / ("h.thex" if fmt == "timestamped" else "h.mcap")
    write_file(str(path), scenarios.run("hexapod", duration=2.0, bus=OneSlowServoBus(115200)), fmt, 115200)
    info, rules = info_figures(path)
    per = {sid: s["latency_s"] for sid, s in info["servos"].items() if "latency_s" in s}
    assert set(per) == {str(i) for i in range(1, 19)}
    assert sum(lat["count"] for lat in per.values()) == info["latency_s"]["count"]
    assert per["3"]["p50"] > 0.4e-3 > max(lat["max"] for sid, lat in per.items() if sid != "3")
    assert info["latency_s"]["max"] == per["3"]["max"]
    (check,) = load_checks([{"code": "U101", "name": "quick", "check": "latency_p95 < 0.3 ms", "for": "each"}], "t")
    results = evaluate([check], info, rules)
    failed = [r for r in results if r.status != PASS]
    assert [r.status for r in failed] == [FAIL] and failed[0].message.startswith("ID 3: latency_p95 0.")
    assert len(results) == 18


def test_a_servo_with_no_timed_reply_has_no_latency_to_check():
    info = {"timed": True, "health": {}, "latency_s": {"count": 4, "p50": 1e-4, "p95": 1e-4, "max": 1e-4},
            "servos": {"1": {"latency_s": {"count": 4, "p50": 1e-4, "p95": 1e-4, "max": 1e-4}}, "2": {}}}
    r1, r2 = evaluate(load_checks([{"code": "U101", "name": "q", "check": "latency_max < 1 ms", "for": "id:1-2"}],
                                  "t.toml"), info)
    assert (r1.status, r2.status) == (PASS, NOT_CHECKABLE)
    assert r2.message == "ID 2: latency_max not checkable: no reply of ID 2 was paired with its request"


def test_a_failed_check_keeps_its_fingerprint_when_its_value_moves():
    """The measured value is a typed parameter: in the message, never in a baseline's fingerprint (issue 32)."""
    from rs30x_sniff.lint.baseline import fingerprint

    def finding_for(missing: int, hz: float | None):
        info = {"timed": hz is not None, "servos": {"1": {"poll_rate_hz": hz, "reads": 9, "missing": missing}},
                "health": {}}
        (r,) = _one({"check": "missing_replies == 0 and poll_hz > 50", "for": "id:1"}, info)
        return findings([r], 100, None)[0]

    a, b = finding_for(2, 10.0), finding_for(5, 12.5)
    assert a.message == "ID 1: missing_replies 2 != 0; poll_hz 10 <= 50"
    assert fingerprint(a) == fingerprint(b) == "U101:1:ID 1: missing_replies * != 0; poll_hz * <= 50"
    assert fingerprint(finding_for(0, 10.0)) != fingerprint(a)  # another comparison failing is another finding
    c, d = finding_for(2, None), finding_for(3, None)  # a fail beside a figure not checkable
    assert fingerprint(c) == fingerprint(d) == \
        "U101:1:ID 1: missing_replies * != 0; poll_hz not checkable: the capture has no timestamps"
    e = finding_for(0, None)
    assert fingerprint(e) == "U101:1:not checkable: ID 1: poll_hz not checkable: the capture has no timestamps"


# ---- one grammar (issue 33): operators, durations and IDs as the filters and options read them ---------------
def test_equals_is_one_operator_either_way():
    info = {"timed": True, "servos": {"4": {"requests": 9, "reads": 9, "returns": 9, "missing": 0}}, "health": {}}
    one, two = evaluate(load_checks([
        {"code": "U101", "name": "a", "check": "missing_replies = 0", "for": "id:4"},
        {"code": "U102", "name": "b", "check": "missing_replies == 0", "for": "id:4"}], "t.toml"), info)
    assert (one.status, one.message) == (two.status, two.message) == (PASS, "ID 4: missing_replies 0 == 0")


@pytest.mark.parametrize("limit, status", [("1min", PASS), ("1 min", PASS), ("2h", PASS), ("50us", FAIL),
                                           ("0.0001s", FAIL), ("0.2ms", PASS)])
def test_a_check_takes_every_duration_unit(limit, status):
    info = {"timed": True, "latency_s": {"count": 3, "p50": 1e-4, "p95": 1.5e-4, "max": 2e-4}, "servos": {},
            "health": {}}
    (r,) = evaluate(load_checks([{"code": "U101", "name": "a", "check": f"latency_p95 < {limit}"}], "t.toml"), info)
    assert r.status == status, r.message


def test_ids_are_read_by_the_one_id_grammar():
    from rs30x_sniff.language import parse_id_range
    assert parse_ids("id:1-3, 0x10") == parse_id_range("1-3, 0x10") == (1, 2, 3, 16)
