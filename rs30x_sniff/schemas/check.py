"""A small JSON Schema checker for the keywords our own schemas use, with each failure said in one line."""

from __future__ import annotations

import re
from functools import cache
from typing import Any

# Why not the jsonschema library at run time: every command loads the memory maps, and importing jsonschema
# (with attrs, referencing and rpds) costs about 0.1 s before the first byte is read. The schemas stay
# standard JSON Schema (draft 2020-12): tests check them with jsonschema, and that both agree on valid and
# invalid maps (tests/protocol/test_memmap_schema.py).

Path = tuple[str | int, ...]
KEYWORDS = frozenset({
    "$schema", "$id", "$defs", "$ref", "title", "description", "x-message", "type", "enum", "pattern",
    "minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum", "maxLength", "minItems", "maxItems", "items",
    "properties", "additionalProperties", "required", "allOf", "anyOf", "not"})


class Failure(Exception):
    """A value that fails its schema: ``path`` (keys and indexes from the document's root) and one line."""

    def __init__(self, path: Path, message: str) -> None:
        super().__init__(message)
        self.path = path
        self.message = message


def check(instance: Any, schema: dict[str, Any]) -> None:
    """Raise :class:`Failure` for the first place ``instance`` fails ``schema``: an unknown key, a missing
    one, or a value (said by the nearest ``x-message`` of the subschemas it failed, ``{value!r}`` filled in)."""
    failure = first_failure(instance, schema)
    if failure is not None:
        raise failure


_TYPES: dict[str, Any] = {
    # TOML's own types: an integer is an int (never a bool, never a float such as 5.0), a number either.
    "object": lambda v: isinstance(v, dict),
    "array": lambda v: isinstance(v, list),
    "string": lambda v: isinstance(v, str),
    "boolean": lambda v: isinstance(v, bool),
    "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
    "number": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
}


@cache
def _pattern(text: str) -> re.Pattern[str]:
    # ECMA-262's $ (what JSON Schema's patterns are written in) is the end of the text; Python's also
    # matches before a final newline.
    return re.compile(text[:-1] + r"\Z" if text.endswith("$") and not text.endswith("\\$") else text)


def _same(a: Any, b: Any) -> bool:
    """JSON equality: true is not 1."""
    return type(a) is type(b) and a == b if isinstance(a, bool) or isinstance(b, bool) else a == b


class _Value(Exception):
    """A keyword failed on a value; said by the nearest x-message on the way back up (None: none yet)."""

    def __init__(self, path: Path, message: str | None) -> None:
        self.path = path
        self.message = message


class _Checker:
    def __init__(self, root: dict[str, Any]) -> None:
        self.root = root

    def node(self, value: Any, schema: dict[str, Any], path: Path) -> None:
        try:
            self._keywords(value, schema, path)
        except _Value as e:
            said = schema.get("x-message")
            if e.message is not None or said is None:
                raise
            raise _Value(path, said.format(value=value)) from None

    def fails(self, value: Any, schema: dict[str, Any]) -> bool:
        try:
            self.node(value, schema, ())
        except (_Value, Failure):
            return True
        return False

    def _keywords(self, value: Any, schema: dict[str, Any], path: Path) -> None:
        unknown = set(schema) - KEYWORDS
        assert not unknown, f"a keyword this checker does not know: {sorted(unknown)}"
        if "$ref" in schema:
            ref = schema["$ref"]
            assert ref.startswith("#/$defs/"), ref
            self.node(value, self.root["$defs"][ref[len("#/$defs/"):]], path)
        kind = schema.get("type")
        if kind is not None and not _TYPES[kind](value):
            raise _Value(path, None)
        if "enum" in schema and not any(_same(value, v) for v in schema["enum"]):
            raise _Value(path, None)
        if isinstance(value, str):
            if "pattern" in schema and _pattern(schema["pattern"]).search(value) is None:
                raise _Value(path, None)
            if len(value) > schema.get("maxLength", len(value)):
                raise _Value(path, None)
        if _TYPES["number"](value) and not self._in_bounds(value, schema):
            raise _Value(path, None)
        for sub in schema.get("allOf", ()):
            self.node(value, sub, path)
        if "anyOf" in schema and all(self.fails(value, sub) for sub in schema["anyOf"]):
            raise _Value(path, None)
        if "not" in schema and not self.fails(value, schema["not"]):
            raise _Value(path, None)
        if isinstance(value, list):
            if not schema.get("minItems", 0) <= len(value) <= schema.get("maxItems", len(value)):
                raise _Value(path, None)
            if "items" in schema:
                for i, item in enumerate(value):
                    self.node(item, schema["items"], (*path, i))
        if isinstance(value, dict):
            self._object(value, schema, path)

    @staticmethod
    def _in_bounds(value: float, schema: dict[str, Any]) -> bool:
        return (value >= schema.get("minimum", value) and value <= schema.get("maximum", value)
                and ("exclusiveMinimum" not in schema or value > schema["exclusiveMinimum"])
                and ("exclusiveMaximum" not in schema or value < schema["exclusiveMaximum"]))

    def _object(self, value: dict[str, Any], schema: dict[str, Any], path: Path) -> None:
        known = schema.get("properties", {})
        extra = schema.get("additionalProperties", True)
        if extra is False:
            for key in value:
                if key not in known:
                    raise Failure((*path, key), "unknown key")
        for key in schema.get("required", ()):
            if key not in value:
                raise Failure((*path, key), "missing")
        for key, sub in known.items():
            if key in value:
                self.node(value[key], sub, (*path, key))
        if isinstance(extra, dict):
            for key in value:
                if key not in known:
                    self.node(value[key], extra, (*path, key))


def first_failure(instance: Any, schema: dict[str, Any]) -> Failure | None:
    """The first place ``instance`` fails ``schema`` (see :func:`check`), or None."""
    try:
        _Checker(schema).node(instance, schema, ())
    except Failure as e:
        return e
    except _Value as e:
        return Failure(e.path, e.message or "has the wrong type or value")
    return None
