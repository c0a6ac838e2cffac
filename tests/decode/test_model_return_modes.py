"""A return mode beyond table 4.3 that a servo's model defines (its map's return_areas: RS204MD's and RS405CB's
0x0D, a return of addresses 60-127) is a request for a reply, for the model the tracker knows for that servo
(--model, or learned from a model-number return): paired with latency on the record and the columnar path, no
B003 or P007. An RS303MR, whose manual has no 0x0D, still expects nothing and still gets P007."""

from __future__ import annotations

import numpy as np
import pytest

from rs30x_sniff.decode import blocks as blocks_module
from rs30x_sniff.decode.frame_runs import FrameRun
from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.decode.pairing import ANSWERED, PAIRED, UNSOLICITED, BusTracker
from rs30x_sniff.protocol.events import ShortPacket
from rs30x_sniff.protocol.memmap import ModelRegistry, default_registry
from rs30x_sniff.protocol.wire import byte_time, encode_read, encode_return, encode_short
from rs30x_sniff.render.records import record_json, text_line
from rs30x_sniff.sim.bus import SimBus
from rs30x_sniff.sim.servo import Servo
from tests.decode.test_capture_edges import timed
from tests.decode.test_columnar import assert_same, columnar_path, record_path

AREA_READ = encode_short(1, 0x0D, 0, b"", length=0, count=1)  # as RS20X30Xlib and gs2d send it
POLL = encode_short(1, 0x09, 0, b"", length=0, count=1)       # table 4.3: addresses 42-59
BT = byte_time(115200)


def sim_capture(model: str, *, ask_model: bool, polls: int = 160, every: int = 40) -> list[tuple[bytes, float]]:
    """A simulated bus with servo 1 of ``model``: the model number read first (``ask_model``), then polls
    with 0x0D reads among them, as the simulator's servo answers each."""
    bus = SimBus(servos=[Servo(model, 1)])
    if ask_model:
        bus.send(encode_read(1, 0, 2))
    for k in range(polls):
        bus.send(AREA_READ if k % every == 5 else POLL)
    return bus.drain(final=True)


def area_requests(records):
    return [r for r in records if type(r.event) is ShortPacket and r.event.flag == 0x0D]


def codes(dec) -> set[str]:
    return {f.code for f in dec.linter.findings}


@pytest.mark.parametrize("how", ["learned", "--model", "per-ID"])
def test_an_rs204md_asked_0x0d_gets_its_68_byte_return_paired_with_latency_on_both_paths(how):
    chunks = sim_capture("RS204MD", ask_model=how == "learned")
    options = {"learned": DecodeOptions(), "--model": DecodeOptions(default_model="RS204MD"),
               "per-ID": DecodeOptions(models={1: "RS204MD"})}[how]
    recs, dec = record_path(chunks, options, lint=True)
    asked = area_requests(recs)
    assert len(asked) == 4
    for req in asked:
        assert req.model.name == "RS204MD"
        assert req.expects == "return" and req.read_range == (60, 68) and req.op == "read"
        assert req.status == ANSWERED
        rep = req.reply
        assert rep is not None and rep.status == PAIRED and rep.request is req
        assert (rep.event.address, rep.event.length, len(rep.event.data)) == (60, 68, 68)
        assert rep.latency is not None and rep.latency > 0
        assert len(req.read_names) == 68
    assert not codes(dec) & {"B002", "B003", "B005", "P007"}
    assert list(dec.bus.servos[1].latencies) == [r.latency for r in recs if r.status == PAIRED and r.latency]
    # The columnar path: the same records, state and findings, with Blocks for the polls between.
    blocks = assert_same(chunks, [len(chunks)], options, lint=True)
    assert blocks > 0
    assert_same(chunks, [1, 3, 7], options, lint=True)  # fed in pieces of any size


def test_the_columnar_path_leaves_the_0x0d_rows_to_the_tracker_and_blocks_the_rest():
    chunks = sim_capture("RS204MD", ask_model=True, polls=200, every=10)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(blocks_module, "MIN_BLOCK", 1)  # every clean stretch a Block, however short
        out, dec, blocks = columnar_path(chunks, [len(chunks)], DecodeOptions(), lint=True)
        assert blocks > 0
        assert not codes(dec) & {"B003", "P007"}
        assert [r.status for r in area_requests(out)] == [ANSWERED] * 20
        assert_same(chunks, [len(chunks)], DecodeOptions(), lint=True)


