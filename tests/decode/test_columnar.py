"""The columnar path (FrameRuns, Blocks) gives the same records, state and findings as the record path."""

import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.decode import blocks as blocks_module
from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.sim import scenarios
from rs30x_sniff.protocol.wire import byte_time, encode_command, encode_long, encode_read, encode_return, encode_short
from tests.decode.test_properties import frames

SETTINGS = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
BT = byte_time(115200)


def record_key(r):
    """Everything a consumer can read off a record (the event with its times, pairing, model, values)."""
    return (r.event, r.event.t_start, r.event.t_end, r.index, r.model and r.model.name,
            r.vid_models and tuple(m.name for m in r.vid_models), r.status, r.latency,
            r.request and r.request.index, r.reply and r.reply.index, r.values,
            tuple((f.code, f.message, f.offset, f.id) for f in r.findings), r.resolved_by and r.resolved_by.index)


def tracker_state(dec):
    bus = dec.bus
    servos = [(i, s.id, s.model.name, bytes(s.image), s.known, s.requests, s.returns, list(s.latencies), s.last_t)
              for i, s in bus.servos.items()]
    last = bus.last_answered
    return servos, bus.next_index, {i: m.name for i, m in bus.learned.items()}, last and last.index


def record_path(chunks, options=None, lint=False):
    dec = Decoder(options, Linter() if lint else None)
    out = []
    for data, t in chunks:
        out += dec.feed(data, t)
    out += dec.close()
    return out, dec


def columnar_path(chunks, groups, options=None, lint=False):
    """Feed ``chunks`` in groups of the given sizes (cycled) through a columnar Decoder."""
    dec = Decoder(options, Linter() if lint else None, columnar=True)
    out, k, g = [], 0, 0
    blocks = 0
    while k < len(chunks):
        n = groups[g % len(groups)]
        g += 1
        step = dec.feed_many(chunks[k:k + n])
        blocks += sum(type(x) is Block for x in step)
        out += step.expanded()
        k += n
    out += dec.close().expanded()
    return out, dec, blocks


def assert_same(chunks, groups, options=None, lint=False):
    a, da = record_path(chunks, options, lint)
    b, db, blocks = columnar_path(chunks, groups, options, lint)
    assert [record_key(r) for r in b] == [record_key(r) for r in a]
    assert tracker_state(db) == tracker_state(da)
    if lint:
        assert [(f.code, f.offset, f.message) for f in db.linter.findings] == \
            [(f.code, f.offset, f.message) for f in da.linter.findings]
    return blocks


def transaction(rng: random.Random, clean: bool = False) -> list[bytes]:
    """A bit of bus traffic: mostly clean polls and goal packets, sometimes what only the tracker can follow."""
    sid = rng.choice([1, 2, 3, 5, 7])
    r = rng.random() * (0.7 if clean else 1.0)
    if r < 0.35:
        return [encode_short(sid, 0x09, 0, b"", length=0, count=1),
                encode_return(sid, 42, bytes(rng.randrange(256) for _ in range(18)))]
    if r < 0.6:  # goals; sometimes the same shape at another address (each address keeps its own writes)
        address = 30 if r < 0.55 else 44
        return [encode_long(address, [(v, bytes(rng.randrange(256) for _ in range(4))) for v in (1, 2, 3, 5)])]
    if r < 0.7:
        return [encode_read(sid, 30, 4), encode_return(sid, 30, bytes(4), rng.choice([0, 0, 0x20]))]
    rare = [
        [encode_short(sid, 0x00, 36, b"\x01")],                                # torque on (no reply)
        [encode_short(sid, 0x01, 36, b"\x01"), b"\x07"],                      # write with ACK
        [encode_read(sid, 0, 2), encode_return(sid, 0, b"\x40\x30")],          # model number: learning
        [encode_read(sid, 42, 2)],                                             # missing reply
        [encode_return(sid, 42, b"\x01\x02")],                                 # unsolicited
        [encode_read(sid, 42, 2), encode_return(sid, 42, b"\x01\x02"), encode_return(sid, 42, b"\x01\x02")],
        [encode_short(sid, 0x00, 4, bytes([rng.choice([1, 2, 3, 9])]))],      # servo_id write: a move
        [encode_short(0xFF, 0x00, 30, b"\x10\x00")],                           # broadcast write
        [encode_read(sid, 42, 2), encode_return(rng.choice([1, 9]), 42, b"\x01\x02")],  # another ID answers
        [b"\x55\xfa"],                                                         # noise
        [encode_long(4, [(1, b"\x09"), (9, b"\x01")])],                        # long packet moving IDs
        # Issue 32: another ID's return after an answered read (unsolicited, not a second reply); a NACK, then a
        # return from the ID asked (a second reply); a reboot (Q001/Q002 settle at it).
        [encode_read(sid, 42, 2), encode_return(sid, 42, b"\x01\x02"), encode_return(sid % 7 + 1, 42, b"\x01\x02")],
        [encode_short(sid, 0x01, 36, b"\x01"), b"\x08", encode_return(sid, 42, b"\x01\x02")],
        [encode_short(sid, 0x00, 6, b"\x04"), encode_command(sid, 0x20)],
    ]
    return rng.choice(rare)


