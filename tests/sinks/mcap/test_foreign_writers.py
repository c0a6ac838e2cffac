"""Our MCAP as other writers make it (the mcap library, foxglove-sdk, trimmed, reordered, no summary or metadata) reads
as the original; other encodings and non-finite times are one-line input errors, and no JSON line holds NaN."""

from __future__ import annotations

import base64
import json
import math
import random

import foxglove
import pytest
from mcap.reader import make_reader
from mcap.records import Channel, DataEnd, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, IndexType, Writer

from rs30x_sniff.render.block_json import NonFiniteError, block_json_lines, record_json_line
from rs30x_sniff.decode.blocks import Block
from rs30x_sniff.cli import main
from rs30x_sniff.sources.mcap_reader import McapRawReader
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.schemas import schema_bytes

from .conftest import ROOT, hexapod_frames

SESSION = ROOT / "captures" / "session-mixed.thex"
RAW = "/rs30x/raw"


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    path = tmp_path_factory.mktemp("orig") / "orig.mcap"
    assert main(["convert", str(SESSION), "-o", str(path)]) == 0
    return path


def records(path):
    """Every record of the file, in file order (chunks opened), with the summary left out."""
    with open(path, "rb") as f:
        out = []
        for r in StreamReader(f, skip_magic=False, emit_chunks=False).records:
            if isinstance(r, DataEnd):
                break
            out.append(r)
        return out


def rewrite(src, dst, *, keep=lambda m: True, order=None, metadata=True, library="python mcap", **writer):
    """``src`` written again record by record with the mcap library's Writer: the same schemas, channels,
    metadata and messages where they were (``keep``: the messages to copy; ``order``: put the messages
    in another order; each channel is registered before its first message)."""
    recs = records(src)
    schemas = {r.id: r for r in recs if isinstance(r, Schema)}
    channels = {r.id: r for r in recs if isinstance(r, Channel)}
    messages = [r for r in recs if isinstance(r, Message) and keep(r)]
    if order is not None:
        messages = order(messages)
    with open(dst, "wb") as f:
        w = Writer(f, **writer)
        w.start(profile=next(r for r in recs if isinstance(r, Header)).profile, library=library)
        if metadata:
            for r in recs:
                if isinstance(r, Metadata):
                    w.add_metadata(r.name, r.metadata)
        sids: dict[int, int] = {}
        cids: dict[int, int] = {}
        for m in messages:
            c = channels[m.channel_id]
            if c.id not in cids:
                s = schemas[c.schema_id]
                if s.id not in sids:
                    sids[s.id] = w.register_schema(s.name, s.encoding, s.data)
                cids[c.id] = w.register_channel(c.topic, c.message_encoding, sids[s.id], c.metadata)
            w.add_message(cids[c.id], m.log_time, m.data, m.publish_time, m.sequence)
        w.finish()
    return dst


def raw_messages(path):
    recs = records(path)
    raw_id = next(c.id for c in recs if isinstance(c, Channel) and c.topic == RAW)
    return [m for m in recs if isinstance(m, Message) and m.channel_id == raw_id]


def outputs(path, capsys, commands=(("decode",), ("decode", "--format", "jsonl"), ("lint",), ("info",))):
    """What each command prints for ``path`` (its name replaced), its exit code, and stderr."""
    out = {}
    for cmd in commands:
        rc = main([*cmd, str(path)])
        got = capsys.readouterr()
        out[cmd] = (rc, got.out.replace(str(path), "X"))
        out[cmd + ("stderr",)] = got.err.replace(str(path), "X")
    return out


def same_as_original(copy, original, capsys):
    want, got = outputs(original, capsys), outputs(copy, capsys)
    for key, value in want.items():
        if key[-1] != "stderr":
            assert got[key] == value, key
            assert value[1]
    return got


