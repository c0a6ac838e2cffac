"""Hypothesis over the pairing state machine: any sequence of requests and replies, with or without times."""

from hypothesis import given, settings
from hypothesis import strategies as st

from rs30x_sniff.decode.pairing import ANSWERED, EXTRA, MISSING, PAIRED, UNKNOWN, UNSEEN, UNSOLICITED, BusTracker
from rs30x_sniff.protocol.events import Ack, Garbage, ReturnPacket, ShortPacket
from rs30x_sniff.decode.framing import decode_all
from rs30x_sniff.protocol.wire import encode_return, encode_short

# Every kind of input the tracker can see, in every state it can be in.
STEPS = {
    "poll": encode_short(1, 0x09, 0, b"", length=0, count=1),
    "read": encode_short(2, 0x0F, 42, b"", length=2, count=0),
    "ask-ack": encode_short(3, 0x01, 36, b"\x01"),
    "write": encode_short(4, 0x00, 30, b"\x00\x00"),
    "return": encode_return(1, 42, bytes(18)),
    "ack": b"\x07",
    "noise": b"\x00\x13",
}


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(sorted(STEPS)), st.floats(0, 0.2)), max_size=25),
       st.booleans())
def test_every_event_released_once_in_order_and_pairs_are_consistent(steps, timed):
    chunks, t = [], 0.0
    for name, pause in steps:
        t += pause
        chunks.append((STEPS[name], t if timed else None))
    events = decode_all(chunks)
    bus = BusTracker(reply_timeout=0.05)
    records = bus.feed_all(events) + bus.close()

    # Released exactly once each, in wire order.
    assert [r.event for r in records] == events
    assert [r.index for r in records] == list(range(len(events)))

    for r in records:
        ev = r.event
        if r.expects is not None:
            assert r.status in (ANSWERED, MISSING, UNKNOWN)
            assert (r.reply is not None) == (r.status == ANSWERED)
            # Unknown only for the last request, which the end of input left waiting within its timeout.
            if r.status == UNKNOWN:
                assert r is max((q for q in records if q.expects is not None), key=lambda q: q.index)
                assert not timed or ev.t_end + 0.05 >= records[-1].event.t_end
            if r.reply is not None:
                assert r.reply.request is r and r.reply.status == PAIRED
                assert r.reply.index > r.index
        elif r.is_request:
            assert r.status is None and r.reply is None
        if r.is_reply:
            assert r.status in (PAIRED, UNSOLICITED, EXTRA, UNSEEN)
            assert (r.request is None) == (r.status in (UNSOLICITED, UNSEEN))
            # Unseen only for the first packet of the capture: its request came before the capture did.
            if r.status == UNSEEN:
                assert not any(q.index < r.index and not isinstance(q.event, Garbage) for q in records)
            if r.request is not None:
                assert r.request.index < r.index
            if r.status == PAIRED and timed:
                # A latency where the clock allows one (never below 0); none where the reply is stamped
                # before its request ended.
                gap = ev.t_start - r.request.event.t_end
                assert (r.latency is None) == (gap < 0)
                assert r.latency is None or 0 <= r.latency <= 0.05 + 1e-9
        if isinstance(ev, Garbage):
            assert r.status is None and r.request is None


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from(["poll", "return", "write", "noise"]), max_size=30))
def test_a_reply_pairs_with_the_latest_request_only_when_nothing_intervened(names):
    events = decode_all([(b"".join(STEPS[n] for n in names), None)])
    records = BusTracker().feed_all(events)
    for prev, cur in zip(records, records[1:]):
        if isinstance(cur.event, ReturnPacket) and isinstance(prev.event, ShortPacket) and prev.expects:
            assert cur.status == PAIRED and cur.request is prev
    assert not any(isinstance(r.event, Ack) for r in records)  # no ACK was asked for
