"""Text captures: BOM, non-ASCII comments, integer and bad times, and errors that name the line."""

from __future__ import annotations

import pytest

from rs30x_sniff.sources.captures import BINARY, HEX, TIMESTAMPED, CaptureError, detect_format, read_capture

from .conftest import FRAME

FRAME_HEX = FRAME.hex(" ").upper()  # FA AF 01 00 1E 02 01 84 03 9B


def _write(tmp_path, name: str, content: bytes | str):
    p = tmp_path / name
    p.write_bytes(content.encode("utf-8") if isinstance(content, str) else content)
    return str(p)


def _data(path: str, fmt: str | None = None) -> bytes:
    return b"".join(d for d, _ in read_capture(path, fmt))


@pytest.mark.parametrize("name", ["a.hex", "a.txt", "noext"])
def test_a_utf8_bom_is_skipped(tmp_path, name):
    p = _write(tmp_path, name, b"\xef\xbb\xbf" + f"{FRAME_HEX}\n".encode())
    assert detect_format(p) == HEX and _data(p) == FRAME
    p = _write(tmp_path, "t" + name, b"\xef\xbb\xbf" + f"0.5 {FRAME_HEX}\n".encode())
    assert detect_format(p) == TIMESTAMPED and list(read_capture(p)) == [(FRAME, 0.5)]


@pytest.mark.parametrize("comment", ["# servo at 90°\n", "# Grad: 90\xb0 (latin-1)\n", "# \u30b5\u30fc\u30dc\n"])
@pytest.mark.parametrize("name", ["a.hex", "noext"])
def test_non_ascii_comments_are_comments(tmp_path, comment, name):
    raw = comment.encode("latin-1") if "latin-1" in comment else comment.encode()
    p = _write(tmp_path, name, raw + f"{FRAME_HEX}  {comment}".encode("utf-8"))
    assert detect_format(p) == HEX and _data(p) == FRAME


def test_integer_times_are_times(tmp_path):
    p = _write(tmp_path, "a.txt", f"10 {FRAME_HEX}\n250 {FRAME_HEX}\n1000 {FRAME_HEX}\n")
    assert detect_format(p) == TIMESTAMPED
    assert [t for _, t in read_capture(p)] == [10.0, 250.0, 1000.0]
    # Clock ticks of 3+ digits that never decrease, even when each could be read as hex bytes.
    p = _write(tmp_path, "b.txt", f"1000 {FRAME_HEX}\n2000 {FRAME_HEX}\n2000 FA\n")
    assert detect_format(p) == TIMESTAMPED
    p = _write(tmp_path, "c.txt", f"0.001 {FRAME_HEX}\n1e-3 FA AF\n")
    assert [t for _, t in read_capture(p)] == [0.001, 0.001]


@pytest.mark.parametrize("content", [
    f"10 {FRAME_HEX}\n20 {FRAME_HEX}\n",       # two-digit first tokens: ambiguous, read as data
    "2000FAAF\n1000FAAF\n",                    # decreasing and written like the rest: not a clock
    "1000 FAAF01\n",                            # one line, its bytes run together as the first token's
    "FA AF 01\n1E 02\n",
])
def test_hex_that_could_be_times_stays_hex(tmp_path, content):
    p = _write(tmp_path, "a.hex", content)
    assert detect_format(p) == HEX
    first = content.split()[0]
    assert _data(p).startswith(bytes.fromhex(first))


@pytest.mark.parametrize("content,times", [
    (f"1767225600 {FRAME_HEX}\n", [1767225600.0]),               # the one line: epoch seconds
    (f"1000 {FRAME_HEX}\n", [1000.0]),                            # one line, a time
    (f"2000 {FRAME_HEX}\n1000 {FRAME_HEX}\n", [2000.0, 1000.0]),  # a clock that went back is still a clock
])
def test_digits_run_together_before_spaced_bytes_are_a_time_and_said(tmp_path, content, times):
    # "1767225600 FA AF ..." as hex would be 17 67 22 56 00 run together before bytes written one by one:
    # no dump writes a line's bytes so, so the first column is read as times, and the reader says it.
    p = _write(tmp_path, "a.txt", content)
    assert detect_format(p) == TIMESTAMPED
    said: list[str] = []
    reader = read_capture(p, warn=said.append, options={"now": 1767225600.0})
    assert [t for _, t in reader] == times and b"".join(d for d, _ in read_capture(p)) == FRAME * len(times)
    first = content.split()[0]
    assert said == [f"{p}: its first column ({first}{', ...' if len(times) > 1 else ''}) is read as times, not "
                    "hex bytes: digits run together before bytes written apart (--input-format hex to read it "
                    "as bytes)"]
    assert [w.message for w in reader.warnings] == said
    assert list(read_capture(p, HEX))[0][0].startswith(bytes.fromhex(first))  # --input-format hex: bytes


