"""Capture edges and time segments, as properties of simulated traffic (issue 22, "How we know it is done").

A clean simulated capture (a scenario that lints clean) stays clean however it is cut at its start or
its end; two captures joined at a seam of the clock (times restarting, or resuming after more than
SEAM_GAP_S of silence) lint as the parts do (offsets shifted) plus one F010 capture-seam finding, and
their figures are the parts' figures. Everything goes through the library's one drive loop
(pipeline.Pipeline: Decoder + Linter, CaptureStats as a sink), record by record and columnar.

The last property reads the same capture through the CLI with its times in other units.
"""

from __future__ import annotations

import json
import re
from collections import Counter
from functools import lru_cache

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.decode.pairing import UNKNOWN, UNSEEN
from rs30x_sniff.protocol.events import CAPTURE_END, CAPTURE_START
from rs30x_sniff.decode.framing import SEAM_BACK_S, SEAM_GAP_S
from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.sinks.pipeline import GROUP_BYTES, Pipeline, Sink
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.sim import SCENARIOS, run
from rs30x_sniff.sinks.stats import CaptureStats, LatencyHistogram
from rs30x_sniff.protocol.wire import byte_time

BAUD = 115200
BT = byte_time(BAUD)

# Scenarios that lint clean (Scenario.expects is empty) and those built to show a fault; short runs.
CLEAN = ("hexapod", "setup")
FAULTY = ("silent-servo", "noise", "bad-checksum", "duplicate-id", "request-before-return")
DURATIONS = {"hexapod": 1.5, "setup": None, "silent-servo": 1.5, "noise": 1.5, "bad-checksum": 1.5,
             "duplicate-id": 1.5, "request-before-return": 1.5}
SEEDS = st.integers(0, 3)
SERIOUS = ("warning", "error")

FEW = settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ---- captures and decoding ----------------------------------------------------------------------
@lru_cache(maxsize=None)
def capture(name: str, seed: int) -> tuple[tuple[bytes, float], ...]:
    """A scenario's simulated capture as (bytes, t) chunks (one frame each, t of its first byte)."""
    return tuple(run(name, baud=BAUD, seed=seed, duration=DURATIONS[name]))


class Collect(Sink):
    """Every record of the run, in wire order (Blocks arrive expanded: no takes_blocks)."""

    def __init__(self) -> None:
        self.records: list = []

    def batch(self, step) -> None:
        self.records += step


class Result:
    def __init__(self, findings, stats, records, nbytes):
        self.findings = findings
        self.stats = stats
        self.records = records
        self.bytes = nbytes

    def serious(self):
        return [f for f in self.findings if f.severity in SERIOUS]


def decode(chunks, columnar: bool = False, group_bytes: int = GROUP_BYTES) -> Result:
    """``chunks`` through Pipeline(Decoder(linter), [CaptureStats, Collect])."""
    chunks = list(chunks)
    linter = Linter(LintConfig(baud=BAUD))
    stats = CaptureStats(BAUD)
    rec = Collect()
    Pipeline(Decoder(DecodeOptions(baud=BAUD), linter, columnar=columnar), [stats, rec], group_bytes).run(chunks)
    return Result(list(linter.findings), stats, rec.records, sum(len(d) for d, _ in chunks))


@lru_cache(maxsize=None)
def whole(name: str, seed: int) -> Result:
    return decode(capture(name, seed))


def cut(chunks, start: int, end: int | None = None) -> list[tuple[bytes, float]]:
    """The bytes [start, end) of a capture as chunks: a chunk cut at its start has its time advanced by
    the byte times cut off (the times of the bytes kept are unchanged)."""
    out = []
    pos = 0
    for data, t in chunks:
        a, b = pos, pos + len(data)
        pos = b
        lo, hi = max(a, start), b if end is None else min(b, end)
        if lo < hi:
            out.append((data[lo - a:hi - a], t + (lo - a) * BT))
    return out


def shifted(chunks, dt: float) -> list[tuple[bytes, float]]:
    return [(d, t + dt) for d, t in chunks]


def last_byte_t(chunks) -> float:
    data, t = chunks[-1]
    return t + (len(data) - 1) * BT


def show(findings) -> str:
    return "\n".join(f"  {f.code} {f.severity} @{f.offset} t={f.t} id={f.id}: {f.message}" for f in findings)