def test_the_tracker_sends_0x0d_rows_through_itself_only_when_some_map_defines_the_mode():
    frames = [AREA_READ, POLL, encode_short(1, 0x02, 0, b"", length=0, count=1)]
    ends = np.cumsum([len(f) for f in frames])
    run = FrameRun(0, b"".join(frames), ends - [len(f) for f in frames], ends, None, None)
    assert BusTracker().rows_needing_tracker(run.header()).tolist() == [True, False, False]
    only_manual = BusTracker(ModelRegistry([default_registry().get("RS303MR")]))
    assert only_manual.rows_needing_tracker(run.header()).tolist() == [False, False, False]


@pytest.mark.parametrize("lint_path", ["record", "columnar"])
def test_an_rs303mr_asked_0x0d_expects_nothing_and_keeps_p007(lint_path):
    chunks = sim_capture("RS303MR", ask_model=True, polls=40, every=10)
    path = record_path if lint_path == "record" else (lambda c, o, lint: columnar_path(c, [len(c)], o, lint)[:2])
    recs, dec = path(chunks, DecodeOptions(), lint=True)
    asked = area_requests(recs)
    assert len(asked) == 4
    for req in asked:
        assert req.model.name == "RS303MR"
        assert req.expects is None and req.read_range is None and req.op == "empty"
        assert req.status is None and req.reply is None
    assert [f.offset for f in dec.linter.findings if f.code == "P007"] == [r.offset for r in asked]
    assert_same(chunks, [len(chunks)], DecodeOptions(), lint=True)


def test_an_rs303mr_s_68_byte_return_after_0x0d_is_unsolicited():
    chunks = timed([AREA_READ, encode_return(1, 60, bytes(68))])  # the reply 0.2 ms after the request
    recs, dec = record_path(chunks, DecodeOptions(default_model="RS303MR"), lint=True)
    assert recs[1].status == UNSOLICITED
    assert {"B003", "P007"} <= codes(dec)
    recs, dec = record_path(chunks, DecodeOptions(default_model="RS204MD"), lint=True)
    assert recs[1].status == PAIRED and recs[1].latency == pytest.approx(0.0002)
    assert not codes(dec) & {"B003", "P007"}


def test_b005_checks_the_range_the_model_defines():
    chunks = timed([AREA_READ, encode_return(1, 42, bytes(18))])  # the reply 0.2 ms after the request
    recs, dec = record_path(chunks, DecodeOptions(default_model="RS204MD"), lint=True)
    b005 = [f for f in dec.linter.findings if f.code == "B005"]
    assert [f.message for f in b005] == ["returns 18 byte(s) from address 42; request @0 asked for 68 from 60"]
    assert recs[1].status == PAIRED


def test_a_missing_0x0d_return_says_the_range_asked():
    chunks = [(AREA_READ, 0.0), (POLL, 0.2)]
    recs, dec = record_path(chunks, DecodeOptions(default_model="RS204MD"), lint=True)
    b002 = [f for f in dec.linter.findings if f.code == "B002"]
    assert len(b002) == 1 and "addresses 60-127" in b002[0].message
    assert recs[0].status == "missing"


def test_the_simulated_servo_answers_0x0d_by_its_model():
    req = record_path([(AREA_READ, 0.0)], DecodeOptions())[0][0].event
    rs204md = Servo("RS204MD", 1)
    rs204md.mem[60:128] = bytes(range(68))
    got = rs204md.receive(req, 0.001)
    assert got is not None
    assert got[0] == encode_return(1, 60, bytes(range(68)), rs204md.status_flags())
    assert Servo("RS405CB", 1).receive(req, 0.001) is not None
    assert Servo("RS303MR", 1).receive(req, 0.001) is None   # no 0x0D in its manual
    assert Servo("RS304MD", 1).receive(req, 0.001) is None


def test_decode_s_line_and_json_say_what_the_request_asks_for():
    chunks = sim_capture("RS204MD", ask_model=True, polls=6)
    recs, _ = record_path(chunks, DecodeOptions())
    req = area_requests(recs)[0]
    line = text_line(req)
    assert " READ id=1 read[60+68]" in line and "NO-REPLY" not in line
    obj = record_json(req)
    assert obj["op"] == "read" and obj["read"]["address"] == 60 and obj["read"]["length"] == 68
    assert obj["reply"] == req.reply.offset
    rep_line = text_line(req.reply)
    assert f"reply_to=@{req.offset}" in rep_line and "latency=" in rep_line and "UNSOLICITED" not in rep_line
    # The RS303MR's: a request for nothing (NOP), no read.
    recs, _ = record_path(sim_capture("RS303MR", ask_model=True, polls=6), DecodeOptions())
    req = area_requests(recs)[0]
    assert " NOP id=1" in text_line(req) and "read" not in record_json(req)
