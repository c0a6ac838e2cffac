"""`rs30x-sniff lint` and `rules` end to end: formats, selection, severities, exit codes, config, -j."""

from __future__ import annotations

import io
import json
import re
import xml.etree.ElementTree as ET

import jsonschema
import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.commands.lint import want_progress
from rs30x_sniff.commands.rules import markdown
from rs30x_sniff.lint import RULES

from .helpers import CAPTURES, ROOT

EXAMPLES = str(CAPTURES / "manual-examples.hex")
M001 = str(CAPTURES / "lint" / "M001-write-read-only.hex")
B006 = str(CAPTURES / "lint" / "B006-return-latency.thex")


@pytest.fixture(autouse=True)
def _no_config(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no pyproject.toml / rs30x-sniff.toml above unless a test writes one


def run(capsys, *argv):
    code = main(["lint", *argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_text_report(capsys):
    code, out, err = run(capsys, EXAMPLES)
    assert code == 1 and err == ""
    assert f"{EXAMPLES}:15:1 P009 combined-flash-reboot: flash write and reboot in one packet" in out
    assert "    FA AF 01 60 07 01 01 12 74" in out
    assert "7 findings (3 errors, 4 warnings) in 1 file." in out
    assert "Skipped (no timestamps in" in out and "B001, B006, Q003" in out.replace("F004, ", "")
    assert "     2  Q004  goal-while-torque-off" in out


def test_text_with_timestamps_has_times_and_no_skips(capsys):
    code, out, _ = run(capsys, B006)
    assert code == 0  # B006 is a warning; --fail-on error
    assert f"{B006}:6:10 (t=0.020600) B006 return-latency: reply 9.906 ms after the request" in out
    assert "Skipped" not in out


def test_fail_on_and_exit_codes(capsys):
    assert run(capsys, B006, "--fail-on", "warning")[0] == 1
    assert run(capsys, B006, "--fail-on", "never")[0] == 0
    assert run(capsys, EXAMPLES, "--fail-on", "never")[0] == 0
    assert run(capsys, EXAMPLES, "--severity", "B002=info", "--severity", "P=warning")[0] == 0
    assert run(capsys, EXAMPLES, "--severity", "B002=info", "--severity", "P=warning", "--fail-on", "warning")[0] == 1


def test_select_ignore(capsys):
    code, out, _ = run(capsys, EXAMPLES, "--select", "P", "--format", "json")
    assert {f["code"] for f in json.loads(out)} == {"P008", "P009"}
    code, out, _ = run(capsys, EXAMPLES, "--select", "Q,write-reserved", "--ignore", "Q002", "--format", "json")
    assert sorted(f["code"] for f in json.loads(out)) == ["M002", "Q004", "Q004"]
    assert code == 0  # only warnings left
    code, out, _ = run(capsys, EXAMPLES, "--ignore", "ALL")
    assert code == 0 and "0 findings" in out


@pytest.mark.parametrize("argv, needle", [
    (["--select", "X123"], "select: unknown rule 'X123'"),
    (["--ignore", "no-such-rule"], "ignore: unknown rule 'no-such-rule'"),
    (["--severity", "F001=fatal"], "level must be one of"),
    (["--severity", "F001"], "expected RULE=LEVEL"),
    (["-j", "0"], "-j 0"),
])
def test_usage_errors_are_one_line_exit_2(capsys, argv, needle):
    code, out, err = run(capsys, EXAMPLES, *argv)
    assert code == 2 and needle in err and err.count("\n") == 1 and "Traceback" not in err


def test_missing_file_is_exit_2_but_other_files_reported(capsys, tmp_path):
    code, out, err = run(capsys, EXAMPLES, str(tmp_path / "nope.hex"))
    assert code == 2
    assert "nope.hex: no such file" in err and err.count("\n") == 1
    assert "P009" in out  # the readable file is still reported


def test_json_format(capsys):
    code, out, _ = run(capsys, EXAMPLES, "--format", "json")
    data = json.loads(out)
    assert len(data) == 7
    assert set(data[0]) == {"file", "offset", "t", "code", "name", "severity", "message", "id"}
    assert data[0] == {"file": EXAMPLES, "offset": 34, "t": None, "code": "B002", "name": "missing-return",
                       "severity": "error", "message": data[0]["message"], "id": 1}


def test_junit_format(capsys):
    code, out, _ = run(capsys, EXAMPLES, B006, "--format", "junit")
    root = ET.fromstring(out)
    suites = root.findall("testsuite")
    assert [s.get("name") for s in suites] == [EXAMPLES, B006]
    cases = {c.get("name"): c for c in suites[0].findall("testcase")}
    assert len(cases) == len(RULES)
    assert cases["P009 combined-flash-reboot"].find("failure") is not None
    assert cases["Q004 goal-while-torque-off"].find("failure") is None  # a warning, below --fail-on error
    assert "Q004" in cases["Q004 goal-while-torque-off"].find("system-out").text
    assert cases["B006 return-latency"].find("skipped") is not None
    assert suites[0].get("failures") == "3"
    b006 = {c.get("name"): c for c in suites[1].findall("testcase")}["B006 return-latency"]
    assert b006.find("skipped") is None and b006.find("failure") is None


# The parts of the SARIF 2.1.0 schema that code scanning relies on.
SARIF_SUBSET = {
    "type": "object",
    "required": ["version", "runs"],
    "properties": {
        "version": {"const": "2.1.0"},
        "$schema": {"type": "string"},
        "runs": {"type": "array", "minItems": 1, "items": {
            "type": "object", "required": ["tool", "results"],
            "properties": {
                "tool": {"type": "object", "required": ["driver"], "properties": {"driver": {
                    "type": "object", "required": ["name", "rules"],
                    "properties": {"name": {"type": "string"}, "rules": {"type": "array", "items": {
                        "type": "object", "required": ["id", "shortDescription"],
                        "properties": {"id": {"type": "string"},
                                       "shortDescription": {"type": "object", "required": ["text"]},
                                       "defaultConfiguration": {"type": "object", "properties": {
                                           "level": {"enum": ["none", "note", "warning", "error"]}}}}}}}}}},
                "results": {"type": "array", "items": {
                    "type": "object", "required": ["ruleId", "message", "locations"],
                    "properties": {
                        "level": {"enum": ["none", "note", "warning", "error"]},
                        "message": {"type": "object", "required": ["text"]},
                        "ruleIndex": {"type": "integer", "minimum": 0},
                        "locations": {"type": "array", "items": {"type": "object", "properties": {
                            "physicalLocation": {"type": "object", "required": ["artifactLocation"], "properties": {
                                "artifactLocation": {"type": "object", "required": ["uri"]},
                                "region": {"type": "object", "properties": {
                                    "startLine": {"type": "integer", "minimum": 1},
                                    "startColumn": {"type": "integer", "minimum": 1},
                                    "byteOffset": {"type": "integer", "minimum": 0},
                                    "byteLength": {"type": "integer", "minimum": 0}}}}}}}}}}},
            }}},
    },
}


def test_sarif_format(capsys):
    code, out, _ = run(capsys, EXAMPLES, "--format", "sarif")
    log = json.loads(out)
    jsonschema.validate(log, SARIF_SUBSET)
    run0 = log["runs"][0]
    rules = run0["tool"]["driver"]["rules"]
    assert [r["id"] for r in rules] == RULES.codes()
    res = run0["results"]
    assert len(res) == 7
    p9 = next(r for r in res if r["ruleId"] == "P009")
    assert rules[p9["ruleIndex"]]["id"] == "P009" and p9["level"] == "error"
    # A text capture's region is its line and column; the stream offset is no position in the file.
    assert p9["locations"][0]["physicalLocation"]["region"] == {"startLine": 15, "startColumn": 1}
    assert p9["properties"]["streamOffset"] == 86
    assert next(r for r in res if r["ruleId"] == "Q004")["level"] == "warning"


def test_github_format(capsys):
    code, out, _ = run(capsys, EXAMPLES, "--format", "github")
    lines = out.splitlines()
    assert len(lines) == 7
    assert lines[0].startswith(f"::error file={EXAMPLES},line=10,col=1,title=B002 missing-return::ID 1 did not answer")
    assert any(line.startswith("::warning ") and "Q004" in line for line in lines)


def test_output_file(capsys, tmp_path):
    out = tmp_path / "report.json"
    assert main(["lint", EXAMPLES, "--format", "json", "-o", str(out)]) == 1
    assert len(json.loads(out.read_text())) == 7


def test_parallel_jobs_same_report(capsys):
    files = [EXAMPLES, M001, B006, str(CAPTURES / "lint" / "Q003-reboot-too-soon-after-flash.thex")]
    serial = run(capsys, *files, "--format", "json")
    parallel = run(capsys, *files, "--format", "json", "-j", "2")
    assert serial[0] == parallel[0] == 1
    assert json.loads(serial[1]) == json.loads(parallel[1])
    assert {f["file"] for f in json.loads(parallel[1])} == set(files) - {B006} | {B006}


def test_config_file_pyproject(capsys, tmp_path):
    (tmp_path / "pyproject.toml").write_text(
        '[project]\nname = "robot"\n\n[tool.rs30x-sniff]\nignore = ["Q"]\nfail-on = "warning"\n'
        'severity = { M002 = "error" }\nformat = "json"\n')
    code, out, _ = run(capsys, EXAMPLES)
    data = json.loads(out)
    assert not any(f["code"].startswith("Q") for f in data)
    assert next(f for f in data if f["code"] == "M002")["severity"] == "error"
    # The command line goes on top: --select replaces, --ignore adds, --format and --fail-on replace.
    code, out, _ = run(capsys, EXAMPLES, "--select", "M002", "--fail-on", "never", "--format", "text")
    assert code == 0 and "M002" in out and "P009" not in out


def test_config_found_upwards_and_own_file_wins(capsys, tmp_path, monkeypatch):
    (tmp_path / "pyproject.toml").write_text('[tool.rs30x-sniff]\nselect = ["P009"]\n')
    sub = tmp_path / "a" / "b"
    sub.mkdir(parents=True)
    monkeypatch.chdir(sub)
    code, out, _ = run(capsys, EXAMPLES, "--format", "json")
    assert {f["code"] for f in json.loads(out)} == {"P009"}
    (sub / "rs30x-sniff.toml").write_text('select = ["M002"]\nreply_timeout = 0.02\n')
    code, out, _ = run(capsys, EXAMPLES, "--format", "json")
    assert {f["code"] for f in json.loads(out)} == {"M002"}
    code, out, _ = run(capsys, EXAMPLES, "--format", "json", "--isolated")
    assert len(json.loads(out)) == 7


@pytest.mark.parametrize("body, needle", [
    ('[tool.rs30x-sniff]\nslect = ["F"]\n', "[tool.rs30x-sniff]: unknown key 'slect'"),
    ('[tool.rs30x-sniff]\nselect = ["F999"]\n', "select: unknown rule 'F999'"),
    ('[tool.rs30x-sniff]\nseverity = { P009 = "loud" }\n', "severity.P009: level must be one of"),
    ('[tool.rs30x-sniff]\nreply-timeout = "fast"\n', "reply-timeout = 'fast': expected a duration such as 50ms"),
    ('[tool.rs30x-sniff]\nmodels = { 3 = "RS999" }\n', "unknown model 'RS999'"),
    ('[tool.rs30x-sniff\n', "not valid TOML"),
])
def test_config_errors_name_file_and_key(capsys, tmp_path, body, needle):
    (tmp_path / "pyproject.toml").write_text(body)
    code, out, err = run(capsys, EXAMPLES)
    assert code == 2 and needle in err and "pyproject.toml" in err and err.count("\n") == 1


def test_explicit_config_and_models(capsys, tmp_path):
    cfg = tmp_path / "robot.toml"
    cfg.write_text('select = ["Q007"]\nmodels = { 1 = "RS304MD" }\n')
    # 90 deg in 0.2 s: fine for an RS303MR (it needs 0.165 s) but too fast for the RS304MD (0.24 s).
    text = "FA AF 01 00 1E 04 01 00 00 64 00 7E\nFA AF 01 00 1E 04 01 84 03 14 00 89\n"
    cap = tmp_path / "c.hex"
    cap.write_text(text)
    code, out, _ = run(capsys, str(cap), "--config", str(cfg), "--format", "json")
    assert [f["code"] for f in json.loads(out)] == ["Q007"]
    code, out, _ = run(capsys, str(cap), "--config", str(cfg), "--format", "json", "--model", "1=RS303MR")
    assert json.loads(out) == []
    code, out, err = run(capsys, str(cap), "--config", str(tmp_path / "missing.toml"))
    assert code == 2 and "no such config file" in err


def test_progress_only_on_a_terminal_outside_ci():
    class Tty(io.StringIO):
        def isatty(self):
            return True
    assert want_progress(Tty(), {}) is True
    assert want_progress(Tty(), {"CI": "true"}) is False
    assert want_progress(io.StringIO(), {}) is False


def test_rules_command(capsys):
    assert main(["rules"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == len(RULES) and out[0].startswith("F001  checksum-mismatch")
    assert main(["rules", "combined-flash-reboot"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("P009 combined-flash-reboot (error")
    assert "What it does:" in text and "Why it matters:" in text and "FA AF 01 60 07 01 01 12 74" in text
    assert main(["rules", "--format", "json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [d["code"] for d in data] == RULES.codes()
    assert {"code", "name", "severity", "summary"} <= set(data[0])
    assert main(["rules", "f001", "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["name"] == "checksum-mismatch"
    assert main(["rules", "Z999"]) == 2
    assert "unknown rule" in capsys.readouterr().err


def test_docs_rules_md_is_up_to_date():
    assert (ROOT / "docs" / "rules.md").read_text() == markdown(), \
        "regenerate: rs30x-sniff rules --format markdown -o docs/rules.md"


_WORDS = {"one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7, "eight": 8, "nine": 9}


def test_docs_count_the_rules_and_families_of_the_registry():
    # Every "N rules" in the README and docs, and the families named beside it, are the registry's.
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    counts = [(d.name, int(n)) for d in docs for n in re.findall(r"\b(\d+) (?:lint )?rules\b", d.read_text())]
    assert counts, "the README no longer says how many rules there are: drop this test or the figure"
    assert all(n == len(RULES) for _, n in counts), (counts, len(RULES))
    readme = (ROOT / "README.md").read_text()
    m = re.search(r"(\w+) families \(([^)]*)\)", readme)
    assert m, "the README's list of rule families moved"
    letters = re.findall(r"`([A-Z])`", m.group(2))
    assert sorted(letters) == sorted({r.code[0] for r in RULES})
    assert _WORDS.get(m.group(1), m.group(1)) == len(letters)


def test_decode_shows_findings(capsys):
    assert main(["decode", EXAMPLES]) == 0
    out = capsys.readouterr().out.splitlines()
    assert any(line.startswith("           - @86 ") and line.endswith("[P008 command-packet-format, P009 combined-flash-reboot]") for line in out)
    assert out[-1].startswith("           - @59       lint  Q002 id-change-not-persisted")
    assert main(["decode", EXAMPLES, "--format", "jsonl", "--select", "P009"]) == 0
    objs = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    flagged = [o for o in objs if o["diagnostics"]]
    assert [(o["offset"], [d["code"] for d in o["diagnostics"]]) for o in flagged] == [(86, ["P009"])]
    assert main(["decode", EXAMPLES, "--no-lint"]) == 0
    assert "[" not in "".join(line.split("read[")[0] for line in capsys.readouterr().out.splitlines())
