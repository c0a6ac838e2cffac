"""Rules keep their own state (declared with state=), and preconditions are a table of named predicates."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import rs30x_sniff.lint as lint_pkg
from rs30x_sniff.lint import RULES, LintConfig, Linter
from rs30x_sniff.lint.registry import WHEN, rule
from rs30x_sniff.lint.state import Shadow
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.protocol.wire import FLAG_REBOOT, encode_command, encode_short

RULE_NAMED = re.compile(r"_?[fpmbsq]\d{3}", re.I)


def _lint(data: bytes, linter: Linter | None = None) -> Linter:
    linter = linter or Linter()
    dec = Decoder(DecodeOptions(), linter)
    dec.feed(data)
    dec.close()
    return linter


def test_no_linter_or_shadow_attribute_is_named_after_a_rule():
    linter = _lint(encode_short(1, 0, 0x06, b"\x04"))
    assert not [a for a in vars(linter) if RULE_NAMED.fullmatch(a)]
    assert not [a for a in Shadow.__slots__ if RULE_NAMED.fullmatch(a)]


def test_each_run_makes_its_own_state_for_each_stateful_rule():
    a, b = Linter(), Linter()
    stateful = [r.code for r in RULES if r.state is not None]
    assert {"Q001", "Q002", "Q003", "Q004", "Q008"} <= set(stateful)
    for code in stateful:
        assert a.state_of(code) is not None and a.state_of(code) is not b.state_of(code)
    assert a.state_of("P001") is None  # no state declared
    assert Linter(LintConfig(select=["P"])).state_of("Q001") is None  # not enabled


def test_state_lives_in_the_rule_not_the_linter():
    baud = encode_short(2, 0, 0x06, b"\x04")
    linter = _lint(baud)
    assert [f.code for f in linter.findings] == ["Q001"]
    assert list(linter.state_of("Q001")) == [2]
    # A second run starts clean: nothing pending from the first.
    assert _lint(encode_command(2, FLAG_REBOOT)).findings == []


def test_goal_while_torque_off_speaks_again_after_torque_is_written():
    off, goal = encode_short(1, 0, 0x24, b"\x00"), encode_short(1, 0, 0x1E, b"\x84\x03")
    linter = _lint(off + goal + goal + off + goal)
    assert [f.code for f in linter.findings] == ["Q004", "Q004"]
    assert linter.state_of("Q004") == {1}


def test_no_rule_dispatches_on_its_argument_count():
    src = Path(lint_pkg.__file__).parent
    for path in src.glob("*.py"):
        assert "len(args)" not in path.read_text(), path.name


def test_when_is_a_table_of_documented_predicates():
    assert set(WHEN) == {"after-cut", "unpaired", "flagged", "crowded", "settles"}
    for name, (doc, holds) in WHEN.items():
        assert isinstance(doc, str) and doc and callable(holds), name
    assert {r.when for r in RULES if r.when} <= set(WHEN)


def test_on_refuses_a_kind_the_rule_did_not_declare():
    doc = "## What it does\nx\n## Why it matters\ny\n## Example\nz\n"
    try:
        @rule("Q990", "test-only-rule", "info", "s", doc, kinds=("short",), column="silent")
        def check(lint, rec, ev):
            pass

        with pytest.raises(ValueError, match="does not declare"):
            check.on("close")
        r = RULES["Q990"]
        assert r.check_for("short") is check
    finally:
        RULES._by_code.pop("Q990", None)
        RULES._by_name.pop("test-only-rule", None)
