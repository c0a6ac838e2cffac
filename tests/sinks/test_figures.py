"""The figure table (rs30x_sniff/sinks/figures.py, issue 33 s1): every figure a check names is a threshold's too, read
the same way, in the same unit and scope; the old [regress] names give the same result with one note; docs/checks.md
holds the table."""

from __future__ import annotations

from pathlib import Path

import pytest

from rs30x_sniff import language
from rs30x_sniff.cli import main
from rs30x_sniff.commands.simulate import write_file
from rs30x_sniff.compare import ThresholdError, bus_values, compare, parse_threshold, parse_thresholds, servo_values
from rs30x_sniff.expect import FIGURES as CHECK_FIGURES
from rs30x_sniff.expect import NOT_CHECKABLE, PASS, evaluate, load_checks
from rs30x_sniff.sim import scenarios
from rs30x_sniff.sinks.figures import (BUS, CHANGE, FIGURES, NEITHER, OLD_THRESHOLD_NAMES, REGISTERS, SERVO, TABLE,
                                       doc_table, range_name, register_unit)

from ..test_expect import info_figures

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def hexapod(tmp_path_factory) -> tuple[dict, list[str] | None]:
    """The hexapod's figures, as info computes them (linted: every figure can be given)."""
    path = tmp_path_factory.mktemp("figures") / "h.thex"
    write_file(str(path), scenarios.run("hexapod"), "timestamped", 115200)
    info, rules = info_figures(path)
    return {**info, "linted": True, "unsolicited_counted": rules is not None and "B003" in rules}, rules


def _check_value(info: dict, rules, name: str, sid: int | None) -> float | None:
    """``name`` of servo ``sid`` (None: the bus) as a figure check measures it (None: not checkable)."""
    entry = {"code": "U101", "name": "x", "check": f"{name} > -1e300"}
    if sid is not None:
        entry["for"] = f"id:{sid}"
    (r,) = evaluate(load_checks([entry], "t.toml"), info, rules)
    if r.status == NOT_CHECKABLE:
        return None
    assert r.status == PASS
    return r.message.params[name].value


def test_every_check_figure_is_a_threshold_figure_with_the_same_unit_and_scope():
    checkable = [f for f in TABLE if f.checkable]
    assert len(checkable) >= 38
    for fig in checkable:
        sign = "+" if fig.worse == NEITHER else ""
        t = parse_threshold(fig.name, f"{sign}0", "t.toml")
        assert t.figure == fig.name and t.scopes == ()  # the figure itself, at every scope it has
        assert fig.read is not None and CHANGE not in fig.scopes
        if fig.needs != "a range":
            assert CHECK_FIGURES[fig.name] is fig
    # A figure only a comparison gives is no check's.
    for fig in TABLE:
        if not fig.checkable:
            assert fig.scopes == (CHANGE,) and fig.name not in CHECK_FIGURES


def test_a_check_and_a_threshold_read_every_figure_alike(hexapod):
    """The same capture: each figure's value is the same number in a check and in diff's rows, bus and servos."""
    info, rules = hexapod
    bus, servos = bus_values(info), servo_values(info)
    seen = 0
    for fig in TABLE:
        if not fig.checkable:
            continue
        if BUS in fig.scopes:
            assert _check_value(info, rules, fig.name, None) == bus[fig.name].value, fig.name
            assert bus[fig.name].unit == (fig.unit or "count")
            seen += bus[fig.name].value is not None
        if SERVO in fig.scopes:
            for sid in ("1", "4"):
                assert _check_value(info, rules, fig.name, int(sid)) == servos[sid][fig.name].value, (fig.name, sid)
    assert seen >= 30  # most figures are measured on a linted, timed capture: the comparison is not vacuous


def test_the_latency_is_ms_and_the_bus_load_percent_in_both(hexapod):
    info, _ = hexapod
    bus = bus_values(info)
    assert bus["latency_p95"].value == pytest.approx(info["latency_s"]["p95"] * 1e3)
    assert bus["bus_load"].value == pytest.approx(info["bus_load"] * 100)
    t = parse_threshold("latency_p95", "+200us", "t")
    assert t.amount == pytest.approx(0.2)  # ms, the figure's unit


@pytest.mark.parametrize("old", sorted(OLD_THRESHOLD_NAMES))
def test_an_old_threshold_name_gives_the_same_result_with_one_note(old):
    new, scope = OLD_THRESHOLD_NAMES[old]
    before = _figures(latency=0.0001, missing=0, temp=40.0)
    after = _figures(latency=0.0002, missing=3, temp=50.0)
    language.deprecation_notes.clear()
    got = compare(before, after, parse_thresholds({old: "+0"}, "t.toml"))
    assert len(language.deprecation_notes) == 1 and old in language.deprecation_notes[0]
    assert new in language.deprecation_notes[0]
    language.deprecation_notes.clear()
    want = compare(before, after, parse_thresholds({new: "+0"}, "t.toml"))
    assert not language.deprecation_notes
    rows = [(c.change.figure, c.change.servo, c.change.before.value, c.change.after.value) for c in got.crossings]
    assert rows, old  # each old name watches something this pair moves
    # The same crossings as the new name's at the one scope the old name held.
    assert rows == [(c.change.figure, c.change.servo, c.change.before.value, c.change.after.value)
                    for c in want.crossings if (c.change.servo is None) == (scope == BUS)]


