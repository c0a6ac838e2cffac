"""`rs30x-sniff diff` (issue 24): two captures side by side, and the [regress] thresholds they are held to.

The comparison (rs30x_sniff.compare) is a pure function of two `info` figure dicts, tested here on hand-made
dicts; the command is tested end to end on simulator captures whose servos answer after different return
delays (the servo's return delay register, No. 7)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.compare import DOWN, UP, ThresholdError, compare, parse_threshold, parse_thresholds
from rs30x_sniff.sim import run
from rs30x_sniff.sources.captures import HEX, TIMESTAMPED, write_capture
from .sim_buses import DelayedBus


# ---- the comparison, on figure dicts ---------------------------------------------------------------
def figures(p95: float | None = 0.0001, *, missing: int = 0, rate: float | None = 50.0, rules=None, linted=True,
            servos=(1, 2), temp_max: float = 40.0, timed: bool = True) -> dict:
    """A capture's figures in the shape `info --format json` gives them."""
    return {
        "input": "x", "timed": timed, "duration_s": 2.0, "bytes": 100, "baud": 115200, "linted": linted,
        "timing_unsupported": None, "bus_load": 0.2 if timed else None,
        "bus_load_peak": {"load": 0.25} if timed else None, "bad_checksums": 0, "garbage_bytes": 0,
        "latency_s": {"count": 10, "p50": p95, "p95": p95, "max": p95, "unmeasured": 0},
        "servos": {str(s): {"requests": 10, "reads": 10, "long_writes": 0, "returns": 10 - missing, "acks": 0,
                            "nacks": 0, "missing": missing if s == 1 else 0, "poll_rate_hz": rate}
                   for s in servos},
        "findings": {"error": 0, "warning": 0, "info": 0},
        "findings_by_rule": dict(rules or {}),
        "health": {str(s): {"model": "RS303MR", "flags": {}, "findings": {},
                            "registers": {"present_temperature": {"min": 30.0, "max": temp_max, "unit": "degC",
                                                                  "count": 5}}} for s in servos},
    }


def thresholds(**table) -> dict:
    return parse_thresholds(table, "rs30x-sniff.toml")


def test_a_latency_rise_past_its_percentage_is_a_regression_and_below_it_is_not():
    t = thresholds(latency_p95="+20%")
    crossed = compare(figures(0.000100), figures(0.000125), t)
    assert [(c.change.figure, c.change.servo) for c in crossed.crossings] == [("latency_p95", None)]
    assert "0.100 ms -> 0.125 ms" in crossed.crossings[0].describe()
    assert "+20%" in crossed.crossings[0].describe()
    assert not compare(figures(0.000100), figures(0.000115), t).crossings
    assert not compare(figures(0.000125), figures(0.000100), t).crossings  # faster is no regression


def test_a_figure_one_capture_cannot_give_is_not_checked_never_passed_nor_crossed():
    t = thresholds(latency_p95="+0%", poll_hz="-1%")
    r = compare(figures(None, rate=None, timed=False), figures(0.001), t)
    assert not r.crossings
    reasons = {(u.figure, u.servo): u.reason for u in r.unchecked}
    assert reasons[("latency_p95", None)] == "BEFORE: no timestamps"
    assert reasons[("poll_hz", "1")] == "BEFORE: no timestamps"
    row = next(c for c in r.bus if c.figure == "latency_p95")
    assert row.delta is None and row.trend is None and row.as_dict()["absent"] == "BEFORE: no timestamps"


def test_a_threshold_no_figure_matches_is_listed_as_not_checked():
    r = compare(figures(servos=(1,)), figures(servos=(2,)), thresholds(poll_hz="-10%"))
    assert not r.crossings
    assert [(u.figure, u.reason) for u in r.unchecked] == [("poll_hz", "no servo in both captures has it")]


def test_per_servo_thresholds_name_the_servo():
    # A figure of the bus and the servos is held on both: the bus's count, and each servo's.
    r = compare(figures(missing=0), figures(missing=2), thresholds(missing_replies="+0"))
    assert [(c.change.servo, c.change.before.value, c.change.after.value) for c in r.crossings] == \
        [(None, 0, 2), ("1", 0, 2)]
    slower = compare(figures(rate=50.0), figures(rate=40.0), thresholds(poll_hz="10%"))  # no sign: poll_hz falls
    assert {c.change.servo for c in slower.crossings} == {"1", "2"}
    assert not compare(figures(rate=50.0), figures(rate=46.0), thresholds(poll_hz="10%")).crossings
    hot = compare(figures(temp_max=40), figures(temp_max=46), thresholds(**{"max(present_temperature)": "+5"}))
    assert {c.change.servo for c in hot.crossings} == {None, "1", "2"}


