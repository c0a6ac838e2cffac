"""The 8N1 decoder over logic samples (rs30x_sniff.sources.uart): bytes, start times, framing errors, the rate."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

np = pytest.importorskip("numpy", reason="logic captures need numpy")

from rs30x_sniff.protocol.chunks import FRAMING_ERROR, Marked  # noqa: E402
from rs30x_sniff.sources.uart import UartDecoder, chunks, decode, encode, estimate_baud, pulse_bit  # noqa: E402
from rs30x_sniff.decode.decoder import Decoder, DecodeOptions  # noqa: E402
from rs30x_sniff.sim import run  # noqa: E402
from rs30x_sniff.protocol.wire import BAUD_RATES, byte_time  # noqa: E402

SR = 1_000_000


def sim(baud: int, duration: float = 1.1) -> list[tuple[bytes, float]]:
    """The simulator's hexapod at ``baud``; a rate the servos cannot run at is the 115200 bus sped up."""
    if baud in BAUD_RATES:
        return list(run("hexapod", baud=baud, duration=duration))
    k = 115200 / baud
    return [(d, t * k) for d, t in run("hexapod", baud=115200, duration=duration / k)]


@pytest.mark.parametrize("baud,rate", [(9600, 1e6), (115200, 1e6), (115200, 4e6), (460800, 4e6), (230400, 1e6)])
def test_encoded_bytes_come_back_with_their_start_times(baud, rate):
    chunks_in = sim(baud)
    x = encode(chunks_in, rate, baud, lead=0.002)
    got = decode(x, rate, baud)
    assert got.values.tobytes() == b"".join(d for d, _ in chunks_in)
    assert not got.errors.any()
    times = [0.002 + t + i * byte_time(baud) for d, t in chunks_in for i in range(len(d))]
    # The start bit's first low sample: at most a sample after the true edge.
    assert np.allclose(got.starts / rate, times, atol=1.5 / rate)


@settings(max_examples=40, deadline=None)
@given(data=st.binary(min_size=1, max_size=60), gaps=st.lists(st.floats(0, 3e-4), min_size=1, max_size=60),
       cuts=st.lists(st.integers(1, 5000), max_size=8), rate=st.sampled_from([1e6, 2e6, 24e5]))
def test_blocks_may_end_anywhere(data, gaps, cuts, rate):
    """Fed in blocks cut at random, the streaming decoder finds what one whole array gives."""
    baud = 115200
    t, pieces = 0.0, []
    for i, b in enumerate(data):
        pieces.append((bytes([b]), t))
        t += byte_time(baud) + gaps[i % len(gaps)]
    x = encode(pieces, rate, baud, lead=1e-4)
    whole = decode(x, rate, baud)
    assert whole.values.tobytes() == data
    dec = UartDecoder(rate, baud)
    bounds = [0, *sorted(set(c % len(x) for c in cuts)), len(x)]
    parts = [dec.feed(x[a:b]) for a, b in zip(bounds, bounds[1:])] + [dec.close()]
    assert np.concatenate([p.values for p in parts]).tobytes() == data
    assert np.array_equal(np.concatenate([p.starts for p in parts]), whole.starts)


def _with_low_stop(x: np.ndarray, rate: float, baud: int, start: float, n: int) -> np.ndarray:
    """Pull the middle of the stop bit of the ``n``-th byte of a run that starts at ``start`` s low (a
    framing error; the line is high again before the next start bit, so that byte's edge is still there)."""
    bit = rate / baud
    a = int(round((start + (n * 10 + 9) * bit / rate) * rate))
    x = x.copy()
    x[a + int(bit / 4):a + int(3 * bit / 4)] = False
    return x


def test_a_low_stop_bit_is_a_framing_error_and_becomes_garbage():
    baud = 115200
    frame = bytes.fromhex("FAAF01001E020184039B")
    x = encode([(frame, 0.0), (frame, 0.002)], SR, baud, lead=1e-4)
    x = _with_low_stop(x, SR, baud, 1e-4, 3)
    got = decode(x, SR, baud)
    assert got.errors.tolist() == [i == 3 for i in range(20)]
    out = list(chunks(got, SR, baud))
    marked = [c for c in out if type(c) is Marked]
    assert len(marked) == 1 and marked[0].error == FRAMING_ERROR and len(marked[0][0]) == 1
    # Through the decoder: the frame it cut is lost, the flagged byte is garbage with its own reason,
    # the next frame decodes.
    dec = Decoder(DecodeOptions(baud=baud))
    recs = []
    for c in out:
        recs += dec.feed(c[0], c[1], None, getattr(c, "error", None))
    recs += dec.close()
    kinds = [(r.event.kind, getattr(r.event, "reason", None)) for r in recs]
    assert ("garbage", FRAMING_ERROR) in kinds
    assert kinds[-1] == ("short", None)


