"""User rules ([[rule]] in the configuration, rs30x_sniff.user_rules): checked as the file loads, and run
like the built-in rules everywhere: `rules`, selection, every report format, the MCAP diagnostics, and
the same findings on the record path as on the columnar path."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from mcap.reader import make_reader

from rs30x_sniff.cli import main
from rs30x_sniff.commands.rules import markdown
from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.filters import parse_filter
from rs30x_sniff.lint import LintConfig, Linter, batch
from rs30x_sniff.lint import config as config_module
from rs30x_sniff.lint.config import ConfigError
from rs30x_sniff.lint.registry import RULES, Rule
from rs30x_sniff.settings import load_config, resolve
from rs30x_sniff.sim import run as simulate
from rs30x_sniff.user_rules import compile_rules, fill

from .test_batch import capture, compare

HOT = {"code": "U001", "name": "servo-too-hot", "severity": "error", "when": "present_temperature>60",
       "message": "ID {id} at {present_temperature}", "doc": "Our rig's servos must stay below 60 degC."}


@pytest.fixture(autouse=True)
def _clean(tmp_path, monkeypatch):
    """Each test in its own folder (no config above); no user rule ever reaches the process-wide registry."""
    monkeypatch.chdir(tmp_path)
    yield
    assert not RULES.user()


def toml(tables: list[dict], **top) -> str:
    def v(x):
        return json.dumps(x) if not isinstance(x, list) else "[" + ", ".join(map(json.dumps, x)) + "]"
    lines = [f"{k.replace('_', '-')} = {v(x)}" for k, x in top.items()]
    for t in tables:
        lines += ["", "[[rule]]"] + [f"{k} = {v(x)}" for k, x in t.items()]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def overheat(tmp_path_factory):
    path = tmp_path_factory.mktemp("overheat") / "x.thex"
    assert main(["simulate", "--scenario", "overheat", "-o", str(path)]) == 0
    return str(path)


def lint(capsys, *argv):
    code = main(["lint", *argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


# ---- loading: one line naming the file, the rule and the key ---------------------------------------
@pytest.mark.parametrize("change, needle", [
    ({"code": "U01"}, "rule #1 (U01): code: 'U01' is not a user rule code"),
    ({"code": "F001"}, "rule #1 (F001): code: 'F001' is not a user rule code (U and three digits, such as U001; "
                       "F is the built-in family 'Framing')"),
    ({"code": "Q123"}, "Q is the built-in family 'Sequences'"),
    ({"name": "Too_Hot"}, "rule #1 (U001): name: 'Too_Hot' is not kebab-case"),
    ({"name": "checksum-mismatch"}, "name: 'checksum-mismatch' is the built-in rule"),
    ({"name": "u002"}, "name: 'u002' reads as a rule code"),
    ({"severity": "fatal"}, "rule #1 (U001): severity: 'fatal': must be one of info, warning, error"),
    ({"when": "present_temperatur>60"}, "rule #1 (U001): when: present_temperatur>60: no register or filter key"),
    ({"when": "kind:servo"}, "rule #1 (U001): when: kind:servo: unknown kind"),
    ({"when": "sev:error"}, "rule #1 (U001): when: sev: tests the findings of other rules"),
    ({"when": None}, "rule #1 (U001): when: missing"),
    ({"message": "{temp}"}, "rule #1 (U001): message: {temp} is not a field a record carries"),
    ({"message": "{id.__class__}"}, "message: {id.__class__}: fields are named"),
    ({"message": "{0}"}, "message: {0}: fields are named"),
    ({"message": "{}"}, "message: {}: fields are named"),
    ({"message": "{id"}, "rule #1 (U001): message: "),
    ({"colour": "red"}, "rule #1 (U001): colour: unknown key"),
])
def test_a_bad_rule_is_one_line_naming_file_rule_and_key(capsys, overheat, change, needle):
    table = {k: v for k, v in {**HOT, **change}.items() if v is not None}
    open("rs30x-sniff.toml", "w").write(toml([table]))
    code, out, err = lint(capsys, overheat)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "rs30x-sniff.toml: rule #1" in err and needle in err, err


def test_a_duplicate_code_or_name_names_both_rules(tmp_path):
    path = tmp_path / "rs30x-sniff.toml"
    path.write_text(toml([HOT, {**HOT, "name": "other"}]))
    with pytest.raises(ConfigError, match=r"rule #2 \(U001\): code: 'U001' is already rule #1's"):
        load_config(path)
    path.write_text(toml([HOT, {**HOT, "code": "U002"}]))
    with pytest.raises(ConfigError, match=r"rule #2 \(U002\): name: 'servo-too-hot' is already rule #1's"):
        load_config(path)


def test_pyproject_table_and_selection_by_the_files_own_rules(capsys, overheat, tmp_path):
    body = toml([HOT], select=["U001"]).replace("[[rule]]", "[[tool.rs30x-sniff.rule]]")
    (tmp_path / "pyproject.toml").write_text("[tool.rs30x-sniff]\n" + body)
    code, out, _ = lint(capsys, overheat, "--format", "json")
    found = json.loads(out)
    assert code == 1 and found and {f["code"] for f in found} == {"U001"}
    # Neither the command nor loading the config leaves its rules in the registry: they are the run's.
    assert "U001" not in RULES
    conf = load_config(tmp_path / "pyproject.toml")
    assert "U001" not in RULES and [r.code for r in conf["rule"]] == ["U001"]


def test_a_selection_of_an_unknown_user_rule_is_an_error(capsys, overheat):
    open("rs30x-sniff.toml", "w").write(toml([HOT]))
    code, _, err = lint(capsys, overheat, "--select", "U002")
    assert code == 2 and "unknown rule 'U002'" in err and err.count("\n") == 1
    code, _, err = lint(capsys, overheat, "--isolated", "--select", "U001")
    assert code == 2 and "unknown rule 'U001'" in err


# ---- the acceptance: the overheat scenario, every output --------------------------------------------
@pytest.fixture
def hot_config():
    open("rs30x-sniff.toml", "w").write(toml([{**HOT, "message": "ID {id} at {present_temperature} degC"}]))


def test_overheat_fires_for_servo_2_only_in_every_format(capsys, overheat, hot_config):
    code, out, _ = lint(capsys, overheat, "--format", "json", "--select", "U001")
    found = json.loads(out)
    assert code == 1 and found and {(f["code"], f["id"], f["severity"]) for f in found} == {("U001", 2, "error")}
    assert all(f["name"] == "servo-too-hot" and int(f["message"].split()[3]) > 60 for f in found)
    n = len(found)

    code, out, _ = lint(capsys, overheat, "--select", "U001")
    lines = [x for x in out.splitlines() if " U001 servo-too-hot: " in x]
    assert code == 1 and len(lines) == n and all(": ID 2 at " in x for x in lines)
    assert f"{n:>6}  U001  servo-too-hot  error" in out

    code, out, _ = lint(capsys, overheat, "--format", "junit", "--select", "servo-too-hot")
    case = ET.fromstring(out).find(".//testcase[@name='U001 servo-too-hot']")
    assert code == 1 and case is not None and case.find("failure").get("message").startswith(f"{n} finding(s): ID 2")

    code, out, _ = lint(capsys, overheat, "--format", "sarif")
    run = json.loads(out)["runs"][0]
    rules = run["tool"]["driver"]["rules"]
    mine = [r for r in rules if r["id"] == "U001"]
    assert mine and mine[0]["name"] == "servo-too-hot" and mine[0]["defaultConfiguration"]["level"] == "error"
    assert "present_temperature>60" in mine[0]["fullDescription"]["text"]
    assert mine[0]["help"]["text"] == HOT["doc"]
    hits = [r for r in run["results"] if r["ruleId"] == "U001"]
    assert len(hits) == n and all(rules[r["ruleIndex"]]["id"] == "U001" and r["properties"]["servoId"] == 2
                                  for r in hits)

    code, out, _ = lint(capsys, overheat, "--format", "github", "--select", "U")
    lines = out.splitlines()
    assert code == 1 and len(lines) == n and all(x.startswith("::error ") and "title=U001 servo-too-hot::ID 2 at "
                                                 in x for x in lines)

    # --ignore and --severity take the user rule by code and by name, like any rule.
    code, out, _ = lint(capsys, overheat, "--format", "json", "--ignore", "servo-too-hot")
    assert "U001" not in out
    code, out, _ = lint(capsys, overheat, "--format", "json", "--select", "U001", "--severity", "U001=info")
    assert code == 0 and {f["severity"] for f in json.loads(out)} == {"info"}


def test_overheat_on_the_mcap_diagnostics_channel(capsys, overheat, hot_config, tmp_path):
    out = tmp_path / "x.mcap"
    assert main(["convert", overheat, "-o", str(out), "--select", "U001"]) == 0
    with open(out, "rb") as f:
        logs = [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=["/rs30x/diagnostics"])]
    assert logs and {x["name"] for x in logs} == {"U001 servo-too-hot"}
    assert all(x["message"].startswith("id 2: ID 2 at ") and x["level"] == 4 for x in logs)


def test_the_default_message_names_the_registers_of_when(capsys, overheat):
    open("rs30x-sniff.toml", "w").write(toml([{k: v for k, v in HOT.items() if k != "message"}]))
    code, out, _ = lint(capsys, overheat, "--format", "json", "--select", "U001")
    msg = json.loads(out)[0]["message"]
    assert msg.startswith("present_temperature ") and msg.endswith("degC (when: present_temperature>60)")


# ---- rules ------------------------------------------------------------------------------------------
def test_rules_lists_and_explains_them_but_the_docs_do_not(capsys, hot_config):
    assert main(["rules"]) == 0
    assert "U001  servo-too-hot" in capsys.readouterr().out.splitlines()[-1]
    assert main(["rules", "U001"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("U001 servo-too-hot (error, user rules)\n") and HOT["doc"] in out
    assert "present_temperature>60" in out and "rs30x-sniff.toml: rule #1" in out
    assert main(["rules", "servo-too-hot", "--format", "json"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["code"] == "U001" and obj["user"] is True and obj["family"] == "User rules"
    assert main(["rules", "--format", "markdown"]) == 0
    md = capsys.readouterr().out
    assert "U001" not in md and "servo-too-hot" not in md and md == markdown()
    assert main(["rules", "--isolated"]) == 0
    assert "U001" not in capsys.readouterr().out


# ---- the registry's public API for them ---------------------------------------------------------------
def test_a_runs_rule_set_holds_its_user_rules_and_leaves_the_registry_alone():
    (hot,) = compile_rules([HOT], "test")
    n = len(RULES)
    rules = RULES.with_user([hot])
    assert rules["U001"] is hot and rules.get("servo-too-hot") is hot and len(rules) == n + 1
    assert rules.codes()[-1] == "U001" and rules.match("U") == ["U001"]
    assert hot not in rules.builtin() and rules.user() == [hot] and rules.builtin() == RULES.builtin()
    assert "U001" not in RULES and len(RULES) == n and RULES.with_user([]).codes() == RULES.codes()


def test_with_user_refuses_what_would_clash():
    (hot,) = compile_rules([HOT], "test")
    with pytest.raises(ValueError, match="bad user rule code"):
        RULES.with_user([Rule("F999", "x-y", "info", "s", "d", ("short",), print, column="silent")])
    clash = Rule("U002", "checksum-mismatch", "info", "s", "d", ("short",), print, column="silent")
    with pytest.raises(ValueError, match="declared twice"):
        RULES.with_user([hot, clash])
    with pytest.raises(ValueError, match="not in RULES"):
        RULES.add_user(hot)
    assert "U001" not in RULES
    rules = RULES.with_user([hot])
    rules.remove_user("F001")
    assert "F001" in rules  # never a built-in rule


def test_two_linters_with_different_user_rules_in_one_process():
    """A library caller lints two captures with different user rules: neither leaks into the other, nor
    into RULES, and neither needs restoring."""
    hot, = compile_rules([HOT], "a")
    far, = compile_rules([{"code": "U001", "name": "far-out", "when": "kind:return present_position>19.6"}], "b")
    a = Linter(LintConfig(rules=RULES.with_user([hot])))
    b = Linter(LintConfig(rules=RULES.with_user([far]), select=["U"]))
    plain = Linter()
    assert [r.code for r in b.rules] == ["U001"] and b.rules[0] is far
    assert hot in a.rules and far not in a.rules and "U001" not in {r.code for r in plain.rules}
    chunks = capture("P001", at=-1, cycles=300)
    for lint in (a, b, plain):
        dec = Decoder(None, lint, columnar=True)
        dec.feed_many(chunks)
        dec.close()
    assert {f.name for f in b.findings} == {"far-out"}  # its U001, under its own name
    assert all(f.code != "U001" for f in a.findings)  # no servo is hot in this capture
    assert "U001" not in {f.code for f in plain.findings} and not RULES.user()
    with pytest.raises(ConfigError, match="unknown rule 'U001'"):
        LintConfig(select=["U001"]).enabled_codes()


def test_fill_names_only_and_never_fails():
    assert fill("ID {id} at {t:.3f} {present_temperature!r}", {"id": 2, "t": None, "present_temperature": 61}) == \
        "ID 2 at ? 61"
    assert fill("{latency:.3f}", {"latency": "x"}) == "x"


# ---- the record path and the columnar path find the same --------------------------------------------
# The capture's positions run 10.0 to 19.8 deg (raw 100 + 2 * (cycle % 50)), goals the same.
RULE_SETS = {
    "registers": [{"code": "U001", "name": "far-out", "when": "kind:return present_position>19.6"},
                  {"code": "U002", "name": "low-three", "when": "id:3 present_position<10.4 -kind:short"},
                  {"code": "U003", "name": "long-goal", "when": "goal_position>19.5", "severity": "error",
                   "message": "{id} {goal_position} {kind}"},
                  {"code": "U004", "name": "lowest", "when": "kind:return -present_position>=10.1"}],
    "time": [{"code": "U010", "name": "late", "when": "latency>2ms"},
             {"code": "U011", "name": "window", "when": "t:1.3-1.31 kind:request"},
             {"code": "U012", "name": "read-reg", "when": "reg:max_torque kind:return"}],
    "never-in-blocks": [{"code": "U020", "name": "acks", "when": "kind:ack,garbage"}],
}


@pytest.mark.parametrize("which", sorted(RULE_SETS))
@pytest.mark.parametrize("anomaly", ["P001", "B006", "Q007"])
def test_record_and_columnar_paths_find_the_same(monkeypatch, which, anomaly):
    rules = compile_rules(RULE_SETS[which], "test")
    calls = []
    real = batch.BlockLinter.quiet
    monkeypatch.setattr(batch.BlockLinter, "quiet", lambda self, blk: calls.append(real(self, blk)) or calls[-1])
    monkeypatch.setattr(config_module, "RULES", RULES.with_user(rules))  # the default LintConfig's rule set
    blocks, codes = compare(capture(anomaly, at=150, cycles=300), groups=(45,))
    assert blocks and any(calls)  # the columns still carry the quiet stretches
    if which != "never-in-blocks":
        assert {r.code for r in rules} & codes, codes  # and the rules spoke


def test_a_block_with_a_match_goes_row_by_row_and_the_others_stay_on_columns(monkeypatch):
    (rule,) = compile_rules([{"code": "U001", "name": "far-out", "when": "kind:return present_position>19.6"}], "t")
    calls = []
    real = batch.BlockLinter.quiet
    monkeypatch.setattr(batch.BlockLinter, "quiet", lambda self, blk: calls.append(real(self, blk)) or calls[-1])
    monkeypatch.setattr(config_module, "RULES", RULES.with_user([rule]))  # the default LintConfig's rule set
    _, codes = compare(capture("P001", at=-1, cycles=300), groups=(60,))
    assert codes == {"U001"} and True in calls and False in calls


# ---- the filter's column form ------------------------------------------------------------------------
FILTERS = ["present_temperature>60", "id:2", "-id:2", "id:0", "id:1-3 kind:return", "kind:long",
           "kind:write", "kind:request", "-kind:reply", "goal_position>10", "-goal_position<=0",
           "reg:present_temperature", "reg:goal_position", "latency>0.3ms", "latency=0", "t:1-2", "t>3.5",
           "torque_enable=on", "present_temperature<=40 -id:1,3", "max_torque>50",
           # earlier terms narrow the rows a register's bytes are read for (its column's ``among``)
           "kind:return present_temperature>60", "id:2 kind:short goal_position>10", "kind:long goal_position>10",
           "id:3 goal_position<0", "latency>0.3ms present_temperature>30", "-id:2 -goal_position<=0"]


@pytest.mark.parametrize("scenario", ["overheat", "hexapod"])
def test_may_match_never_misses_a_match(scenario):
    """Filter.may_match against matches, row by row, on a simulator scenario's Blocks."""
    chunks = list(simulate(scenario, duration=3.0))
    dec = Decoder(None, None, columnar=True)
    step = list(dec.feed_many(chunks)) + list(dec.close())
    blocks = [x for x in step if type(x) is Block]
    assert blocks
    for text in FILTERS:
        flt = parse_filter(text)
        hits = 0
        for blk in blocks:
            maybe = flt.may_match(blk)
            assert maybe.dtype == bool and len(maybe) == len(blk)
            got = np.array([flt.matches(blk.fresh_record(k)) for k in range(len(blk))])
            assert not (got & ~maybe).any(), (text, np.flatnonzero(got & ~maybe)[:5])
            hits += int(got.sum())
            # Exact where the columns tell everything (a long packet to servos of mixed models: may-match).
            if "-" not in text and "=" not in text.replace(">=", "").replace("<=", "") and "write" not in text \
                    and "reg:" not in text and blk.vid_models is None:
                assert (maybe == got).all(), text
        if text == "present_temperature>60":
            assert (hits > 0) == (scenario == "overheat")


def test_the_settings_carry_the_rules(tmp_path):
    path = tmp_path / "rs30x-sniff.toml"
    path.write_text(toml([HOT], select=["servo-too-hot"], severity={"U001": "warning"})
                    .replace('severity = {"U001": "warning"}', '[severity]\nU001 = "warning"'))
    conf = load_config(path)
    s = resolve(config=conf)
    assert [r.code for r in s.user_rules] == ["U001"]
    cfg = s.lint_config()
    assert cfg.enabled_codes() == ["U001"] and cfg.severities()["U001"] == "warning"
    assert cfg.rules["U001"] is s.user_rules[0] and "U001" not in RULES


def test_decode_lint_info_convert_and_the_monitor_agree_on_them(capsys, overheat, hot_config, tmp_path):
    """The user rule's findings through every command that lints (tests/sinks/test_one_pipeline.py): the
    monitor's store holds the same ones as lint's report, the MCAP's diagnostics and info's counts."""
    from pathlib import Path

    from tests.sinks.test_one_pipeline import check_agreement

    linted = check_agreement(capsys, Path(overheat), ["--select", "U001,F,B"], tmp_path)
    assert {code for code, _ in linted} == {"U001"} and sum(linted.values()) > 10
