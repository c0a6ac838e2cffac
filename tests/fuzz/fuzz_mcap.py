"""Atheris target: the MCAP reader (damaged, cut and foreign files); properties in targets.check_mcap."""

import sys
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parent))

# Everything the target runs is imported here, inside the hook, so that it is instrumented for coverage.
with atheris.instrument_imports(include=["rs30x_sniff", "targets"]):
    import rs30x_sniff.sources.mcap_reader
    import rs30x_sniff.sinks.pipeline  # noqa: F401
    import targets

if __name__ == "__main__":
    atheris.Setup(sys.argv, targets.TARGETS["mcap"])
    atheris.Fuzz()
