"""The resynchronizing frame decoder: golden frames, faults as data, timestamps and gaps."""

import pytest

from rs30x_sniff.protocol.events import (
    BAD_HEADER, CAPTURE_END, NOISE, TRUNCATED, Ack, Garbage, LongPacket, Nack, ReturnPacket, ShortPacket)
from rs30x_sniff.decode.framing import FrameDecoder
from rs30x_sniff.protocol.wire import byte_time, encode_return, encode_short
from tests.conftest import decode_three_ways, h

GOAL_90 = h("FA AF 01 00 1E 02 01 84 03 9B")
LONG = h("FA AF 00 00 1E 03 03 01 64 00 02 64 00 05 F4 01 ED")
READ_42 = h("FA AF 01 0F 2A 02 00 26")


def kinds(events):
    return [(type(e).__name__, e.offset, len(e.raw)) for e in events]


def test_short_packet_header_fields():
    [ev] = decode_three_ways(GOAL_90)
    assert isinstance(ev, ShortPacket)
    assert (ev.id, ev.flag, ev.address, ev.length, ev.count, ev.data) == (1, 0, 0x1E, 2, 1, h("84 03"))
    assert ev.checksum_ok and ev.op == "write" and ev.offset == 0 and ev.raw == GOAL_90


def test_long_packet_is_split_per_vid():
    [ev] = decode_three_ways(LONG)
    assert isinstance(ev, LongPacket)
    assert [(r.vid, r.data) for r in ev.records] == [(1, h("64 00")), (2, h("64 00")), (5, h("F4 01"))]


def test_read_request_has_no_data_and_its_range():
    [ev] = decode_three_ways(READ_42)
    assert ev.op == "read" and ev.data == b"" and ev.read_range == (42, 2)


def test_return_packet_flags_decoded():
    frame = encode_return(3, 42, h("84 03"), flags=0xA0)
    [ev] = decode_three_ways(frame)
    assert isinstance(ev, ReturnPacket) and ev.id == 3
    assert ev.flag_names == ("temperature_limit", "temperature_alarm")


def test_command_packets_classified():
    evs = decode_three_ways(h("FA AF 01 40 FF 00 00 BE FA AF 01 20 FF 00 00 DE FA AF 01 10 FF FF 00 11"))
    assert [e.op for e in evs] == ["flash", "reboot", "initialize"]
    assert all(e.checksum_ok for e in evs)


def test_ack_and_nack_only_after_a_request_for_one():
    ask = encode_short(1, 0x01, 0x24, b"\x01")
    evs = decode_three_ways(ask + b"\x07" + ask + b"\x08")
    assert [type(e) for e in evs] == [ShortPacket, Ack, ShortPacket, Nack]
    # The same byte after a request that asked for no ACK is noise.
    evs = decode_three_ways(GOAL_90 + b"\x07")
    assert [type(e) for e in evs] == [ShortPacket, Garbage]
    assert evs[1].reason == NOISE


def test_garbage_before_and_between_frames():
    evs = decode_three_ways(h("00 11 22") + GOAL_90 + h("FA 13") + LONG)
    assert kinds(evs) == [("Garbage", 0, 3), ("ShortPacket", 3, 10), ("Garbage", 13, 2), ("LongPacket", 15, 17)]


def test_bad_checksum_is_a_corrupt_frame_decoded_as_far_as_it_goes():
    bad = GOAL_90[:-1] + b"\x00"
    evs = decode_three_ways(bad + LONG)
    assert kinds(evs) == [("ShortPacket", 0, 10), ("LongPacket", 10, 17)]
    assert not evs[0].checksum_ok and evs[0].data == h("84 03") and evs[1].checksum_ok


def test_frame_cut_short_by_another_frame_is_garbage_then_the_frame():
    evs = decode_three_ways(GOAL_90[:6] + LONG)
    assert kinds(evs) == [("Garbage", 0, 6), ("LongPacket", 6, 17)]
    assert evs[0].reason == TRUNCATED