def key(f, offset_shift: int = 0):
    """What a finding says, its stream offsets (its own and any '@N' in its message) shifted."""
    message = re.sub(r"@(\d+)", lambda m: f"@{int(m.group(1)) + offset_shift}", f.message)
    return (f.code, f.severity, f.offset + offset_shift, f.t, f.id, message)


def joined(a, b, mode: str, gap: float):
    """Capture ``b`` after ``a``: its times as they are (restart) or resumed ``gap`` s after ``a``'s last byte."""
    a, b = list(a), list(b)
    if mode == "gap":
        b = shifted(b, last_byte_t(a) + gap - b[0][1])
    else:
        assert b[0][1] < a[-1][1] - SEAM_BACK_S  # a restart the decoder must see
    return a, b


def test_the_clean_scenarios_lint_clean():
    """The ground the properties stand on: the chosen scenarios, uncut, raise no finding at all, and
    the fault scenarios do raise some (so the joined-findings property compares something)."""
    for name in CLEAN:
        assert not SCENARIOS[name].expects
        for seed in range(4):
            for columnar in (False, True):
                r = decode(capture(name, seed), columnar)
                assert r.findings == [], f"{name} seed {seed}:\n{show(r.findings)}"
                assert r.stats.latency.count > 0 and r.stats.timed
    for name in FAULTY:
        assert whole(name, 0).findings, name


# ---- 1. a capture started at any byte of its first frames ---------------------------------------
def _check_start(name: str, seed: int, k: int, columnar: bool) -> None:
    full = whole(name, seed)
    r = decode(cut(capture(name, seed), k), columnar)
    assert not r.serious(), f"{name} seed {seed} started at byte {k} (columnar={columnar}):\n{show(r.serious())}"
    first = r.records[0]
    starts = [rec.event[0] for rec in full.records]
    if k not in starts:  # the capture cut a frame: its tail is garbage 'capture-start'
        assert first.kind == "garbage" and first.event.reason == CAPTURE_START, (k, first)
    else:
        orig = full.records[starts.index(k)]
        if orig.kind in ("ack", "nack") and first.kind == "garbage":
            # A lone ACK/NACK byte first: without its request it is one byte like any noise, the
            # tail of something the capture cut (no finding either way).
            assert first.event.reason == CAPTURE_START, (k, first)
            return
        assert first.kind == orig.kind
        if not orig.is_request and orig.kind != "garbage" and orig.status == "paired":
            assert first.status == UNSEEN, (k, first.status)  # it answered a request before the capture


def _first_frames_end(name: str, seed: int, n: int = 3) -> int:
    return whole(name, seed).records[n - 1].event.end_offset


@FEW
@given(name=st.sampled_from(CLEAN), seed=SEEDS, columnar=st.booleans(), data=st.data())
def test_start_at_any_byte_of_the_first_frames_is_clean(name, seed, columnar, data):
    k = data.draw(st.integers(0, _first_frames_end(name, seed)), label="k")
    _check_start(name, seed, k, columnar)


@pytest.mark.parametrize("name", CLEAN)
def test_start_at_every_byte_of_the_first_frames_is_clean(name):
    """The same, exhaustively for seed 0 (the issue says every byte offset)."""
    for k in range(_first_frames_end(name, 0) + 1):
        _check_start(name, 0, k, columnar=False)


# ---- 2. a capture ended right after any request -------------------------------------------------
def _check_end(name: str, seed: int, i: int, columnar: bool) -> None:
    full = whole(name, seed)
    req = full.records[i]
    end = req.event.end_offset
    r = decode(cut(capture(name, seed), 0, end), columnar)
    assert not r.serious(), (f"{name} seed {seed} ended after the request at {req.event[0]}..{end} "
                             f"(columnar={columnar}):\n{show(r.serious())}")
    last = [rec for rec in r.records if rec.event[0] == req.event[0]]
    assert len(last) == 1 and last[0].event.end_offset == end
    if req.expects is not None:  # still in its reply time at the end: unknown, not missing
        assert last[0].status == UNKNOWN, (name, seed, i, last[0].status)


def _request_indices(name: str, seed: int) -> list[int]:
    return [i for i, rec in enumerate(whole(name, seed).records) if rec.is_request]


