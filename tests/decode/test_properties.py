"""Hypothesis properties of the frame decoder: no crash, every byte once, chunking-proof, resynchronizing."""

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.protocol.events import LongPacket, ReturnPacket, ShortPacket
from rs30x_sniff.protocol.wire import encode_long, encode_return, encode_short
from tests.conftest import assert_same_events, decode_chunks, split_timed

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])

short_packets = st.builds(
    lambda sid, flag, address, data: encode_short(sid, flag, address, data),
    st.integers(1, 255), st.sampled_from([0x00, 0x01, 0x09, 0x0F, 0x40, 0x20]), st.integers(0, 139),
    st.binary(max_size=12),
)
long_packets = st.builds(
    lambda address, size, vids: encode_long(address, [(v, bytes([v] * size)) for v in vids]),
    st.integers(0, 59), st.integers(0, 6), st.lists(st.integers(1, 127), min_size=1, max_size=6),
)
return_packets = st.builds(
    lambda sid, address, data, flags: encode_return(sid, address, data, flags),
    st.integers(1, 127), st.integers(0, 139), st.binary(max_size=30), st.sampled_from([0, 0x02, 0x20, 0x80, 0xAA]),
)
frames = st.one_of(short_packets, long_packets, return_packets)
stream_bytes = st.one_of(
    st.binary(max_size=300),
    st.lists(st.one_of(frames, st.binary(max_size=8), st.sampled_from([b"\xfa", b"\xfa\xaf", b"\xfd\xdf", b"\x07"])),
             max_size=20).map(b"".join),
)


@SETTINGS
@given(stream_bytes, st.lists(st.integers(1, 400), max_size=30), st.sampled_from([None, 0.0, 12.5]))
def test_every_byte_once_and_chunking_does_not_matter(data, cuts, t0):
    whole = decode_chunks(split_timed(data, [], t0))
    chunked = decode_chunks(split_timed(data, cuts, t0))
    assert_same_events(chunked, whole)
    assert b"".join(e.raw for e in whole) == data
    offset = 0
    for e in whole:
        assert e.offset == offset and len(e.raw) > 0
        offset += len(e.raw)


@SETTINGS
@given(st.binary(max_size=500))
def test_no_exception_on_any_bytes_byte_by_byte(data):
    events = decode_chunks(split_timed(data, list(range(1, len(data))), 3.0))
    assert sum(len(e.raw) for e in events) == len(data)


@SETTINGS
@given(st.lists(st.tuples(st.binary(max_size=12), frames), min_size=1, max_size=8), st.binary(max_size=12))
def test_valid_frames_recovered_after_arbitrary_garbage(pieces, tail):
    data = bytearray()
    placed = []
    for junk, frame in pieces:
        data += junk
        placed.append((len(data), frame))
        data += frame
    data += tail
    events = decode_chunks([(bytes(data), None)])
    intact = {(e.offset, e.raw) for e in events if e.kind in ("short", "long", "return") and e.checksum_ok}
    for off, frame in placed:
        if (off, frame) in intact:
            continue
        # The only excuse: junk formed an intact frame by chance that starts before this one and runs
        # into it (e.g. junk FD DF followed by FA AF 01 00 54 00 is itself a return packet with a good Sum).
        assert any(o < off < o + len(r) for o, r in intact), (off, frame.hex())


@SETTINGS
@given(frames)
def test_encode_then_decode_gives_the_packet_back(frame):
    [ev] = decode_chunks([(frame, None)])
    assert ev.raw == frame and ev.checksum_ok
    if isinstance(ev, LongPacket):
        again = encode_long(ev.address, [(r.vid, r.data) for r in ev.records])
    elif isinstance(ev, ReturnPacket):
        again = encode_return(ev.id, ev.address, ev.data, ev.flags)
    else:
        assert isinstance(ev, ShortPacket)
        again = encode_short(ev.id, ev.flag, ev.address, ev.data, length=ev.length, count=ev.count)
    assert again == frame
