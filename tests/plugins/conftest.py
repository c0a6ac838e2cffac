"""What the plug-in tests share: the simulator's scenarios as capture files, made once per test process."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from rs30x_sniff.cli import main
from rs30x_sniff.sim import SCENARIOS

SIM_SECONDS = "1.5"  # long enough for the overheat scenario's servo 2 to pass 60 degC


@pytest.fixture(scope="session")
def scenario_files(tmp_path_factory) -> list[Path]:
    """Each simulator scenario, SIM_SECONDS long (seed 0), as a timestamped hex capture."""
    d = tmp_path_factory.mktemp("scenarios")
    paths = []
    for name in SCENARIOS:
        p = d / f"{name}.thex"
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(["simulate", "--scenario", name, "--duration", SIM_SECONDS, "--seed", "0", "-o", str(p)]) == 0
        paths.append(p)
    return paths