@FEW
@given(name=st.sampled_from(CLEAN), seed=SEEDS, columnar=st.booleans(), data=st.data())
def test_end_right_after_any_request_is_clean(name, seed, columnar, data):
    i = data.draw(st.sampled_from(_request_indices(name, seed)), label="request index")
    _check_end(name, seed, i, columnar)


def test_end_right_after_every_request_of_setup_is_clean():
    """Exhaustively on the setup session (writes with ACK, flash, reboot, reads; seed 0)."""
    for i in _request_indices("setup", 0):
        _check_end("setup", 0, i, columnar=False)


# ---- 3. two captures joined at a seam -----------------------------------------------------------
MODES = st.sampled_from(["restart", "gap"])
GAPS = st.floats(SEAM_GAP_S + 0.01, 5000.0)
GROUPS = st.sampled_from([GROUP_BYTES, 64, 700])


def _check_joined_findings(names, seeds, mode, gap, columnar, group_bytes):
    a, b = joined(capture(names[0], seeds[0]), capture(names[1], seeds[1]), mode, gap)
    ra, rb = decode(a), decode(b)
    rab = decode(a + b, columnar, group_bytes)
    seam = [f for f in rab.findings if f.code == "F010"]
    where = f"{names[0]}#{seeds[0]} + {names[1]}#{seeds[1]}, {mode} (gap {gap}), columnar={columnar}/{group_bytes}"
    assert len(seam) == 1, f"{where}: F010 findings:\n{show(seam)}"
    assert seam[0].severity == "info" and seam[0].name == "capture-seam"
    assert seam[0].offset == ra.bytes, where
    assert seam[0].t == pytest.approx(b[0][1], abs=1e-9), where
    expected = Counter(key(f) for f in ra.findings) + Counter(key(f, ra.bytes) for f in rb.findings)
    got = Counter(key(f) for f in rab.findings if f is not seam[0])
    assert got == expected, (f"{where}:\nonly in the joined capture:\n{show_keys(got - expected)}\n"
                             f"only in the parts:\n{show_keys(expected - got)}")


def show_keys(c: Counter) -> str:
    return "\n".join(f"  {k} x{n}" for k, n in sorted(c.items(), key=lambda kv: kv[0][2])) or "  (none)"


@FEW
@given(names=st.tuples(st.sampled_from(CLEAN), st.sampled_from(CLEAN)), seeds=st.tuples(SEEDS, SEEDS),
       mode=MODES, gap=GAPS, columnar=st.booleans(), group_bytes=GROUPS)
def test_joined_clean_captures_lint_as_the_parts_plus_one_seam(names, seeds, mode, gap, columnar, group_bytes):
    _check_joined_findings(names, seeds, mode, gap, columnar, group_bytes)


@FEW
@given(names=st.tuples(st.sampled_from(FAULTY + CLEAN), st.sampled_from(FAULTY)), seeds=st.tuples(SEEDS, SEEDS),
       mode=MODES, gap=GAPS, columnar=st.booleans())
def test_joined_faulty_captures_lint_as_the_parts_plus_one_seam(names, seeds, mode, gap, columnar):
    """The same with parts that have findings of their own: each lands at its offset, shifted."""
    _check_joined_findings(names, seeds, mode, gap, columnar, GROUP_BYTES)


@FEW
@given(names=st.tuples(st.sampled_from(CLEAN), st.sampled_from(CLEAN)), seeds=st.tuples(SEEDS, SEEDS),
       mode=MODES, gap=GAPS, side=st.sampled_from(["end of the first", "start of the second"]),
       columnar=st.booleans(), data=st.data())
