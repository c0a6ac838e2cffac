"""action.yml stays true: a composite action whose inputs are declared, whose rs30x-sniff commands are docs/ci.md's
workflow's and exist, and whose steps, run in bash as a runner would, pass an unchanged capture, fail a slower one."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.commands.test_ci_doc import blocks
from tests.commands.test_ci_doc import commands as workflow_commands

ROOT = Path(__file__).resolve().parents[2]
ACTION = ROOT / "action.yml"
BIN = Path(sys.executable).parent  # rs30x-sniff as installed beside the tests' Python

try:
    import yaml
except ImportError:  # the text checks below still run
    yaml = None


def action() -> dict:
    if yaml is None:
        pytest.skip("PyYAML is not installed: action.yml is checked by its text only")
    return yaml.safe_load(ACTION.read_text())


def run_steps() -> list[dict]:
    return [s for s in action()["runs"]["steps"] if "run" in s]


def rs30x_commands(script: str) -> list[list[str]]:
    """The rs30x-sniff commands of a step's script, as argv (a line continued with a backslash read whole)."""
    text = script.replace("\\\n", " ")
    return [shlex.split(line.strip().split(" #")[0]) for line in text.splitlines()
            if line.strip().startswith("rs30x-sniff ")]


def options(argv: list[str]) -> list[str]:
    """The options of a command; one given only when an input is set (`${BASELINE:+--baseline "$BASELINE"}`) too."""
    words = [re.sub(r"^\$\{\w+:\+", "", a) for a in argv]
    return [w for w in words if w.startswith("-")]


def assert_options_exist(argv: list[str]) -> None:
    helped = subprocess.run([str(BIN / "rs30x-sniff"), argv[1], "--help"], capture_output=True, text=True)
    assert helped.returncode == 0, helped.stderr
    for opt in options(argv):
        assert re.search(rf"(^|[\s\[,]){re.escape(opt)}\b", helped.stdout), f"{argv[1]} has no {opt}"


def test_by_its_text_a_composite_action_running_commands_that_exist():
    """What holds without a YAML parser: a composite action, and rs30x-sniff's commands and options as it runs them."""
    text = ACTION.read_text()
    assert re.search(r"^runs:\n  using: composite$", text, re.M)
    ours = rs30x_commands(text)
    assert [argv[1] for argv in ours] == ["lint", "diff"]
    for argv in ours:
        assert_options_exist(argv)


def test_a_composite_action_whose_expressions_name_declared_inputs():
    a = action()
    assert a["runs"]["using"] == "composite" and a["name"] and a["description"]
    assert a["inputs"]["capture"]["required"] is True
    declared = set(a["inputs"])
    used = set(re.findall(r"inputs\.([A-Za-z0-9_-]+)", ACTION.read_text()))
    assert used == declared, used ^ declared  # every input is read, none read undeclared
    for step in run_steps():
        assert step["shell"] == "bash", step
        # The inputs reach a script through its environment, never pasted into it (no injection, one quoting).
        assert "${{" not in step["run"], step["name"]


def test_its_commands_are_the_workflows_and_exist():
    ours = [argv for step in run_steps() for argv in rs30x_commands(step["run"])]
    assert [argv[1] for argv in ours] == ["lint", "diff"]
    _, doc_lint, doc_diff = workflow_commands()
    # The same command with the same options as docs/ci.md's workflow (the paths are the inputs').
    for argv, doc in zip(ours, (doc_lint, doc_diff)):
        assert sorted(options(argv)) == sorted(options(doc)), (argv, doc)
        assert_options_exist(argv)
    assert "--format github" in " ".join(doc_lint) and "--format" in ours[0]


def test_the_page_shows_the_action_with_its_inputs():
    uses = [b for b in blocks("yaml") if "uses: " in b and "rs30x-sniff@" in b]
    assert uses, "docs/ci.md shows the action's use"
    declared = set(action()["inputs"])
    for block in uses:
        given = yaml.safe_load(block)["jobs"]["bus"]["steps"]
        step = next(s for s in given if "rs30x-sniff@" in s.get("uses", ""))
        assert set(step["with"]) <= declared and "capture" in step["with"]


# ---- the steps, run as a runner runs them ------------------------------------------------------------
def expression(text: str, inputs: dict[str, str], github: dict[str, str]) -> str:
    """The `${{ a || b || 'literal' }}` expressions action.yml's environments use, evaluated as GitHub does."""
    def one(m: re.Match) -> str:
        for term in (t.strip() for t in m.group(1).split("||")):
            if term.startswith("'"):
                value = term.strip("'")
            elif term.startswith("inputs."):
                value = inputs.get(term[7:], action()["inputs"][term[7:]].get("default", ""))
            else:
                assert term.startswith("github."), term
                value = github.get(term[7:], "")
            if value:
                return value
        return ""
    return re.sub(r"\$\{\{(.*?)\}\}", one, text)


