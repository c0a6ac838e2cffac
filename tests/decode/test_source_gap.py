"""A source's gap (a port lost and found again, issue 26) is a seam, not a fault: wherever it falls and however
short it is, the only finding is F010 at the gap, nothing is paired across it, and every byte is in one event."""

from __future__ import annotations

from functools import lru_cache

from hypothesis import given, settings, strategies as st

from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.protocol.chunks import SourceGap
from rs30x_sniff.sim import run
from rs30x_sniff.sinks.pipeline import decode_records, drive
from rs30x_sniff.sinks.stats import CaptureStats


@lru_cache(maxsize=None)
def traffic(name: str) -> tuple:
    return tuple(run(name, duration=1.5, seed=3))


def with_gap(chunks, cut: int, seconds: float) -> list:
    """The chunks with the line lost after chunk ``cut`` for ``seconds`` (the later times moved on by it)."""
    before, after = list(chunks[:cut]), [(d, t + seconds) for d, t in chunks[cut:]]
    lost_at = before[-1][1] if before else None
    return [*before, SourceGap(after[0][1], lost_at, "the port was gone (test)"), *after]


@settings(max_examples=25, deadline=None)
@given(name=st.sampled_from(["hexapod", "setup"]), where=st.floats(0.05, 0.95), seconds=st.floats(0.001, 20.0),
       columnar=st.booleans())
def test_a_gap_anywhere_is_one_seam_and_no_fault(name, where, seconds, columnar):
    chunks = traffic(name)
    cut = max(1, min(len(chunks) - 1, int(len(chunks) * where)))
    linter = Linter(LintConfig())
    stats = CaptureStats(115200)
    drive(with_gap(chunks, cut, seconds), Decoder(None, linter, columnar=columnar), stats)
    plain = Linter(LintConfig())
    drive([(d, t) for d, t in chunks], Decoder(None, plain, columnar=columnar))
    # The gap adds its seam and takes away nothing but what straddled it: a request before the gap whose reply
    # came after is no longer paired, and is not reported missing either.
    got = [f.code for f in linter.findings]
    assert got.count("F010") == [f.code for f in plain.findings].count("F010") + 1
    assert set(got) - {"F010"} <= {f.code for f in plain.findings}
    assert stats.as_dict()["segments"] == 2
    seam = next(f for f in linter.findings if f.code == "F010")
    assert "the port was gone (test)" in seam.message


def test_every_byte_is_in_one_event_around_the_gap():
    chunks = traffic("hexapod")
    gapped = with_gap(chunks, len(chunks) // 2, 2.0)
    recs = list(decode_records(gapped))
    data = b"".join(d for d, _ in chunks)
    assert b"".join(r.event.raw for r in recs) == data
    assert [r.event.raw for r in recs] == [r.event.raw for r in decode_records(chunks)]  # the same frames


def test_a_gap_before_any_byte_parts_nothing():
    chunks = traffic("hexapod")
    linter = Linter(LintConfig())
    drive([SourceGap(0.0, None, "x"), *chunks], Decoder(None, linter), CaptureStats(115200))
    assert "F010" not in {f.code for f in linter.findings}
