"""No module of rs30x_sniff reaches into another's private names (issue 23, docs/architecture.md).

Parsed with ``ast``, every module of the package is checked for
(a) ``from X import _name`` where X is a module of the package other than the importing one, and
(b) ``obj._name`` where ``obj`` is not ``self``, ``cls`` or ``super()`` and ``_name`` is not a dunder.
What a module needs of another is given a public name there instead.
"""

from __future__ import annotations

import ast
from pathlib import Path

from .imports import PACKAGE, imported_from, module_name

# (module, the expression as ast.unparse writes it): each with why it is not a crossing.
ALLOWED = {
    # stdlib: argparse has no public name for the type of add_subparsers()' result (annotations only).
    **{(f"commands/{m}.py", "argparse._SubParsersAction"): "stdlib"
       for m in ("convert", "decode", "export", "info", "lint", "monitor", "record", "rules", "serve",
                 "simulate", "table")},
    # stdlib: os._exit is the documented way to end a process at once (a monitor whose terminal hung up, after its
    # recording is finished: Textual would wait for ever to restore the screen).
    ("tui/app.py", "os._exit"): "stdlib",
    # Block.part: the new Block (same class) gets the Records already built of its rows.
    ("decode/blocks.py", "sub._records"): "own class",
    # open_capture: the CaptureReader of the same module, sniffed now when no format is given.
    ("sources/captures.py", "reader._start"): "own class",
    # _Recording (tui/feed.py) stops the recording of its Feeder, a class of the same module.
    ("tui/feed.py", "self.feeder._note"): "own class",
    ("tui/feed.py", "self.feeder._close_sink"): "own class",
}


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def crossings(path: Path, source: str | None = None) -> list[str]:
    """Each cross-module use of a private name in the module at ``path`` (``source``: its text, if
    not read from the file), as 'module:line: what', less the allowed ones."""
    rel = path.relative_to(PACKAGE).as_posix()
    module = module_name(path)
    tree = ast.parse(path.read_text() if source is None else source, rel)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            target = imported_from(node, module, path.name == "__init__.py")
            if target is None or target == module:
                continue
            for alias in node.names:
                if _private(alias.name):
                    found.append(f"{rel}:{node.lineno}: from {target} import {alias.name}")
        elif isinstance(node, ast.Attribute) and _private(node.attr):
            obj = node.value
            if isinstance(obj, ast.Name) and obj.id in ("self", "cls"):
                continue
            if isinstance(obj, ast.Call) and isinstance(obj.func, ast.Name) and obj.func.id == "super":
                continue
            text = ast.unparse(node)
            if (rel, text) not in ALLOWED:
                found.append(f"{rel}:{node.lineno}: {text}")
    return found


def _modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def test_no_module_uses_another_modules_private_names():
    found = [c for p in _modules() for c in crossings(p)]
    assert not found, "private names used across modules (give them a public name):\n" + "\n".join(found)


def test_every_allowed_use_is_still_there():
    """An allow-list entry whose use is gone is dropped, so the list stays short and true."""
    used = set()
    for p in _modules():
        rel = p.relative_to(PACKAGE).as_posix()
        for node in ast.walk(ast.parse(p.read_text(), rel)):
            if isinstance(node, ast.Attribute) and _private(node.attr):
                used.add((rel, ast.unparse(node)))
    assert set(ALLOWED) <= used, sorted(set(ALLOWED) - used)


# The crossings issue 23 removed: each would be caught again.
_FIXED = [
    ("sinks/stats.py", "from .health import _FLUSH_ROWS\n", "from rs30x_sniff.sinks.health import _FLUSH_ROWS"),
    ("sinks/stats.py", "def f(health):\n    return health._wr\n", "health._wr"),
    ("sinks/stats.py", "def f(health, b):\n    health._flush_short(1, b, True)\n", "health._flush_short"),
    ("sinks/mcap/blocks.py", "def f(ch):\n    return ch._time, ch._channel\n", "ch._time"),
    ("sinks/mcap/blocks.py", "from ...protocol.memmap import _value_text\n",
     "from rs30x_sniff.protocol.memmap import _value_text"),
    ("render/block_text.py", "from ..protocol.memmap import _ByRaw, _converter\n",
     "from rs30x_sniff.protocol.memmap import _converter"),
    ("render/block_text.py", "from .records import _shown\n", "from rs30x_sniff.render.records import _shown"),
    ("render/block_json.py", "def f(rec):\n    return rec._layout()\n", "rec._layout"),
    ("tui/store.py", "def f(run):\n    return run._cols\n", "run._cols"),
]


def test_a_fixed_crossing_coming_back_fails():
    for rel, code, want in _FIXED:
        found = crossings(PACKAGE / rel, code)
        assert any(want in c for c in found), (rel, code, found)


def test_what_is_not_a_crossing():
    code = ("from .health import FLUSH_ROWS\n"
            "from collections import _chain\n"          # not of the package: not this test's business
            "class A:\n"
            "    def f(self):\n"
            "        return self._x, super()._y, type(self).__len__, self.__class__\n"
            "    @classmethod\n"
            "    def g(cls):\n"
            "        return cls._z\n")
    assert crossings(PACKAGE / "sinks/stats.py", code) == []
