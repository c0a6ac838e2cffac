"""Text captures in UTF-16 (with a byte-order mark), UTF-8 with a mark, and CR or CRLF line ends read exactly as
UTF-8 with LF does; any other encoding is one line naming it."""

from __future__ import annotations

import os
import subprocess
import sys
import threading

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.sources.captures import HEX, TIMESTAMPED, CaptureError, detect_format, read_capture

from .conftest import CAPTURES, ROOT

MANUAL = CAPTURES / "manual-examples.hex"   # comments, blank lines, many bytes a line
SESSION = CAPTURES / "session-mixed.thex"   # timestamped, a comment header

# Each encoding as a file writes it: its byte-order mark, then the text.
ENCODINGS = {
    "utf-8": lambda text: text.encode("utf-8"),
    "utf-8-bom": lambda text: b"\xef\xbb\xbf" + text.encode("utf-8"),
    "utf-16-le-bom": lambda text: b"\xff\xfe" + text.encode("utf-16-le"),  # PowerShell's `>`
    "utf-16-be-bom": lambda text: b"\xfe\xff" + text.encode("utf-16-be"),
}
LINE_ENDS = {"lf": "\n", "crlf": "\r\n", "cr": "\r"}


def _encoded(text: str, encoding: str, end: str) -> bytes:
    return ENCODINGS[encoding](text.replace("\n", LINE_ENDS[end]))


def _read(path: str) -> tuple[str, list, list]:
    """The format, the chunks, and where (line, column) each chunk's first byte is."""
    reader = read_capture(path, warn=None)
    chunks = list(reader)
    where, offset = [], 0
    for data, _ in chunks:
        where.append(reader.locate(offset))
        offset += len(data)
    return reader.format, chunks, where


def _pipe(content: bytes) -> tuple[str, int]:
    r, w = os.pipe()

    def writer() -> None:
        view = memoryview(content)
        try:
            while view:
                view = view[os.write(w, view):]
        finally:
            os.close(w)

    threading.Thread(target=writer, daemon=True).start()
    return f"/dev/fd/{r}", r


@pytest.fixture(scope="module")
def plain():
    return {fmt: _read(str(src)) for fmt, src in ((HEX, MANUAL), (TIMESTAMPED, SESSION))}


@pytest.mark.parametrize("fmt,src", [(HEX, MANUAL), (TIMESTAMPED, SESSION)])
@pytest.mark.parametrize("encoding", sorted(ENCODINGS))
@pytest.mark.parametrize("end", sorted(LINE_ENDS))
@pytest.mark.parametrize("name", ["capture.txt", "capture"])
def test_every_encoding_and_line_end_reads_as_utf8_lf(tmp_path, plain, fmt, src, encoding, end, name):
    p = tmp_path / name
    p.write_bytes(_encoded(src.read_text("utf-8"), encoding, end))
    assert detect_format(str(p)) == fmt
    assert _read(str(p)) == plain[fmt]  # the same chunks, times and line:column of every chunk


# A capture made of random lines (comments, blank lines, bytes spaced or not, times in any spelling), written
# in every encoding and line end: the same chunks as its UTF-8 LF file, from a file and from a pipe.
_byte = st.binary(min_size=1, max_size=12)
_line = st.one_of(
    st.tuples(st.just("data"), _byte, st.booleans()),
    st.tuples(st.just("comment"), st.text(st.characters(blacklist_categories=("Cs", "Cc")), max_size=20),
              st.booleans()),
    st.tuples(st.just("blank"), st.just(b""), st.booleans()),
)


def _text(lines, timed: bool) -> str:
    out, t = [], 0.25
    for kind, value, flag in lines:
        if kind == "data":
            hexs = value.hex(" ").upper() if flag else value.hex()  # spaced, or run together
            t += 0.000125
            out.append(f"{t:.6f} {hexs}" if timed else hexs)
        elif kind == "comment":
            out.append(("  " if flag else "") + "# " + value.replace("\r", " ").replace("\n", " ")
                       .replace("\x85", " ").replace("\u2028", " ").replace("\u2029", " "))
        else:
            out.append("   " if flag else "")
    return "\n".join(out) + "\n"


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lines=st.lists(_line, min_size=1, max_size=30).filter(lambda ls: any(k == "data" for k, _, _ in ls)),
       timed=st.booleans(), encoding=st.sampled_from(sorted(ENCODINGS)), end=st.sampled_from(sorted(LINE_ENDS)),
       piped=st.booleans())
