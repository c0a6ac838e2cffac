"""The pre-commit hook (.pre-commit-hooks.yaml): a robot repository's captures linted on commit, by pre-commit itself.

pre-commit installs the hook from this repository's committed HEAD (try-repo, then a config naming that commit)
into a virtualenv of its own with pip: the package registries are all it needs. One PRE_COMMIT_HOME serves the
module, so the hook is installed once."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.commands.test_ci_doc import blocks

ROOT = Path(__file__).resolve().parents[2]

pytestmark = [
    pytest.mark.skipif(importlib.util.find_spec("pre_commit") is None,
                       reason="pre-commit is not installed (pip install pre-commit)"),
    pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed"),
    pytest.mark.skipif(not (ROOT / ".git").exists(), reason="not a git checkout: pre-commit installs a hook from one"),
]


def head() -> str:
    done = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"no commit to install the hook from: {done.stderr.strip()}")
    if subprocess.run(["git", "cat-file", "-e", "HEAD:.pre-commit-hooks.yaml"], cwd=ROOT).returncode != 0:
        pytest.skip(".pre-commit-hooks.yaml is not committed yet: pre-commit installs the committed hook")
    return done.stdout.strip()


@pytest.fixture(scope="module")
def env(tmp_path_factory) -> dict[str, str]:
    home = tmp_path_factory.mktemp("pre-commit-home")
    return {**os.environ, "PRE_COMMIT_HOME": str(home), "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t",
            "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t", "PRE_COMMIT_COLOR": "never"}


def pre_commit(repo: Path, env: dict[str, str], *argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pre_commit", *argv], cwd=repo, env=env, capture_output=True,
                          text=True, timeout=900)


def git(repo: Path, env: dict[str, str], *argv: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["git", *argv], cwd=repo, env=env, capture_output=True, text=True, check=check)


@pytest.fixture
def robot(tmp_path, env) -> Path:
    """A robot repository: its rig's capture (known findings), a firmware image in Intel HEX and notes, staged."""
    repo = tmp_path / "robot"
    git(tmp_path, env, "init", "-q", str(repo))
    (repo / "captures").mkdir()
    shutil.copy(ROOT / "captures" / "session-mixed.thex", repo / "captures" / "rig.thex")
    (repo / "firmware").mkdir()
    (repo / "firmware" / "servo-board.hex").write_text(":10010000214601360121470136007EFE09D2190140\n:00000001FF\n")
    (repo / "rs30x-sniff.toml").write_text(blocks("toml")[0])  # docs/ci.md's: the robot's own rules and checks
    (repo / "notes.txt").write_text("gait v2\n")
    git(repo, env, "add", ".")
    return repo


def test_try_repo_lints_the_captures_and_only_them(robot, env):
    done = pre_commit(robot, env, "try-repo", str(ROOT), "rs30x-sniff-lint", "--ref", head(), "--all-files",
                      "--verbose")
    out = done.stdout + done.stderr
    assert done.returncode == 1, out  # the rig's capture has findings at error
    assert "captures/rig.thex:" in out and "B002 missing-return" in out, out
    assert "servo-board.hex" not in out and "notes.txt" not in out  # a firmware image is not a capture


def test_a_commit_with_a_new_finding_is_stopped_and_one_the_baseline_knows_is_not(robot, env):
    hook = subprocess.run([str(Path(sys.executable).parent / "rs30x-sniff"), "lint", "captures/rig.thex",
                           "--write-baseline", "lint-baseline.json"], cwd=robot, capture_output=True, text=True)
    assert hook.returncode == 0, hook.stderr
    (robot / ".pre-commit-config.yaml").write_text(
        f"repos:\n  - repo: {ROOT}\n    rev: {head()}\n    hooks:\n      - id: rs30x-sniff-lint\n"
        "        args: [--baseline, lint-baseline.json]\n")
    git(robot, env, "add", ".")
    installed = pre_commit(robot, env, "install")
    assert installed.returncode == 0, installed.stderr
    first = git(robot, env, "commit", "-q", "-m", "the rig", check=False)
    assert first.returncode == 0, first.stdout + first.stderr  # its findings are the baseline's
    # The next capture has a servo past 60 degC: the robot's rule U001 is a new finding, and the commit stops.
    hot = "FD DF 02 00 2A 12 01 " + "00 " * 8 + "3D 00 " + "00 " * 8  # present_temperature (No. 50) = 61 degC
    s = 0
    for b in bytes.fromhex(hot.replace("FD DF", "")):
        s ^= b
    capture = robot / "captures" / "rig.thex"
    last = float(capture.read_text().strip().splitlines()[-1].split()[0])
    with capture.open("a") as f:
        f.write(f"{last + 0.01:.6f} {hot}{s:02X}\n")
    git(robot, env, "add", "captures/rig.thex")
    before = git(robot, env, "rev-parse", "HEAD").stdout
    second = git(robot, env, "commit", "-q", "-m", "hotter", check=False)
    assert second.returncode != 0 and "U001" in second.stdout + second.stderr, second.stdout + second.stderr
    assert git(robot, env, "rev-parse", "HEAD").stdout == before
