"""The shared words of the little languages (issue 33 §2): durations, ID ranges and operators parse one way."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rs30x_sniff import language
from rs30x_sniff.language import LanguageError, parse_duration, parse_id_range, say_duration


@pytest.mark.parametrize("text,seconds", [
    ("50ms", 0.05), ("1.5s", 1.5), ("10min", 600.0), ("2h", 7200.0), ("1d", 86400.0), ("150us", 150e-6),
    ("150µs", 150e-6), ("250ns", 250e-9), ("2", 2.0), ("0.002", 0.002), ("1e-3s", 1e-3), (" 30 s ", 30.0),
    ("5MS", 0.005), ("90sec", 90.0),
])
def test_a_duration_is_seconds(text, seconds):
    assert math.isclose(parse_duration(text), seconds, rel_tol=1e-12)


@pytest.mark.parametrize("text", ["", "ms", "5 parsecs", "inf", "nan", "-1s", "0", "1.2.3s", "5mss"])
def test_a_bad_duration_is_one_line_naming_the_option(text):
    with pytest.raises(LanguageError) as e:
        parse_duration(text, what="--reply-timeout")
    assert str(e.value).startswith("--reply-timeout") and "\n" not in str(e.value)


def test_zero_only_where_allowed():
    assert parse_duration("0ms", allow_zero=True) == 0.0
    with pytest.raises(LanguageError):
        parse_duration("0ms")


def test_m_is_minutes_for_one_release_with_a_note():
    language.deprecation_notes.clear()
    assert parse_duration("5m") == 300.0
    assert len(language.deprecation_notes) == 1 and "'min'" in language.deprecation_notes[0]
    parse_duration("7m")
    assert len(language.deprecation_notes) == 1  # said once


@given(st.integers(min_value=1, max_value=10**6), st.sampled_from(["ns", "us", "ms", "s", "min", "h", "d"]))
def test_a_said_duration_reads_back_the_same(n, unit):
    seconds = parse_duration(f"{n}{unit}")
    assert math.isclose(parse_duration(say_duration(seconds)), seconds, rel_tol=1e-9)


@given(st.sets(st.integers(min_value=0, max_value=255), min_size=1))
def test_an_id_set_written_as_ranges_reads_back(ids):
    ordered = sorted(ids)
    runs, start = [], ordered[0]
    for a, b in zip(ordered, ordered[1:] + [None]):
        if b != a + 1:
            runs.append(f"{start}-{a}" if a != start else str(a))
            start = b
    assert parse_id_range(",".join(runs)) == tuple(ordered)


@pytest.mark.parametrize("text,why", [("7-3", "backwards"), ("300", "run from"), ("x", "not an ID"),
                                      ("1-", "not an ID")])
def test_a_bad_id_range_says_why(text, why):
    with pytest.raises(LanguageError, match=why):
        parse_id_range(text)


def test_equality_is_one_operator_spelled_either_way():
    assert language.operator_of("=") is language.operator_of("==")
    with pytest.raises(LanguageError):
        language.operator_of("=>")
