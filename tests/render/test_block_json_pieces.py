"""decode --format jsonl writes a Block's lines in pieces (render.block_json.block_json_pieces): the pieces make the
Block's whole text, in order, and none holds more than its share of lines, whatever the Block's length."""

import sys
from pathlib import Path

import pytest

from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.lint import Linter
from rs30x_sniff.render.block_json import block_json_lines, block_json_pieces

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from traffic import hexapod_frames  # noqa: E402


@pytest.mark.parametrize("lines", [1, 7, 1024])
@pytest.mark.parametrize("lint", [True, False])
def test_pieces_make_the_whole_text(lines, lint):
    dec = Decoder(None, Linter() if lint else None, columnar=True)
    steps = [dec.feed_many(hexapod_frames(2000)), dec.close()]
    blocks = [b for step in steps for b in step if type(b) is Block]
    assert any(not b.linted_by_rows for b in blocks)  # the template path is the one cut in pieces
    for blk in blocks:
        for only, rows in ((None, None), ({1, 2}, list(range(0, len(blk), 3)))):
            pieces = list(block_json_pieces(blk, only, rows, lines=lines))
            assert "".join(pieces) == block_json_lines(blk, only, rows=rows)
            if not blk.linted_by_rows:
                assert all(0 < p.count("\n") <= lines for p in pieces)
                shown = len(blk) if rows is None else len(rows)
                assert len(pieces) == -(-shown // lines)
