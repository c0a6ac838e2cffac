"""JSON from templates (rs30x_sniff.render.block_json), a Block's lines and a single Record's, is byte for byte the
records' own JSON (render.record_json_text)."""

import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.protocol import memmap
from rs30x_sniff.decode import blocks
from rs30x_sniff.render.block_json import block_json_lines, record_json_line
from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.render.records import record_json_text
from rs30x_sniff.sim import scenarios
from tests.render.test_block_text import odd_traffic
from tests.decode.test_columnar import traffic
from tests.decode.test_properties import frames

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
from traffic import hexapod_frames  # noqa: E402

ONLY = [None, {1}, {2, 3}]


def check_blocks(chunks, lint: bool, group: int = 400, options=None) -> int:
    """Decode columnar; for every Block (before anything builds its records) compare the template
    lines with the records' own, whole, for some servos, compact and for a subset of rows."""
    dec = Decoder(options, Linter() if lint else None, columnar=True)
    seen = 0
    steps = [dec.feed_many(chunks[k:k + group]) for k in range(0, len(chunks), group)] + [dec.close()]
    for step in steps:
        for blk in step:
            if type(blk) is not Block:
                continue
            quiet = not blk.linted_by_rows
            rows = list(range(0, len(blk), 3))
            got = [(block_json_lines(blk, only, compact), block_json_lines(blk, only, compact, rows))
                   for only in ONLY for compact in (False, True)]
            recs = blk.records()
            want = [("".join(record_json_text(r, only, compact) + "\n" for r in recs),
                     "".join(record_json_text(recs[k], only, compact) + "\n" for k in rows))
                    for only in ONLY for compact in (False, True)]
            assert got == want
            seen += quiet
    return seen


@pytest.mark.parametrize("timed", [True, False])
@pytest.mark.parametrize("lint", [True, False])
def test_hexapod_traffic(timed, lint):
    chunks = [(d, t if timed else None) for d, t in hexapod_frames(3000)]
    assert check_blocks(chunks, lint) > 0


@pytest.mark.parametrize("name", sorted(scenarios.SCENARIOS))
def test_scenarios(name):
    check_blocks(list(scenarios.run(name, duration=2.0)), lint=True)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10**6), n=st.integers(1, 200), timed=st.booleans(), rare=st.sampled_from([0.3, 0.05]),
       lint=st.booleans(), mixed=st.booleans())
def test_random_traffic(monkeypatch, seed, n, timed, rare, lint, mixed):
    monkeypatch.setattr(blocks, "MIN_BLOCK", 1)
    monkeypatch.setattr(memmap, "MAX_CACHED", 8)  # the models' template caches fill and clear too
    # mixed: servo 2 is an RS304MD among RS303MRs, so a long packet's records have two models
    check_blocks(traffic(seed, n, timed=timed, gaps=True, faults=False, rare=rare), lint, group=50,
                 options=DecodeOptions(models={2: "RS304MD"}) if mixed else None)


def test_mixed_models_are_written_from_templates(monkeypatch):
    """A long packet to servos of two models is a template's row, not a Record's (no Record is built)."""
    chunks = traffic(5, 400, timed=True, gaps=False, faults=False, rare=0.0)
    dec = Decoder(DecodeOptions(models={2: "RS304MD"}), None, columnar=True)
    step = dec.feed_many(chunks)
    mixed = [b for b in step if type(b) is Block and b.vid_models is not None]
    assert mixed
    built = []
    monkeypatch.setattr(Block, "records", lambda self: built.append(self) or [])
    for blk in mixed:
        assert block_json_lines(blk).count("\n") == len(blk)
    assert not built


def test_a_write_and_a_return_with_the_same_header_bytes():
    """FA AF 02 00 1E 04 01 (a write of 4 bytes at 30) and FD DF 02 00 1E 04 01 (a return of the same)
    share everything after the sync bytes: their templates must not."""
    from rs30x_sniff.protocol.wire import byte_time, encode_read, encode_return, encode_short

    bt = byte_time(115200)
    chunks, t = [], 0.0
    for k in range(200):
        for frame in (encode_short(2, 0x00, 30, bytes([k, 0, 5, 0])), encode_read(2, 30, 4),
                      encode_return(2, 30, bytes([k, 0, 5, 0]))):
            chunks.append((frame, t))
            t += len(frame) * bt + 0.0001
    assert check_blocks(chunks, lint=True) > 0
    assert check_blocks([(d, None) for d, _ in chunks], lint=False) > 0


# ---- record_json_line: the record path's JSON ----------------------------------------------------
def check_records(chunks, lint: bool = False, options=None) -> int:
    """Decode record by record (a live port's path); every record's record_json_line held to
    record_json_text for each ``only``, spaced and compact, twice (the second from the cached
    template). Returns how many records were written from a template without a dict (as seen by
    their fields: the template path builds no Field objects)."""
    dec = Decoder(options, Linter() if lint else None)
    templated = 0
    for step in [dec.feed(d, t) for d, t in chunks] + [dec.close()]:
        for rec in step:
            built = rec._fields is not None
            for only in ONLY:
                for compact in (False, True):
                    want = record_json_text(rec, only, compact)
                    assert record_json_line(rec, only, compact) == want, (only, compact, rec.event)
                    assert record_json_line(rec, only, compact) == want
            templated += not built and rec._fields is None and not rec.findings
    return templated


@pytest.mark.parametrize("lint", [True, False])
def test_record_json_of_hexapod(lint):
    chunks = hexapod_frames(2000)
    assert check_records(chunks, lint) > 0.9 * len(chunks)
    assert check_records([(d, None) for d, _ in chunks], lint) > 0.9 * len(chunks)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 10**6), n=st.integers(1, 200), timed=st.booleans(), gaps=st.booleans(),
       faults=st.booleans(), rare=st.sampled_from([0.3, 0.05]), lint=st.booleans(), mixed=st.booleans())
def test_record_json_of_random_traffic(monkeypatch, seed, n, timed, gaps, faults, rare, lint, mixed):
    # Missing, unsolicited and extra replies, bad Sums, garbage, findings, servos of two models.
    from rs30x_sniff.decode.decoder import DecodeOptions

    monkeypatch.setattr(memmap, "MAX_CACHED", 8)  # the models' template caches fill and clear too
    check_records(traffic(seed, n, timed=timed, gaps=gaps, faults=faults, rare=rare), lint,
                  DecodeOptions(models={2: "RS304MD"}) if mixed else None)


@settings(max_examples=60, deadline=None)
@given(st.lists(frames, max_size=60), st.booleans())
def test_record_json_of_arbitrary_frames(pieces, lint):
    check_records([(p, None) for p in pieces], lint)


def test_record_json_of_odd_shapes():
    import random

    assert check_records(odd_traffic(random.Random(5), 600)) > 0


def test_record_json_of_times_that_are_not_plain_floats():
    """A source may stamp numpy floats, whose repr is not their JSON: those lines come from the dict."""
    import numpy as np

    chunks = [(d, np.float64(t)) for d, t in hexapod_frames(200)]
    check_records(chunks)
