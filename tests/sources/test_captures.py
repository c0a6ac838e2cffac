"""Capture formats: detection by extension and content, streaming reads, one-line errors."""

import pytest

from rs30x_sniff.sources.captures import (
    BINARY, HEX, TIMESTAMPED, CaptureError, detect_format, read_capture, write_capture)

FRAME = bytes.fromhex("FAAF0100 1E020184 039B".replace(" ", ""))


def test_hex_text_with_comments_and_any_number_per_line(tmp_path):
    p = tmp_path / "a.hex"
    p.write_text("# header\nFA AF 01 00   # first half\n1E 02 01 84 03 9B\n\n")
    assert detect_format(str(p)) == HEX
    assert b"".join(d for d, _ in read_capture(str(p))) == FRAME


def test_timestamped_hex(tmp_path):
    p = tmp_path / "a.txt"
    p.write_text("0.000000 FA AF 01 00 1E\n0.000434 02 01 84 03 9B\n")
    assert detect_format(str(p)) == TIMESTAMPED
    assert list(read_capture(str(p))) == [(FRAME[:5], 0.0), (FRAME[5:], 0.000434)]


def test_binary_by_extension_and_by_content(tmp_path):
    a = tmp_path / "a.bin"
    a.write_bytes(FRAME * 3)
    b = tmp_path / "capture"
    b.write_bytes(b"\x00" + FRAME)
    assert detect_format(str(a)) == BINARY and detect_format(str(b)) == BINARY
    assert b"".join(d for d, _ in read_capture(str(a))) == FRAME * 3


def test_roundtrip_through_writers(tmp_path):
    chunks = [(FRAME, 1.5), (FRAME[:3], 1.6)]
    for fmt, name in ((BINARY, "x.bin"), (HEX, "x.hex"), (TIMESTAMPED, "x.thex")):
        p = tmp_path / name
        write_capture(p, chunks, fmt)
        back = list(read_capture(str(p)))
        assert b"".join(d for d, _ in back) == FRAME + FRAME[:3]
        if fmt == TIMESTAMPED:
            assert [t for _, t in back] == [1.5, 1.6]


@pytest.mark.parametrize("content,message", [
    ("FA AF ZZ\n", "not a hex byte: 'ZZ'"),
    ("FA AF 0\n", "not a hex byte: '0'"),
])
def test_bad_hex_names_file_and_line(tmp_path, content, message):
    p = tmp_path / "bad.hex"
    p.write_text("FA AF\n" + content)
    with pytest.raises(CaptureError) as e:
        list(read_capture(str(p)))
    assert f"{p}:2: {message}" in str(e.value)


def test_missing_file_and_unknown_content(tmp_path):
    with pytest.raises(CaptureError, match="no such file"):
        detect_format(str(tmp_path / "nope.hex"))
    p = tmp_path / "notes.md"
    p.write_text("hello world, this is not a capture\n")
    with pytest.raises(CaptureError, match="unknown capture format"):
        detect_format(str(p))