@pytest.mark.parametrize("old", sorted(OLD_THRESHOLD_NAMES))
def test_the_note_says_the_new_spelling_that_holds_the_same(old):
    """The spelling the note gives, { limit, for }, gives the old name's crossings exactly."""
    new, scope = OLD_THRESHOLD_NAMES[old]
    before = _figures(latency=0.0001, missing=0, temp=40.0)
    after = _figures(latency=0.0002, missing=3, temp=50.0)
    crossings = [compare(before, after, parse_thresholds(table, "t.toml")).crossings
                 for table in ({old: "+0"}, {new: {"limit": "+0", "for": "bus" if scope == BUS else "each"}})]
    assert [(c.change.servo, c.change.after.value) for c in crossings[0]] == \
        [(c.change.servo, c.change.after.value) for c in crossings[1]] != []


@pytest.mark.parametrize("value, words", [
    ({"limit": "+0", "for": "id:9-1"}, "runs backwards"), ({"limit": "+0", "for": "all"}, 'expected "bus"'),
    ({"for": "each"}, "keys: limit, for"), ({"limit": "+0", "fore": "bus"}, "keys: limit, for"),
])
def test_a_bad_scoped_threshold_is_one_line(value, words):
    with pytest.raises(ThresholdError) as e:
        parse_threshold("missing_replies", value, "t.toml")
    assert str(e.value).startswith("t.toml: regress.missing_replies") and words in str(e.value)
    with pytest.raises(ThresholdError, match="poll_hz is no figure of the whole bus"):
        parse_threshold("poll_hz", {"limit": "-10%", "for": "bus"}, "t.toml")


def test_a_threshold_for_some_servos_holds_those_alone():
    before, after = _figures(missing=0), _figures(missing=3)  # servo 1 misses replies
    some = parse_thresholds({"missing_replies": {"limit": "+0", "for": "id:2"}}, "t.toml")
    assert not compare(before, after, some).crossings
    one = parse_thresholds({"missing_replies": {"limit": "+0", "for": "id:1-2"}}, "t.toml")
    assert [c.change.servo for c in compare(before, after, one).crossings] == ["1"]


def test_a_bus_load_fraction_reads_as_its_percentage_points_with_a_note():
    before, after = _figures(load=0.20), _figures(load=0.26)
    language.deprecation_notes.clear()
    old = compare(before, after, parse_thresholds({"bus_load": "+0.05"}, "t.toml"))
    assert len(language.deprecation_notes) == 1 and "percentage points" in language.deprecation_notes[0]
    language.deprecation_notes.clear()
    new = compare(before, after, parse_thresholds({"bus_load": "+5"}, "t.toml"))
    assert not language.deprecation_notes
    assert [c.describe() for c in old.crossings] == [c.describe() for c in new.crossings]
    assert len(new.crossings) == 1 and "20.0 % -> 26.0 %" in new.crossings[0].describe()
    assert not compare(before, after, parse_thresholds({"bus_load": "+10"}, "t.toml")).crossings


def test_the_command_prints_an_old_names_note_once(capsys, tmp_path):
    cap = tmp_path / "h.thex"
    write_file(str(cap), scenarios.run("hexapod", duration=1.0), "timestamped", 115200)
    conf = tmp_path / "rs30x-sniff.toml"
    conf.write_text('[regress]\nmissing_replies_total = "+0"\ngoal_position_max = "+5"\n')
    assert main(["diff", str(cap), str(cap), "--config", str(conf), "--fail-on-regress"]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if "will be refused in the next release" in line]
    assert len(notes) == 2 and all(n.startswith("rs30x-sniff: warning: ") for n in notes), err
    assert 'missing_replies_total is now missing_replies = { limit = ..., for = "bus" }' in notes[0]
    assert 'goal_position_max is now "max(goal_position)" = { limit = ..., for = "each" }' in notes[1]
    # lint reads the same file: the same notes, once each.
    main(["lint", str(cap), "--config", str(conf), "--fail-on", "never", "--format", "json"])
    err = capsys.readouterr().err
    assert sum("will be refused" in line for line in err.splitlines()) == 2, err


def test_docs_checks_md_holds_the_table():
    doc = (ROOT / "docs" / "checks.md").read_text()
    assert doc_table() in doc, "docs/checks.md: regenerate its table with python -m rs30x_sniff.sinks.figures"


def test_range_figures_are_written_as_checks_write_them():
    assert range_name("max", "present_temperature") in FIGURES
    t = parse_threshold("max(present_temperature)", "+5 degC", "t")
    assert (t.figure, t.amount) == ("max(present_temperature)", 5.0)


# ---- hand-made figure dicts ------------------------------------------------------------------------------------
def _figures(*, latency: float = 0.0001, missing: int = 0, temp: float = 40.0, load: float = 0.2) -> dict:
    """A capture's figures in the shape ``info --format json`` gives them (two servos; servo 1 misses replies)."""
    servos = (1, 2)
    lat = {"count": 10, "p50": latency, "p95": latency, "max": latency, "unmeasured": 0}
    return {
        "timed": True, "duration_s": 2.0, "bytes": 100, "baud": 115200, "timing_unsupported": None,
        "bus_load": load, "bus_load_peak": {"load": load + 0.05}, "bad_checksums": 0, "garbage_bytes": 0,
        "packets": 40, "segments": 1, "latency_s": lat,
        "servos": {str(s): {"requests": 10, "reads": 10, "long_writes": 0, "returns": 10 - missing, "acks": 0,
                            "nacks": 0, "missing": missing if s == 1 else 0, "poll_rate_hz": 50.0,
                            "latency_s": lat} for s in servos},
        "findings": {"error": 0, "warning": missing, "info": 0},
        "findings_by_rule": {"B003 unsolicited-return": missing} if missing else {},
        "health": {str(s): {"model": "RS303MR", "flags": {},
                            "findings": {"B003": missing} if s == 1 and missing else {},
                            "registers": {r: {"min": temp - 10, "max": temp, "unit": register_unit(r), "count": 5}
                                          for r in REGISTERS}}
                   for s in servos},
    }
