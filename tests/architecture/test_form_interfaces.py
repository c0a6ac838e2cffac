"""The columnar form reaches the record form through public interfaces only (issue 23): the Block code
moves the BusTracker by its public API, and no module but decode/blocks.py touches a Block's kept Records."""

from __future__ import annotations

import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "rs30x_sniff"


def test_blocks_and_the_decoder_use_the_trackers_public_api():
    for name, var in (("decode/blocks.py", "tracker"), ("decode/decoder.py", "bus")):
        text = (PACKAGE / name).read_text()
        assert not re.findall(rf"\b{var}\._\w+", text), name


def test_no_module_but_blocks_touches_a_blocks_kept_records():
    used = [str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
            if p.name != "blocks.py" or p.parent.name != "decode"
            if re.search(r"(?<!self)\._records?\b", p.read_text())]  # a Block's _records or _record()
    assert not used
