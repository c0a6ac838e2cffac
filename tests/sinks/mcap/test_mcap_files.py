"""The file itself: readable by the mcap library both ways, chunks bounded, metadata, damaged and foreign files."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap

import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from rs30x_sniff.sources.captures import CaptureError, read_capture
from rs30x_sniff.sinks.mcap.writer import McapSink
from rs30x_sniff.sources.mcap_reader import McapRawReader

from .conftest import ROOT, hexapod_frames, to_mcap


@pytest.fixture(scope="module")
def hexapod_mcap(tmp_path_factory):
    """About 4.4 s of hexapod traffic in chunks of at most 1 s (and 64 KiB)."""
    path = tmp_path_factory.mktemp("m") / "h.mcap"
    frames = hexapod_frames(1500)
    to_mcap(frames, path, chunk_size=64 * 1024, models={5: "RS304MD"})
    return path, frames


def test_seeking_and_streaming_readers_agree(hexapod_mcap):
    path, frames = hexapod_mcap
    with open(path, "rb") as f:
        seeking = make_reader(f)
        summary = seeking.get_summary()
        assert summary is not None and summary.statistics.message_count > 0
        assert len(summary.chunk_indexes) > 3
        assert all(ci.compression == "zstd" for ci in summary.chunk_indexes)
        # Message indexes let a seeking reader pick one topic without decompressing blindly.
        raw_seek = [m.data for _, _, m in seeking.iter_messages(topics=["/rs30x/raw"])]
    with open(path, "rb") as f:
        stream = make_reader(f, validate_crcs=True)
        assert type(stream).__name__ == "SeekingReader"
    with open(path, "rb") as f:
        from mcap.reader import NonSeekingReader
        raw_stream = [m.data for _, c, m in NonSeekingReader(f, validate_crcs=True).iter_messages()
                      if c.topic == "/rs30x/raw"]
    assert raw_seek == raw_stream and len(raw_seek) == len(frames)
    assert summary.statistics.message_count == sum(summary.statistics.channel_message_counts.values())


def test_chunks_are_bounded_by_time_and_size(hexapod_mcap):
    path, _ = hexapod_mcap
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    spans = [(ci.message_end_time - ci.message_start_time) / 1e9 for ci in summary.chunk_indexes]
    assert max(spans) <= 1.0
    assert max(ci.uncompressed_size for ci in summary.chunk_indexes) <= 64 * 1024 + 4096
    # A chunk per second of traffic (or more): a killed writer loses at most about a second.
    assert len(spans) >= 4


def test_metadata_says_what_the_file_is(hexapod_mcap):
    path, _ = hexapod_mcap
    with open(path, "rb") as f:
        reader = make_reader(f)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        assert reader.get_header().library.startswith("rs30x-sniff")
    assert meta["rs30x"]["baud"] == "115200" and meta["rs30x"]["time_base"] == "capture"
    assert meta["rs30x"]["source"] == "test" and meta["rs30x"]["tool_version"]
    assert meta["rs30x"]["models"] == "5=RS304MD"
    # finish() adds what the bus taught: every servo seen, with its model.
    models = dict(item.split("=") for item in meta["rs30x.models"]["models"].split(","))
    assert len(models) == 18 and models["5"] == "RS304MD" and models["1"] == "RS303MR"
    r = McapRawReader(str(path))
    assert r.read_metadata()["rs30x"]["baud"] == "115200" and r.baud == 115200


def test_log_times_are_capture_times(hexapod_mcap):
    path, frames = hexapod_mcap
    with open(path, "rb") as f:
        raws = [(m.log_time, json.loads(m.data)) for _, c, m in make_reader(f).iter_messages(topics=["/rs30x/raw"])]
    assert [lt for lt, _ in raws] == [round(t * 1e9) for _, t in frames]
    assert [o["t"] for _, o in raws] == [t for _, t in frames]


def test_synthetic_times_for_untimed_captures(tmp_path):
    data = b"".join(d for d, _ in hexapod_frames(400))
    out = tmp_path / "u.mcap"
    to_mcap([(data, None)], out, baud=57600)
    with open(out, "rb") as f:
        reader = make_reader(f)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        raws = [(m.log_time, json.loads(m.data)) for _, c, m in reader.iter_messages(topics=["/rs30x/raw"])]
    assert meta["rs30x"]["time_base"] == "synthetic"
    assert len(raws) > 1  # a big untimed block is split
    for lt, o in raws:
        assert o["t"] is None
        assert lt == round(o["offset"] * 10 / 57600 * 1e9)


def test_finish_is_idempotent_and_context_manager_finishes_on_error(tmp_path):
    sink = McapSink(str(tmp_path / "a.mcap"), source="s", baud=115200, time_base="monotonic")
    sink.raw(b"\xfa\xaf", 1.0)
    sink.finish()
    size = sink.bytes_written
    sink.finish()
    assert sink.bytes_written == size == (tmp_path / "a.mcap").stat().st_size
    with pytest.raises(RuntimeError):
        with McapSink(str(tmp_path / "b.mcap"), source="s", baud=115200, time_base="capture") as s2:
            s2.raw(b"\x07", 0.5)
            raise RuntimeError("capture failed")
    assert list(read_capture(str(tmp_path / "b.mcap"))) == [(b"\x07", 0.5)]
    with pytest.raises(ValueError):
        McapSink(str(tmp_path / "c.mcap"), source="s", baud=115200, time_base="sundial")


# ---- damaged and foreign files -------------------------------------------------------------------
def test_a_file_cut_anywhere_is_read_up_to_its_last_complete_chunk(hexapod_mcap, tmp_path):
    path, frames = hexapod_mcap
    blob = path.read_bytes()
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    chunk_ends = sorted(ci.chunk_start_offset + ci.chunk_length for ci in summary.chunk_indexes)
    data_end = max(chunk_ends)
    cuts = [9, 40, chunk_ends[0] - 10, chunk_ends[0], chunk_ends[1] + 3, (chunk_ends[1] + chunk_ends[2]) // 2,
            data_end - 1, len(blob) - 30, len(blob) - 1]
    full = b"".join(d for d, _ in frames)
    for cut in cuts:
        cut_path = tmp_path / f"cut{cut}.mcap"
        cut_path.write_bytes(blob[:cut])
        warnings: list[str] = []
        reader = McapRawReader(str(cut_path), warn=warnings.append)
        got = b"".join(r[0] for r in reader)
        assert full.startswith(got), cut
        if cut < data_end:
            assert reader.complete is False and len(warnings) == 1, cut
            assert "\n" not in warnings[0] and str(cut_path) in warnings[0]
            prev_end = max([e for e in chunk_ends if e <= cut], default=0)
            assert 0 <= reader.lost_bytes <= cut - prev_end, cut
            assert (f"lost the last {reader.lost_bytes} bytes" in warnings[0]) == (reader.lost_bytes > 0)
            complete_chunks = sum(1 for e in chunk_ends if e <= cut)
            assert reader.chunks == complete_chunks, cut
        else:
            # The data section is whole: only the summary or footer is missing, nothing is lost.
            assert got == full
            assert reader.complete is True and not warnings


def test_a_cut_file_warns_on_stderr_through_read_capture(hexapod_mcap, tmp_path, capsys):
    path, _ = hexapod_mcap
    blob = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(blob[: len(blob) // 2])
    n = sum(len(d) for d, _ in read_capture(str(cut)))
    err = capsys.readouterr().err
    assert n > 0 and err.count("\n") == 1 and "warning" in err and "lost the last" in err


def test_garbage_and_foreign_files_are_one_line_errors(tmp_path):
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"this is not an mcap file at all")
    with pytest.raises(CaptureError, match="not an MCAP file"):
        list(read_capture(str(bad)))
    foreign = tmp_path / "other.mcap"
    with open(foreign, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="some-robot")
        sid = w.register_schema("x", "jsonschema", b"{}")
        cid = w.register_channel("/pose", "json", sid)
        w.add_message(cid, 1, b"{}", 1)
        w.finish()
    with pytest.raises(CaptureError, match="not an rs30x-sniff MCAP") as e:
        list(read_capture(str(foreign)))
    assert "\n" not in str(e.value)
    # A whole-length chunk whose compressed bytes were damaged is an error, not a crash.
    good = tmp_path / "g.mcap"
    to_mcap(hexapod_frames(50), good)
    blob = bytearray(good.read_bytes())
    with open(good, "rb") as f:
        ci = make_reader(f).get_summary().chunk_indexes[0]
    mid = ci.chunk_start_offset + ci.chunk_length // 2
    blob[mid:mid + 8] = b"\xff" * 8
    damaged = tmp_path / "d.mcap"
    damaged.write_bytes(bytes(blob))
    with pytest.raises(CaptureError, match="corrupt"):
        list(read_capture(str(damaged)))


def test_a_killed_writer_loses_at_most_about_a_second(tmp_path):
    """A recorder killed with SIGKILL leaves a file readable up to within ~1 s of log time of the kill."""
    out = tmp_path / "killed.mcap"
    script = textwrap.dedent(f"""
        import sys, time
        from rs30x_sniff.sinks.mcap.writer import McapSink
        sink = McapSink({str(out)!r}, source="port", baud=115200, time_base="capture")
        t = 0.0
        while True:
            sink.raw(b"\\xfa\\xaf\\x01\\x09\\x00\\x00\\x01\\x09", t)
            if t >= 5.0 and t - 0.01 < 5.0:
                print("at", t, flush=True)
            if t >= 5.0:
                time.sleep(0.001)
            t += 0.01
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        line = proc.stdout.readline()
        assert line.startswith("at")
        given = float(line.split()[1])
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    warnings: list[str] = []
    times = [r[1] for r in McapRawReader(str(out), warn=warnings.append)]
    assert warnings and times
    assert times[-1] >= given - 1.05