def test_findings_by_rule_new_gone_changed_and_the_new_findings_threshold():
    before = figures(rules={"B002 missing-return": 2, "F002 garbage-bytes": 1, "B008 nack": 4})
    after = figures(rules={"B002 missing-return": 5, "B006 return-latency": 3, "B008 nack": 4})
    r = compare(before, after, thresholds(new_findings=0, new_rules="+1"))
    f = r.findings
    assert f.new == {"B006 return-latency": 3}
    assert f.gone == {"F002 garbage-bytes": 1}
    assert f.changed == {"B002 missing-return": (2, 5)}
    assert f.same == {"B008 nack": 4}
    assert f.new_findings == 3 + 3
    assert [(c.change.figure, c.change.after.value) for c in r.crossings] == [("new_findings", 6)]
    back = compare(after, before, thresholds(new_findings=1))  # fewer B002 count for nothing; F002 is back
    assert back.findings.new == {"F002 garbage-bytes": 1} and not back.crossings
    assert not compare(before, before, thresholds(new_findings=0)).crossings


def test_without_lint_the_findings_are_absent_with_the_reason():
    r = compare(figures(linted=False), figures(), thresholds(new_findings=0, unsolicited_replies="+0"))
    assert r.findings.absent == "BEFORE: not linted (--no-lint)"
    assert not r.crossings
    assert {u.figure for u in r.unchecked} == {"new_findings", "unsolicited_replies"}


def test_a_servo_gone_is_counted():
    r = compare(figures(servos=(1, 2, 3)), figures(servos=(1, 2)), thresholds(servos_gone=0))
    assert r.only_before == ["3"] and r.only_after == []
    assert [(c.change.figure, c.change.after.value) for c in r.crossings] == [("servos_gone", 1)]


@pytest.mark.parametrize("value, direction, percent, amount", [
    ("+20%", UP, 20.0, None), ("-10%", DOWN, 10.0, None), ("20%", UP, 20.0, None), ("+0.2 ms", UP, None, 0.2),
    ("+50us", UP, None, 0.05), (0.5, UP, None, 0.5), ("+0.5", UP, None, 0.5), ("+1min", UP, None, 60000.0),
    ("+0.001s", UP, None, 1.0),
])
def test_threshold_forms(value, direction, percent, amount):
    # A latency is in ms, as in a check: a bare number is ms, any time unit converts (language.TIME_UNITS).
    t = parse_threshold("latency_p95", value, "f.toml")
    assert (t.direction, t.percent) == (direction, percent)
    assert t.amount == pytest.approx(amount) if amount is not None else t.amount is None
    assert parse_threshold("poll_hz", "10%", "f").direction == DOWN  # no sign: the way the figure gets worse


@pytest.mark.parametrize("key, value, words", [
    ("latency_p9", "+20%", "unknown figure"),
    ("latency_p95", "twenty", "expected a signed amount"),
    ("latency_p95", True, "expected a number"),
    ("missing_replies", "+2 ms", "is a count"),
    ("poll_hz", "+2 ms", "'ms' does not fit"),
    ("requests", "5", "give a sign"),
    ("new_findings", "-1", "count of the change"),
    ("new_findings", "+5%", "count of the change"),
    ("bus_load", float("nan"), "finite"),
])
def test_a_bad_threshold_is_one_message_naming_the_file_and_key(key, value, words):
    with pytest.raises(ThresholdError) as e:
        parse_threshold(key, value, "conf/rs30x-sniff.toml")
    assert str(e.value).startswith(f"conf/rs30x-sniff.toml: regress.{key}")
    assert words in str(e.value)


