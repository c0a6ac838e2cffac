"""Atheris target: the MCAP reader (damaged, cut and foreign files); properties in targets.check_mcap."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from targets import run_atheris  # noqa: E402

if __name__ == "__main__":
    run_atheris("mcap")
