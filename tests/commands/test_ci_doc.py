"""docs/ci.md stays true: its configuration loads, and its rs30x-sniff commands run as it says on a bundled capture."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "ci.md"


def blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", DOC.read_text(), re.S)


def commands() -> list[list[str]]:
    """Every rs30x-sniff command of the page, in order: the baseline's, then the workflow's."""
    lines = [line.strip() for block in blocks("sh") + blocks("yaml") for line in block.splitlines()]
    return [shlex.split(line.split("#")[0]) for line in lines if line.startswith("rs30x-sniff ")]


def run(argv: list[str], cwd: Path, summary: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT), GITHUB_STEP_SUMMARY=str(summary))
    return subprocess.run([sys.executable, "-m", "rs30x_sniff", *argv[1:]], cwd=cwd, env=env,
                          capture_output=True, text=True)


def rig(tmp_path: Path) -> Path:
    (tmp_path / "captures").mkdir()
    shutil.copy(ROOT / "captures" / "session-mixed.thex", tmp_path / "captures" / "rig.thex")
    (tmp_path / "rs30x-sniff.toml").write_text(blocks("toml")[0])
    return tmp_path


def test_the_page_names_the_commands_it_documents():
    names = [c[1] for c in commands()]
    assert names == ["lint", "lint", "diff"], names


def test_the_workflow_passes_on_an_unchanged_capture(tmp_path):
    repo = rig(tmp_path)
    shutil.copy(repo / "captures" / "rig.thex", repo / "main-rig.thex")  # git show origin/main:... on main
    summary = tmp_path / "summary.md"
    write, lint, diff = commands()
    done = run(write, repo, summary)
    assert done.returncode == 0 and (repo / "lint-baseline.json").exists(), done.stderr
    done = run(lint, repo, summary)
    assert done.returncode == 0, done.stdout + done.stderr  # every finding the rig has is in the baseline
    done = run(diff, repo, summary)
    assert done.returncode == 0, done.stdout + done.stderr
    table = (repo / "diff.md").read_text()
    assert "| latency_p95 |" in table and "| bus |" in table


def test_a_new_fault_fails_the_lint_step_and_a_slower_bus_the_diff_step(tmp_path):
    repo = rig(tmp_path)
    summary = tmp_path / "summary.md"
    write, lint, diff = commands()
    assert run(write, repo, summary).returncode == 0
    # The branch's capture gains a servo past 60 degC: the user rule's finding is new to the baseline.
    hot = "FD DF 02 00 2A 12 01 " + "00 " * 8 + "3D 00 " + "00 " * 8  # present_temperature (No. 50) = 61 degC
    body = bytes.fromhex(hot.replace("FD DF", "").strip())
    s = 0
    for b in body:
        s ^= b
    text = (repo / "captures" / "rig.thex").read_text()
    last = float(text.strip().splitlines()[-1].split()[0])
    with open(repo / "captures" / "rig.thex", "a") as f:
        f.write(f"{last + 0.01:.6f} {hot}{s:02X}\n")
    done = run(lint, repo, summary)
    assert done.returncode == 1 and "U001" in done.stdout, done.stdout + done.stderr
    # main's capture is the unchanged one; on the branch every reply comes 0.3 ms later (p95 up far past +20 %)
    shutil.copy(ROOT / "captures" / "session-mixed.thex", repo / "main-rig.thex")
    lines = (repo / "main-rig.thex").read_text().splitlines()
    later = [f"{float(x.split()[0]) + 0.0003:.6f} {x.split(maxsplit=1)[1]}" if " FD DF " in x else x for x in lines]
    (repo / "captures" / "rig.thex").write_text("\n".join(later) + "\n")
    done = run(diff, repo, summary)
    assert done.returncode == 1 and "latency_p95" in done.stderr + done.stdout, done.stdout + done.stderr
