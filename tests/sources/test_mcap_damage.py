"""Corrupt and foreign MCAP files: read up to the damage with a warning, or a one-line error; never a traceback."""

from __future__ import annotations

import os

import pytest
from mcap.reader import make_reader

from rs30x_sniff.sources.captures import CaptureError, CaptureWarning, read_capture
from rs30x_sniff.sources.mcap_reader import McapRawReader

from .conftest import make_mcap


def _read(path, warnings: list | None = None) -> tuple[list, McapRawReader]:
    reader = McapRawReader(str(path), warn=(warnings.append if warnings is not None else None))
    return [(r[0], r[1]) for r in reader], reader


def _chunk_offsets(path) -> list[tuple[int, int]]:
    with open(path, "rb") as f:
        return sorted((ci.chunk_start_offset, ci.chunk_length) for ci in make_reader(f).get_summary().chunk_indexes)


def _flip(path, out, positions, mask=0xFF):
    blob = bytearray(path.read_bytes())
    for i in positions:
        blob[i] ^= mask
    out.write_bytes(bytes(blob))
    return out


def test_a_destroyed_header_is_an_error_not_an_empty_capture(small_mcap, tmp_path):
    path, _ = small_mcap
    # Byte 16 is the top byte of the header's length (it was a traceback); 9-13 its low bytes
    # (it was an empty capture, and "0 findings").
    for positions in ([16], [9, 10, 11, 12, 13], [9], [12]):
        bad = _flip(path, tmp_path / "bad.mcap", positions)
        with pytest.raises(CaptureError, match=r"corrupt MCAP at byte 8, in its header") as e:
            list(read_capture(str(bad)))
        assert "\n" not in str(e.value)
        McapRawReader(str(bad)).read_metadata()  # what convert and info call first: no traceback either


def test_damage_mid_file_keeps_the_chunks_before_it(small_mcap, tmp_path):
    path, original = small_mcap
    chunks = _chunk_offsets(path)
    assert len(chunks) >= 4
    start, length = chunks[2]
    bad = _flip(path, tmp_path / "mid.mcap", [start + length // 2])
    warnings: list[str] = []
    got, reader = _read(bad, warnings)
    assert got and got == original[:len(got)] and len(got) < len(original)
    assert reader.chunks == 2 and reader.complete is False and reader.damaged_at == start
    assert len(warnings) == 1 and f"at byte {start}" in warnings[0] and "read the 2 chunks before it" in warnings[0]
    w = reader.warnings[0]
    assert isinstance(w, CaptureWarning) and w.offset == start and w.lost_bytes == bad.stat().st_size - start
    assert str(w) == warnings[0] and w.path == str(bad)


def test_warnings_are_data_through_read_capture(small_mcap, tmp_path, capsys):
    path, original = small_mcap
    start, length = _chunk_offsets(path)[1]
    bad = _flip(path, tmp_path / "mid.mcap", [start + 30])
    seen: list[str] = []
    r = read_capture(str(bad), warn=seen.append)
    got = list(r)
    assert got == original[:len(got)] and got
    assert [w.message for w in r.warnings] == seen and r.warnings[0].offset == start
    assert capsys.readouterr().err == ""
    r = read_capture(str(bad))  # the default still says it on stderr, once
    list(r)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "warning" in err and f"at byte {start}" in err


def test_a_lost_chunk_is_not_read_past(small_mcap, tmp_path):
    # A chunk whose record type is damaged would be skipped as an unknown record: the raw offsets
    # of the next chunk show the hole, and reading stops at the first chunk after it.
    path, original = small_mcap
    start, _ = _chunk_offsets(path)[2]
    blob = bytearray(path.read_bytes())
    blob[start] = 0x09  # an attachment: a record type a reader may skip
    bad = tmp_path / "hole.mcap"
    bad.write_bytes(bytes(blob))
    got, reader = _read(bad, [])
    assert got == original[:len(got)] and reader.chunks == 2
    assert "missing" in reader.warnings[0].message


def test_foreign_and_empty_files(tmp_path):
    from mcap.writer import Writer

    foreign = tmp_path / "other.mcap"
    with open(foreign, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="some-robot")
        w.finish()
    with pytest.raises(CaptureError, match="not an rs30x-sniff MCAP"):
        list(read_capture(str(foreign)))
    empty = make_mcap(tmp_path / "empty.mcap", [])
    assert list(read_capture(str(empty))) == []  # an empty capture, written whole: not damage


def _prefix_or_error(path, original: list) -> str:
    try:
        got, reader = _read(path, [])
    except CaptureError as e:
        assert "\n" not in str(e)
        return "error"
    assert got == original[:len(got)], "not a prefix of the capture"
    if len(got) < len(original):
        assert reader.complete is False and len(reader.warnings) == 1
    return "prefix" if len(got) < len(original) else "whole"


@pytest.mark.parametrize("mask", [0xFF, 0x01, 0x80])
def test_every_byte_flipped(small_mcap, tmp_path, mask):
    """Each byte of a small MCAP flipped in turn: a one-line error or the start of the capture."""
    path, original = small_mcap
    blob = path.read_bytes()
    step = 1 if mask == 0xFF else 7
    outcomes = {"error": 0, "prefix": 0, "whole": 0}
    bad = tmp_path / "f.mcap"
    bad.write_bytes(blob)
    with open(bad, "r+b", buffering=0) as f:  # flipped in place and back: no file rewritten per position
        for i in range(0, len(blob), step):
            os.pwrite(f.fileno(), bytes([blob[i] ^ mask]), i)
            outcomes[_prefix_or_error(bad, original)] += 1
            os.pwrite(f.fileno(), blob[i:i + 1], i)
    # Damage in the chunks keeps what came before; the summary is never needed.
    assert outcomes["prefix"] > 0 and outcomes["whole"] > 0 and outcomes["error"] > 0, outcomes


def test_every_truncation(small_mcap, tmp_path):
    path, original = small_mcap
    blob = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    for n in list(range(0, len(blob), 50)) + [len(blob) - 1]:
        cut.write_bytes(blob[:n])
        outcome = _prefix_or_error(cut, original)
        assert outcome != "error" or n < 9, n  # a cut file is never an error, past its magic


def test_an_mcap_fifo_is_refused(tmp_path, small_mcap):
    import threading

    path, _ = small_mcap
    fifo = tmp_path / "f.mcap"
    os.mkfifo(fifo)

    def feed():
        try:
            with open(fifo, "wb") as w:
                w.write(path.read_bytes())
        except BrokenPipeError:
            pass

    threading.Thread(target=feed, daemon=True).start()
    with pytest.raises(CaptureError, match="needs a seekable file"):
        list(read_capture(str(fifo)))


def test_a_foreign_writer_name_with_a_newline_stays_one_line(tmp_path):
    # Found by fuzz_mcap: the header's library string went into the message as it was.
    from mcap.writer import Writer

    foreign = tmp_path / "other.mcap"
    with open(foreign, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="rs\nevil")
        w.finish()
    with pytest.raises(CaptureError, match="not an rs30x-sniff MCAP") as e:
        list(read_capture(str(foreign)))
    assert "\n" not in str(e.value) and "'rs\\nevil'" in str(e.value)
