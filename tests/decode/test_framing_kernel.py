"""The numpy framing kernel takes exactly the frames the state machine would: a differential test."""

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.decode import framing
from rs30x_sniff.decode.framing_kernel import scan_regular_arrays
from rs30x_sniff.protocol.wire import encode_long, encode_read, encode_return, encode_short
from tests.conftest import assert_same_events, decode_chunks, split_timed
from tests.decode.test_properties import frames

SETTINGS = settings(max_examples=200, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

# Mostly clean traffic (so the kernel has runs to take) with the irregularities it must stop at:
# noise, lone sync bytes, ACK/NACK after requests that ask for them, cut and corrupt frames, and
# frames whose data holds a sync pair.
ack_request = st.builds(lambda sid: encode_short(sid, 0x01, 0xFF, b"", length=0, count=0), st.integers(1, 127))
irregular = st.one_of(
    st.binary(min_size=1, max_size=6),
    st.sampled_from([b"\xfa", b"\xfa\xaf", b"\xfd\xdf", b"\x07", b"\x08", b"\xfa\xaf\x01\x00\x00\xff\xff"]),
    ack_request.map(lambda f: f + b"\x07"),
    frames.map(lambda f: f[:-1]),
    frames.map(lambda f: f[:-1] + bytes([f[-1] ^ 0x5A])),
    st.just(encode_return(1, 0x2A, b"\xfa\xaf\x01\x02\xfd\xdf")),
)
streams = st.lists(st.one_of(frames, frames, frames, irregular), min_size=1, max_size=60).map(b"".join)


def scan(window: bytes, max_data: int) -> tuple[list[int], list[int], bool]:
    """The kernel's run, its starts and ends as lists."""
    starts, ends, more = scan_regular_arrays(window, max_data)
    return starts.tolist(), ends.tolist(), more


@pytest.fixture(params=["small windows", "default windows"])
def windows(request, monkeypatch):
    if request.param == "small windows":
        # Tiny windows make every path of the window logic run on short inputs.
        monkeypatch.setattr(framing, "_KERNEL_MIN", 8)
        monkeypatch.setattr(framing, "_KERNEL_START", 16)
        monkeypatch.setattr(framing, "_KERNEL_MAX", 64)
    return request.param


@SETTINGS
@given(data=streams, cuts=st.lists(st.integers(1, 2000), max_size=20), t0=st.sampled_from([None, 0.0, 3.25]),
       gap=st.sampled_from([20.0, None]))
def test_kernel_on_and_off_give_the_same_events(windows, data, cuts, t0, gap):
    chunks = split_timed(data, cuts, t0)
    plain = decode_chunks(chunks, kernel=False, gap_bytes=gap)
    fast = decode_chunks(chunks, kernel=True, gap_bytes=gap)
    assert_same_events(fast, plain)
    assert b"".join(e.raw for e in fast) == data


@SETTINGS
@given(data=streams)
def test_the_kernel_run_is_a_prefix_of_clean_frames(data):
    starts, ends, more = scan(data, 1024)
    assert starts == ([0] + ends[:-1] if starts else [])
    events = decode_chunks([(data, None)], kernel=False)
    taken = [(e.offset, e.end_offset) for e in events[:len(starts)]]
    assert taken == list(zip(starts, ends))
    assert all(e.checksum_ok and e.kind in ("short", "long", "return") for e in events[:len(starts)])


def test_the_kernel_says_why_it_stopped():
    a, b = encode_read(1, 0x2A, 2), encode_return(1, 0x2A, b"\x10\x00")
    assert scan(a + b + a[:5], 1024) == ([0, 8], [8, 18], True)         # the window ends inside a frame
    assert scan(a + b + b"\x55" + a, 1024) == ([0, 8], [8, 18], False)  # noise
    assert scan(a + b"\x07" + a, 1024) == ([0], [8], False)             # an ACK byte
    long = encode_long(0x1E, [(v, b"\x00\x01") for v in range(1, 5)])
    assert scan(long + a, 1024) == ([0, len(long)], [len(long), len(long) + 8], True)
    assert scan(long + a, 4) == ([], [], False)                         # over max_data: not a frame


def test_long_clean_input_goes_through_the_kernel(monkeypatch):
    calls = []
    real = framing.scan_regular_arrays
    monkeypatch.setattr(framing, "scan_regular_arrays", lambda *a: calls.append(1) or real(*a))
    data = (encode_read(3, 0x2A, 2) + encode_return(3, 0x2A, b"\x10\x00")) * 2000
    events = decode_chunks([(data[i:i + 8192], None) for i in range(0, len(data), 8192)])
    assert len(events) == 4000 and calls and len(calls) < 50