def test_joined_with_a_frame_cut_at_the_seam_is_clean(names, seeds, mode, gap, side, columnar, data):
    a, b = list(capture(names[0], seeds[0])), list(capture(names[1], seeds[1]))
    if side == "end of the first":
        d = data.draw(st.integers(1, len(a[-1][0]) - 1), label="bytes dropped")
        a = cut(a, 0, sum(len(x) for x, _ in a) - d)
    else:
        d = data.draw(st.integers(1, len(b[0][0]) - 1), label="bytes dropped")
        b = cut(b, d)
    a, b = joined(a, b, mode, gap)
    nbytes = sum(len(x) for x, _ in a)
    r = decode(a + b, columnar)
    assert not r.serious(), f"{names}, {seeds}, {mode}, {side} cut by {d}:\n{show(r.serious())}"
    seam = [f for f in r.findings if f.code == "F010"]
    assert len(seam) == 1 and seam[0].offset == nbytes, show(r.findings)
    garbage = [rec for rec in r.records if rec.kind == "garbage"]
    assert len(garbage) == 1, garbage
    g = garbage[0].event
    if side == "end of the first":
        assert g.reason == CAPTURE_END and g[0] + len(g.raw) == nbytes, g
    else:
        assert g.reason == CAPTURE_START and g[0] == nbytes, g


# ---- 3. figures of the joined capture -----------------------------------------------------------
def _merged(h1: LatencyHistogram, h2: LatencyHistogram) -> LatencyHistogram:
    m = h1 + h2
    assert m.count == h1.count + h2.count and m.max == max(x for x in (h1.max, h2.max) if x is not None)
    return m


JOINS = dict(names=st.tuples(st.sampled_from(CLEAN), st.sampled_from(CLEAN)), seeds=st.tuples(SEEDS, SEEDS),
             mode=MODES, gap=GAPS, columnar=st.booleans())


@FEW
@given(**JOINS)
def test_joined_figures_counts_and_latencies_are_the_parts(names, seeds, mode, gap, columnar):
    a, b = joined(capture(names[0], seeds[0]), capture(names[1], seeds[1]), mode, gap)
    sa, sb = decode(a).stats, decode(b).stats
    s = decode(a + b, columnar).stats
    assert s.timed
    assert s.bytes == sa.bytes + sb.bytes
    assert s.records == sa.records + sb.records
    assert s.by_kind == sa.by_kind + sb.by_kind
    assert s.garbage_bytes == 0
    m = _merged(sa.latency, sb.latency)
    assert s.latency.count == m.count
    assert s.latency.bins == m.bins
    for p in (50, 95, 99):
        assert s.latency.percentile(p) == m.percentile(p)
    assert s.latency.max == m.max
    for sid in set(sa.servos) | set(sb.servos):
        got, parts = s.servos[sid], [x.servos[sid] for x in (sa, sb) if sid in x.servos]
        assert got.reads == sum(p.reads for p in parts) and got.returns == sum(p.returns for p in parts)
        assert got.missing == 0
    assert s.bus_load is None or 0.0 <= s.bus_load <= 1.0


@FEW
@given(**JOINS)
def test_joined_figures_are_segment_aware(names, seeds, mode, gap, columnar):
    """Durations add up, and load and rates are measured within segments (not across the seam's gap or
    back-jump): CaptureStats by time segment. Kept apart from the counts above so that a failure here
    says "the figures are not segment-aware" on its own."""
    a, b = joined(capture(names[0], seeds[0]), capture(names[1], seeds[1]), mode, gap)
    sa, sb = decode(a).stats, decode(b).stats
    s = decode(a + b, columnar).stats
    where = f"{names[0]}#{seeds[0]} + {names[1]}#{seeds[1]}, {mode} (gap {gap})"
    assert s.duration == pytest.approx(sa.duration + sb.duration, rel=1e-9), (
        f"{where}: duration {s.duration!r}, parts {sa.duration!r} + {sb.duration!r}")
    load = s.bus_load
    assert load is not None and 0.0 <= load <= 1.0, f"{where}: bus_load {load!r}"
    assert load == pytest.approx(s.line_time / (sa.duration + sb.duration), rel=1e-9), where
    for sid in set(sa.servos) & set(sb.servos):
        rates = [x.servos[sid].poll_rate for x in (sa, sb)]
        if None in rates:
            continue
        r = s.servos[sid].poll_rate
        assert r is not None and min(rates) * 0.98 <= r <= max(rates) * 1.02, f"{where}: ID {sid} {r!r} vs parts {rates}"


# ---- 4. the same capture with its times in another unit (CLI) -----------------------------------
def _has_time_unit(capsys) -> bool:
    from rs30x_sniff.cli import main

    assert main(["lint", "--help"]) == 0
    return "--time-unit" in capsys.readouterr().out


