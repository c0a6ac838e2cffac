"""Fuzz targets: one function per reader (and the decoder) taking arbitrary bytes and checking its properties."""

# Each check_<target>(data) returns, or raises AssertionError (a property broken) or anything else
# (a crash); CaptureError is the documented answer to bad input and is swallowed. Shared by the
# atheris scripts (fuzz_<target>.py) and the pytest smoke test.

from __future__ import annotations

import math
import os
import re
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))  # run as a script: the package from this checkout

from rs30x_sniff.sources.captures import (
    BINARY, HEX, MCAP, TIMESTAMPED, CaptureError, detect_format, input_formats, read_capture)

CAPTURES = ROOT / "captures"
_DIR = Path(tempfile.mkdtemp(prefix="rs30x-fuzz-"))
_HEX = re.compile(rb"^(?:[0-9a-fA-F]{2})+$")
_NUMBER = re.compile(rb"^[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$|^[+-]?(?:nan|inf|infinity)$", re.I)


def _file(data: bytes, name: str) -> str:
    p = _DIR / name
    p.write_bytes(data)
    return str(p)


# ---- readers ---------------------------------------------------------------------------------------
def check_bin(data: bytes) -> None:
    """Binary: the chunks are the file, byte for byte."""
    path = _file(data, "x.bin")
    assert b"".join(d for d, _ in read_capture(path, BINARY)) == data


def _reference_text(data: bytes, timestamped: bool) -> list[tuple[bytes, float | None]] | None:
    """What a text capture holds, by a slow, independent reading of the format (None: it is invalid)."""
    # The encodings and line ends a text capture may come in (README): UTF-32 is refused, UTF-16 with its mark
    # read, and CRLF or a lone CR end a line as LF does.
    if data.startswith((b"\xff\xfe\x00\x00", b"\x00\x00\xfe\xff")):
        return None
    for bom, encoding in ((b"\xff\xfe", "utf-16-le"), (b"\xfe\xff", "utf-16-be")):
        if data.startswith(bom):
            data = data[2:].decode(encoding, "replace").encode("utf-8")
            break
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    out: list[tuple[bytes, float | None]] = []
    for line in data.split(b"\n"):
        tokens = line.split(b"#", 1)[0].split()
        if not tokens:
            continue
        t = None
        if timestamped:
            if not _NUMBER.match(tokens[0]):
                return None
            t = float(tokens[0])
            if not (math.isfinite(t) and t >= 0):
                return None
            tokens = tokens[1:]
        if not all(_HEX.match(tok) for tok in tokens):
            return None
        chunk = bytes.fromhex(b"".join(tokens).decode())
        if chunk:
            out.append((chunk, t))
    return out


def _check_text(data: bytes, fmt: str) -> None:
    path = _file(data, "x.txt")
    expected = _reference_text(data, fmt == TIMESTAMPED)
    reader = read_capture(path, fmt)
    try:
        got = list(reader)
    except CaptureError as e:
        assert expected is None, f"rejected a valid capture: {e}"
        assert e.line is not None and "\n" not in str(e), str(e)
        return
    assert expected is not None, "accepted an invalid capture"
    if fmt == TIMESTAMPED:
        assert got == expected
    else:
        assert b"".join(d for d, _ in got) == b"".join(d for d, _ in expected)
    # Every byte is accounted for: locate() points at its two hex digits.
    text = data[3:] if data.startswith(b"\xef\xbb\xbf") else data
    lines = re.split(rb"\r\n|\r|\n", text)  # a lone CR ends a line too, as the reader counts lines
    stream = b"".join(d for d, _ in got)
    for offset, byte in enumerate(stream):
        where = reader.locate(offset)
        assert where is not None, offset
        line, col = where
        assert lines[line - 1][col - 1:col + 1].upper() == b"%02X" % byte, (offset, where)
    assert reader.locate(len(stream)) is None


def _check_sniffed(data: bytes) -> None:
    """Detection by content: a format or a CaptureError; then reading as detected fails only with one."""
    path = _file(data, "x")
    try:
        fmt = detect_format(path)
        assert fmt in input_formats()  # ours, or another tool's log (rs30x_sniff.sources.foreign)
        if fmt != MCAP:
            for _ in read_capture(path):
                pass
    except CaptureError as e:
        assert "\n" not in str(e)


def check_hex(data: bytes) -> None:
    """Hex text: exactly what an independent reading finds, or a CaptureError naming the line."""
    _check_text(data, HEX)
    _check_sniffed(data)


def check_timestamped(data: bytes) -> None:
    """Timestamped hex: the same, with every time finite and non-negative."""
    _check_text(data, TIMESTAMPED)
    _check_sniffed(data)


