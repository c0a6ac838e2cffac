"""A large Block some rule speaks of is halved (Linter.feed_block): the findings, records and every column form's
output are those of the record path, and the rows far from a finding stay on the column forms."""

import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.lint import Linter
from rs30x_sniff.lint import linter as linter_module
from rs30x_sniff.render.block_json import block_json_lines
from rs30x_sniff.render.records import record_json_text
from tests.decode.test_columnar import assert_same

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from traffic import hexapod_frames  # noqa: E402

BAUD = 115200


def with_late_replies(frames: int, late: list[int], delay: float = 0.006) -> list:
    """Hexapod traffic with the replies at the ``late`` positions (fractions of the capture, by index) 6 ms late:
    B006 on each (the servo's return delay says 0.1 ms; the margin is 2 ms), and nothing else to find."""
    chunks = hexapod_frames(frames, BAUD)
    returns = [k for k, (d, _) in enumerate(chunks) if d[0] == 0xFD]
    shift = [0.0] * len(chunks)
    for where in late:
        k = returns[min(len(returns) - 1, int(where * len(returns)))]
        for j in range(k, len(chunks)):
            shift[j] += delay
    return [(d, t + s) for (d, t), s in zip(chunks, shift)]


def columnar_steps(chunks) -> tuple[list, Linter]:
    linter = Linter()
    dec = Decoder(DecodeOptions(baud=BAUD), linter, columnar=True)
    items = list(dec.feed_many(chunks))
    items += dec.close()
    return items, linter


def counted(monkeypatch) -> tuple[list[int], list[int]]:
    """The sizes of the Blocks the linter is given, and of every column check it makes, as they happen."""
    checks: list[int] = []
    blocks_in: list[int] = []
    real_check, real_feed = linter_module.Linter._check_parts, linter_module.Linter.feed_block

    def check(self, blk, out, tries):
        checks.append(len(blk))
        return real_check(self, blk, out, tries)

    def feed_block(self, blk):
        blocks_in.append(len(blk))
        return real_feed(self, blk)

    monkeypatch.setattr(linter_module.Linter, "_check_parts", check)
    monkeypatch.setattr(linter_module.Linter, "feed_block", feed_block)
    return checks, blocks_in


def test_a_finding_in_a_long_stretch_costs_only_the_rows_around_it():
    chunks = with_late_replies(4000, [0.5])
    items, linter = columnar_steps(chunks)
    assert [f.code for f in linter.findings] == ["B006"]
    blocks = [x for x in items if type(x) is Block]
    assert len(blocks) > 1  # halved
    by_rows = sum(len(b) for b in blocks if b.linted_by_rows)
    quiet = sum(len(b) for b in blocks if not b.linted_by_rows)
    assert 0 < by_rows <= 4 * linter_module.SPLIT_ROWS and quiet > 10 * by_rows
    # The finding sits on a row of a part linted by rows, and that part's lines carry it.
    (holder,) = [b for b in blocks if b.linted_by_rows and any(r.findings for r in b.records())]
    assert "B006" in block_json_lines(holder)


def test_findings_everywhere_give_up_halving_soon(monkeypatch):
    """Findings all over a Block: at most 2 x SPLIT_TRIES + 1 column checks of it, then row by row."""
    chunks = with_late_replies(4000, [i / 40 for i in range(40)])
    checks, blocks_in = counted(monkeypatch)
    items, linter = columnar_steps(chunks)
    assert [f.code for f in linter.findings].count("B006") == 40
    assert blocks_in and len(checks) <= len(blocks_in) * (2 * linter_module.SPLIT_TRIES + 1)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(late=st.lists(st.floats(0.0, 1.0), max_size=6), frames=st.integers(200, 3000),
       group=st.sampled_from([400, 1500, 100000]), split_rows=st.sampled_from([2, 8, 32]))
def test_halving_matches_the_record_path(late, frames, group, split_rows):
    chunks = with_late_replies(frames, late)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(linter_module, "SPLIT_ROWS", split_rows)
        assert_same(chunks, [group], DecodeOptions(baud=BAUD), lint=True)
        # And each part's lines are its records' own.
        items, _ = columnar_steps(chunks)
    for blk in items:
        if type(blk) is Block:
            assert block_json_lines(blk) == "".join(record_json_text(r) + "\n" for r in blk.records())


def test_a_late_reply_is_cut_out_of_its_block_by_the_rows_b006_names(monkeypatch):
    """B006's column form names its late replies: the reply and its request go by rows, and the rows before and
    after are checked once more on the columns (no halving down to it)."""
    chunks = with_late_replies(4000, [0.5])
    checks, blocks_in = counted(monkeypatch)
    items, linter = columnar_steps(chunks)
    assert [f.code for f in linter.findings] == ["B006"]
    blocks = [x for x in items if type(x) is Block]
    by_rows = [b for b in blocks if b.linted_by_rows]
    assert [len(b) for b in by_rows] == [2]  # the late reply and its request
    (request, reply) = by_rows[0].records()
    assert reply.request is not None and reply.findings and reply.findings[0].code == "B006"
    assert len(checks) == len(blocks_in) + 2  # the Block that held it, then the rows before and after it
