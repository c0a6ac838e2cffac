"""The filter language speaks language.py's grammar (issue 33 s2): every time unit, `==` as `=`, one ID grammar."""

from __future__ import annotations

import pytest

from rs30x_sniff import language
from rs30x_sniff.filters import FilterError, parse_filter


@pytest.mark.parametrize("unit", sorted(language.TIME_UNITS))
@pytest.mark.parametrize("key", ["latency", "t"])
def test_every_time_unit_of_the_grammar_is_a_filter_unit(key, unit):
    assert parse_filter(f"{key}>2{unit}") is not None


@pytest.mark.parametrize("term", ["latency>1kg", "t<3parsecs", "latency>=5mins"])
def test_a_unit_not_of_the_grammar_is_refused_with_the_grammar_s_units(term):
    with pytest.raises(FilterError, match=f"is not a time unit \\({language.TIME_UNITS_SAID}\\)"):
        parse_filter(term)


@pytest.mark.parametrize("op", sorted(language.OPERATORS))
def test_every_operator_of_the_grammar_is_a_filter_operator(op):
    assert parse_filter(f"present_temperature{op}40") is not None
    assert parse_filter(f"latency{op}1ms") is not None


@pytest.mark.parametrize("text", ["1-6", "1,3,5", "0x10", "0-255", "3,1-2"])
def test_ids_are_the_grammar_s(text):
    assert language.parse_id_range(text)
    assert parse_filter(f"id:{text}") is not None and parse_filter(f"id=={text}") is not None


@pytest.mark.parametrize("text, why", [("300", "IDs run from 0 to 255"), ("6-1", "runs backwards"),
                                       ("x", "is not an ID or a range")])
def test_a_bad_id_range_says_the_grammar_s_reason(text, why):
    with pytest.raises(FilterError, match=why):
        parse_filter(f"id:{text}")
    with pytest.raises(language.LanguageError, match=why):
        language.parse_id_range(text)
