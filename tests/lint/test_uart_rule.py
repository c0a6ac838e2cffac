"""F008 uart-error: bytes the capturing tool flagged are garbage with their reason, said once per run, never F002."""

from __future__ import annotations

import io
import json

import pytest

from rs30x_sniff.protocol.chunks import FRAMING_ERROR, PARITY_ERROR, SERVO, Marked
from rs30x_sniff.cli import main
from rs30x_sniff.sources import foreign
from rs30x_sniff.lint import RULES, LintConfig, Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.sinks.pipeline import drive
from rs30x_sniff.protocol.wire import encode_short

from .helpers import CAPTURES

GOAL = encode_short(1, 0, 0x1E, b"\x84\x03")
GOAL2 = encode_short(2, 0, 0x1E, b"\x84\x03")  # needs no reply: nothing but the rule under test fires


def lint(chunks, config: LintConfig | None = None):
    linter = Linter(config)
    dec = drive(chunks, Decoder(DecodeOptions(), linter))
    return linter, dec


def codes(linter) -> list[tuple[int, str]]:
    return [(f.offset, f.code) for f in linter.findings]


def test_a_flagged_byte_between_frames_is_f008_only():
    linter, _ = lint([(GOAL, 0.0), Marked(b"\x00", 0.002, error=FRAMING_ERROR), (GOAL2, 0.003)])
    assert codes(linter) == [(10, "F008")]
    f = linter.findings[0]
    assert f.severity == "error" and "0x00" in f.message and "framing error" in f.message and f.id is None


def test_a_flagged_byte_inside_a_frame_cuts_it():
    chunks = [(GOAL[:4], 0.0), Marked(GOAL[4:5], 0.0004, error=FRAMING_ERROR), (GOAL[5:], 0.0005), (GOAL2, 0.003)]
    linter, _ = lint(chunks)
    assert codes(linter) == [(0, "F003"), (4, "F008"), (5, "F002")]


def test_a_run_of_flagged_bytes_is_said_once_and_noise_after_it_is_f002():
    bt = 10 / 115200
    chunks = [Marked(bytes((0x55 + k,)), k * bt, error=FRAMING_ERROR if k % 2 else PARITY_ERROR) for k in range(6)]
    chunks += [(b"\x12\x34", 6 * bt), Marked(b"\x99", 8 * bt, error=FRAMING_ERROR), (GOAL, 0.01)]
    linter, dec = lint(chunks)
    assert codes(linter) == [(0, "F008"), (6, "F002"), (8, "F008")]
    assert "parity error" in linter.findings[0].message and "8N1" in linter.findings[0].message


def test_flagged_bytes_are_garbage_with_their_reason():
    dec = Decoder(DecodeOptions())
    recs = [r for c in [Marked(b"\x07", 0.0, sender=SERVO, error=PARITY_ERROR), (GOAL2, 0.001)]
            for r in dec.feed(c[0], c[1], getattr(c, "sender", None), getattr(c, "error", None))] + dec.close()
    assert [(r.event.kind, getattr(r.event, "reason", None)) for r in recs] == [
        ("garbage", PARITY_ERROR), ("short", None)]


def test_f008_can_be_ignored_and_selected():
    chunks = [Marked(b"\x00", 0.0, error=FRAMING_ERROR), (GOAL, 0.001)]
    assert codes(lint(chunks, LintConfig(ignore=["uart-error"]))[0]) == []
    assert codes(lint(chunks, LintConfig(select=["F008"]))[0]) == [(0, "F008")]


def test_the_doc_example_is_a_saleae_table_that_shows_the_rule():
    text = RULES["F008"].example
    fmt = foreign.sniff(text.encode())
    assert fmt is not None and fmt.name == "saleae"
    chunks = list(fmt.read(io.BytesIO(text.encode()), foreign.ReadContext("example.csv")))
    linter, _ = lint(chunks)
    assert codes(linter) == [(0, "F003"), (7, "F008"), (8, "F002")]


@pytest.mark.parametrize(("name", "found"), [
    ("saleae-logic2-iso.csv", [(772, "F003"), (785, "F008"), (787, "F002"), (798, "B001")]),
    ("saleae-logic1.csv", [(1244, "F002"), (1245, "F008"), (1246, "F002")]),
    ("saleae-logic2.csv", []),
])
def test_the_saleae_samples(capsys, name, found):
    path = str(CAPTURES / "foreign" / name)
    assert main(["lint", path, "--format", "json"]) == (1 if found else 0)
    data = json.loads(capsys.readouterr().out)  # one object per finding
    assert sorted((f["offset"], f["code"]) for f in data) == found
