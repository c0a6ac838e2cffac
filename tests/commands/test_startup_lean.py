"""Start-up (issue 35): what lint of a plain file does not need is not imported, a pyproject.toml that only names the
package is not parsed, and the collector keeps out of the modules' objects in a process of its own."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from rs30x_sniff import cli
from rs30x_sniff.settings import _may_hold_our_table, find_config

ROOT = Path(__file__).resolve().parents[2]
TINY = ROOT / "captures" / "manual-examples.hex"

PROBE = """
import gc, json, sys
from rs30x_sniff.cli import main
sys.argv = ["rs30x-sniff", *sys.argv[1:]]
code = main()
print(json.dumps({"code": code, "modules": sorted(sys.modules), "frozen": gc.get_freeze_count(),
                  "collecting": gc.isenabled()}))
"""


def probe(cwd: Path, *argv: str) -> dict:
    """What a fresh process running ``rs30x-sniff ARGV`` in ``cwd`` has imported (its last stdout line)."""
    out = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, cwd=cwd).stdout
    return json.loads(out.splitlines()[-1])


def test_lint_of_a_file_loads_no_baseline_figures_tempfile_toml_or_threads(tmp_path):
    # A project that depends on us and runs our command as one of its scripts: no table of ours to read.
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "robot"\ndependencies = ["rs30x-sniff"]\n\n'
                                             '[project.scripts]\nrs30x-sniff = "rs30x_sniff.cli:main"\n')
    got = probe(tmp_path, "lint", str(TINY))
    assert got["code"] in (0, 1)
    unneeded = {"rs30x_sniff.lint.baseline", "rs30x_sniff.sinks.stats", "tempfile", "tomllib", "threading"}
    assert unneeded.isdisjoint(got["modules"])


def test_what_lint_leaves_out_is_there_when_asked_for(tmp_path):
    (tmp_path / "pyproject.toml").write_text('[tool.rs30x-sniff]\nselect = ["P009"]\n')
    out = tmp_path / "base.json"
    got = probe(tmp_path, "lint", str(TINY), "--write-baseline", str(out))
    assert got["code"] == 0 and out.is_file()
    assert {"rs30x_sniff.lint.baseline", "tomllib"} <= set(got["modules"])


@pytest.mark.parametrize("text", [
    '[tool.rs30x-sniff]\nselect = ["F"]\n',
    '[tool."rs30x-sniff"]\n',
    "[ tool . 'rs30x-sniff' . regress ]\n",
    '[[tool.rs30x-sniff.rule]]\n',
    '[tool]\nrs30x-sniff = { select = ["F"] }\n',
    '["tool"]\n"rs30x-sniff".select = ["F"]\n',
    'tool = { rs30x-sniff = { select = ["F"] } }\n',
    'tool.rs30x-sniff.select = ["F"]\n',
    '[tool.rs30x-sniff\n',  # broken: read, so that load_config says so
])
def test_a_pyproject_that_may_hold_our_table_is_read(text):
    assert _may_hold_our_table(text)


@pytest.mark.parametrize("text", [
    '[project]\nname = "rs30x-sniff"\n',
    '[project.scripts]\nrs30x-sniff = "rs30x_sniff.cli:main"\n\n[tool.ruff]\nline-length = 120\n',
    '[project]\ndependencies = ["rs30x-sniff>=1"]\n[tool.mypy]\nstrict = true\n',
    '[tool.ruff]\n',  # no word of ours
])
def test_a_pyproject_that_only_names_the_package_is_not(text):
    assert not _may_hold_our_table(text)


def test_find_config_passes_a_pyproject_without_our_table_and_finds_one_above(tmp_path):
    (tmp_path / "pyproject.toml").write_text('[tool.rs30x-sniff]\nselect = ["P009"]\n')
    sub = tmp_path / "robot"
    sub.mkdir()
    (sub / "pyproject.toml").write_text('[project.scripts]\nrs30x-sniff = "rs30x_sniff.cli:main"\n')
    assert find_config(sub) == tmp_path / "pyproject.toml"
    (sub / "pyproject.toml").write_text('[tool]\nrs30x-sniff = { select = ["P009"] }\n')
    assert find_config(sub) == sub / "pyproject.toml"


def test_a_process_freezes_its_modules_once_and_collects_after(tmp_path):
    got = probe(tmp_path, "rules")
    assert got["code"] == 0 and got["frozen"] > 0 and got["collecting"]


def test_a_library_callers_main_freezes_nothing_and_leaves_the_collector_on():
    import gc

    before = gc.get_freeze_count()
    assert cli.main(["rules"]) == 0
    assert gc.isenabled() and gc.get_freeze_count() == before


def test_main_on_another_thread_sets_no_signal_handler(capsys):
    codes: list[int] = []
    t = threading.Thread(target=lambda: codes.append(cli.main(["rules"])))
    t.start()
    t.join()
    assert codes == [0]
    assert "F001" in capsys.readouterr().out
