"""Memory maps already read and checked, kept in the user's cache: a start-up reads them without TOML or schema."""

# Every command that decodes loads every map in decoders/ (six files): parsing their TOML and checking each against
# schemas/memory_map.json took about 20 ms of each start-up. A map whose bytes, schema and checker are those of a
# load that passed is kept here as its parsed document (marshal), under a name made from all three; parse_model
# still runs every check the schema cannot make (names given once, ranges within a register) on every load.
# Nothing here is ever needed: an unreadable, unwritable or damaged cache is a cache miss.

from __future__ import annotations

import marshal
import os
from pathlib import Path
from typing import Any

from _blake2 import blake2b  # hashlib would load OpenSSL first: 3 ms of every start-up

_PACKAGE = Path(__file__).resolve().parent.parent
# What decides whether a document passes: the schema and its checker (a change to either is a new key).
_CHECKERS = (_PACKAGE / "schemas" / "memory_map.json", _PACKAGE / "schemas" / "check.py")
FORMAT = b"rs30x-sniff map cache 1"


def cache_dir() -> Path | None:
    """$XDG_CACHE_HOME/rs30x-sniff/maps, else ~/.cache/rs30x-sniff/maps; None where neither can be named."""
    base = os.environ.get("XDG_CACHE_HOME")
    if not base:
        home = os.environ.get("HOME")
        if not home:
            return None
        base = os.path.join(home, ".cache")
    return Path(base) / "rs30x-sniff" / "maps"


def key(raw: bytes) -> str | None:
    """The cache name of a map file's bytes, with the schema and checker of this install; None if they cannot be
    looked at (then nothing is cached)."""
    h = blake2b(FORMAT, digest_size=20)
    try:
        for p in _CHECKERS:
            st = p.stat()
            h.update(f"{st.st_size}:{st.st_mtime_ns};".encode())
    except OSError:
        return None
    h.update(raw)
    return h.hexdigest()


def get(raw: bytes) -> dict[str, Any] | None:
    """The document of a map with these bytes that passed the schema, as kept; None if none is kept."""
    k, d = key(raw), cache_dir()
    if k is None or d is None:
        return None
    try:
        doc = marshal.loads((d / f"{k}.marshal").read_bytes())
    except (OSError, EOFError, ValueError, TypeError):
        return None
    return doc if isinstance(doc, dict) else None


def keep(raw: bytes, doc: dict[str, Any]) -> None:
    """Keep the document of a map that passed the schema (written whole or not at all; never an error)."""
    k, d = key(raw), cache_dir()
    if k is None or d is None:
        return
    try:
        blob = marshal.dumps(doc)
    except ValueError:  # a value marshal cannot hold (a TOML date): such a map is read each time
        return
    import tempfile  # a map not kept yet: most start-ups keep none

    try:
        d.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=d, prefix=".part-")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(blob)
            os.replace(tmp, d / f"{k}.marshal")
        except BaseException:
            os.unlink(tmp)
            raise
    except OSError:
        return
