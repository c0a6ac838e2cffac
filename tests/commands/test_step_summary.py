"""`--format github` and GITHUB_STEP_SUMMARY (issue 24): lint and diff append a Markdown summary to the file the
variable names (never replacing what earlier steps wrote), nothing for other formats or when it is unset, and a
file that cannot be written is one warning line, the command's result unchanged."""

from __future__ import annotations

import io
import json
from collections import Counter
from pathlib import Path

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.lint import Finding
from rs30x_sniff.lint.baseline import BaselineReport, Entry
from rs30x_sniff.lint.report import STEP_SUMMARY, FileResult, github_escape, md_cell, md_code, write_step_summary
from rs30x_sniff.sim import run as sim_run
from rs30x_sniff.sources.captures import TIMESTAMPED, write_capture

from ..conftest import CAPTURES
from .sim_buses import DelayedBus

MIXED = str(CAPTURES / "session-mixed.thex")
OLD = "## an earlier step\n\nits summary, kept\n"


@pytest.fixture(autouse=True)
def _clean(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no pyproject.toml / rs30x-sniff.toml above
    monkeypatch.delenv(STEP_SUMMARY, raising=False)  # not the runner's own summary, when run in a workflow


@pytest.fixture
def summary(tmp_path, monkeypatch) -> Path:
    p = tmp_path / "step-summary.md"
    p.write_text(OLD)
    monkeypatch.setenv(STEP_SUMMARY, str(p))
    return p


def cli(capsys, *argv) -> tuple[int, str, str]:
    code = main([*map(str, argv)])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def appended(p: Path) -> str:
    """What the command added after the earlier step's summary (which must be there, unchanged)."""
    text = p.read_text()
    assert text.startswith(OLD), text
    return text[len(OLD):]


def cells(row: str) -> list[str]:
    """A Markdown table row's cells, split on the pipes no backslash escapes."""
    assert row.startswith("|") and row.endswith("|"), row
    out, cur, k = [], "", 1
    while k < len(row):
        ch = row[k]
        if ch == "\\" and k + 1 < len(row):
            cur += ch + row[k + 1]
            k += 2
            continue
        if ch == "|":
            out.append(cur.strip())
            cur = ""
        else:
            cur += ch
        k += 1
    return out


def table(md: str, header: str) -> list[list[str]]:
    """The rows (as cells) of the table whose header line starts with ``header``."""
    lines = md.splitlines()
    start = next(k for k, line in enumerate(lines) if line.startswith(header))
    assert set(lines[start + 1]) <= set("|-:"), lines[start + 1]
    rows = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        rows.append(cells(line))
    return rows


def simulate(tmp_path: Path, scenario: str, seed: int) -> Path:
    out = tmp_path / f"{scenario}-{seed}.thex"
    write_capture(out, list(sim_run(scenario, seed=seed)), TIMESTAMPED)
    return out


# ---- lint -------------------------------------------------------------------------------------------
def test_lint_github_appends_findings_by_rule_matching_json(capsys, summary):
    code, out, err = cli(capsys, "lint", MIXED, "--format", "github")
    assert code == 1 and err == ""
    assert out.startswith("::")  # the annotations on stdout, as before
    md = appended(summary)
    assert md.startswith("\n### rs30x-sniff lint: 10 findings (4 errors, 6 warnings)\n")
    assert f"- {md_code(MIXED)}: " in md
    rows = table(md, "| code | rule | severity | count |")
    found = json.loads(cli(capsys, "lint", MIXED, "--format", "json", "--fail-on", "never")[1])
    assert {r[0]: int(r[3]) for r in rows} == dict(Counter(f["code"] for f in found))
    assert {r[0]: (r[1], r[2]) for r in rows} == {f["code"]: (f["name"], f["severity"]) for f in found}
    assert all(len(r) == 4 for r in rows)
    assert "**4 findings at or above --fail-on error.**" in md


def test_lint_summary_of_several_files_and_fail_on(capsys, summary, tmp_path):
    capture = simulate(tmp_path, "silent-servo", 1)
    code, _, _ = cli(capsys, "lint", MIXED, capture, "--format", "github", "--fail-on", "never")
    assert code == 0
    md = appended(summary)
    assert md.count("### rs30x-sniff lint") == 1
    assert f"- {md_code(str(capture))}: " in md and f"- {md_code(MIXED)}: " in md
    found = json.loads(cli(capsys, "lint", MIXED, capture, "--format", "json", "--fail-on", "never")[1])
    rows = table(md, "| code | rule | severity | count |")
    assert {r[0]: int(r[3]) for r in rows} == dict(Counter(f["code"] for f in found))
    assert "Nothing at or above --fail-on never." in md


def test_each_step_appends_its_own_summary(capsys, summary):
    cli(capsys, "lint", MIXED, "--format", "github")
    once = appended(summary)
    cli(capsys, "lint", MIXED, "--format", "github")
    assert appended(summary) == once + once  # appended again, the first kept


@pytest.mark.parametrize("fmt", ["text", "json", "junit", "sarif"])
def test_lint_other_formats_append_nothing(capsys, summary, fmt):
    cli(capsys, "lint", MIXED, "--format", fmt)
    assert summary.read_text() == OLD


def test_lint_without_the_variable_writes_no_summary_and_the_same_stdout(capsys, tmp_path, monkeypatch):
    code, plain, err = cli(capsys, "lint", MIXED, "--format", "github")
    assert err == "" and list(tmp_path.iterdir()) == []
    p = tmp_path / "s.md"
    monkeypatch.setenv(STEP_SUMMARY, str(p))
    assert cli(capsys, "lint", MIXED, "--format", "github") == (code, plain, "")
    assert p.read_text().startswith("### rs30x-sniff lint")  # a new file: no blank line first


def test_lint_with_a_baseline_counts_new_absorbed_and_stale(capsys, summary, tmp_path):
    base = tmp_path / "baseline.json"
    firsts = [simulate(tmp_path, s, 1) for s in ("silent-servo", "bad-checksum")]
    assert cli(capsys, "lint", *firsts, "--write-baseline", base)[0] == 0
    assert summary.read_text() == OLD  # --write-baseline reports nothing
    later = [simulate(tmp_path, s, 2) for s in ("silent-servo", "overheat")]
    code, _, err = cli(capsys, "lint", *later, "--baseline", base, "--format", "github", "--fail-on", "never")
    assert code == 0 and err == ""
    report = json.loads(cli(capsys, "lint", *later, "--baseline", base, "--format", "json", "--fail-on", "never")[1])
    md = appended(summary)
    new = Counter(f["code"] for f in report["findings"])
    absorbed = report["baseline"]["absorbed"]
    assert absorbed > 0 and new  # the test holds both kinds
    rows = table(md, "| code | rule | severity | new | absorbed |")
    assert {r[0]: int(r[3]) for r in rows if int(r[3])} == dict(new)
    assert sum(int(r[4]) for r in rows) == absorbed
    assert md.startswith(f"\n### rs30x-sniff lint: {sum(new.values())} new findings")
    assert f"Baseline {md_code(str(base))}: {sum(new.values())} new, {absorbed} absorbed" in md
    stale = report["baseline"]["stale"]
    assert stale  # bad-checksum's entries are not seen again
    srows = table(md, "| code | servo | message | count before |")
    assert [(r[0], r[1], int(r[3])) for r in srows] == [(e["code"], str(e["id"]) if e["id"] is not None else "bus",
                                                         e["count"]) for e in stale]


def test_an_unwritable_summary_is_one_warning_and_the_result_unchanged(capsys, tmp_path, monkeypatch):
    expected = cli(capsys, "lint", MIXED, "--format", "github")
    monkeypatch.setenv(STEP_SUMMARY, str(tmp_path))  # a directory: cannot be opened for appending
    code, out, err = cli(capsys, "lint", MIXED, "--format", "github")
    assert (code, out) == expected[:2]
    assert err.count("\n") == 1 and err.startswith("rs30x-sniff: warning: GITHUB_STEP_SUMMARY=")
    assert "Traceback" not in err
    monkeypatch.setenv(STEP_SUMMARY, str(tmp_path / "missing" / "s.md"))
    assert cli(capsys, "lint", MIXED, "--format", "github")[:2] == expected[:2]


# ---- Markdown escaping ------------------------------------------------------------------------------
def test_cells_escape_pipes_and_line_breaks():
    assert md_cell("a | b\nc\r\nd") == "a \\| b<br>c<br>d"
    tricky = md_cell("x\\|y")  # a backslash before a pipe: escaped too, so the pipe stays in the cell
    assert tricky == "x\\\\\\|y" and cells(f"| {tricky} | z |") == [tricky, "z"]
    assert md_code("a`b") == "`` a`b ``" and md_code("plain") == "`plain`"


def test_a_message_with_pipes_and_newlines_keeps_its_row():
    stale = [Entry("U001:x", "U001", 3, "left | right\nnext line", 2), Entry("F002:y", "F002", None, "ok", 1)]
    r = FileResult("a|b.thex", findings=[Finding("F001", "checksum-mismatch", "error", "m | n", 0, None, 1)],
                   absorbed=[], records=5)
    buf = io.StringIO()
    write_step_summary([r], buf, "error", BaselineReport("base|line.json", 0, stale))
    md = buf.getvalue()
    rows = table(md, "| code | servo | message | count before |")
    assert rows == [["U001", "3", "left \\| right<br>next line", "2"], ["F002", "bus", "ok", "1"]]
    assert table(md, "| code | rule | severity | new | absorbed |") == [
        ["F001", "checksum-mismatch", "error", "1", "0"]]


# ---- diff -------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> tuple[str, str]:
    d = tmp_path_factory.mktemp("summary-diff")
    out = []
    for name, delay in (("fast", 0), ("slow", 3)):
        p = d / f"{name}.thex"
        write_capture(p, list(sim_run("silent-servo", duration=1.5, bus=DelayedBus(115200, delay))), TIMESTAMPED)
        out.append(str(p))
    return out[0], out[1]


DIFF = ("--isolated", "--threshold", "latency_p95=+20%", "--threshold", "missing_replies=+0")


@pytest.mark.parametrize("fail", [False, True])
def test_diff_github_is_the_text_with_an_annotation_per_crossing(capsys, pair, fail):
    more = ["--fail-on-regress"] if fail else []
    text = cli(capsys, "diff", *pair, *DIFF, *more)
    doc = json.loads(cli(capsys, "diff", *pair, *DIFF, "--format", "json")[1])
    code, out, err = cli(capsys, "diff", *pair, *DIFF, "--format", "github", *more)
    assert (code, err) == (text[0], text[2]) and code == (1 if fail else 0)
    assert out.startswith(text[1])
    notes = out[len(text[1]):].splitlines()
    assert len(notes) == len(doc["regressions"]) >= 1  # the bus's latency, and each servo's that crossed
    level = "error" if fail else "warning"
    assert all("title=rs30x-sniff diff%3A latency_p95 " in n for n in notes)
    assert notes[0].startswith(f"::{level} file={github_escape(pair[1], True)},"
                               f"title=rs30x-sniff diff%3A latency_p95 regressed::")
    # The message is the crossing's text, with % encoded as a workflow command needs (%25: GitHub decodes it).
    assert notes[0].endswith("::" + doc["regressions"][0]["text"].replace("%", "%25"))


def test_diff_github_appends_the_markdown_table(capsys, pair, summary):
    markdown = cli(capsys, "diff", *pair, *DIFF, "--format", "markdown")[1]
    assert summary.read_text() == OLD  # --format markdown writes stdout only
    code, _, err = cli(capsys, "diff", *pair, *DIFF, "--format", "github", "--fail-on-regress")
    assert code == 1 and "regression: latency_p95" in err
    md = appended(summary)
    assert md == "\n" + markdown
    assert md.startswith("\n### rs30x-sniff diff: **1 threshold crossed**")
    rows = table(md, "| findings by rule | before | after | |")
    assert ["B002 missing-return", rows[0][1], rows[0][1], "same"] == rows[0]


@pytest.mark.parametrize("fmt", ["text", "json", "markdown"])
def test_diff_other_formats_append_nothing(capsys, pair, summary, fmt):
    cli(capsys, "diff", *pair, *DIFF, "--format", fmt)
    assert summary.read_text() == OLD


def test_diff_github_without_the_variable_writes_nothing(capsys, pair, tmp_path):
    code, out, err = cli(capsys, "diff", *pair, *DIFF, "--format", "github")
    assert code == 0 and "::warning" in out and err == ""
    assert list(tmp_path.iterdir()) == []


def test_diff_unwritable_summary_is_one_warning_and_the_exit_code_unchanged(capsys, pair, tmp_path, monkeypatch):
    monkeypatch.setenv(STEP_SUMMARY, str(tmp_path))
    code, out, err = cli(capsys, "diff", *pair, *DIFF, "--format", "github", "--fail-on-regress")
    assert code == 1 and "::error" in out
    warnings = [line for line in err.splitlines() if "warning" in line]
    assert len(warnings) == 1 and warnings[0].startswith("rs30x-sniff: warning: GITHUB_STEP_SUMMARY=")
    assert "Traceback" not in err