def test_corrupt_length_that_swallows_the_next_frame():
    # Length 0x40 claims 64 data bytes; the intact frame inside wins, the head is garbage.
    evs = decode_three_ways(h("FA AF 01 00 1E 40 01 84 03 9B") + READ_42 + GOAL_90 * 8)
    assert evs[0] == Garbage(0, h("FA AF 01 00 1E 40 01 84 03 9B"), None, None, TRUNCATED)
    assert [type(e) for e in evs[1:]] == [ShortPacket] * 9


def test_implausible_header_is_bad_header_garbage():
    dec = FrameDecoder(max_data=64)
    evs = dec.feed(h("FA AF 01 00 1E FF FF") + GOAL_90) + dec.close()
    assert kinds(evs) == [("Garbage", 0, 7), ("ShortPacket", 7, 10)]
    assert evs[0].reason == BAD_HEADER


def test_incomplete_frame_at_end_of_input():
    evs = decode_three_ways(GOAL_90 + GOAL_90[:5])
    assert kinds(evs) == [("ShortPacket", 0, 10), ("Garbage", 10, 5)]
    assert evs[1].reason == CAPTURE_END  # cut by the end of the capture, not by its sender


def test_decoder_waits_for_the_rest_of_a_frame():
    dec = FrameDecoder()
    assert dec.feed(GOAL_90[:4]) == []
    assert dec.feed(GOAL_90[4:9]) == []
    [ev] = dec.feed(GOAL_90[9:])
    assert ev.raw == GOAL_90
    assert dec.close() == []


def test_timestamps_of_start_and_end():
    bt = byte_time(115200)
    evs = decode_three_ways(GOAL_90 + READ_42, t0=1.0)
    assert evs[0].t_start == pytest.approx(1.0)
    assert evs[0].t_end == pytest.approx(1.0 + 10 * bt)
    assert evs[1].t_start == pytest.approx(1.0 + 10 * bt)


def test_idle_gap_inside_a_frame_ends_it_as_truncated():
    bt = byte_time(115200)
    dec = FrameDecoder(115200, gap_bytes=20)
    evs = dec.feed(GOAL_90[:5], 0.0)
    evs += dec.feed(READ_42, 0.5)  # half a second of silence after 5 bytes
    evs += dec.close()
    assert kinds(evs) == [("Garbage", 0, 5), ("ShortPacket", 5, 8)]
    assert evs[0].reason == TRUNCATED and evs[0].t_end == pytest.approx(5 * bt)
    assert evs[1].t_start == pytest.approx(0.5)


def test_short_pause_inside_a_frame_is_tolerated():
    bt = byte_time(115200)
    dec = FrameDecoder(115200, gap_bytes=20)
    evs = dec.feed(GOAL_90[:5], 0.0) + dec.feed(GOAL_90[5:], 5 * bt + 10 * bt) + dec.close()
    assert kinds(evs) == [("ShortPacket", 0, 10)]


def test_garbage_runs_split_at_idle_gaps():
    dec = FrameDecoder(115200, gap_bytes=20)
    evs = dec.feed(h("00 01 02"), 0.0) + dec.feed(h("03 04"), 1.0) + dec.close()
    assert kinds(evs) == [("Garbage", 0, 3), ("Garbage", 3, 2)]


def test_every_byte_in_exactly_one_event():
    data = h("00") + GOAL_90[:7] + LONG + h("FD DF 01") + GOAL_90 + h("07 FA")
    evs = decode_three_ways(data)
    assert b"".join(e.raw for e in evs) == data
    assert [e.offset for e in evs] == [sum(len(x.raw) for x in evs[:k]) for k in range(len(evs))]


def test_feed_after_close_is_a_usage_error():
    dec = FrameDecoder()
    dec.close()
    with pytest.raises(RuntimeError):
        dec.feed(b"\x00")