# ---- any writer's MCAP ----------------------------------------------------------------------------------
@pytest.mark.parametrize("variant", [
    {},
    {"compression": CompressionType.NONE},
    {"compression": CompressionType.LZ4, "chunk_size": 4096},
    {"use_chunking": False},
    {"index_types": IndexType.NONE, "use_statistics": False, "use_summary_offsets": False,
     "repeat_channels": False, "repeat_schemas": False},
])
def test_a_copy_by_the_mcap_writer_reads_as_the_original(original, tmp_path, capsys, variant):
    if variant.get("compression") == CompressionType.LZ4:
        pytest.importorskip("lz4")
    copy = rewrite(original, tmp_path / "copy.mcap", **variant)
    with open(copy, "rb") as f:
        assert make_reader(f).get_header().library == "python mcap"
    got = same_as_original(copy, original, capsys)
    assert all(v == "" for k, v in got.items() if k[-1] == "stderr")  # nothing to say about it


def test_a_copy_without_summary_footer_or_metadata_reads_and_says_what_is_missing(original, tmp_path, capsys):
    copy = rewrite(original, tmp_path / "copy.mcap", metadata=False)
    # Only the data section: cut right after Data End (no summary, no footer).
    with open(copy, "rb") as f:
        footer = next(r for r in StreamReader(f).records if isinstance(r, Footer))
    blob = copy.read_bytes()
    bare = tmp_path / "bare.mcap"
    bare.write_bytes(blob[:footer.summary_start or len(blob) - 37])
    reader = McapRawReader(str(bare), warn=None)
    assert b"".join(r[0] for r in reader) == b"".join(r[0] for r in McapRawReader(str(original), warn=None))
    assert reader.complete is True and reader.metadata == {}
    got = same_as_original(bare, original, capsys)
    err = got[("decode", "stderr")]
    assert err.count("\n") == 1 and "no 'rs30x' metadata" in err and "baud rate" in err


def test_metadata_after_the_chunks_is_found_before_reading(original, tmp_path):
    """Another writer may put its metadata anywhere in the data section: read_metadata (what sets the
    baud before decoding) finds ours past the chunks, without a warning that it is missing."""
    recs = records(original)
    meta = [r for r in recs if isinstance(r, Metadata)]
    late = tmp_path / "late.mcap"
    rewrite(original, late, metadata=False, chunk_size=512)
    # Written again with the metadata at the end of the data section.
    with open(late, "rb") as f:
        msgs = [r for r in StreamReader(f).records if isinstance(r, (Schema, Channel, Message))]
    with open(late, "wb") as f:
        w = Writer(f, chunk_size=512)
        w.start(profile="", library="late")
        for r in msgs:
            if isinstance(r, Schema):
                w.register_schema(r.name, r.encoding, r.data)
            elif isinstance(r, Channel):
                w.register_channel(r.topic, r.message_encoding, r.schema_id, r.metadata)
            else:
                w.add_message(r.channel_id, r.log_time, r.data, r.publish_time, r.sequence)
        for r in meta:
            w.add_metadata(r.name, r.metadata)
        w.finish()
    kinds = [type(r) for r in records(late)]
    assert kinds.index(Message) < kinds.index(Metadata)  # the chunks come first
    reader = McapRawReader(str(late), warn=None)
    assert reader.read_metadata()["rs30x"]["baud"] == "115200" and reader.baud == 115200
    list(reader)
    assert reader.warnings == []


def test_a_foxglove_sdk_file_with_our_schema_and_bodies_reads_as_the_original(original, tmp_path, capsys):
    sdk = tmp_path / "sdk.mcap"
    ctx = foxglove.Context()
    writer = foxglove.open_mcap(str(sdk), context=ctx)
    channel = foxglove.Channel(RAW, schema=foxglove.Schema(name="rs30x.Raw", encoding="jsonschema",
                                                           data=schema_bytes("rs30x.Raw")),
                               message_encoding="json", context=ctx)
    for m in raw_messages(original):
        channel.log(m.data, log_time=m.log_time)
    writer.close()
    with open(sdk, "rb") as f:
        assert not make_reader(f).get_header().library.startswith("rs30x-sniff")
    same_as_original(sdk, original, capsys)