def test_a_short_glitch_is_not_a_start_bit():
    baud = 115200
    x = encode([(b"\xfa\xaf", 1e-3)], SR, baud)
    x[200:203] = False  # 3 us low, under half a bit: high again at the start bit's centre
    got = decode(x, SR, baud)
    assert got.values.tobytes() == b"\xfa\xaf" and not got.errors.any()


def test_a_capture_that_starts_low_or_ends_mid_byte_drops_the_cut_bytes():
    baud = 115200
    bit = SR / baud
    x = encode([(b"\x00\x55\xa5", 0.0)], SR, baud, lead=0.0)
    cut = x[int(3 * bit):int(27 * bit)]  # starts inside byte 0's data (low), ends inside byte 2
    assert not cut[0]
    got = decode(cut, SR, baud)
    assert got.values.tobytes() == b"\x55"


def test_a_line_held_low_is_one_framing_error_per_frame_time_until_it_rises():
    baud = 115200
    x = encode([(b"\x01", 1e-3)], SR, baud, trail=1e-3)
    x[200:200 + 300] = False  # a 300 us break: about 3.5 frames
    got = decode(x, SR, baud)
    assert got.errors[0] and got.values[0] == 0
    assert got.values.tobytes()[-1:] == b"\x01" and not got.errors[-1]


@pytest.mark.parametrize("baud,rate", [(9600, 1e6), (57600, 1e6), (115200, 1e6), (115200, 4e6), (230400, 4e6),
                                       (460800, 4e6)])
def test_the_rate_is_found_from_the_samples(baud, rate):
    x = encode(sim(baud, 1.1), rate, baud, lead=1e-3)
    guess = estimate_baud(x, rate)
    assert guess.baud == baud, guess.evidence
    assert guess.score == 1.0 and "valid frames" in guess.evidence
    assert any(t.baud == baud and t.framing_errors == 0 for t in guess.tries)


def test_a_few_short_glitches_do_not_move_the_bit_time():
    """The bit time is a low percentile of the pulse widths, not the single shortest pulse."""
    baud, rate = 115200, 1e6
    x = encode(sim(baud, 1.1), rate, baud, lead=1e-3)
    rng = np.random.default_rng(1)
    for at in rng.choice(np.flatnonzero(x[:-10] & x[10:]), 30, replace=False):
        x[at] = False  # 1-sample spikes on the idle line
    bit, _ = pulse_bit(x)
    assert abs(bit - rate / baud) < 0.5
    assert estimate_baud(x, rate).baud == baud


def test_without_frames_the_rate_comes_from_the_pulses_and_framing_errors():
    baud = 38400
    rng = np.random.default_rng(3)
    noise = bytes(rng.integers(0, 256, 400, dtype=np.uint8).tolist())
    x = encode([(noise, 0.0)], SR, baud, lead=1e-3)
    guess = estimate_baud(x, SR)
    assert guess.baud == baud and guess.score == 0.0 and "no valid RS30x frame" in guess.evidence


def test_too_few_pulses_say_so():
    assert not estimate_baud(np.ones(1000, bool), SR)
    assert "too few" in estimate_baud(encode([(b"\xff", 0.0)], SR, 9600), SR).evidence


def test_too_few_samples_per_bit_is_an_error():
    with pytest.raises(ValueError, match="too slow"):
        UartDecoder(1e6, 460800)


def test_back_to_back_bytes_make_one_chunk_and_gaps_start_another():
    baud = 115200
    x = encode([(b"\x01\x02\x03", 0.0), (b"\x04", 0.001)], SR, baud, lead=1e-4)
    out = list(chunks(decode(x, SR, baud), SR, baud))
    assert [c[0] for c in out] == [b"\x01\x02\x03", b"\x04"]
    assert abs(out[1][1] - 0.0011) < 2 / SR
