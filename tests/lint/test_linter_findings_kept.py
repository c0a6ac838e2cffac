"""What a Linter keeps of its findings: all of them by default, none it has handed on with keep_findings=False."""

from __future__ import annotations

from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.lint import Linter
from rs30x_sniff.protocol.wire import encode_short


def _noisy(n: int) -> list[tuple[bytes, float]]:
    """``n`` requests with a bad checksum, one every 10 ms: a finding each."""
    out = []
    for i in range(n):
        frame = bytearray(encode_short(1, 0, 0x1E, b"\x00\x00"))
        frame[-1] ^= 0xFF
        out.append((bytes(frame), i * 0.01))
    return out


def _handed_on(linter: Linter, chunks) -> list:
    dec = Decoder(None, linter)
    got = []
    for data, t in chunks:
        got += dec.feed(data, t).findings
    got += dec.close().findings
    return got


def test_a_linter_that_keeps_none_hands_on_the_same_findings_and_holds_none():
    chunks = _noisy(200)
    keeping, not_keeping = Linter(), Linter(keep_findings=False)
    a, b = _handed_on(keeping, chunks), _handed_on(not_keeping, chunks)
    assert len(a) >= 200 and [(f.code, f.offset) for f in a] == [(f.code, f.offset) for f in b]
    assert keeping.findings == a  # every one, for a library caller to read at the end
    assert not_keeping.findings == []  # however many came: a live run's memory does not grow with them
