"""A broken memory map on RS30X_DECODERS is one clear line and exit 2 for every command, never a traceback."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tests.conftest import CAPTURES, ROOT


@pytest.mark.parametrize("command", ["decode", "lint", "info"])
def test_a_broken_map_is_one_line(tmp_path, command):
    good = (ROOT / "decoders" / "rs303mr.toml").read_text()
    bad = good.replace('name = "RS303MR"', 'name = "RS999"', 1).replace('access = "reserved"', 'access = "bogus"', 1)
    (tmp_path / "bad.toml").write_text(bad)
    env = dict(os.environ, RS30X_DECODERS=str(tmp_path))
    done = subprocess.run([sys.executable, "-m", "rs30x_sniff", command, str(CAPTURES / "manual-examples.hex")],
                          capture_output=True, text=True, env=env, cwd=ROOT)
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "bad.toml" in lines[0] and "access" in lines[0], done.stderr
