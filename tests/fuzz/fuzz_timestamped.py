"""Atheris target: the timestamped hex reader and format sniffing; properties in targets.check_timestamped."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from targets import run_atheris  # noqa: E402

if __name__ == "__main__":
    run_atheris("timestamped")
