"""The tracker's special cases are written once (rs30x_sniff.decode.pairing): ``frame_case`` for one frame,
as the tracker decides each event, and its column twin ``frame_cases``, which the columnar path asks
through ``BusTracker.rows_needing_tracker``. Held equal here on random runs, and the two paths held to
the same records and state on runs full of these cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.decode import blocks as blocks_module
from rs30x_sniff.decode.frame_runs import LONG, RETURN, SHORT, FrameRun
from rs30x_sniff.decode.pairing import (
    BROADCAST_WRITE, MODEL_NUMBER, MODEL_RETURN_MODE, PAST_MAP, PLAIN, SERVO_ID_WRITE, BusTracker, frame_case,
    frame_cases)
from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.protocol.events import LongPacket, ReturnPacket, ShortPacket
from rs30x_sniff.protocol.wire import byte_time, encode_long, encode_read, encode_return, encode_short
from tests.decode.test_columnar import assert_same

SETTINGS = settings(max_examples=200, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

# Addresses near the cases' edges: the model number (0-1), servo_id (4), the end of the map (255).
addresses = st.sampled_from([0, 1, 2, 3, 4, 5, 30, 42, 140, 250, 253, 254, 255])
ids = st.sampled_from([1, 2, 3, 5, 127, 255])
shorts = st.builds(lambda sid, flag, address, data: encode_short(sid, flag, address, data),
                   ids, st.sampled_from([0x00, 0x01, 0x09, 0x0D, 0x0F, 0x02]), addresses, st.binary(max_size=8))
longs = st.builds(lambda address, size, vids: encode_long(address, [(v, bytes([v] * size)) for v in vids]),
                  addresses, st.integers(0, 5), st.lists(st.sampled_from([1, 2, 3, 5, 9]), min_size=1, max_size=4))
returns = st.builds(lambda sid, address, data: encode_return(sid, address, data),
                    ids, addresses, st.one_of(st.sampled_from([b"\x30\x30", b"\x40\x30", b"\x99\x99"]),
                                              st.binary(max_size=8)))
frames = st.one_of(shorts, longs, returns)
configured = st.sampled_from([{}, {1: "rs303mr"}, {2: "rs304md", 5: "rs303mr"}, {1: "rs204md", 3: "rs405cb"}])
# The return modes beyond table 4.3 the bundled maps define (RS204MD's and RS405CB's 0x0D), as the tracker
# gathers them; and none, as a registry without such maps gives.
AREA_MODES = frozenset({0x0D})
area_modes = st.sampled_from([AREA_MODES, frozenset()])


def run_of(frames: list[bytes]) -> FrameRun:
    """The frames back to back as the kernel's run (untimed)."""
    ends = np.cumsum([len(f) for f in frames])
    return FrameRun(0, b"".join(frames), ends - [len(f) for f in frames], ends, None, None)


def case_of(ev, id_address: int, configured, modes=AREA_MODES) -> int:
    """frame_case of one event, its arguments taken as the tracker takes them."""
    if type(ev) is LongPacket:
        return frame_case(LONG, 0, ev.address, ev.length - 1, id_address, configured, ev.flag, modes)
    kind = SHORT if type(ev) is ShortPacket else RETURN
    assert type(ev) in (ShortPacket, ReturnPacket)
    flag = ev.flag if type(ev) is ShortPacket else ev.flags
    return frame_case(kind, ev.id, ev.address, len(ev.data), id_address, configured, flag, modes)


@SETTINGS
@given(st.lists(frames, min_size=1, max_size=40), st.sampled_from([4, 0, 200, 255]), configured, area_modes)
def test_the_column_form_is_the_single_frame_form_on_every_row(fs, id_address, models, modes):
    run = run_of(fs)
    cases = frame_cases(run.header(), id_address, models, modes)
    assert cases.dtype == np.uint8
    assert cases.tolist() == [case_of(ev, id_address, models, modes) for ev in run.events()]


@SETTINGS
@given(st.lists(frames, min_size=1, max_size=40), configured)
def test_the_tracker_hands_the_column_form_to_the_columnar_path(fs, models):
    run = run_of(fs)
    bus = BusTracker(models=models)
    want = [case_of(ev, 4, models) != PLAIN for ev in run.events()]  # servo_id at 4 in every map
    assert bus.rows_needing_tracker(run.header()).tolist() == want


def test_each_case_by_example():
    def case(frame, models=()):
        return case_of(run_of([frame]).event(0), 4, models)

    assert case(encode_short(1, 0, 30, b"\x01\x02")) == PLAIN
    assert case(encode_read(1, 0, 2)) == PLAIN                      # a read carries no data
    assert case(encode_short(255, 0, 30, b"\x01")) == BROADCAST_WRITE
    assert case(encode_short(255, 0, 30, b"")) == PLAIN              # a broadcast without data writes nothing
    assert case(encode_short(1, 0, 4, b"\x02")) == SERVO_ID_WRITE
    assert case(encode_short(1, 0, 3, b"\x00\x02")) == SERVO_ID_WRITE
    assert case(encode_short(1, 0, 255, b"\x00\x02")) == PAST_MAP
    assert case(encode_short(255, 0, 255, b"\x00\x02")) == BROADCAST_WRITE | PAST_MAP
    assert case(encode_long(4, [(1, b"\x07"), (2, b"\x08")])) == SERVO_ID_WRITE
    assert case(encode_long(4, [(1, b""), (2, b"")])) == PLAIN     # VIDs only: no data
    assert case(encode_long(254, [(1, b"\x00\x01\x02")])) == PAST_MAP
    assert case(encode_return(1, 0, b"\x40\x30")) == MODEL_NUMBER
    assert case(encode_return(1, 0, b"\x40\x30"), {1}) == PLAIN      # a configured model is not learned
    assert case(encode_return(1, 0, b"\x40")) == PLAIN
    assert case(encode_return(1, 4, b"\x02")) == PLAIN               # a return moves no servo
    assert case(encode_return(1, 250, bytes(8))) == PAST_MAP
    assert case(encode_short(1, 0x0D, 0, b"", length=0, count=0)) == MODEL_RETURN_MODE  # a model's 60-127 read
    assert case(encode_short(1, 0x0D, 4, b"\x02")) == MODEL_RETURN_MODE | SERVO_ID_WRITE
    assert case(encode_short(1, 0x02, 0, b"", length=0, count=0)) == PLAIN  # no map defines mode 0010
    assert case(encode_return(1, 60, bytes(68), 0x0D)) == PLAIN               # a return's flags are no mode


BT = byte_time(115200)


def poll(sid: int) -> list[bytes]:
    return [encode_short(sid, 0x09, 0, b"", length=0, count=1), encode_return(sid, 42, bytes(range(18)))]


@SETTINGS
@given(st.lists(st.one_of(frames, st.sampled_from([1, 2, 3]).map(poll)), min_size=1, max_size=60),
       configured, st.booleans())
def test_both_paths_agree_on_runs_full_of_special_cases(items, models, timed):
    frames_ = [f for x in items for f in (x if isinstance(x, list) else [x])]
    chunks, t = [], 1.0
    for f in frames_:
        chunks.append((f, t if timed else None))
        t += len(f) * BT + 0.0001
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(blocks_module, "MIN_BLOCK", 1)  # every clean stretch a Block, however short
        assert_same(chunks, [len(chunks)], DecodeOptions(models=models))
