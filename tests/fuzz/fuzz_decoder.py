"""Atheris target: the decoder (rs30x_sniff.pipeline.Decoder) fed arbitrary chunks and times; properties in targets.check_decoder."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from targets import run_atheris  # noqa: E402

if __name__ == "__main__":
    run_atheris("decoder")
