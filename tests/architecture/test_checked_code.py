"""The package is checked code: ruff and mypy, each as pyproject.toml configures it, pass on rs30x_sniff (issue 33)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _run(module: str, *args: str) -> subprocess.CompletedProcess[str]:
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} is not installed (pip install -e '.[test]')")
    return subprocess.run([sys.executable, "-m", module, *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=600)


def test_ruff_passes_on_the_package():
    done = _run("ruff", "check", "rs30x_sniff")
    assert done.returncode == 0, done.stdout + done.stderr


def test_mypy_passes_on_the_package():
    # No arguments: [tool.mypy] in pyproject.toml names the package and the untyped third parties.
    done = _run("mypy")
    assert done.returncode == 0, done.stdout[-5000:] + done.stderr
