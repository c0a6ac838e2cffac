"""What the history weighs: a FrameRun counts once however many held Blocks share it; built rows weighed anew."""

from __future__ import annotations

import sys
from pathlib import Path

from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.tui.memory import HeldBytes, block_nbytes, built_nbytes, record_size, run_nbytes

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from bench.traffic import hexapod_frames  # noqa: E402


def a_block() -> Block:
    dec = Decoder(DecodeOptions(), columnar=True)
    step = list(dec.feed_many(hexapod_frames(3000))) + list(dec.close())
    return max((x for x in step if type(x) is Block), key=len)


def test_a_run_shared_by_two_blocks_counts_once():
    blk = a_block()
    half = len(blk) // 2
    if blk.answered[half - 1]:
        half += 1  # a reply stays with its request
    head, tail = blk.part(0, half), blk.part(half, len(blk))
    weighed = HeldBytes()
    weighed.add_block(head)
    weighed.add_block(tail)
    assert weighed.total == block_nbytes(head) + block_nbytes(tail) + run_nbytes(blk.run)
    weighed.drop_block(head)
    assert weighed.total == block_nbytes(tail) + run_nbytes(blk.run)
    weighed.drop_block(tail)
    assert weighed.total == 0


def test_built_rows_are_weighed_again_when_they_change():
    blk = a_block()
    weighed = HeldBytes()
    weighed.add_block(blk)
    assert weighed.built([blk]) == 0
    blk.record(3)
    one = weighed.built([blk])
    assert one == built_nbytes(blk) > 0
    blk.record(10)
    assert weighed.built([blk]) == built_nbytes(blk) > one
    weighed.drop_block(blk)
    assert weighed.total == 0


def test_records_in_and_out():
    dec = Decoder(DecodeOptions())
    recs = [r for d, t in hexapod_frames(50) for r in dec.feed(d, t)]
    weighed = HeldBytes()
    weighed.add_records(recs)
    assert weighed.total == sum(map(record_size, recs))
    weighed.drop_records(recs[:10])
    assert weighed.total == sum(map(record_size, recs[10:]))