def check_mcap(data: bytes) -> None:
    """MCAP: a CaptureError, or raw chunks whose stream offsets follow on (the reader checks them)."""
    from rs30x_sniff.sources.mcap_reader import McapRawReader

    path = _file(data, "x.mcap")
    reader = McapRawReader(path, warn=None)
    try:
        reader.read_metadata()
        _ = reader.baud, reader.models
        got = [(d, t) for d, t, _, _ in reader]
    except CaptureError as e:
        assert "\n" not in str(e)
        return
    assert all(isinstance(d, bytes) for d, _ in got)
    assert sum(1 for w in reader.warnings if "ignored" not in w.message) <= 1  # one place reading stopped
    if reader.complete is False:
        assert reader.warnings
    try:
        assert [c for c in read_capture(path, warn=None)] == got
    except CaptureError as e:  # pragma: no cover - the same reader: it cannot fail the second time
        raise AssertionError(f"read once, then not: {e}") from None


# ---- the decoder -----------------------------------------------------------------------------------
def chunks_from(data: bytes) -> list[tuple[bytes, float | None]]:
    """Arbitrary bytes as decoder input: a flags byte, then (length, time step, payload) records.

    Flag bit 0: the chunks have times; bit 1: a time step may go backwards (as a bad capture can).
    """
    if not data:
        return []
    flags, pos = data[0], 1
    timed, backwards = flags & 1, flags & 2
    t = 0.0
    out: list[tuple[bytes, float | None]] = []
    while pos < len(data):
        n = data[pos]
        step = data[pos + 1] if pos + 1 < len(data) else 0
        payload = data[pos + 2:pos + 2 + n]
        pos += 2 + n
        if backwards and step & 0x80:
            t = max(0.0, t - (step & 0x7F) / 1000)
        else:
            t += step / 10000
        out.append((payload, t if timed else None))
    return out


def encode_chunks(chunks: list[tuple[bytes, float | None]], timed: bool) -> bytes:
    """The inverse of :func:`chunks_from` (for seeds): chunks longer than 255 bytes are split."""
    out = bytearray([1 if timed else 0])
    last = 0.0
    for data, t in chunks:
        for i in range(0, max(len(data), 1), 255):
            piece = data[i:i + 255]
            step = 0
            if timed and t is not None and i == 0:
                step = max(0, min(255, round((t - last) * 10000)))
                last += step / 10000
            out += bytes([len(piece), step]) + piece
    return bytes(out)


def check_decoder(data: bytes) -> None:
    """Decoder: no exception, and every byte fed comes out in exactly one record's raw bytes."""
    from rs30x_sniff.decode.decoder import DecodeOptions, Decoder

    dec = Decoder(DecodeOptions())
    fed = 0
    out = 0
    for payload, t in chunks_from(data):
        fed += len(payload)
        out += sum(len(rec.event.raw) for rec in dec.feed(payload, t))
    out += sum(len(rec.event.raw) for rec in dec.close())
    assert out == fed, f"fed {fed} bytes, records hold {out}"


TARGETS = {"bin": check_bin, "hex": check_hex, "timestamped": check_timestamped, "mcap": check_mcap,
           "decoder": check_decoder}


# ---- seeds ---------------------------------------------------------------------------------------
def seeds(target: str) -> dict[str, bytes]:
    """Seed inputs for ``target``, made from the sample captures (name -> content)."""
    texts = sorted(CAPTURES.glob("*.hex")) + sorted(CAPTURES.glob("*.thex")) + \
        sorted((CAPTURES / "lint").glob("*.hex")) + sorted((CAPTURES / "lint").glob("*.thex"))
    out: dict[str, bytes] = {}
    if target in ("hex", "timestamped"):
        ext = ".thex" if target == "timestamped" else ".hex"
        for p in texts:
            if p.suffix == ext:
                out[p.name] = p.read_bytes()
        return out
    for p in texts:
        chunks = list(read_capture(str(p)))
        if target == "bin":
            out[p.stem + ".bin"] = b"".join(d for d, _ in chunks)
        elif target == "decoder":
            timed = any(t is not None for _, t in chunks)
            out[p.stem + ".dec"] = encode_chunks(chunks, timed)
        elif target == "mcap" and len(out) < 12 and p.stat().st_size < 8000:
            out[p.stem + ".mcap"] = _mcap_bytes(chunks)
    return out


def _mcap_bytes(chunks: list[tuple[bytes, float | None]]) -> bytes:
    """A small MCAP as `convert` writes it (raw, packets, state, findings), with short chunks."""
    import io

    from rs30x_sniff.sinks.mcap.writer import McapSink
    from rs30x_sniff.decode.decoder import DecodeOptions, Decoder

    buf = io.BytesIO()
    timed = any(t is not None for _, t in chunks)
    sink = McapSink(buf, source="seed", baud=115200, time_base="capture" if timed else "synthetic",
                    chunk_seconds=0.05, chunk_size=2048)
    dec = Decoder(DecodeOptions())
    with sink:
        for data, t in chunks:
            sink.raw(data, t)
            for rec in dec.feed(data, t):
                sink.record(rec)
        for rec in dec.close():
            sink.record(rec)
    return buf.getvalue()


def write_seeds(target: str, directory: str | os.PathLike) -> int:
    """Write the seeds of ``target`` into ``directory`` (created); returns how many."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    s = seeds(target)
    for name, content in s.items():
        (d / name).write_bytes(content)
    return len(s)
