"""The sample session: its faults are found, nothing else, and docs/lint-example.md shows the real output."""

from __future__ import annotations

from collections import Counter

from .helpers import CAPTURES, ROOT, lint_chunks, parse
from .make_session import build, lint_example


def test_session_is_small_and_realistic():
    path = CAPTURES / "session-mixed.thex"
    assert path.stat().st_size < 100_000
    frames = [line for line in path.read_text().splitlines() if line and not line.startswith("#")]
    assert 300 <= len(frames) <= 400
    assert [(round(t, 6), f.hex(" ").upper()) for t, f, _ in build()] == [
        (float(line.split()[0]), " ".join(line.split("#")[0].split()[1:])) for line in frames]


def test_session_findings():
    linter = lint_chunks(parse((CAPTURES / "session-mixed.thex").read_text())[0])
    assert linter.timed and not linter.skipped
    assert Counter(f.code for f in linter.findings) == Counter(
        ["B002", "B001", "B006", "S002", "F002", "F001", "M003", "Q007", "Q003", "Q001"])
    assert linter.records > 300


def test_lint_example_doc_is_up_to_date():
    assert (ROOT / "docs" / "lint-example.md").read_text() == lint_example(), \
        "regenerate: python tests/lint/make_session.py"
