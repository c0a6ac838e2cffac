"""`lint` runs the configuration's figure checks ([[expect]]) at the end of each capture, like any rule."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

CONFIG = """
[[expect]]
code = "U101"
name = "legs-polled-fast"
severity = "error"
check = "poll_hz >= 5"
for = "id:1-6"

[[expect]]
code = "U102"
name = "legs-polled-very-fast"
severity = "error"
check = "poll_hz >= 10"
for = "id:1-3"
"""


def lint(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rs30x_sniff", "lint", *args], cwd=cwd, capture_output=True,
                          text=True, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})


@pytest.fixture(scope="module")
def rig(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("rig")
    subprocess.run([sys.executable, "-m", "rs30x_sniff", "simulate", "--scenario", "hexapod", "--duration", "3",
                    "-o", str(d / "h.thex")], check=True, capture_output=True, env={"PYTHONPATH": str(ROOT)})
    (d / "h.hex").write_text(" ".join(  # the same bytes without their times: no poll rate to check
        line.split(maxsplit=1)[1] for line in (d / "h.thex").read_text().splitlines() if line.strip()) + "\n")
    (d / "rs30x-sniff.toml").write_text(CONFIG)
    return d


def test_a_failed_check_is_a_finding_with_the_measured_value(rig):
    done = lint(rig, "h.thex", "--format", "json")
    assert done.returncode == 1, done.stderr
    found = json.loads(done.stdout)
    assert sorted((f["code"], f["id"]) for f in found) == [("U102", 1), ("U102", 2), ("U102", 3)]
    assert all(re.fullmatch(r"ID [123]: poll_hz [5-9]\.\d+ < 10", f["message"]) for f in found), found


def test_checks_take_select_ignore_and_severity(rig):
    assert lint(rig, "h.thex", "--ignore", "U102").returncode == 0
    done = lint(rig, "h.thex", "--severity", "U102=warning", "--format", "json")
    assert done.returncode == 0 and {f["severity"] for f in json.loads(done.stdout)} == {"warning"}


def test_a_figure_the_capture_cannot_give_is_not_checkable_never_a_pass(rig):
    done = lint(rig, "h.hex", "--format", "json", "--select", "U101")
    found = json.loads(done.stdout)
    assert found and all(f["code"] == "U101" and "not checkable" in f["message"] for f in found), found


def test_a_bad_check_is_one_line_and_exit_2(tmp_path, rig):
    (tmp_path / "rs30x-sniff.toml").write_text(CONFIG.replace("poll_hz >= 5", "poll_hz >= 5 Hz and"))
    done = lint(tmp_path, str(rig / "h.thex"))
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1 and "U101" in done.stderr and "Traceback" not in done.stderr
