"""Only wire.py knows what the flag bits mean (tables 4.2-4.4): no other module masks a flag with a literal."""

import re
from pathlib import Path

import rs30x_sniff

ROOT = Path(rs30x_sniff.__file__).resolve().parent
# A flag (or flags) masked or compared with a number: "flag & 0x0F", "ev.flags & 0x80", "flag & 0x70 == 0x60".
MASKED = re.compile(r"\bflags?\b[^\n#]*?&\s*(0x[0-9A-Fa-f]+|\d+)")
RAW_MASKS = re.compile(r"&\s*0x(0F|70|60|55)\b", re.I)


def _code_lines(path: Path):
    """Lines of Python outside string literals' doc examples: skip lines inside triple-quoted strings."""
    in_doc = False
    for n, line in enumerate(path.read_text().splitlines(), 1):
        quotes = line.count('"""')
        if in_doc:
            if quotes % 2:
                in_doc = False
            continue
        if quotes % 2:
            in_doc = True
            line = line.split('"""')[0]
        yield n, line.split("#")[0]


def test_no_module_but_wire_masks_flags_with_literals():
    offenders = []
    for path in sorted(ROOT.rglob("*.py")):
        if path == ROOT / "protocol" / "wire.py":
            continue
        for n, line in _code_lines(path):
            if MASKED.search(line) or RAW_MASKS.search(line):
                offenders.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not offenders, "flag meanings belong in wire.py:\n" + "\n".join(offenders)


def test_the_check_would_catch_a_literal():
    assert MASKED.search("mode = ev.flag & 0x0F")
    assert MASKED.search("if ev.flags & 0x80:")
    assert RAW_MASKS.search("x = f & 0x70")
    assert not MASKED.search("if ev.flag & COMMAND_BITS:")
