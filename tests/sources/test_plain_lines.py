"""A timestamped capture's plain lines ("TIME HH HH ...") are read many at a time (captures._plain_lines): the same
chunks, the same places for locate(), the same errors (line and column) and the same unit as line by line, whatever
the other lines among them (comments, spacing, signs, bad bytes or times) and wherever the blocks are cut."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rs30x_sniff.sources import captures
from rs30x_sniff.sources.base import CaptureError
from rs30x_sniff.sources.captures import read_capture

from .conftest import frames

BASE = [b"%.6f %s" % (t, data.hex(" ").upper().encode()) for data, t in frames(900)]

# Lines of other kinds, each dropped in at a line: (its text; the line's time comes first where it has %s).
ODD = [
    b"# a comment", b"", b"   ", b"%s FA AF 01 # and a comment", b"%s FAAF 01", b"%s FAAF01", b"%s FA  AF 01",
    b"%s FA AF 01 ", b" %s FA AF 01", b"%s\tFA AF 01", b"%s  FA AF", b"+%s FA AF 01", b"%se0 FA AF 01",
    b"-%s FA AF 01", b"%s FA ZZ 01", b"%s", b"%s fa af 01", b"%s FA AF 0", b"%s FA AF 01\r",
    b"5000000000.5 FA AF 01", b"nan FA AF", b"1_0.5 FA", b"%s FA AF # \xc2\xb5s", b"\xef\xbb\xbf%s FA AF",
    b"%s FA.AF", b".%s FA AF", b"%s. FA AF", b"%s FA    AF 01",
    b"%s FAAF  01", b"%s FAAF 01 ", b"%s FA AF\x0b01", b"%s FA AF\x0c", b"0x10 FA AF",
]


def _read(path: Path) -> tuple[list, list, object, tuple | None]:
    """(chunks, locate() of every offset and two past the end, the unit, the error) of ``path``."""
    reader = read_capture(str(path))
    chunks, error = [], None
    try:
        for chunk in reader:
            chunks.append(chunk)
    except CaptureError as e:
        error = (str(e), e.line, e.column)
    size = sum(len(d) for d, _ in chunks)
    where = [reader.locate(k) for k in range(size + 2)]
    return chunks, where, reader.time_unit, error


@pytest.fixture
def line_by_line(monkeypatch):
    """Read with no blocks of whole lines (every line through readline), as before blocks."""
    def read(path: Path):
        with monkeypatch.context() as m:
            m.setattr(captures._Lines, "_whole_lines", lambda self: None)
            return _read(path)
    return read


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(odd=st.lists(st.tuples(st.integers(0, len(BASE)), st.sampled_from(ODD)), max_size=4),
       block=st.sampled_from([16, 100, 700, 4096, 1 << 18]), last_lf=st.booleans())
def test_blocks_read_as_line_by_line(tmp_path, monkeypatch, line_by_line, odd, block, last_lf):
    lines = list(BASE)
    for at, text in sorted(odd, reverse=True):
        t = lines[min(at, len(lines) - 1)].split(b" ")[0]
        lines.insert(at, text.replace(b"%s", t) if b"%s" in text else text)
    path = tmp_path / "c.thex"
    path.write_bytes(b"\n".join(lines) + (b"\n" if last_lf else b""))
    monkeypatch.setattr(captures, "_BLOCK_SIZE", block)
    want = line_by_line(path)
    got = _read(path)
    assert got == want
    assert want[0] or want[3]  # something read, or an error said


@pytest.mark.parametrize("block", [64, 4096])
@pytest.mark.parametrize("odd", ODD)
def test_each_kind_of_line_among_plain_ones(tmp_path, monkeypatch, line_by_line, odd, block):
    """Each other kind of line, well past the lines that tell the unit (read in blocks before and after it)."""
    lines = list(BASE)
    lines.insert(600, odd.replace(b"%s", lines[600].split(b" ")[0]))
    path = tmp_path / "c.thex"
    path.write_bytes(b"\n".join(lines) + b"\n")
    monkeypatch.setattr(captures, "_BLOCK_SIZE", block)
    assert _read(path) == line_by_line(path)


def test_a_long_plain_capture_is_read_in_blocks(tmp_path, monkeypatch):
    """The blocks are taken (not every line one by one), and give every line's chunk and place."""
    path = tmp_path / "c.thex"
    path.write_bytes(b"\n".join(BASE) + b"\n")
    calls = []
    plain = captures._plain_lines

    def counted(*args):
        got = plain(*args)
        calls.append(got is not None)
        return got

    monkeypatch.setattr(captures, "_BLOCK_SIZE", 4096)
    monkeypatch.setattr(captures, "_plain_lines", counted)
    chunks, where, _, error = _read(path)
    assert error is None and calls and all(calls)
    assert chunks == [(d, float(b"%.6f" % t)) for d, t in frames(900)]
    raw = path.read_bytes().split(b"\n")
    data = b"".join(d for d, _ in chunks)
    for k, (line, col) in enumerate(where[:-2]):
        assert raw[line - 1][col - 1:col + 1] == b"%02X" % data[k]
    assert where[-2:] == [None, None]
