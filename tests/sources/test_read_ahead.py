"""A capture read by a child process (io.read_ahead) is what read_input reads: chunks, marks, warnings, errors."""

from __future__ import annotations

import io
import pickle

import pytest

from rs30x_sniff.protocol.chunks import Marked
from rs30x_sniff.sources import read_ahead as read_ahead_module
from rs30x_sniff.sources.captures import CaptureError, write_capture
from rs30x_sniff.sources.inputs import read_input
from rs30x_sniff.sources.read_ahead import ReadAhead, receive, send_all

from .conftest import CAPTURES, frames, make_mcap
from .test_mcap_damage import _chunk_offsets, _flip

BAUD = 115200


def as_read(chunks) -> list:
    """Chunks with everything that tells them apart: bytes, time, type and marks."""
    return [(c[0], c[1], type(c).__name__, getattr(c, "sender", None), getattr(c, "error", None)) for c in chunks]


def both(path, **kw):
    """(chunks, warnings, error) of read_input in this process, and of a ReadAhead."""
    out = []
    for read in (read_input, ReadAhead):
        warnings: list[str] = []
        chunks: list = []
        error = None
        try:
            for c in read(str(path), baud=BAUD, warn=warnings.append, **kw):
                chunks.append(c)
        except CaptureError as e:
            error = (str(e), e.line, e.column)
        out.append((as_read(chunks), warnings, error))
    return out


@pytest.mark.parametrize("name", ["session-mixed.thex", "manual-examples.hex", "foreign/spy.log",
                                  "foreign/socat.log", "foreign/saleae-logic2.csv", "foreign/sigrok-hexapod.sr"])
def test_the_same_chunks_as_read_input(name):
    here, ahead = both(CAPTURES / name)
    assert here == ahead and here[0] and here[2] is None


def test_arrival_times_laid_back_and_untimed_binary(tmp_path):
    chunks = frames(3000)
    thex = tmp_path / "a.thex"
    write_capture(str(thex), chunks, "timestamped")
    here, ahead = both(thex, time_ref="arrival")
    assert here == ahead and len(here[0]) == 3000
    (tmp_path / "a.bin").write_bytes(b"".join(d for d, _ in chunks) * 20)  # several batches, no times
    here, ahead = both(tmp_path / "a.bin")
    assert here == ahead and {t for _, t, *_ in here[0]} == {None}


def test_a_damaged_mcap_warns_once_and_keeps_what_came_before(tmp_path):
    path = make_mcap(tmp_path / "small.mcap", frames(50))
    start, length = _chunk_offsets(path)[2]
    bad = _flip(path, tmp_path / "mid.mcap", [start + length // 2])
    here, ahead = both(bad)
    assert here == ahead and len(here[1]) == 1 and f"at byte {start}" in here[1][0]


def test_a_bad_line_is_the_same_one_line_error_after_what_came_before(tmp_path):
    p = tmp_path / "bad.thex"
    p.write_text("".join(f"{i * 0.001:.6f} FA AF 01 00 1E 02 01 00 00 1C\n" for i in range(20000)) + "0.5 FA ZZ\n")
    here, ahead = both(p)
    assert here == ahead
    assert here[2] == (f"{p}:20001: not a hex byte: 'ZZ'", 20001, 8) and len(here[0]) == 20000


def test_a_missing_file_is_a_one_line_error(tmp_path):
    here, ahead = both(tmp_path / "nope.hex")
    assert here[2] is not None and ahead[2] is not None and "\n" not in ahead[2][0] and not ahead[0]


def test_leaving_early_stops_the_child(tmp_path):
    p = tmp_path / "big.thex"
    write_capture(str(p), frames(50000), "timestamped")
    r = ReadAhead(str(p), baud=BAUD)
    first = [next(r) for _ in range(10)]
    r.close()
    assert r._proc.returncode is not None  # killed and reaped
    assert as_read(first) == as_read(list(read_input(str(p), baud=BAUD))[:10])


def test_a_child_that_dies_is_a_one_line_error(tmp_path):
    p = tmp_path / "big.thex"
    write_capture(str(p), frames(50000), "timestamped")
    r = ReadAhead(str(p), baud=BAUD)
    next(r)
    r._proc.kill()
    with pytest.raises(CaptureError, match="the process reading it ended early"):
        for _ in r:
            pass


def test_every_kind_of_batch(monkeypatch):
    """Plain chunks in one blob, untimed ones, marked ones and a batch mixing times and None, through
    the messages themselves (no process): in order, each as it was."""
    mixed = [(b"\x01", 0.5), (b"\x02\x03", None)]
    chunks = ([(bytes([i]) * (i % 7 + 1), i * 0.25) for i in range(40)] + [(b"\xfa" * 300_000, 11.0)]
              + [Marked(b"\x07", 12.0, sender="servo"), Marked(b"\x08", None, error="framing")]
              + [(b"\x00" * 5, None)] * 3 + mixed)

    def fake_read_input(path, fmt, *, baud, time_ref, warn, options):
        warn("worked around something")
        yield from chunks
        raise CaptureError(f"{path}:9: broken", line=9, column=2)

    monkeypatch.setattr("rs30x_sniff.sources.inputs.read_input", fake_read_input)
    monkeypatch.setattr(read_ahead_module, "BATCH_BYTES", 64)
    out = io.BytesIO()
    send_all(out, {"path": "x.thex", "fmt": None, "baud": BAUD, "time_ref": None, "options": None})
    out.seek(0)
    kinds = []
    load_one = lambda: pickle.load(out)  # noqa: E731

    def load():
        msg = load_one()
        kinds.append(msg[0])
        return msg

    warnings: list[str] = []
    got = []
    with pytest.raises(CaptureError, match="x.thex:9: broken") as e:
        for c in receive(load, "x.thex", warnings.append):
            got.append(c)
    assert as_read(got) == as_read(chunks) and e.value.line == 9 and e.value.column == 2
    assert warnings == ["worked around something"]
    assert {"data", "chunks", "warn", "error"} <= set(kinds)
