"""locate(): from a stream byte offset back to the line and column of a text capture."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from rs30x_sniff.sources.captures import BINARY, HEX, TIMESTAMPED, read_capture, write_capture

from .conftest import CAPTURES, FRAME, frames, make_mcap


def _check_every_byte(path: str, fmt: str | None = None) -> int:
    """Every byte read is found at the line and column locate() gives; returns the bytes read."""
    reader = read_capture(path, fmt)
    data = b"".join(d for d, _ in reader)
    raw = open(path, "rb").read()
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]  # columns count from after the BOM, as an editor shows them
    lines = raw.split(b"\n")
    for offset, byte in enumerate(data):
        line, col = reader.locate(offset)
        assert lines[line - 1][col - 1:col + 1] == b"%02X" % byte or \
            lines[line - 1][col - 1:col + 1].upper() == b"%02X" % byte, (offset, line, col)
    assert reader.locate(len(data)) is None and reader.locate(-1) is None
    return len(data)


def test_locate_in_the_sample_captures():
    assert _check_every_byte(str(CAPTURES / "manual-examples.hex")) > 200
    assert _check_every_byte(str(CAPTURES / "session-mixed.thex")) == 7903


def test_locate_uneven_lines_and_comments(tmp_path):
    p = tmp_path / "a.hex"
    p.write_bytes(b"\xef\xbb\xbf# head\n\n  FA AF  01 #c\nFAAF0100 1E\t02\n\n   9B\n")
    assert _check_every_byte(str(p)) == 10
    r = read_capture(str(p))
    list(r)
    assert r.locate(0) == (3, 3) and r.locate(2) == (3, 10) and r.locate(3) == (4, 1) and r.locate(4) == (4, 3)
    assert r.locate(9) == (6, 4) and r.locate(8) == (4, 13)


def test_locate_timestamped(tmp_path):
    p = tmp_path / "a.thex"
    p.write_text("0.5 FA AF 01\n# gap\n  0.75   00 1E\n")
    r = read_capture(str(p))
    assert list(r) == [(b"\xfa\xaf\x01", 0.5), (b"\x00\x1e", 0.75)]
    assert [r.locate(i) for i in range(6)] == [(1, 5), (1, 8), (1, 11), (3, 10), (3, 13), None]


def test_locate_follows_the_reading(tmp_path):
    # Offsets are known as soon as their line has been read (a big hex file comes in 64 KiB chunks).
    p = tmp_path / "big.hex"
    write_capture(p, [(FRAME * 100, None)] * 200, HEX)
    r = read_capture(str(p))
    first = next(r)
    assert r.locate(len(first) - 1) is not None
    assert r.locate(len(FRAME) * 100 * 200 - 1) is None
    list(r)
    assert r.locate(len(FRAME) * 100 * 200 - 1) == (200, 1 + 3 * (len(FRAME) * 100 - 1))


def test_locate_is_none_for_binary_and_mcap(tmp_path):
    b = tmp_path / "a.bin"
    write_capture(b, [(FRAME, None)], BINARY)
    r = read_capture(str(b))
    list(r)
    assert r.locate(0) is None
    m = make_mcap(tmp_path / "a.mcap", frames(3))
    r = read_capture(str(m))
    list(r)
    assert r.locate(0) is None


_hex_byte = st.integers(0, 255).map(lambda b: b"%02X" % b)
_space = st.sampled_from([b" ", b"  ", b"\t", b" \t "])
_token = st.lists(_hex_byte, min_size=1, max_size=3).map(b"".join)
_line = st.tuples(
    st.sampled_from([b"", b" ", b"\t"]),
    st.lists(_token, max_size=6),
    _space,
    st.sampled_from([b"", b"# note", b"# 90\xc2\xb0", b"#"]),
    st.sampled_from([b"\n", b"\r\n"]),
)


@settings(max_examples=150, deadline=None)
@given(lines=st.lists(_line, min_size=1, max_size=12), bom=st.booleans(),
       times=st.booleans())
def test_locate_property(tmp_path_factory, lines, bom, times):
    out = []
    for i, (lead, tokens, space, comment, eol) in enumerate(lines):
        time = b"%d.%03d " % (i, i) if times and tokens else b""
        out.append(lead + time + space.join(tokens) + (space + comment if comment else b"") + eol)
    p = tmp_path_factory.mktemp("loc") / "x.txt"
    p.write_bytes((b"\xef\xbb\xbf" if bom else b"") + b"".join(out))
    n = _check_every_byte(str(p), TIMESTAMPED if times else HEX)
    assert n == sum(len(tok) // 2 for _, tokens, _, _, _ in lines for tok in tokens)
