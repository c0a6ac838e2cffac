"""One capture per rule under captures/lint: every expected finding is found, and nothing else."""

from __future__ import annotations

import io

import pytest

from rs30x_sniff.sources import foreign
from rs30x_sniff.lint import RULES, LintConfig, Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.sinks.pipeline import drive

from .helpers import CAPTURES, found, lint_chunks, lint_text, parse

FILES = sorted((CAPTURES / "lint").glob("*.*hex"))
# Rules about what hex text cannot say (a byte the capturing UART flagged): their capture is a sample
# of another tool's format, whose findings the rule's own test checks.
ELSEWHERE = {
    "F008": CAPTURES / "foreign" / "saleae-logic2-iso.csv",  # tests/lint/test_uart_rule.py
    "F009": CAPTURES / "foreign" / "spy-swapped.log",        # tests/lint/test_direction_rule.py
}


def test_every_rule_has_a_capture():
    have = {p.name.split("-", 1)[0] for p in FILES}
    assert have | set(ELSEWHERE) == set(RULES.codes())
    assert all(p.is_file() for p in ELSEWHERE.values())
    for p in FILES:
        code = p.name.split("-", 1)[0]
        assert p.stem == f"{code}-{RULES[code].name}"


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_capture_findings_exactly(path):
    chunks, expected = parse(path.read_text())
    code = path.name.split("-", 1)[0]
    assert any(c == code for _, c in expected), "the capture must show its own rule firing"
    got = found(lint_chunks(chunks))
    missing = expected - got
    extra = got - expected
    assert not missing and not extra, f"missing {sorted(missing)}, extra {sorted(extra)}"


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_rule_can_be_ignored(path):
    code = path.name.split("-", 1)[0]
    linter = lint_chunks(parse(path.read_text())[0], LintConfig(ignore=[code]))
    assert code not in {f.code for f in linter.findings}


@pytest.mark.parametrize("rule", list(RULES), ids=lambda r: r.code)
def test_doc_example_shows_the_rule(rule):
    """Each rule's documented example packet, linted, gives that rule's finding."""
    assert rule.example.strip()
    assert rule.section("What it does") and rule.section("Why it matters")
    codes = {f.code for f in _lint_example(rule.example).findings}
    assert rule.code in codes


def _lint_example(text: str) -> Linter:
    """A doc example linted: hex text, or another tool's format where hex cannot show the rule."""
    other = foreign.sniff(text.encode())
    if other is None:
        return lint_text(text)
    linter = Linter()
    drive(other.read(io.BytesIO(text.encode()), foreign.ReadContext("example")), Decoder(DecodeOptions(), linter))
    return linter


def test_manual_examples_exact():
    """The manual's own examples break a few rules; exactly these."""
    chunks, _ = parse((CAPTURES / "manual-examples.hex").read_text())
    got = sorted((f.offset, f.code) for f in lint_chunks(chunks).findings)
    assert got == [
        (34, "B002"),   # the read of present_position has no return among the examples
        (42, "Q004"),   # the long packet comes after the reboot example: torque is off
        (59, "Q002"),   # ID 1 -> 5 never flashed (said at the end of input)
        (86, "P008"),   # return_delay written in a flash+reboot packet ...
        (86, "P009"),   # ... with both bits set
        (105, "M002"),  # ccw_angle_limit sent to reserved address 0x10
        (139, "Q004"),  # goal after that packet's reboot, torque off again
    ]


def test_timing_rules_skipped_without_timestamps():
    text = (CAPTURES / "lint" / "B006-return-latency.thex").read_text()
    untimed = "\n".join(" ".join(line.split("#")[0].split()[1:]) for line in text.splitlines() if line.strip() and not line.startswith("#"))
    linter = lint_text(untimed)
    assert linter.timed is False
    assert set(linter.skipped) == {r.code for r in RULES if r.needs_time}
    assert not any(f.code == "B006" for f in linter.findings)


def test_findings_attach_to_their_records():
    from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
    from rs30x_sniff.lint import Linter
    chunks, _ = parse((CAPTURES / "lint" / "M001-write-read-only.hex").read_text())
    dec = Decoder(DecodeOptions(), Linter())
    recs = [r for d, t in chunks for r in dec.feed(d, t)] + dec.close()
    flagged = [r for r in recs if r.findings]
    assert [r.offset for r in flagged] == sorted({f.offset for r in flagged for f in r.findings})
    assert all(f.offset == r.offset for r in flagged for f in r.findings)
