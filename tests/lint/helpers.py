"""Helpers for the lint tests: read a capture with `# expect:` comments, lint text or files."""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

from rs30x_sniff.lint import LintConfig, Linter
from rs30x_sniff.decode.decoder import DecodeOptions, Decoder

ROOT = Path(__file__).resolve().parents[2]
CAPTURES = ROOT / "captures"
_EXPECT = re.compile(r"expect:\s*((?:[A-Z]\d{3}[ ,]*)+)")


def parse(text: str) -> tuple[list[tuple[bytes, float | None]], Counter]:
    """Chunks of a hex or timestamped hex capture, and the expected (offset, code) findings."""
    chunks: list[tuple[bytes, float | None]] = []
    expected: Counter = Counter()
    offset = 0
    for line in text.splitlines():
        data_part, _, comment = line.partition("#")
        toks = data_part.split()
        if not toks:
            continue
        t = None
        if "." in toks[0]:
            t = float(toks.pop(0))
        data = bytes.fromhex("".join(toks))
        m = _EXPECT.search(comment)
        if m:
            for code in re.findall(r"[A-Z]\d{3}", m.group(1)):
                expected[(offset, code)] += 1
        chunks.append((data, t))
        offset += len(data)
    if chunks and chunks[0][1] is None:
        chunks = [(b"".join(d for d, _ in chunks), None)]  # untimed: one stream, as a file reader gives it
    return chunks, expected


def lint_chunks(chunks, config: LintConfig | None = None, options: DecodeOptions | None = None) -> Linter:
    linter = Linter(config)
    dec = Decoder(options or DecodeOptions(), linter)
    for data, t in chunks:
        dec.feed(data, t)
    dec.close()
    return linter


def lint_text(text: str, config: LintConfig | None = None) -> Linter:
    return lint_chunks(parse(text)[0], config)


def found(linter: Linter) -> Counter:
    return Counter((f.offset, f.code) for f in linter.findings)
