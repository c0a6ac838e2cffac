"""--time-format on text lines: each form's meaning, the record and column forms equal in every form, and a
capture's seams (a clock restart, a lost port, a cut) shown honestly."""

from __future__ import annotations

import io
import json
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.decode import blocks as blocks_module
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.filters import parse_filter
from rs30x_sniff.lint import Linter
from rs30x_sniff.render.times import (
    ABSOLUTE, DELTA, EPOCH, NO_TIME, RELATIVE, TIME_FORMATS, LineClock, TimeForm, delta_text, wall_text)
from rs30x_sniff.sim import run as simulate
from rs30x_sniff.sinks.lines import JsonlSink, TextSink
from rs30x_sniff.sinks.pipeline import drive

T0 = 1795832946.25  # 2026-11-28 02:29:06.25 UTC: a live port's wall-clock times
SETTINGS = settings(max_examples=25, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])



@pytest.fixture(params=[1, blocks_module.MIN_BLOCK], ids=["tiny blocks", "default blocks"])
def min_block(request, monkeypatch):
    monkeypatch.setattr(blocks_module, "MIN_BLOCK", request.param)
    return request.param


def bus(seconds: float = 0.6, t0: float = T0, scenario: str = "hexapod", seed: int = 1):
    return [(d, t0 + t) for d, t in simulate(scenario, duration=seconds, seed=seed)]


def text(chunks, mode: str, *, columnar: bool, anchor=None, lint: bool = False, **kw) -> str:
    out = io.StringIO()
    drive(iter(chunks), Decoder(DecodeOptions(), Linter() if lint else None, columnar=columnar),
          TextSink(out, times=TimeForm(mode, anchor), **kw))
    return out.getvalue()


def json_times(chunks) -> list[float | None]:
    out = io.StringIO()
    drive(iter(chunks), Decoder(DecodeOptions(), None, columnar=True), JsonlSink(out))
    return [json.loads(line)["t"] for line in out.getvalue().splitlines()]


def shown(lines: str) -> list[str]:
    """The time field of each line (the text before ' @offset')."""
    return [line[:line.index(" @")].strip() for line in lines.splitlines() if " lint  " not in line]


# ---- what each form says ----------------------------------------------------------------------
def test_each_form_of_a_wall_clock_capture(utc):
    chunks = bus()
    ts = json_times(chunks)  # JSON keeps the capture's own times: seconds since 1970 here
    assert ts[0] == pytest.approx(T0 + 0.00005, abs=1e-6) and all(t > 1e9 for t in ts)
    rel = shown(text(chunks, RELATIVE, columnar=True))
    assert rel[:2] == ["0.000000", "0.000800"]  # since the first byte, not since 1970
    assert rel == [f"{t - ts[0]:.6f}" for t in ts]
    ab = shown(text(chunks, ABSOLUTE, columnar=True))
    assert ab[:2] == ["2026-11-28 02:29:06.250050", "2026-11-28 02:29:06.250850"]
    ep = shown(text(chunks, EPOCH, columnar=True))
    assert ep[:2] == ["1795832946.250050", "1795832946.250850"] and ep == [f"{t:.6f}" for t in ts]
    assert [a[-6:] for a in ab] == [e[-6:] for e in ep]  # the same rounding of the microseconds
    de = shown(text(chunks, DELTA, columnar=True))
    assert de[:2] == ["0.000000", "0.000800"]
    assert de[1:] == [f"{b - a:.6f}" for a, b in zip(ts, ts[1:])]


def test_a_capture_timed_from_its_start_keeps_its_own_times():
    chunks = bus(t0=0.5)  # a file's own clock: the times lint, info and t: filters speak
    ts = json_times(chunks)
    assert shown(text(chunks, RELATIVE, columnar=True)) == [f"{t:.6f}" for t in ts]
    said: list[str] = []
    for mode in (ABSOLUTE, EPOCH):
        out = io.StringIO()
        form = TimeForm(mode, say=said.append)
        drive(iter(chunks), Decoder(columnar=True), TextSink(out, times=form))
        # No wall clock: never an invented date; seconds since the start, said once.
        assert shown(out.getvalue()) == [f"{t:.6f}" for t in ts] and form.shown == RELATIVE
    assert len(said) == 2 and all("not wall-clock times" in s for s in said)


def test_an_anchored_log_has_a_wall_clock(utc):
    chunks = bus(t0=0.0)
    ts = json_times(chunks)
    anchor = 1795370381.0
    ab = shown(text(chunks, ABSOLUTE, columnar=True, anchor=lambda: anchor))
    assert ab[0] == wall_text(anchor + ts[0]) and ab[0].startswith("2026-11-22 17:59:41.")
    assert shown(text(chunks, RELATIVE, columnar=True, anchor=anchor)) == [f"{t:.6f}" for t in ts]


def test_untimed_lines_say_no_time():
    data = b"".join(d for d, _ in bus())
    chunks = [(data[i:i + 300], None) for i in range(0, len(data), 300)]
    for mode in TIME_FORMATS:
        assert set(shown(text(chunks, mode, columnar=True))) == {"-"}


