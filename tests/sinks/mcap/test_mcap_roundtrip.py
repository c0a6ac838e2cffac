"""Round trips: capture -> MCAP -> export gives the same bytes, and decoding the MCAP the same events."""

from __future__ import annotations

import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.cli import main
from rs30x_sniff.sources.captures import read_capture
from rs30x_sniff.decode.decoder import DecodeOptions
from rs30x_sniff.sinks.pipeline import decode_records
from rs30x_sniff.render.records import record_json
from rs30x_sniff.protocol.wire import byte_time, encode_long, encode_read, encode_return, encode_short

from .conftest import chunks_of, to_mcap


def events(chunks, baud=115200):
    return [record_json(r) for r in decode_records(chunks, DecodeOptions(baud=baud))]


def test_sample_captures_round_trip(sample_capture, tmp_path):
    orig = chunks_of(sample_capture)
    out = tmp_path / "x.mcap"
    to_mcap(orig, out)
    back = list(read_capture(str(out)))
    assert b"".join(d for d, _ in back) == b"".join(d for d, _ in orig)
    assert all(t is None for _, t in back)  # no timestamps were invented
    assert events(back) == events(orig)
    assert len(events(orig)) > 10


def test_timestamped_round_trip_keeps_every_chunk_and_time(hexapod_thex, tmp_path):
    orig = chunks_of(hexapod_thex)
    out = tmp_path / "x.mcap"
    to_mcap(orig, out)
    back = list(read_capture(str(out)))
    assert back == orig  # chunk for chunk, time for time
    assert events(back) == events(orig)


def test_export_gives_identical_bytes(sample_capture, hexapod_thex, tmp_path, capsys):
    for src in (sample_capture, hexapod_thex):
        mcap = tmp_path / (src.stem + ".mcap")
        assert main(["convert", str(src), "-o", str(mcap), "--no-lint"]) == 0
        orig = b"".join(d for d, _ in read_capture(str(src)))
        assert main(["export", str(mcap), "-o", str(tmp_path / "out.bin"), "--force"]) == 0
        assert (tmp_path / "out.bin").read_bytes() == orig
        assert main(["export", str(mcap), "-o", str(tmp_path / "out.hex"), "--force"]) == 0
        assert b"".join(d for d, _ in read_capture(str(tmp_path / "out.hex"))) == orig
    # The timestamped capture comes back line for line.
    assert main(["export", str(tmp_path / "hexapod.mcap"), "-o", str(tmp_path / "out.thex"), "--force"]) == 0
    assert (tmp_path / "out.thex").read_text().split("\n") == [
        ln.upper() for ln in hexapod_thex.read_text().split("\n")]


def test_decode_command_reads_mcap_like_the_original(hexapod_thex, tmp_path, capsys):
    mcap = tmp_path / "h.mcap"
    assert main(["convert", str(hexapod_thex), "-o", str(mcap), "--no-lint"]) == 0
    capsys.readouterr()
    assert main(["decode", str(hexapod_thex), "--format", "jsonl"]) == 0
    a = capsys.readouterr().out
    assert main(["decode", str(mcap), "--format", "jsonl"]) == 0
    b = capsys.readouterr().out
    assert a == b and a.count("\n") == 700


# ---- generated streams ---------------------------------------------------------------------------
servo_id = st.integers(1, 20)
frames = st.one_of(
    st.builds(lambda i, a, d: encode_short(i, 0, a, d), servo_id, st.integers(0x1E, 0x24), st.binary(min_size=1, max_size=4)),
    st.builds(lambda i: encode_short(i, 0x09, 0, b"", length=0, count=1), servo_id),
    st.builds(lambda i: encode_read(i, 42, 2), servo_id),
    st.builds(lambda i, d: encode_return(i, 42, d), servo_id, st.binary(min_size=18, max_size=18)),
    st.builds(lambda recs: encode_long(30, recs),
              st.lists(st.tuples(servo_id, st.binary(min_size=4, max_size=4)), min_size=1, max_size=5)),
    st.sampled_from([b"\x07", b"\x08"]),
    st.binary(max_size=6),  # noise
)


@st.composite
def streams(draw):
    parts = draw(st.lists(frames, min_size=1, max_size=30))
    data = b"".join(parts)
    cuts = sorted(draw(st.lists(st.integers(0, len(data)), max_size=8)))
    pieces = [data[a:b] for a, b in zip([0, *cuts], [*cuts, len(data)]) if b > a]
    if draw(st.booleans()):
        return [(p, None) for p in pieces]
    bt = byte_time(115200)
    out, t, off = [], 0.0, 0
    for p in pieces:
        t += draw(st.sampled_from([0.0, 0.0001, 0.003, 0.2, 1.5]))  # idle gaps, some past a chunk's time bound
        out.append((p, round(t + off * bt, 6)))
        off += len(p)
    return out


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(streams())
def test_generated_streams_round_trip(chunks):
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "g.mcap"
        to_mcap(chunks, out, chunk_seconds=0.5, chunk_size=512)
        back = list(read_capture(str(out)))
    if not chunks or chunks[0][1] is None:
        assert b"".join(x for x, _ in back) == b"".join(x for x, _ in chunks)
    else:
        assert back == chunks
    assert events(back) == events(chunks)