def condition(text: str | None, failed: bool, inputs: dict[str, str]) -> bool:
    """A step's `if:` (the forms action.yml uses): `inputs.X == 'v'`, with `always() && ` before it or not."""
    if text is None:
        return not failed
    always = text.startswith("always() && ")
    m = re.fullmatch(r"inputs\.([a-z-]+) == '([^']*)'", text.removeprefix("always() && "))
    assert m, text
    value = inputs.get(m.group(1), action()["inputs"][m.group(1)].get("default", ""))
    return (always or not failed) and value == m.group(2)


def run_action(repo: Path, tmp: Path, inputs: dict[str, str], github: dict[str, str]) -> tuple[list[int | None], str]:
    """The action's bash steps in ``repo`` (the install step left out: rs30x-sniff is the tests'); each step's exit
    status (None: skipped) and the job summary."""
    summary, temp = tmp / "summary.md", tmp / "runner-temp"
    temp.mkdir()
    summary.write_text("")
    codes: list[int | None] = []
    failed = False
    for step in run_steps():
        if step["name"].startswith("install"):
            continue
        if not condition(step.get("if"), failed, inputs):
            codes.append(None)
            continue
        env = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ['PATH']}", "RUNNER_TEMP": str(temp),
               "GITHUB_STEP_SUMMARY": str(summary), "GITHUB_OUTPUT": str(tmp / "output"),
               "GITHUB_ACTION_PATH": str(ROOT)}
        env.update({k: expression(v, inputs, github) for k, v in step.get("env", {}).items()})
        done = subprocess.run(["bash", "--noprofile", "--norc", "-eo", "pipefail", "-c", step["run"]], cwd=repo,
                              env=env, capture_output=True, text=True, timeout=300)
        codes.append(done.returncode)
        failed = failed or done.returncode != 0
    return codes, summary.read_text()


def git(repo: Path, *argv: str) -> None:
    subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *argv], cwd=repo, check=True,
                   capture_output=True)


@pytest.fixture
def robot(tmp_path):
    """A robot repository as a pull request's checkout: main's capture pushed to origin, a branch on top."""
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    origin, repo = tmp_path / "origin.git", tmp_path / "robot"
    git(tmp_path, "init", "-q", "--bare", str(origin))
    git(tmp_path, "init", "-q", "-b", "main", str(repo))
    (repo / "captures").mkdir()
    shutil.copy(ROOT / "captures" / "session-mixed.thex", repo / "captures" / "rig.thex")
    (repo / "rs30x-sniff.toml").write_text(blocks("toml")[0])
    done = subprocess.run([str(BIN / "rs30x-sniff"), "lint", "captures/rig.thex", "--write-baseline",
                           "lint-baseline.json"], cwd=repo, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    git(repo, "add", ".")
    git(repo, "commit", "-q", "-m", "the rig")
    git(repo, "remote", "add", "origin", str(origin))
    git(repo, "push", "-q", "origin", "main")
    git(repo, "checkout", "-q", "-b", "gait")
    return repo


def test_an_unchanged_capture_passes_and_the_diff_is_in_the_summary(robot, tmp_path):
    codes, summary = run_action(robot, tmp_path, {"capture": "captures/rig.thex", "baseline": "lint-baseline.json"},
                                {"base_ref": "main"})
    assert codes == [0, 0, 0]
    assert "| latency_p95 |" in summary  # the diff's table, after lint's own summary


def test_without_the_baseline_the_known_findings_fail_the_lint_step(robot, tmp_path):
    codes, summary = run_action(robot, tmp_path, {"capture": "captures/rig.thex"}, {"base_ref": "main"})
    assert codes == [1, None, 0]  # the diff is not run after a failed lint, as in the workflow; the summary is
    assert "B002" in summary and "| latency_p95 |" not in summary


def test_slower_replies_on_the_branch_fail_the_diff_step_and_still_reach_the_summary(robot, tmp_path):
    lines = (robot / "captures" / "rig.thex").read_text().splitlines()
    later = [f"{float(x.split()[0]) + 0.0003:.6f} {x.split(maxsplit=1)[1]}" if " FD DF " in x else x for x in lines]
    (robot / "captures" / "rig.thex").write_text("\n".join(later) + "\n")
    git(robot, "commit", "-q", "-am", "slower")
    # A shallow checkout of the branch (actions/checkout's default): the step fetches the base branch itself.
    git(robot, "update-ref", "-d", "refs/remotes/origin/main")
    codes, summary = run_action(robot, tmp_path, {"capture": "captures/rig.thex", "baseline": "lint-baseline.json"},
                                {"base_ref": "main"})
    assert codes[:2] == [0, 1] and codes[2] == 0
    assert "latency_p95" in summary


def test_a_capture_new_on_the_branch_is_nothing_to_compare(robot, tmp_path):
    shutil.copy(robot / "captures" / "rig.thex", robot / "captures" / "arm.thex")
    done = subprocess.run([str(BIN / "rs30x-sniff"), "lint", "captures/arm.thex", "--write-baseline",
                           "arm-baseline.json"], cwd=robot, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    git(robot, "add", ".")
    git(robot, "commit", "-q", "-m", "the arm")
    codes, summary = run_action(robot, tmp_path, {"capture": "captures/arm.thex", "baseline": "arm-baseline.json",
                                                  "base-ref": "main"}, {})
    assert codes == [0, 0, 0] and "| latency_p95 |" not in summary