def test_a_copy_trimmed_by_time_reads_from_where_it_starts(original, tmp_path, capsys):
    raws = raw_messages(original)
    times = sorted(m.log_time for m in raws)
    lo, hi = times[len(times) // 3], times[2 * len(times) // 3]
    trimmed = rewrite(original, tmp_path / "trim.mcap", keep=lambda m: lo <= m.log_time < hi,
                      library=records(original)[0].library)  # the same library name as ours
    kept = [json.loads(m.data) for m in raws if lo <= m.log_time < hi]
    start = kept[0]["offset"]
    assert start > 0
    warnings: list[str] = []
    reader = McapRawReader(str(trimmed), warn=warnings.append)
    got = list(reader)
    assert [r[0] for r in got] == [base64.b64decode(k["data"]) for k in kept]
    assert [r[1] for r in got] == [k["t"] for k in kept]
    assert reader.complete is True and reader.damaged_at is None
    assert len(warnings) == 1 and f"starts at byte {start}" in warnings[0]
    # Every command reads it: decoded from its first byte, not called corrupt.
    for cmd in (["decode"], ["lint"], ["info"]):
        rc = main([*cmd, str(trimmed)])
        captured = capsys.readouterr()
        assert rc in (0, 1) and "corrupt" not in captured.err and captured.out, cmd
    assert main(["decode", str(trimmed)]) == 0
    first = capsys.readouterr().out.splitlines()[0].split()
    assert float(first[0]) == pytest.approx(kept[0]["t"], abs=1e-6) and first[1] == "@0"


def test_messages_in_another_order_are_read_in_stream_order(original, tmp_path, capsys):
    """Chunks reordered (a writer of its own order, a copy sorted another way): the raw bytes carry
    their stream offsets, so the capture is the same."""
    def shuffled(messages):
        blocks = [messages[i:i + 40] for i in range(0, len(messages), 40)]
        random.Random(7).shuffle(blocks)
        return [m for b in blocks for m in b]

    copy = rewrite(original, tmp_path / "shuffled.mcap", order=shuffled, chunk_size=2048)
    with open(copy, "rb") as f:
        assert [m.log_time for _, _, m in make_reader(f).iter_messages(log_time_order=False)] != sorted(
            m.log_time for m in records(original) if isinstance(m, Message))
    reader = McapRawReader(str(copy), warn=None)
    assert list(reader) == list(McapRawReader(str(original), warn=None))
    assert reader.warnings == [] and reader.complete is True
    same_as_original(copy, original, capsys)


def test_a_hole_is_still_damage_whatever_the_order(original, tmp_path):
    """Messages put back in order never hide lost capture bytes: a copy missing some raw messages in the
    middle is read up to the hole, with the warning a damaged file gets."""
    raws = raw_messages(original)
    gone = {m.data for m in raws[len(raws) // 2:len(raws) // 2 + 3]}
    copy = rewrite(original, tmp_path / "hole.mcap", keep=lambda m: m.data not in gone, chunk_size=2048)
    warnings: list[str] = []
    got = b"".join(r[0] for r in McapRawReader(str(copy), warn=warnings.append))
    full = b"".join(r[0] for r in McapRawReader(str(original), warn=None))
    assert got and full.startswith(got) and len(got) == json.loads(raws[len(raws) // 2].data)["offset"]
    assert len(warnings) == 1 and "corrupt MCAP" in warnings[0] and "are missing" in warnings[0]


@pytest.mark.parametrize("encoding", ["cbor", "protobuf", "ros1"])
def test_another_encoding_on_our_topic_is_one_line(tmp_path, capsys, encoding):
    path = tmp_path / "enc.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="other")
        sid = w.register_schema("rs30x.Raw", "jsonschema", schema_bytes("rs30x.Raw"))
        cid = w.register_channel(RAW, encoding, sid)
        w.add_message(cid, 1, b"\xa2\x01\x02", 1)
        w.finish()
    for cmd in (["decode"], ["lint"], ["info"], ["convert", "-o", str(tmp_path / "o.mcap")]):
        assert main([cmd[0], str(path), *cmd[1:]]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("rs30x-sniff: error:") and "Traceback" not in err
        assert f"unsupported encoding {encoding} on /rs30x/raw" in err and str(path) in err
    assert not (tmp_path / "o.mcap").exists()


def test_another_schema_on_our_topic_is_not_read_as_ours(tmp_path, capsys):
    path = tmp_path / "schema.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="other")
        sid = w.register_schema("acme.Bytes", "jsonschema", b"{}")
        cid = w.register_channel(RAW, "json", sid)
        w.add_message(cid, 1, b'{"offset":0,"t":0.0,"data":"+q8="}', 1)
        w.finish()
    assert main(["decode", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "acme.Bytes" in err and "rs30x.Raw" in err


def test_another_tools_mcap_is_still_refused(tmp_path, capsys):
    path = tmp_path / "pose.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="some-robot")
        sid = w.register_schema("x", "jsonschema", b"{}")
        w.add_message(w.register_channel("/pose", "json", sid), 1, b"{}", 1)
        w.finish()
    assert main(["decode", str(path)]) == 2
    assert "not an rs30x-sniff MCAP (written by some-robot; it has no /rs30x/raw channel)" in capsys.readouterr().err


# ---- non-finite and out-of-range times ------------------------------------------------------------------
def with_time(original, dst, text, at=5):
    """A copy whose ``at``-th raw message says ``"t": text`` (as JSON that Python's reader takes)."""
    n = [0]

    def order(messages):
        out = []
        raw_id = next(c.id for c in records(original) if isinstance(c, Channel) and c.topic == RAW)
        for m in messages:
            if m.channel_id == raw_id:
                if n[0] == at:
                    body = json.loads(m.data)
                    text_body = json.dumps(body).replace(f'"t": {json.dumps(body["t"])}', f'"t": {text}')
                    assert text in text_body
                    m = Message(channel_id=m.channel_id, sequence=m.sequence, log_time=m.log_time,
                                publish_time=m.publish_time, data=text_body.encode())
                n[0] += 1
            out.append(m)
        return out

    return rewrite(original, dst, order=order, library="rs30x-sniff test")


@pytest.mark.parametrize("text", ["Infinity", "-Infinity", "NaN", "1e300", "1e400", "-1e300", "1" + "0" * 400])
def test_a_non_finite_or_huge_time_is_an_input_error_where_it_is(original, tmp_path, capsys, text):
    bad = with_time(original, tmp_path / "bad.mcap", text)
    log_time = raw_messages(bad)[5].log_time
    out = tmp_path / "out.mcap"
    for cmd in (["convert", str(bad), "-o", str(out)], ["decode", "--format", "jsonl", str(bad)],
                ["lint", str(bad)], ["info", str(bad)]):
        assert main(cmd) == 2, cmd
        got = capsys.readouterr()
        assert got.err.count("\n") == 1 and got.err.startswith("rs30x-sniff: error:"), got.err
        assert str(bad) in got.err and "/rs30x/raw message 6" in got.err and f"log time {log_time} ns" in got.err
        assert "not a finite number" in got.err
        for line in got.out.splitlines():  # whatever came before the error is JSON
            json.loads(line, parse_constant=lambda c: pytest.fail(f"{c} in {line}"))
    assert not out.exists()


def test_large_finite_times_still_read(original, tmp_path, capsys):
    """The bound is what an MCAP log time holds, not a guess: an epoch time in seconds reads."""
    ok = with_time(original, tmp_path / "ok.mcap", "1732550000.5")
    assert [r[1] for r in McapRawReader(str(ok), warn=None)][5] == 1732550000.5


# ---- the JSON writer's guard ------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [math.inf, -math.inf, math.nan])
def test_json_lines_never_hold_a_non_finite_number(bad):
    """Behind the sources' checks: a record or a Block with a non-finite time is refused, never written
    as NaN, Infinity or inf."""
    frames = hexapod_frames(60)
    dec = Decoder(None, None)
    recs = [r for i, (data, t) in enumerate(frames) for r in dec.feed(data, bad if i == 10 else t)]
    recs += list(dec.close())
    lines = []
    with pytest.raises(NonFiniteError, match="not a finite number"):
        for r in recs:
            lines.append(record_json_line(r))
    assert lines and len(lines) < len(recs)
    # The columnar decoder keeps such a time out of its Blocks (it decodes it as a Record, above); a
    # Block that held one anyway (its time column, set here) is refused as a whole.
    dec = Decoder(None, None, columnar=True)
    blocks = [b for step in (dec.feed_many(frames), dec.close()) for b in step if type(b) is Block]
    assert blocks and "".join(block_json_lines(b) for b in blocks)
    blocks[0].t0[len(blocks[0]) // 2] = bad
    with pytest.raises(NonFiniteError, match="not a finite number"):
        block_json_lines(blocks[0])