def test_any_capture_in_any_encoding_and_line_end_reads_the_same(tmp_path_factory, lines, timed, encoding, end,
                                                                 piped):
    d = tmp_path_factory.mktemp("enc")
    text = _text(lines, timed)
    ref = d / "ref.txt"
    ref.write_bytes(text.encode("utf-8"))
    expected = [c for c in read_capture(str(ref), TIMESTAMPED if timed else HEX, warn=None, options={"now": 0})]
    content = _encoded(text, encoding, end)
    fmt = TIMESTAMPED if timed else HEX
    if piped:
        path, fd = _pipe(content)
        try:
            got = list(read_capture(path, fmt, warn=None, options={"now": 0}))
        finally:
            os.close(fd)
    else:
        p = d / "x.txt"
        p.write_bytes(content)
        got = list(read_capture(str(p), fmt, warn=None, options={"now": 0}))
    assert b"".join(c[0] for c in got) == b"".join(c[0] for c in expected)
    assert [c[1] for c in got if c[1] is not None] == [c[1] for c in expected if c[1] is not None]


@pytest.mark.parametrize("encoding,name", [
    ("utf-32", "UTF-32 LE"),
    ("utf-32-be-bom", "UTF-32 BE"),
    ("utf-16-le", "UTF-16 LE without a byte-order mark"),
    ("utf-16-be", "UTF-16 BE without a byte-order mark"),
])
@pytest.mark.parametrize("src", [MANUAL, SESSION])
def test_another_encoding_is_one_line_naming_it(tmp_path, encoding, name, src):
    text = src.read_text("utf-8")
    content = b"\x00\x00\xfe\xff" + text.encode("utf-32-be") if encoding == "utf-32-be-bom" else text.encode(encoding)
    p = tmp_path / f"x{src.suffix}"
    p.write_bytes(content)
    with pytest.raises(CaptureError) as e:
        list(read_capture(str(p)))
    assert str(e.value).startswith(f"{p}: a text capture in {name}, which is not read ")
    assert e.value.line == 1  # where the encoding shows (an editor's or CI annotation's place)
    proc = subprocess.run([sys.executable, "-m", "rs30x_sniff", "decode", str(p), "--isolated"], capture_output=True,
                          text=True, cwd=ROOT, timeout=60)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr and name in proc.stderr


def test_a_cr_only_hex_file_is_not_one_comment(tmp_path, plain):
    # The case: a CR-only .hex decoded as empty (exit 0): its first comment line swallowed the file.
    p = tmp_path / "mac.hex"
    p.write_bytes(MANUAL.read_bytes().replace(b"\n", b"\r"))
    assert _read(str(p)) == plain[HEX]
    out = subprocess.run([sys.executable, "-m", "rs30x_sniff", "decode", str(p), "--isolated", "--no-lint"],
                         capture_output=True, text=True, cwd=ROOT, timeout=60)
    direct = subprocess.run([sys.executable, "-m", "rs30x_sniff", "decode", str(MANUAL), "--isolated", "--no-lint"],
                            capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert out.returncode == 0 and out.stdout == direct.stdout and out.stdout.count("\n") > 10


def test_powershell_output_on_stdin(plain):
    # `Get-Content x.thex > y.thex` then `rs30x-sniff decode - < y.thex`, or piped.
    content = b"\xff\xfe" + SESSION.read_text("utf-8").replace("\n", "\r\n").encode("utf-16-le")
    code = ("from rs30x_sniff.sources.captures import read_capture\n"
            "r = read_capture('-', warn=None)\n"
            "print(r.format, sum(len(d) for d, _ in r))\n")
    proc = subprocess.run([sys.executable, "-c", code], input=content, capture_output=True, cwd=ROOT, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.decode().split() == [TIMESTAMPED, str(sum(len(d) for d, _ in plain[TIMESTAMPED][1]))]
