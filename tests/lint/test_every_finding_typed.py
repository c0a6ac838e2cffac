"""Every built-in rule's finding carries typed parameters (issue 32 §4): its message is a lint.params.Message, so a
baseline fingerprints it by its key, never by patterns over its text (lint/baseline.py keeps those for version 1
files alone)."""

from __future__ import annotations

import pytest

from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.lint.params import key_of
from rs30x_sniff.sim import SCENARIOS, run
from rs30x_sniff.sinks.pipeline import drive
from rs30x_sniff.sources.captures import read_capture
from tests.conftest import CAPTURES

FILES = sorted(p for p in (CAPTURES / "lint").iterdir() if p.suffix in (".hex", ".thex")) + [
    CAPTURES / "manual-examples.hex", CAPTURES / "session-mixed.thex"]


def findings_of(chunks, columnar: bool) -> list:
    linter = Linter(LintConfig())
    drive(chunks, Decoder(None, linter, columnar=columnar))
    return linter.findings


@pytest.mark.parametrize("columnar", [False, True], ids=["records", "columns"])
@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_each_example_capture_s_findings_are_typed(path, columnar):
    found = findings_of(read_capture(str(path), warn=None), columnar)
    assert found or path.name.startswith("session"), "the example gives no finding"
    untyped = [(f.code, str(f.message)) for f in found if key_of(f.message) is None]
    assert not untyped, untyped


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_each_scenario_s_findings_are_typed(name):
    found = findings_of(list(run(name, duration=10, seed=2)), columnar=True)
    untyped = [(f.code, str(f.message)) for f in found if key_of(f.message) is None]
    assert not untyped, untyped