def test_a_clock_of_whole_numbers_is_not_said(tmp_path):
    p = _write(tmp_path, "a.txt", f"1000 {FRAME_HEX}\n2000 {FRAME_HEX}\n")
    said: list[str] = []
    assert [t for _, t in read_capture(p, warn=said.append)] == [1000.0, 2000.0] and said == []


def test_forced_timestamped_reads_two_digit_times(tmp_path):
    p = _write(tmp_path, "a.hex", f"10 {FRAME_HEX}\n20 FA AF\n")
    assert list(read_capture(p, TIMESTAMPED)) == [(FRAME, 10.0), (b"\xfa\xaf", 20.0)]


@pytest.mark.parametrize("bad", ["nan", "inf", "-0.5", "-inf", "NaN", "1e999"])
def test_bad_times_are_bad_times_with_a_line_number(tmp_path, bad):
    p = _write(tmp_path, "a.thex", f"0.1 FA AF\n0.2 FA AF\n{bad} FA AF\n0.4 FA\n")
    assert detect_format(p) == TIMESTAMPED
    with pytest.raises(CaptureError) as e:
        list(read_capture(p))
    assert str(e.value) == f"{p}:3: time {bad!r} is not a finite, non-negative number"
    assert (e.value.line, e.value.column) == (3, 1)


def test_a_bad_first_time_is_named_too(tmp_path):
    # Detection sees a file of times; the reader says which time is bad.
    p = _write(tmp_path, "a.txt", f"nan {FRAME_HEX}\n")
    with pytest.raises(CaptureError, match=r":1: time 'nan' is not a finite"):
        list(read_capture(p))


@pytest.mark.parametrize("content,fmt,line,col,message", [
    ("FA AF\n  FA ZZ 01\n", HEX, 2, 6, "not a hex byte: 'ZZ'"),
    ("FA AF\nFA 0\n", HEX, 2, 4, "not a hex byte: '0'"),
    ("FA AF\nFA 90°\n", HEX, 2, 4, "not a hex byte: '90°'"),
    ("0.1 FA AF\n0.2  FA GG\n", TIMESTAMPED, 2, 9, "not a hex byte: 'GG'"),
    ("0.1 FA AF\nabc FA\n", TIMESTAMPED, 2, 1, "expected a time in seconds, got 'abc'"),
    ("0.1 FA AF\n 0.2 FA 1\n", TIMESTAMPED, 2, 9, "not a hex byte: '1'"),
])
def test_every_text_error_names_line_and_column(tmp_path, content, fmt, line, col, message):
    p = _write(tmp_path, "bad.txt", content)
    with pytest.raises(CaptureError) as e:
        list(read_capture(p, fmt))
    assert str(e.value) == f"{p}:{line}: {message}"
    assert (e.value.line, e.value.column) == (line, col)
    assert "\n" not in str(e.value)


def test_a_text_file_without_extension_and_a_bad_token_names_the_line(tmp_path):
    # Read as its first data line says, so the error points at the bad line, not "unknown format".
    p = _write(tmp_path, "capture", "FA AF 01\nFA XX\n")
    with pytest.raises(CaptureError, match=r"capture:2: not a hex byte: 'XX'"):
        list(read_capture(p))
    p = _write(tmp_path, "notes", "hello world, this is not a capture\n")
    with pytest.raises(CaptureError, match="unknown capture format"):
        detect_format(p)


def test_binary_is_not_mistaken_for_text(tmp_path):
    p = _write(tmp_path, "capture", b"#" + FRAME * 3)
    assert detect_format(p) == BINARY and _data(p) == b"#" + FRAME * 3
    p = _write(tmp_path, "a.hex", FRAME)
    with pytest.raises(CaptureError, match=r"a.hex:1: not a hex byte"):
        list(read_capture(p))


def test_a_head_cut_mid_line_still_sniffs(tmp_path):
    # The 4 KiB window ends inside a line (and inside a UTF-8 comment character).
    line = f"0.000100 {FRAME_HEX}  # 90°\n"
    content = line * (4096 // len(line) + 3)
    p = _write(tmp_path, "x", content)
    assert detect_format(p) == TIMESTAMPED
    assert len(list(read_capture(p))) == content.count("\n")
