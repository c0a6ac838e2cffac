"""Marked chunks: UART-flagged bytes become garbage of their own, and who-sent-what reaches the linter."""

from hypothesis import given, settings, strategies as st

from rs30x_sniff.protocol.chunks import FRAMING_ERROR, HOST, PARITY_ERROR, SERVO, Marked, SenderMap, marks, remark
from rs30x_sniff.decode.framing import GARBAGE_PIECE, FrameDecoder
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.sinks.pipeline import decode_records
from rs30x_sniff.sources.timebase import to_first_byte
from rs30x_sniff.protocol.wire import encode_read

REQ = encode_read(1, 0x2A, 2)


def test_a_flagged_byte_cuts_the_frame_in_progress_and_is_garbage_with_its_reason():
    events = [r.event for r in decode_records([
        Marked(REQ[:4], 0.0, sender=HOST), Marked(b"\x55", 0.001, error=FRAMING_ERROR), (REQ, 0.002)])]
    assert [(e.kind, getattr(e, "reason", None)) for e in events] == [
        ("garbage", "truncated"), ("garbage", FRAMING_ERROR), ("short", None)]
    assert events[1].raw == b"\x55" and events[1].offset == 4 and events[1].t_start == 0.001


def test_a_flagged_byte_is_never_an_ack():
    ack_request = bytes.fromhex("FAAF0101FF000001")  # return mode 0001 asks for an ACK (table 4.3)
    dec = FrameDecoder(115200)
    out = dec.feed(ack_request, 0.0) + dec.feed_fault(b"\x07", 0.001, PARITY_ERROR) + dec.close()
    assert [e.kind for e in out][-1] == "garbage" and out[-1].reason == PARITY_ERROR


def test_a_long_flagged_run_comes_in_pieces():
    dec = FrameDecoder(115200)
    out = dec.feed_fault(bytes(300), 0.0, FRAMING_ERROR) + dec.close()
    assert [len(e.raw) for e in out] == [GARBAGE_PIECE, GARBAGE_PIECE, 300 - 2 * GARBAGE_PIECE]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.binary(min_size=1, max_size=12).map(lambda b: REQ + b), st.booleans()), max_size=12),
       st.data())
def test_events_do_not_depend_on_how_plain_bytes_between_faults_are_chunked(pieces, data):
    def run(split: bool):
        dec = FrameDecoder(115200)
        out = []
        for blob, fault in pieces:
            if fault:
                out += dec.feed_fault(blob[:1], None, FRAMING_ERROR)
                blob = blob[1:]
            cuts = sorted(data.draw(st.lists(st.integers(0, len(blob)), max_size=4))) if split else []
            for a, b in zip([0, *cuts], [*cuts, len(blob)]):
                out += dec.feed(blob[a:b], None)
        return out + dec.close()

    whole, split = run(False), run(True)
    assert whole == split
    assert sum(len(e.raw) for e in whole) == sum(len(b) for b, _ in pieces)


def test_senders_reach_the_linter_and_survive_retiming():
    chunks = [Marked(REQ, 1.0, sender=HOST), Marked(b"\x07", 1.001, sender=SERVO), (REQ, 2.0)]
    moved = list(to_first_byte(chunks, 115200))
    assert [marks(c) for c in moved] == [(HOST, None), (SERVO, None), (None, None)]
    assert remark(chunks[0], b"x", 3.0).sender == HOST
    dec = Decoder()
    for c in moved:
        dec.feed(c[0], c[1], *marks(c))
    assert [dec.senders.at(o) for o in (0, 7, 8, 9, 100)] == [HOST, HOST, SERVO, None, None]


def test_sender_map_keeps_only_changes():
    m = SenderMap()
    assert not m and m.at(5) is None
    m.note(0, HOST)
    m.note(8, HOST)
    m.note(8, HOST)
    m.note(16, SERVO)
    m.note(16, HOST)  # same offset: the later note wins... and merges with the run before it
    assert m.at(20) == HOST and m.at(3) == HOST
