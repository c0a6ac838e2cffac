"""The linter's column form (rs30x_sniff.lint.batch) finds what the record path finds, rule by rule.

Each case hides one anomaly in clean traffic that the columnar path takes as Blocks; the findings, the
records' findings and the linter's memory must match the record path's, and the anomaly's rule must
have spoken (so a column form that misses it fails here).
"""

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.decode import blocks as blocks_module
from rs30x_sniff.lint import batch
from rs30x_sniff.lint.registry import RULES, Registry, Rule, frame, rule
from rs30x_sniff.protocol.wire import (
    FLAG_REBOOT, RETURN_HEADER, byte_time, encode_command, encode_long, encode_read, encode_return, encode_short)
from tests.decode.test_columnar import columnar_path, record_key, record_path

BT = byte_time(115200)
SERVOS = (1, 2, 3, 4)


def _goal(pos: int, gt: int = 50) -> bytes:
    return pos.to_bytes(2, "little", signed=True) + gt.to_bytes(2, "little")


def clean_cycle(cycle: int, sid: int) -> list[bytes]:
    """One cycle of a healthy bus: goals to every servo (slow, small steps), then one poll and its return."""
    goals = encode_long(30, [(v, _goal(100 + (cycle % 50) * 2)) for v in SERVOS])
    ret = encode_return(sid, 42, _goal(100 + (cycle % 50) * 2) + bytes(14))
    return [goals, encode_short(sid, 0x09, 0, b"", length=0, count=1), ret]


# Each anomaly: (rule it trips, frames to put in place of one cycle's poll, extra gap inside a frame).
ANOMALIES = {
    "P001": [encode_short(2, 0x89, 0, b"", length=0, count=1), encode_return(2, 42, bytes(18))],
    "P005": [encode_long(30, [(v, _goal(120)) for v in (1, 2, 200)])],
    "P004": [encode_long(30, [(v, _goal(120)) for v in (1, 2, 2)])],
    "P012": [encode_short(2, 0x09, 0, b"", length=0, count=1), frame(2, 0, 42, 18, 2, *bytes(18), header=RETURN_HEADER)],
    "B004": [encode_short(2, 0x09, 0, b"", length=0, count=1), encode_return(3, 42, bytes(18))],
    "B005": [encode_short(2, 0x09, 0, b"", length=0, count=1), encode_return(2, 30, bytes(4))],
    "M001": [encode_short(2, 0x00, 42, b"\x00\x00")],
    "M002": [encode_short(2, 0x00, 34, b"\x00")],
    "M003": [encode_short(2, 0x00, 30, (2000).to_bytes(2, "little", signed=True))],
    "M004": [encode_short(2, 0x00, 31, b"\x00")],
    "Q007": [encode_long(30, [(v, _goal(-1400, 1)) for v in SERVOS])],
    "B006": "late reply",
    "F004": "gap inside a frame",
    # Issue 32: a second return from the ID asked, within the window; a return from another ID 80 ms after an
    # answered poll (B003, which names the poll: the linter's latest request after a Block); reboots before any
    # flash write of a baud_rate or servo_id change (said at the reboot).
    "B009": [encode_short(2, 0x09, 0, b"", length=0, count=1), encode_return(2, 42, bytes(18)),
             encode_return(2, 42, bytes(18))],
    "B003": "late return from another ID",
    "Q001": [encode_short(2, 0x00, 6, b"\x04"), encode_command(2, FLAG_REBOOT)],
    "Q002": [encode_short(2, 0x00, 4, b"\x07"), encode_command(7, FLAG_REBOOT)],
}