# ---- the command, on simulator captures --------------------------------------------------------------
@pytest.fixture(scope="module")
def captures(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("diff")
    out = {}
    for name, delay in (("fast", 0), ("slow", 3)):
        chunks = list(run("silent-servo", duration=1.5, bus=DelayedBus(115200, delay)))
        out[name] = d / f"{name}.thex"
        write_capture(out[name], chunks, TIMESTAMPED)
        if name == "fast":
            out["untimed"] = d / "fast.hex"
            write_capture(out["untimed"], chunks, HEX)
    return out


@pytest.fixture
def conf(tmp_path) -> Path:
    p = tmp_path / "rs30x-sniff.toml"
    p.write_text('[regress]\nlatency_p95 = "+20%"\nmissing_replies = "+0"\nnew_findings = 0\n')
    return p


def test_the_latency_change_of_a_slower_return_delay_fails_under_fail_on_regress(capsys, captures, conf):
    code = main(["diff", str(captures["fast"]), str(captures["slow"]), "--config", str(conf), "--fail-on-regress"])
    out, err = capsys.readouterr()
    assert code == 1
    assert "latency_p95" in out and "crossed" in out
    lines = [line for line in err.splitlines() if "regression" in line]
    # latency only (the bus's, and each answering servo's): the missing replies and findings are the same in both
    assert len(lines) >= 2 and all("regression: latency_p95 (" in line for line in lines), err
    assert "latency_p95 (bus)" in lines[0] and " -> " in lines[0] and "threshold +20%" in lines[0]


def test_no_threshold_crossed_exits_0(capsys, captures, conf):
    # Faster replies, and a capture against itself: nothing got worse.
    assert main(["diff", str(captures["slow"]), str(captures["fast"]), "--config", str(conf),
                 "--fail-on-regress"]) == 0
    assert main(["diff", str(captures["fast"]), str(captures["fast"]), "--config", str(conf),
                 "--fail-on-regress"]) == 0
    assert "regression" not in capsys.readouterr().err


@pytest.mark.parametrize("side", [0, 1])
def test_an_empty_capture_is_no_session_to_compare(capsys, captures, tmp_path, side):
    # Against an empty capture every count would read "better": it is an input error instead, and no output.
    empty = tmp_path / "empty.thex"
    empty.write_bytes(b"")
    pair = [str(captures["fast"]), str(empty)][::-1 if side else 1]
    out = tmp_path / "diff.md"
    assert main(["diff", *pair, "--format", "markdown", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "no data" in err and len(err.strip().splitlines()) == 1 and not out.exists()


def test_without_fail_on_regress_a_crossed_threshold_is_reported_and_exits_0(capsys, captures, conf):
    assert main(["diff", str(captures["fast"]), str(captures["slow"]), "--config", str(conf)]) == 0
    out = capsys.readouterr().out
    assert "crossed      latency_p95 (bus)" in out


def test_json_output(capsys, captures):
    assert main(["diff", str(captures["fast"]), str(captures["slow"]), "--isolated", "--format", "json",
                 "--threshold", "latency_p95=+20%"]) == 0
    doc = json.loads(capsys.readouterr().out)
    row = next(r for r in doc["bus"] if r["figure"] == "latency_p95")
    # Three steps of the return delay: 150 us later (table 4.5 No. 7: 50 us a step).
    assert row["unit"] == "ms" and row["after"] - row["before"] == pytest.approx(0.150, abs=0.020)
    assert row["trend"] == "worse" and row["percent"] > 20
    assert [(r["figure"], r["servo"], r["threshold"]) for r in doc["regressions"]][0] == ("latency_p95", None, "+20%")
    assert {r["figure"] for r in doc["regressions"]} == {"latency_p95"}
    assert doc["before"]["input"] == str(captures["fast"]) and doc["after"]["timed"] is True
    assert set(doc["servos"]) == {"1", "2", "3", "4", "5", "6"}
    poll = next(r for r in doc["servos"]["4"] if r["figure"] == "missing_replies")
    assert poll["before"] == poll["after"] and poll["before"] > 0  # servo 4 never answers, in both
    assert doc["findings"]["same"] and not doc["findings"]["new"]


def test_markdown_output(capsys, captures):
    assert main(["diff", str(captures["fast"]), str(captures["slow"]), "--isolated", "--format", "markdown",
                 "--threshold", "latency_p95=+20%"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("### rs30x-sniff diff: **1 threshold crossed**")  # on the bus and the servos: one
    assert "- :x: latency_p95 (bus):" in out
    assert "| bus | before | after | change |" in out
    row = next(line for line in out.splitlines() if line.startswith("| latency_p95 |"))
    assert row.count("|") == 5 and "worse" in row
    assert "| B002 missing-return |" in out


def test_text_output_side_by_side(capsys, captures):
    assert main(["diff", str(captures["fast"]), str(captures["slow"]), "--isolated"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"before  {captures['fast']}:")
    row = next(line for line in out.splitlines() if line.strip().startswith("latency_p95"))
    assert "->" in row and "worse" in row
    assert "thresholds: none" in out


def test_a_capture_without_timestamps_leaves_latency_unchecked(capsys, captures, conf):
    # A threshold checked on nothing is no pass (issue 32): exit 1 "not checkable", unless allowed.
    assert main(["diff", str(captures["untimed"]), str(captures["slow"]), "--config", str(conf),
                 "--fail-on-regress"]) == 1
    err = capsys.readouterr().err
    assert "error: not checkable: latency_p95 (bus), threshold +20%: BEFORE: no timestamps" in err
    assert main(["diff", str(captures["untimed"]), str(captures["slow"]), "--config", str(conf),
                 "--fail-on-regress", "--allow-unchecked"]) == 0
    out = capsys.readouterr().out
    assert "not checked  latency_p95 (bus), threshold +20%: BEFORE: no timestamps" in out
    row = next(line for line in out.splitlines() if line.strip().startswith("latency_p95"))
    assert "absent: BEFORE: no timestamps" in row


@pytest.mark.parametrize("text, words", [
    ('[regress]\nlatency_p9 = "+20%"\n', "regress.latency_p9: unknown figure"),
    ('[regress]\nlatency_p95 = "lots"\n', "regress.latency_p95 = 'lots'"),
    ('regress = 3\n', "regress = 3: expected a table"),
])
def test_a_bad_regress_table_is_one_line_and_exit_2(capsys, captures, tmp_path, text, words):
    p = tmp_path / "rs30x-sniff.toml"
    p.write_text(text)
    assert main(["diff", str(captures["fast"]), str(captures["slow"]), "--config", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert str(p) in err and words in err


def test_pyproject_regress_table(capsys, captures, tmp_path, monkeypatch):
    (tmp_path / "pyproject.toml").write_text('[tool.rs30x-sniff.regress]\nlatency_p95 = "+20%"\n')
    monkeypatch.chdir(tmp_path)  # found as the nearest configuration
    assert main(["diff", str(captures["fast"]), str(captures["slow"]), "--fail-on-regress"]) == 1
    assert "threshold +20%" in capsys.readouterr().err
    (tmp_path / "pyproject.toml").write_text('[tool.rs30x-sniff.regress]\nlatency_p95 = "+200%"\n')
    assert main(["diff", str(captures["fast"]), str(captures["slow"]), "--fail-on-regress"]) == 0


def test_other_commands_accept_a_configuration_with_a_regress_table(capsys, captures, conf):
    assert main(["info", str(captures["fast"]), "--config", str(conf)]) == 0


def test_a_bad_threshold_option_is_one_line(capsys, captures):
    assert main(["diff", str(captures["fast"]), str(captures["slow"]), "--isolated", "--threshold", "p95"]) == 2
    assert "--threshold p95: expected FIGURE=LIMIT" in capsys.readouterr().err
    assert main(["diff", str(captures["fast"]), str(captures["slow"]), "--isolated",
                 "--threshold", "latency_p95=+1 Hz"]) == 2
    assert "--threshold: regress.latency_p95" in capsys.readouterr().err


def test_an_output_file_is_not_replaced_without_force(capsys, captures, tmp_path):
    out = tmp_path / "diff.md"
    out.write_text("kept")
    args = ["diff", str(captures["fast"]), str(captures["slow"]), "--isolated", "--format", "markdown", "-o", str(out)]
    assert main(args) == 2
    assert out.read_text() == "kept" and "already exists" in capsys.readouterr().err
    assert main([*args, "--force"]) == 0
    assert out.read_text().startswith("### rs30x-sniff diff")


def test_both_inputs_from_stdin_is_a_usage_error(capsys):
    assert main(["diff", "-", "-", "--isolated"]) == 2
    assert "at most one of them" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["latency_p95", "servo_latency_p95"])
def test_a_servos_own_latency_is_a_figure_of_its_row(capsys, captures, name):
    """latency_p95 of each servo's replies, held to a threshold per servo (silent-servo's ID 3 never answers: no
    latency of its own, so its row is not checked, never passed); the old name servo_latency_p95 holds the servos
    only, with a note."""
    code = main(["diff", str(captures["fast"]), str(captures["slow"]), "--threshold", f"{name}=+20%",
                 "--fail-on-regress", "--format", "json"])
    out, err = capsys.readouterr()
    report = json.loads(out)
    assert code == 1
    crossed = {r["servo"] for r in report["regressions"]}
    answering = {sid for sid, rows in report["servos"].items()
                 if any(r["figure"] == "latency_p95" and r["before"] is not None for r in rows)}
    assert crossed - {None} == answering and len(answering) >= 2
    assert (None in crossed) == (name == "latency_p95")
    unchecked = {u["servo"] for u in report["unchecked"] if u["figure"] == "latency_p95"}
    assert unchecked == set(report["servos"]) - answering
    notes = [line for line in err.splitlines() if "servo_latency_p95" in line]
    assert len(notes) == (name != "latency_p95") and all(n.startswith("rs30x-sniff: warning: ") for n in notes)
