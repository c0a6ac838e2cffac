"""block_text writes a Block's rows, and record_line a single Record, byte for byte as render.text_line does."""

import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.traffic import hexapod_frames
from rs30x_sniff.decode import blocks as blocks_module
from rs30x_sniff.render.block_text import block_text, record_line
from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.lint import Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder
from rs30x_sniff.render.records import text_line, verbose_lines
from rs30x_sniff.sim import scenarios
from rs30x_sniff.protocol.memmap import default_registry
from rs30x_sniff.protocol.wire import byte_time, encode_long, encode_read, encode_return, encode_short
from tests.decode.test_columnar import traffic
from tests.decode.test_properties import frames

SETTINGS = settings(max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
BT = byte_time(115200)
ONLY = (None, {1}, {2, 3})


def expected(blk, only, verbose=False, rows=None):
    """What TextSink.line writes for each record of ``blk`` (those of ``rows``)."""
    recs = blk.records()
    if rows is not None:
        recs = [recs[k] for k in rows]
    if verbose:
        return "".join(text_line(r, only) + "\n" + "\n".join(verbose_lines(r)) + "\n" for r in recs)
    return "".join(text_line(r, only) + "\n" for r in recs)


def check_step(step, rng):
    """Every Block of ``step``: block_text asked first (the Block as the Decoder left it, records maybe
    not built), then held to the records; again once they are built, and verbose. Returns (Blocks,
    those block_text met with their records not all built)."""
    blocks = [x for x in step if type(x) is Block]
    fresh = 0
    for blk in blocks:
        n = len(blk)
        untouched = not blk.linted_by_rows
        asked = []
        for only in ONLY:
            asked.append((only, None, block_text(blk, only)))
            rows = sorted(rng.sample(range(n), rng.randrange(n + 1)))
            asked.append((only, rows, block_text(blk, only, rows=rows)))
        assert untouched == (not blk.linted_by_rows), "block_text built every record"
        fresh += untouched
        for only, rows, text in asked:
            assert text == expected(blk, only, rows=rows), (only, rows)
        rows = sorted(rng.sample(range(n), min(n, 3)))
        for only in ONLY:
            assert block_text(blk, only) == expected(blk, only)
            assert block_text(blk, only, verbose=True, rows=rows) == expected(blk, only, True, rows)
    return len(blocks), fresh


def check_blocks(chunks, groups=(1000,), options=None, lint=False, seed=0):
    """Decode ``chunks`` columnar, ``groups[i]`` chunks per feed_many (cycled), checking each step's
    Blocks as it comes (a later step may yet give a finding to a record kept from an earlier one)."""
    rng = random.Random(seed)
    dec = Decoder(options, Linter() if lint else None, columnar=True)
    blocks = fresh = 0
    k = g = 0
    while k < len(chunks):
        n = groups[g % len(groups)]
        b, f = check_step(dec.feed_many(chunks[k:k + n]), rng)
        blocks, fresh, k, g = blocks + b, fresh + f, k + n, g + 1
    b, f = check_step(dec.close(), rng)
    return blocks + b, fresh + f


@pytest.fixture
def tiny_blocks(monkeypatch):
    # Blocks of a row or two: every edge between a Block and the records around it.
    monkeypatch.setattr(blocks_module, "MIN_BLOCK", 1)


def shapes(tag):
    """(key, shape) of every shape compiled so far and kept by the models (tag "text": a Block's rows,
    "text record": single Records), the key without its tag."""
    return [(key[1:], shape) for m in default_registry().models.values() for key, shape in m.cache.items()
            if type(key) is tuple and key[0] == tag]


def forget_shapes(tag):
    for m in default_registry().models.values():
        for key in [k for k in m.cache if type(k) is tuple and k[0] == tag]:
            del m.cache[key]


def no_fallback():
    """Every shape compiled so far has its template (none sent to the record path)."""
    return all(s.fn is not None for _, s in shapes("text"))


def fallbacks_explained():
    """A shape goes to the record path only when it is meant to: a long packet naming a VID twice
    whose fields may hide (reserved bytes), where the order of its groups depends on the data. Any
    other means a template failed its check against text_line on its first row."""
    for key, shape in shapes("text"):
        if shape.fn is None:
            header = key[1]
            assert len(header) == 3 and len(set(header[2])) < len(header[2]), key
    return True


@pytest.mark.parametrize("lint", [False, True], ids=["plain", "lint"])
@pytest.mark.parametrize("timed", [True, False], ids=["timed", "untimed"])
def test_hexapod(timed, lint):
    chunks = hexapod_frames(3000)
    if not timed:
        data = b"".join(d for d, _ in chunks)
        chunks = [(data[i:i + 4096], None) for i in range(0, len(data), 4096)]
    forget_shapes("text")
    blocks, fresh = check_blocks(chunks, (700, 300) if timed else (5, 3), lint=lint)
    assert blocks > 2 and fresh == blocks
    assert no_fallback()


@pytest.mark.parametrize("min_block", [1, blocks_module.MIN_BLOCK], ids=["tiny blocks", "default blocks"])
@pytest.mark.parametrize("lint", [False, True], ids=["plain", "lint"])
@pytest.mark.parametrize("name", sorted(scenarios.SCENARIOS))
def test_scenarios(name, lint, min_block, monkeypatch):
    monkeypatch.setattr(blocks_module, "MIN_BLOCK", min_block)
    chunks = list(scenarios.run(name, duration=2.0))
    check_blocks(chunks, (1000, 37), lint=lint, seed=len(name))
    assert fallbacks_explained()


def test_scenarios_reach_templates():
    """The scenarios together put blocks whose records are not built through the templates."""
    total = 0
    for name in sorted(scenarios.SCENARIOS):
        total += check_blocks(list(scenarios.run(name, duration=2.0)), (1000,), lint=True)[1]
    assert total > 0


@SETTINGS
@given(seed=st.integers(0, 10**6), n=st.integers(1, 300), timed=st.booleans(), gaps=st.booleans(),
       faults=st.booleans(), lint=st.booleans(), groups=st.lists(st.integers(1, 200), min_size=1, max_size=3),
       rare=st.sampled_from([0.3, 0.05, 0.01]), mixed=st.booleans())
def test_random_traffic(tiny_blocks, seed, n, timed, gaps, faults, lint, groups, rare, mixed):
    chunks = traffic(seed, n, timed=timed, gaps=gaps, faults=faults, rare=rare)
    options = DecodeOptions(models={2: "RS304MD"}) if mixed else None
    check_blocks(chunks, groups, options, lint=lint, seed=seed)
    assert fallbacks_explained()


@SETTINGS
@given(st.lists(frames, max_size=60), st.lists(st.integers(1, 40), min_size=1, max_size=3), st.booleans())
def test_arbitrary_frames(tiny_blocks, pieces, groups, lint):
    # Any address, length and data: partial registers, reserved bytes, enums, tables, hex, flags.
    check_blocks([(p, None) for p in pieces], groups, lint=lint)
    assert fallbacks_explained()


def odd_traffic(rng, n):
    """Clean transactions of every shape the templates handle specially, timed."""
    chunks, t = [], 1.0
    for _ in range(n):
        sid = rng.choice([1, 2, 3])
        r = rng.randrange(9)
        if r == 0:    # a return with reserved bytes that are sometimes not zero, and status flags
            tx = [encode_read(sid, 50, 10),
                  encode_return(sid, 50, bytes(rng.choice([0, 0, 7]) for _ in range(10)), rng.choice([0, 0x20, 0x82]))]
        elif r == 1:  # a long packet over reserved_34 and max_torque, VIDs repeated
            vids = rng.choice([(1, 2, 3), (1, 2, 1), (3, 3)])
            tx = [encode_long(34, [(v, bytes([rng.choice([0, 5]), 100])) for v in vids])]
        elif r == 2:  # the high byte of goal_position and goal_time (partial registers)
            tx = [encode_short(sid, 0x00, 31, bytes(rng.randrange(256) for _ in range(3)))]
        elif r == 3:  # enums and a table (baud_rate: codes it does not know show as ?N)
            tx = [encode_short(sid, 0x00, 36, bytes([rng.randrange(3)])),
                  encode_read(sid, 5, 2), encode_return(sid, 5, bytes([rng.randrange(2), rng.randrange(12)]))]
        elif r == 4:  # hex registers
            tx = [encode_read(sid, 2, 2), encode_return(sid, 2, bytes([rng.randrange(256), 0]))]
        elif r == 5:  # a command with no data, and a fixed-range read
            tx = [encode_short(sid, rng.choice([0x40, 0x20]), rng.choice([0xFF, 4]), b"", length=0, count=0),
                  encode_short(sid, 0x03, 0, b"", length=0, count=1), encode_return(sid, 0x00 + 30, bytes(30))]
        elif r == 6:  # a long packet with nothing after the VIDs, and one of no length
            tx = [encode_long(30, [(1, b""), (2, b"")])]
        elif r == 7:  # a broadcast with no data, and a write+read
            tx = [encode_short(255, 0x00, 30, b"", length=0, count=0),
                  encode_short(sid, 0x0F, 30, b"\x10\x00", length=2, count=1),
                  encode_return(sid, 30, b"\x10\x00")]
        else:         # goal positions, negative too
            tx = [encode_long(30, [(v, rng.randrange(-1800, 1800).to_bytes(2, "little", signed=True) + b"\x05\x00")
                                   for v in (1, 2, 3)])]
        for frame in tx:
            chunks.append((frame, t))
            t += len(frame) * BT + rng.choice([0.0, 0.0001, 0.0003])
    return chunks


@pytest.mark.parametrize("models", [None, {2: "RS304MD"}], ids=["one model", "mixed models"])
@pytest.mark.parametrize("lint", [False, True], ids=["plain", "lint"])
def test_odd_shapes(tiny_blocks, models, lint):
    chunks = odd_traffic(random.Random(3), 1500)
    options = DecodeOptions(models=models or {})
    fresh = check_blocks(chunks, (400, 250), options, lint=lint)[1]
    fresh += check_blocks([(d, None) for d, _ in chunks], (400,), options, lint=lint, seed=1)[1]
    assert fresh > 0 or lint  # the linter has things to say of these rows: it builds them all
    assert fallbacks_explained()


# ---- record_line: the record path's lines ------------------------------------------------------------
def check_records(chunks, options=None, lint=False):
    """Decode ``chunks`` record by record (the path of a live port), each record's record_line held to
    text_line for every ``only``, twice (the second from the cached shape). Returns (records, those
    written from a template, which must have built no Field objects)."""
    dec = Decoder(options, Linter() if lint else None)
    n = templated = 0
    steps = [dec.feed(d, t) for d, t in chunks] + [dec.close()]
    for step in steps:
        for rec in step:
            n += 1
            built = rec._fields is not None
            for only in ONLY:
                want = text_line(rec, only) + "\n"
                if not built:
                    rec._fields = None  # text_line kept them: record_line must do without
                assert record_line(rec, only) == want, (only, rec.event)
                assert record_line(rec, only) == want
            templated += not built and rec._fields is None
    return n, templated


def record_fallbacks_explained():
    """As fallbacks_explained, for the record shapes: only a long packet naming a VID twice may fail."""
    for key, shape in shapes("text record"):
        if shape.fn is None:
            assert key[2] and len(set(key[2])) < len(key[2]), key
    return True


@pytest.mark.parametrize("lint", [False, True], ids=["plain", "lint"])
def test_record_lines_of_hexapod(lint):
    forget_shapes("text record")
    n, templated = check_records(hexapod_frames(2000), lint=lint)
    assert templated > 0.9 * n  # the clean requests and replies, paired or waited for
    assert all(s.fn is not None for _, s in shapes("text record"))


@SETTINGS
@given(seed=st.integers(0, 10**6), n=st.integers(1, 200), timed=st.booleans(), gaps=st.booleans(),
       faults=st.booleans(), lint=st.booleans(), rare=st.sampled_from([0.3, 0.05]), mixed=st.booleans())
def test_record_lines_of_random_traffic(seed, n, timed, gaps, faults, lint, rare, mixed):
    # Missing and unsolicited replies, bad Sums, garbage, findings, servos of two models.
    chunks = traffic(seed, n, timed=timed, gaps=gaps, faults=faults, rare=rare)
    check_records(chunks, DecodeOptions(models={2: "RS304MD"}) if mixed else None, lint=lint)
    assert record_fallbacks_explained()


@SETTINGS
@given(st.lists(frames, max_size=60), st.booleans())
def test_record_lines_of_arbitrary_frames(pieces, lint):
    check_records([(p, None) for p in pieces], lint=lint)
    assert record_fallbacks_explained()


@pytest.mark.parametrize("models", [None, {2: "RS304MD"}], ids=["one model", "mixed models"])
def test_record_lines_of_odd_shapes(models):
    options = DecodeOptions(models=models or {})
    chunks = odd_traffic(random.Random(4), 600)
    assert check_records(chunks, options)[1] > 0
    assert check_records([(d, None) for d, _ in chunks], options, lint=True)[0] > 0
    assert record_fallbacks_explained()