def _thex(path, chunks, scale: float, offset: float, decimals: int) -> None:
    # Times rounded to whole microseconds first, so every file holds the same instants exactly.
    lines = [f"{offset + round(t * 1e6) * scale / 1e6:.{decimals}f} {d.hex(' ')}" for d, t in chunks]
    path.write_text("\n".join(lines) + "\n")


def _same_words(a: str, b: str, exact: bool) -> bool:
    """Two messages alike: equal, or (not ``exact``) equal but for numbers that differ in their last digit."""
    if exact or a == b:
        return a == b
    num = r"-?\d+\.\d+"
    if re.sub(num, "#", a) != re.sub(num, "#", b):
        return False
    for p, q in zip(re.findall(num, a), re.findall(num, b)):
        step = 10 ** -len(p.split(".")[1])
        if abs(float(p) - float(q)) > step * 1.01:
            return False
    return True


def _close(x, y) -> bool:
    """Equal JSON values, floats to within a millionth (a figure computed from other float times)."""
    if isinstance(x, dict) and isinstance(y, dict):
        return x.keys() == y.keys() and all(_close(x[k], y[k]) for k in x)
    if isinstance(x, float) and isinstance(y, float):
        return x == pytest.approx(y, rel=1e-6)
    return x == y


UNITS = [("ms", 1e3, 0.0, 3), ("us", 1e6, 0.0, 0), ("ms", 1e3, 1_700_000_000_000.0, 3)]


@pytest.mark.parametrize("name", ["hexapod", "silent-servo", "request-before-return"])
@pytest.mark.parametrize("unit,scale,epoch,decimals", UNITS, ids=["ms", "us", "epoch-ms"])
def test_times_in_another_unit_lint_and_info_the_same(tmp_path, capsys, name, unit, scale, epoch, decimals):
    from rs30x_sniff.cli import main

    if not _has_time_unit(capsys):
        pytest.skip("lint has no --time-unit yet")
    chunks = capture(name, 0)
    ref, other = tmp_path / "s.thex", tmp_path / f"{unit}.thex"
    _thex(ref, chunks, 1.0, 0.0, 6)
    _thex(other, chunks, scale, epoch, decimals)
    anchor = epoch / scale  # the other file's times count from here, in seconds

    def run_cli(*argv):
        code = main([*argv, "--isolated", "--format", "json"])
        return code, json.loads(capsys.readouterr().out)

    c1, f1 = run_cli("lint", str(ref))
    c2, f2 = run_cli("lint", str(other), "--time-unit", unit)
    assert c1 == c2
    if name != "hexapod":
        assert f1, "the fault scenario should have findings to compare"
    assert len(f1) == len(f2)
    for x, y in zip(f1, f2):
        assert {k: v for k, v in x.items() if k not in ("file", "t", "message")} == \
            {k: v for k, v in y.items() if k not in ("file", "t", "message")}
        # Epoch times are seconds since the epoch in a float (about 0.24 us apart): a duration a message
        # prints to the microsecond may round the other way. Its words and the figures' size agree.
        assert _same_words(x["message"], y["message"], exact=not epoch), (x["message"], y["message"])
        assert y["t"] - anchor == pytest.approx(x["t"], abs=1e-6)

    c1, i1 = run_cli("info", str(ref))
    c2, i2 = run_cli("info", str(other), "--time-unit", unit)
    assert c1 == c2
    # Latencies (the bus's and each servo's) are differences of times: to within the epoch float's 0.24 us.
    lat1 = [i1["latency_s"], *(s.pop("latency_s", {}) for s in i1["servos"].values())]
    lat2 = [i2["latency_s"], *(s.pop("latency_s", {}) for s in i2["servos"].values())]
    for k in ("duration_s", "bus_load", "bytes", "records", "packets", "by_type", "servos", "findings",
              "findings_by_rule", "timed"):
        assert _close(i2.get(k), i1.get(k)), f"info {k}: {i2.get(k)!r} (in {unit}) != {i1.get(k)!r} (in s)"
    assert [x.keys() for x in lat2] == [x.keys() for x in lat1]
    for x, y in zip(lat2, lat1):
        for p in ("count", "p50", "p95", "max"):
            if p in y:
                assert x[p] == pytest.approx(y[p], abs=1.5e-6), p