def capture(anomaly: str, at: int, cycles: int = 300, timed: bool = True, more: dict | None = None):
    """``cycles`` clean cycles with ``anomaly`` in cycle ``at`` (and ``more``: {cycle: anomaly})."""
    where = {at: anomaly, **(more or {})}
    chunks, t = [], 1.0
    for cycle in range(cycles):
        frames = clean_cycle(cycle, SERVOS[cycle % len(SERVOS)])
        extra = ANOMALIES[where[cycle]] if cycle in where else None
        if isinstance(extra, list):
            frames = frames[:1] + extra
        for k, frame in enumerate(frames):
            if extra == "gap inside a frame" and k == 0:
                chunks += [(frame[:5], t), (frame[5:], t + 5 * BT + 10 * BT)]
                t += len(frame) * BT + 10 * BT + 0.0001
                continue
            if extra == "late reply" and k == 2:
                t += 0.01
            chunks.append((frame, t if timed else None))
            t += len(frame) * BT + 0.0001
            if extra == "late return from another ID" and k == 2:
                t += 0.08
                late = encode_return(3, 42, bytes(18))
                chunks.append((late, t if timed else None))
                t += len(late) * BT + 0.0001
        t = max(t, 1.0 + (cycle + 1) * 0.003)
    return chunks


def compare(chunks, groups=(500,)):
    a, da = record_path(chunks, lint=True)
    b, db, blocks = columnar_path(chunks, list(groups), lint=True)
    assert [record_key(r) for r in b] == [record_key(r) for r in a]
    found = [(f.code, f.offset, f.message, f.id) for f in da.linter.findings]
    assert [(f.code, f.offset, f.message, f.id) for f in db.linter.findings] == found
    assert [(f.code, f.offset) for f in db.linter.close()] == [(f.code, f.offset) for f in da.linter.close()]
    shadows = lambda d: {i: tuple(getattr(s, k) for k in s.__slots__) for i, s in d.linter.servos.items()}  # noqa: E731
    assert shadows(db) == shadows(da)
    assert list(db.linter.servos) == list(da.linter.servos)
    assert db.linter.ids == da.linter.ids and db.linter.records == da.linter.records
    times = lambda d: (d.linter.state_of("F007").times.spacings, d.linter.state_of("F007").times.last)  # noqa: E731
    assert times(db) == times(da)
    return blocks, {f[0] for f in found}


def test_every_rule_declares_its_column_form():
    for r in RULES:
        assert r.column in ("header", "silent") or callable(r.column), r.code


def test_a_rule_without_a_column_form_is_an_error_when_it_registers():
    doc = "## What it does\nx\n## Why it matters\ny\n## Example\nz\n"
    with pytest.raises(ValueError, match="column"):
        rule("Q990", "scratch-rule", "info", "A scratch rule.", doc, kinds=("short",))(lambda lint, rec, ev: None)
    assert "Q990" not in RULES
    with pytest.raises(ValueError, match="column"):
        Registry().add(Rule("Q991", "scratch-rule", "info", "s", doc, ("short",), print, column="sometimes"))


def test_clean_traffic_is_linted_on_the_columns(monkeypatch):
    calls = []
    real = batch.BlockLinter.quiet
    monkeypatch.setattr(batch.BlockLinter, "quiet", lambda self, blk: calls.append(real(self, blk)) or calls[-1])
    blocks, codes = compare(capture("P001", at=-1))
    assert blocks and calls and all(calls) and not codes


@pytest.mark.parametrize("anomaly", sorted(ANOMALIES))
@pytest.mark.parametrize("at", [3, 150, 299])
def test_an_anomaly_in_clean_traffic(anomaly, at):
    blocks, codes = compare(capture(anomaly, at))
    assert anomaly in codes and blocks


@pytest.mark.parametrize("anomaly", ["P001", "B005", "M003", "Q007"])
def test_untimed(anomaly):
    blocks, codes = compare(capture(anomaly, 100, timed=False))
    assert anomaly in codes and blocks


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(picks=st.dictionaries(st.integers(0, 119), st.sampled_from(sorted(ANOMALIES)), max_size=6),
       groups=st.lists(st.integers(1, 400), min_size=1, max_size=3), tiny=st.booleans(), timed=st.booleans())