def traffic(seed: int, n: int, *, timed: bool, gaps: bool, faults: bool, rare: float = 0.3):
    rng = random.Random(seed)
    chunks, t = [], 1.0
    for _ in range(n):
        for frame in transaction(rng, clean=rng.random() > rare):
            chunks.append((frame, t if timed else None))
            # Mostly a servo's return delay or more (table 4.6 No. 7: 100 us at least); now and then none, as
            # bytes of one read laid out at the line rate give (a reply then has no latency: pairing.MIN_REPLY_LATENCY).
            t += len(frame) * BT + rng.choice([0.0, 0.0001, 0.0001, 0.0002, 0.0002]
                                              + ([0.004, 0.08] if gaps else []))
            if faults and rng.random() < 0.02:
                t -= rng.choice([0.001, 0.5 * BT])
    return chunks


@pytest.fixture(params=[1, blocks_module.MIN_BLOCK], ids=["tiny blocks", "default blocks"])
def min_block(request, monkeypatch):
    # Blocks of a row or two put every edge between a Block and a record through its paces.
    monkeypatch.setattr(blocks_module, "MIN_BLOCK", request.param)
    return request.param


SETTINGS = settings(SETTINGS, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@SETTINGS
@given(seed=st.integers(0, 10**6), n=st.integers(1, 400), timed=st.booleans(), gaps=st.booleans(),
       faults=st.booleans(), groups=st.lists(st.integers(1, 300), min_size=1, max_size=4), lint=st.booleans(),
       split=st.booleans(), rare=st.sampled_from([0.3, 0.05, 0.01]))
def test_columnar_path_matches_record_path(min_block, seed, n, timed, gaps, faults, groups, lint, split, rare):
    chunks = traffic(seed, n, timed=timed, gaps=gaps, faults=faults, rare=rare)
    if split and not timed:  # arbitrary chunking of an untimed stream
        data = b"".join(d for d, _ in chunks)
        cut = random.Random(seed).randrange(1, 50)
        chunks = [(data[i:i + cut], None) for i in range(0, len(data), cut)]
    assert_same(chunks, groups, lint=lint)


@SETTINGS
@given(st.lists(st.one_of(frames, frames, st.binary(max_size=6)), max_size=80),
       st.lists(st.integers(1, 40), min_size=1, max_size=3), st.booleans())
def test_columnar_path_matches_on_arbitrary_frames(min_block, pieces, groups, lint):
    assert_same([(p, None) for p in pieces if p], groups, lint=lint)


def test_clean_traffic_becomes_blocks():
    rng = random.Random(1)
    chunks, t = [], 0.0
    for _ in range(2000):
        for frame in transaction(rng, clean=True):
            chunks.append((frame, t))
            t += len(frame) * BT + 0.0001
    assert assert_same(chunks, [500]) > 0


def test_models_configured_and_mixed():
    options = DecodeOptions(models={2: "RS304MD"})
    assert assert_same(traffic(5, 600, timed=True, gaps=False, faults=False, rare=0.03), [250], options, lint=True) > 0


@pytest.mark.parametrize("vids", [[(1, b"")], [(2, b""), (1, b"")], []])
def test_long_packets_without_data_carry_their_vids_models(min_block, vids):
    # Servos of two models; a Block whose only long packets carry VIDs alone (Length 1) or nothing
    # (Length 0): each record still has its VIDs' models, as the tracker gives them (a tuple, never None).
    options = DecodeOptions(models={2: "RS304MD"})
    poll = [encode_short(1, 0x09, 0, b"", length=0, count=1), encode_return(1, 42, bytes(18))]
    long = encode_long(0, vids) if vids else encode_short(0, 0, 0, b"", length=0, count=0)
    chunks = [(f, None) for f in poll * 20 + [long] + poll * 20]
    assert assert_same(chunks, [len(chunks)], options) > 0


@pytest.mark.parametrize("name", sorted(scenarios.SCENARIOS))
def test_scenarios(name):
    chunks = list(scenarios.run(name, duration=2.0))
    assert_same(chunks, [1000], lint=True)


def test_a_failing_source_loses_nothing_already_read():
    """The columnar Pipeline holds up to 64 KiB of chunks before decoding them: a source that fails
    midway still has every chunk it gave decoded and handed to the sinks."""
    from rs30x_sniff.sinks.pipeline import Pipeline
    from rs30x_sniff.sinks.lines import FindingsSink

    chunks = traffic(4, 50, timed=True, gaps=False, faults=False, rare=0.0)

    def source():
        yield from chunks
        raise OSError("adapter unplugged")

    found = FindingsSink()
    with pytest.raises(OSError):
        Pipeline(Decoder(None, Linter(), columnar=True), [found]).run(source())
    whole, _ = record_path(chunks, lint=True)
    assert found.records == len(whole) > 50


@pytest.mark.parametrize("group_bytes", [1, 100, 1 << 16])
def test_a_pipeline_decodes_a_file_in_groups_of_its_size(group_bytes):
    from rs30x_sniff.sinks.pipeline import Pipeline, Sink

    chunks = traffic(7, 300, timed=True, gaps=False, faults=False)
    sizes = []

    class Keep(Sink):
        takes_blocks = True

        def __init__(self):
            self.steps = []

        def batch(self, step):
            self.steps.append(step)

    class Counting(Pipeline):
        def feed_many(self, group):
            sizes.append([len(d) for d, _ in group])
            return super().feed_many(group)

    keep = Keep()
    Counting(Decoder(DecodeOptions(), columnar=True), [keep], group_bytes=group_bytes).run(chunks)
    assert sum(map(sum, sizes)) == sum(len(d) for d, _ in chunks)
    # Each group but the last closes with the chunk that brings it to the size.
    assert all(sum(g[:-1]) < group_bytes <= sum(g) for g in sizes[:-1]) and sum(sizes[-1][:-1]) < group_bytes
    assert [record_key(r) for s in keep.steps for r in s.expanded()] == \
        [record_key(r) for r in record_path(chunks)[0]]