# ---- record form == column form ----------------------------------------------------------------
@pytest.mark.parametrize("mode", TIME_FORMATS)
@pytest.mark.parametrize("lint", [False, True], ids=["plain", "lint"])
def test_record_and_column_forms_agree(mode, lint, min_block, utc):
    chunks = bus(1.0, scenario="bad-checksum")
    want = text(chunks, mode, columnar=False, lint=lint)
    assert text(chunks, mode, columnar=True, lint=lint) == want
    assert text(chunks, mode, columnar=True, lint=lint, verbose=True) == text(chunks, mode, columnar=False,
                                                                               lint=lint, verbose=True)
    # Lines left out (--id, --filter) still count as the previous event of a delta.
    for kw in ({"ids": {2}}, {"filter": parse_filter("kind:return")}):
        assert text(chunks, mode, columnar=True, lint=lint, **kw) == text(chunks, mode, columnar=False, lint=lint,
                                                                           **kw)
    if mode == DELTA:
        only = text(chunks, mode, columnar=True, ids={2})
        every = text(chunks, mode, columnar=True)
        assert only and set(stamps(only)) <= set(stamps(every))


def stamps(lines: str) -> list[str]:
    """Each line's time and offset (a long packet's line for --id holds that servo's fields alone)."""
    return [line.split(" host ")[0].split(" servo ")[0] for line in lines.splitlines()]


def test_a_filtered_delta_is_to_the_previous_event_on_the_wire():
    chunks = bus()
    ts = json_times(chunks)
    every = text(chunks, DELTA, columnar=True).splitlines()
    returns = text(chunks, DELTA, columnar=True, filter=parse_filter("kind:return")).splitlines()
    assert returns and all(line in every for line in returns)  # the same delta as among every line
    # A return follows its request by its request's length and the reply delay: never the time since the
    # previous return.
    assert max(float(s) for s in shown("\n".join(returns))) < max(b - a for a, b in zip(ts, ts[1:])) + 1e-9


# ---- seams -------------------------------------------------------------------------------------
def seam_capture(cut: float, kind: str, t0: float) -> list:
    """A bus with a seam at ``cut`` of its chunks: its clock restarting at ``t0`` again, or a lost port
    (``gap``: 3 s without bytes on a clock that runs on)."""
    a = bus(0.4, t0=t0, seed=2)
    k = max(1, int(len(a) * cut))
    first, rest = a[:k], a[k:]
    if kind == "restart":
        start = rest[0][1] if rest else t0
        rest = [(d, t0 + (t - start)) for d, t in rest]
    else:
        rest = [(d, t + 3.0) for d, t in rest]
    return first + rest


@SETTINGS
@given(cut=st.floats(0.05, 0.95), kind=st.sampled_from(["restart", "gap"]), wall=st.booleans(),
       mode=st.sampled_from(TIME_FORMATS))
def test_seams_are_shown_honestly(cut, kind, wall, mode):
    t0 = T0 if wall else 0.25
    chunks = seam_capture(cut, kind, t0)
    ts = json_times(chunks)
    got = shown(text(chunks, mode, columnar=True))
    assert got == shown(text(chunks, mode, columnar=False))
    if mode == RELATIVE:
        # One origin for the whole capture: its first byte (wall clock) or its own 0; never moved at a seam.
        origin = ts[0] if wall else 0.0
        assert got == [f"{t - origin:.6f}" for t in ts]
    elif mode == DELTA:
        values = [None if g == "-" else float(g) for g in got]
        assert values[0] == 0.0
        for (a, b), v in zip(zip(ts, ts[1:]), values[1:]):
            # A restart has no duration to give ('-'); a lost port's seconds are real ones, counted.
            assert v is None if b < a else v == pytest.approx(b - a, abs=1e-6)
        assert all(v is None or v >= 0 for v in values)
        if kind == "gap":
            assert any(v is not None and v >= 3.0 for v in values)


# ---- pieces ------------------------------------------------------------------------------------
def test_delta_text_is_never_negative():
    assert delta_text(1.0, None, 1.0).strip() == "0.000000"
    assert delta_text(2.0, None, 1.0) == NO_TIME  # the previous event is not known (the monitor's history)
    assert delta_text(1.0, 2.0) == NO_TIME  # the clock went back
    assert delta_text(None, 1.0) == NO_TIME
    assert delta_text(2.5, 2.0).strip() == "0.500000"


def test_wall_text_never_invents_a_date(utc):
    assert wall_text(T0) == "2026-11-28 02:29:06.250000"
    assert wall_text(T0, 2) == "2026-11-28 02:29:06.25"
    assert wall_text(-5.0) == "-5.000000" and wall_text(1e300)[:4] == "1000"
    assert re.fullmatch(r"\d+\.\d{6}", wall_text(1e20))


def test_a_late_finding_has_its_records_time_and_no_delta():
    form = TimeForm(RELATIVE)
    clock = LineClock(form)
    clock.record(T0)
    assert clock.finding(T0 + 1.5) == pytest.approx(1.5)
    delta = LineClock(TimeForm(DELTA))
    delta.record(T0)
    assert delta.finding(T0 + 1.5) == NO_TIME


def test_an_unknown_form_is_refused():
    with pytest.raises(ValueError):
        TimeForm("local")