def test_anomalies_anywhere(monkeypatch, picks, groups, tiny, timed):
    monkeypatch.setattr(blocks_module, "MIN_BLOCK", 1 if tiny else 32)
    compare(capture("P001", -1, cycles=120, timed=timed, more=picks), groups)


def test_blocks_longer_than_the_spacings_f007_keeps():
    """F007 keeps the last 512 byte spacings: a Block of thousands of rows adds only its last ones."""
    chunks = capture("P001", at=-1, cycles=600)
    assert len(chunks) > 2 * 512
    blocks, codes = compare(chunks, groups=(len(chunks),))
    assert blocks and not codes


# ---- servos of mixed models: long packets planned per servo's model ---------------------------------------------
def mixed_models(chunks: list, timed: bool = True) -> list:
    """``chunks`` after a model-number read of each servo: odd IDs answer RS304MD (0x3040), even RS303MR (0x3030),
    so long packets go to servos of mixed models (Block.vid_models) and Q007 holds each to its own top speed."""
    head, t = [], 0.1
    for v in SERVOS:
        for frame in (encode_short(v, 0x0F, 0, b"", length=2, count=0),
                      encode_return(v, 0, (0x3040 if v % 2 else 0x3030).to_bytes(2, "little"))):
            head.append((frame, t if timed else None))
            t += len(frame) * BT + 0.0001
    return head + chunks


@pytest.fixture
def quiet_calls(monkeypatch):
    """(Block has servos of mixed models, quiet's verdict) of each BlockLinter.quiet call."""
    calls = []
    real = batch.BlockLinter.quiet

    def quiet(self, blk):
        calls.append((blk.vid_models is not None, real(self, blk)))
        return calls[-1][1]

    monkeypatch.setattr(batch.BlockLinter, "quiet", quiet)
    return calls


def test_mixed_models_are_linted_on_the_columns(quiet_calls):
    blocks, codes = compare(mixed_models(capture("P001", at=-1)))
    mixed = [verdict for is_mixed, verdict in quiet_calls if is_mixed]
    assert blocks and mixed and all(mixed) and not codes  # every Block of mixed models stays on the columns


@pytest.mark.parametrize("anomaly", sorted(a for a in ANOMALIES if a not in ("B006", "F004")))
@pytest.mark.parametrize("at", [3, 150])
def test_an_anomaly_among_servos_of_mixed_models(quiet_calls, anomaly, at):
    blocks, codes = compare(mixed_models(capture(anomaly, at)))
    assert anomaly in codes and any(is_mixed for is_mixed, _ in quiet_calls)


def test_q007_holds_each_servo_of_a_long_packet_to_its_own_models_speed():
    """From 10 deg (the cycle's goal) to -15 deg in 50 ms, 500 deg/s: within the RS303MR's top speed (60 deg in
    0.11 s, 545 deg/s), past the RS304MD's (0.16 s, 375 deg/s), so Q007 names the odd IDs (RS304MD) only, on
    both paths."""
    ANOMALIES["Q007-mixed"] = [encode_long(30, [(v, _goal(-150, 5)) for v in SERVOS])]
    try:
        a, da = record_path(mixed_models(capture("Q007-mixed", 100)), lint=True)
        blocks, codes = compare(mixed_models(capture("Q007-mixed", 100)))
    finally:
        del ANOMALIES["Q007-mixed"]
    assert "Q007" in codes
    assert sorted({f.id for f in da.linter.findings if f.code == "Q007"}) == [v for v in SERVOS if v % 2]


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(picks=st.dictionaries(st.integers(0, 119), st.sampled_from(sorted(ANOMALIES)), max_size=6),
       groups=st.lists(st.integers(1, 400), min_size=1, max_size=3), timed=st.booleans())
def test_anomalies_anywhere_among_servos_of_mixed_models(picks, groups, timed):
    compare(mixed_models(capture("P001", -1, cycles=120, timed=timed, more=picks), timed), groups)
