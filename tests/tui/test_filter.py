"""The monitor's filter language: every key, combinations, negation, free text, and the errors it explains."""

from __future__ import annotations

import pytest

from rs30x_sniff.filters import FilterError, parse_filter
from rs30x_sniff.protocol.wire import encode_long, encode_return, encode_short

from .helpers import FakeFinding, manual_records, records_of


@pytest.fixture(scope="module")
def recs():
    return manual_records()


def offsets(recs, text):
    flt = parse_filter(text)
    return [r.offset for r in recs if flt.matches(r)]


def test_empty_filter_is_none():
    assert parse_filter("") is None
    assert parse_filter("   ") is None


def test_id_single_range_and_list():
    chunks = [(encode_short(sid, 0, 30, b"\x00\x00"), None) for sid in (1, 2, 3, 6, 7, 200)]
    recs = records_of(chunks)
    ids = lambda text: [r.id for r in recs if parse_filter(text).matches(r)]  # noqa: E731
    assert ids("id:3") == [3]
    assert ids("id:1-6") == [1, 2, 3, 6]
    assert ids("id:1,6-7,0xC8") == [1, 6, 7, 200]
    assert ids("id=2") == [2]


def test_id_matches_long_packet_by_its_servos(recs):
    # The manual's long packet carries records for IDs 1, 2 and 5.
    assert 42 in offsets(recs, "id:5")
    assert 42 in offsets(recs, "id:2")
    assert 42 not in offsets(recs, "id:3")


def test_id_of_a_reply_comes_from_its_request():
    recs = records_of([(encode_short(4, 0x01, 0xFF, b"", length=0, count=0), 0.0), (b"\x07", 0.001)])
    assert [r.kind for r in recs if parse_filter("id:4").matches(r)] == ["short", "ack"]


def test_kind_by_event_kind_op_word_and_side(recs):
    assert offsets(recs, "kind:return") == [227]
    assert offsets(recs, "kind:long") == [42]
    assert offsets(recs, "kind:read") == [34, 219]
    assert offsets(recs, "kind:flash") == [10]
    assert offsets(recs, "kind:reply") == [227]
    assert len(offsets(recs, "kind:request")) == len(recs) - 1
    assert offsets(recs, "kind:return,long") == [42, 227]


def test_reg_matches_writes_reads_and_returns(recs):
    # @0 writes goal_position, @42 is a long packet of goals, @139.. write it, @171 too.
    got = offsets(recs, "reg:goal_position")
    assert got == [0, 42, 139, 149, 159, 171]
    # A read of 42-59 and its return both cover present_voltage; the 2-byte read at @34 does not.
    assert offsets(recs, "reg:present_voltage") == [219, 227]
    assert offsets(recs, "reg:present_position") == [34, 219, 227]


def test_sev_compares_worst_and_any(recs):
    recs = manual_records()
    by_off = {r.offset: r for r in recs}
    by_off[0].findings.append(FakeFinding("X1", "a", "info", "m", 0))
    by_off[10].findings.append(FakeFinding("X2", "b", "warning", "m", 10))
    by_off[18].findings.append(FakeFinding("X3", "c", "error", "m", 18))
    assert offsets(recs, "sev>=warning") == [10, 18]
    assert offsets(recs, "sev:error") == [18]
    assert offsets(recs, "sev>info") == [10, 18]
    assert offsets(recs, "sev<warning") == [0]
    assert offsets(recs, "sev<=warning") == [0, 10]
    assert offsets(recs, "sev>=warn") == [10, 18]


def test_free_text_is_case_insensitive_and_quoted_phrases(recs):
    assert offsets(recs, "BRAKE") == [210]
    assert offsets(recs, '"goal_time=5.00s"') == [159]
    assert offsets(recs, '"reverse=reverse"') == [68]
    assert offsets(recs, "no-reply") == [34]
    # Free text with a colon must be quoted; quoted, it is text and matches the summary.
    assert offsets(recs, '"1:goal_position=10.0deg"') == [42]


def test_terms_combine_and_negate(recs):
    assert offsets(recs, "id:1 kind:read") == [34, 219]
    assert offsets(recs, "kind:read -no-reply") == [219]
    assert offsets(recs, "reg:goal_position !kind:long") == [0, 139, 149, 159, 171]


def test_free_text_search_does_not_keep_decoded_fields(recs):
    rec = next(r for r in recs if r.offset == 227)
    assert rec._fields is None
    parse_filter("volt").matches(rec)
    assert rec._fields is None  # a search over a long history must not leave every record's fields in memory


@pytest.mark.parametrize("text, reason", [
    ("ids:3", "unknown filter key 'ids'"),
    ("id:x", "'x' is not an ID"),
    ("id:7-2", "runs backwards"),
    ("id:300", "IDs run from 0 to 255"),
    ("id:", "id: needs a value"),
    ("kind:bogus", "unknown kind"),
    ("reg:goal", "no such register (did you mean goal_position, goal_time?)"),
    ("sev>=fatal", "unknown severity"),
    ("id>=3", "id takes ':'"),
    ('"unclosed', "unclosed quote"),
    ('""', "empty quotes"),
])
def test_errors_say_why(text, reason):
    with pytest.raises(FilterError) as e:
        parse_filter(text)
    assert reason in str(e.value)
    assert "\n" not in str(e.value)


def test_return_carrying_part_of_a_register_is_matched_by_range():
    # A return of address 43 alone carries the high byte of present_position (42-43).
    recs = records_of([(encode_short(1, 0x0F, 43, b"", length=1, count=0), 0.0),
                       (encode_return(1, 43, b"\x03"), 0.0005),
                       (encode_long(30, [(1, b"\x00\x00")]), 0.002)])
    assert [r.kind for r in recs if parse_filter("reg:present_position").matches(r)] == ["short", "return"]


def test_the_monitor_shares_decodes_filter_language(recs):
    from rs30x_sniff import filters
    assert parse_filter is filters.parse_filter and FilterError is filters.FilterError
    # The manual's return @227 answers the read @219 with present_position=90.0deg.
    assert offsets(recs, "present_position>80") == [227]
    assert offsets(recs, "reg:present_position=90") == [227]
    assert offsets(recs, "goal_position=10 kind:long") == [42]
    assert offsets(recs, "kind:return -present_position>80") == []
