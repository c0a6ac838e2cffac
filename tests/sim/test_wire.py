"""Re-timing: a receiver at the sender's rate reads the bytes back; at another rate it reads garbage."""

from __future__ import annotations

import pytest

from rs30x_sniff.decode.framing import decode_all
from rs30x_sniff.sim import run
from rs30x_sniff.sim.wire import DROP, ZERO, SimWire, retime
from rs30x_sniff.protocol.wire import encode_short


@pytest.mark.parametrize("baud", [9600, 57600, 115200, 230400])
def test_same_rate_gives_the_bytes_back_with_their_times(baud):
    chunks = list(run("hexapod", baud=baud, duration=1.5))
    got = list(retime(chunks, baud, baud))
    assert b"".join(d for d, _ in got) == b"".join(d for d, _ in chunks)
    bt = 10 / baud
    times = [t + k * bt for d, t in chunks for k in range(len(d))]
    got_times = [t + k * bt for d, t in got for k in range(len(d))]
    assert got_times == pytest.approx(times, abs=1e-9)


def test_115200_read_at_57600_is_garbage_with_no_valid_frame():
    chunks = list(run("hexapod", baud=115200, duration=2.0))
    got = list(retime(chunks, 115200, 57600))
    assert sum(len(d) for d, _ in got) > 1000
    events = decode_all(got, baud=57600)
    assert not any(e.kind != "garbage" and e.checksum_ok for e in events)


@pytest.mark.parametrize("sent, read", [(115200, 230400), (57600, 115200), (9600, 115200), (230400, 9600)])
def test_other_rates_give_no_valid_frame(sent, read):
    got = list(retime(run("hexapod", baud=sent, duration=2.0), sent, read))
    assert got
    assert not any(e.kind != "garbage" and e.checksum_ok for e in decode_all(got, baud=read))


def test_times_keep_their_place_and_chunks_never_overlap():
    got = list(retime(run("hexapod", baud=115200, duration=2.0), 115200, 57600))
    bt = 10 / 57600
    for (a, ta), (b, tb) in zip(got, got[1:]):
        assert tb >= ta + (len(a) - 1) * bt + 9.5 / 57600 - 1e-12


def test_framing_errors_kept_zeroed_or_dropped():
    frames = encode_short(1, 0, 0x1E, b"\x84\x03") * 4
    keep = b"".join(d for d, _ in retime([(frames, 0.0)], 115200, 57600))
    zero = b"".join(d for d, _ in retime([(frames, 0.0)], 115200, 57600, framing_error=ZERO))
    drop = b"".join(d for d, _ in retime([(frames, 0.0)], 115200, 57600, framing_error=DROP))
    assert len(keep) == len(zero) > len(drop)
    assert 0 in zero
    with pytest.raises(ValueError):
        list(retime([(frames, 0.0)], 115200, 57600, framing_error="nope"))


def test_sim_wire_reads_depend_on_the_receiver_rate():
    wire = SimWire(run("hexapod", baud=115200, duration=10), 115200, start=2.0)
    right = wire.read_chunks(115200, 0.2)
    wrong = wire.read_chunks(57600, 0.2)
    assert any(e.checksum_ok and e.kind != "garbage" for e in decode_all(right, baud=115200))
    assert not any(e.checksum_ok and e.kind != "garbage" for e in decode_all(wrong, baud=57600))
    assert wire.t == pytest.approx(2.4)
    assert all(2.2 <= t < 2.4 for _, t in wrong)
