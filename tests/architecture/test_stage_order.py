"""Data flows one way through the stages (docs/architecture.md), and so do the imports: no module of a
stage imports a later stage (issue 23).

Every ``import`` and ``from ... import`` of every module under rs30x_sniff/ is read with ``ast``, those
inside functions too (a lazy import is still a dependency), but for those under ``if TYPE_CHECKING:``
(never run: they name a later stage's type for the checker), and each is placed by the folder (or
top-level module) it names. The stages, lowest first:

    version.py, language.py, errors.py, protocol, schemas -> sources -> decode -> lint -> render, plugins -> filters.py -> sinks -> settings.py
        -> the top: cli.py, allocator.py, commands/, tui/, sim/, the package itself (__init__.py, __main__.py)

``plugins/`` (the sigrok, Logic 2 and Wireshark plug-ins made from the maps) is an output form of the maps, as
render's are, and sits beside it. ``filters.py`` (the filter language) reads Records and render's words, and sinks (decode --filter's lines)
and the monitor filter with it: it sits between render and sinks. ``settings.py`` builds every stage's
options (DecodeOptions, LintConfig, a source's time base) and only the commands read it: it sits just
below the top, so that no stage depends on the command line's settings. ``schemas/`` (the MCAP
channels' and the memory map's JSON Schemas, and the small checker of the latter) and ``language.py`` (durations, ID ranges, operators) import nothing of the package. The top imports anything; within one stage, or
among the top's folders, any order goes.
"""

from __future__ import annotations

import ast
from pathlib import Path

from .imports import PACKAGE, imported_from, module_name, run_time_nodes

TOP = len(("protocol", "sources", "decode", "lint", "render", "filters", "sinks", "settings"))
RANK = {"version": 0, "language": 0, "errors": 0, "protocol": 0, "schemas": 0, "sources": 1, "decode": 2, "lint": 3, "render": 4, "plugins": 4,
        "filters": 5,
        "sinks": 6, "settings": 7, "user_rules": 7, "compare": 7, "expect": 7,
        "cli": TOP, "allocator": TOP, "commands": TOP, "tui": TOP, "sim": TOP, "__main__": TOP, "": TOP}

# Upward imports that remain, (importing module, imported module) -> why. Each is a known crossing
# (docs/architecture.md): remove it here when it is gone from the code.
ALLOWED = {
    # --baud auto and a logic analyzer's rate count checksum-valid frames at each candidate rate with the
    # frame decoder (decode.autobaud.scan, score_bytes). The rates from timestamps alone are protocol.baud.
    ("rs30x_sniff.sources.uart", "rs30x_sniff.decode.autobaud"): "the sampled line's rate decodes at each rate",
}


def _stage(module: str) -> str:
    """The stage a module of the package belongs to: its folder, or its own name at the top level."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def _imports(path: Path, module: str) -> set[str]:
    """Every module of the package ``path`` imports, by absolute name (``from X import name``: X, and
    X.name where that is a module of its own)."""
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    # Imports under ``if TYPE_CHECKING:`` are left out: Python never runs them, so no stage depends on a later
    # one through them; they only let the checker name a later stage's type where it is passed (the Decoder's
    # Linter), which is how a stage is handed what comes after it.
    for node in run_time_nodes(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            name = imported_from(node, module, is_package) or node.module or ""
            found.add(name)
            for alias in node.names:  # from . import wire: the module wire
                sub = f"{name}.{alias.name}"
                if _is_module(sub):
                    found.add(sub)
    return {m for m in found if m == "rs30x_sniff" or m.startswith("rs30x_sniff.")}


def _is_module(name: str) -> bool:
    rel = Path(*name.split(".")[1:])
    return (PACKAGE / rel).with_suffix(".py").is_file() or (PACKAGE / rel / "__init__.py").is_file()


def _upward() -> dict[tuple[str, str], str]:
    """(importing module, imported module) -> "stage -> stage", for every import of a later stage."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        module = module_name(path)
        here = _stage(module)
        for target in _imports(path, module):
            there = _stage(target)
            if RANK[there] > RANK[here]:
                out[(module, target)] = f"{here or 'rs30x_sniff'} -> {there or 'rs30x_sniff'}"
    return out


def test_every_folder_and_top_level_module_has_a_stage():
    names = {p.stem if p.is_file() else p.name for p in PACKAGE.iterdir()
             if (p.suffix == ".py" or (p / "__init__.py").is_file())}
    assert names - {"__init__"} <= set(RANK), sorted(names - {"__init__"} - set(RANK))


def test_no_stage_imports_a_later_one():
    upward = _upward()
    crossings = {pair: how for pair, how in upward.items() if pair not in ALLOWED}
    assert not crossings, "imports of a later stage:\n" + "\n".join(
        f"  {a} imports {b} ({how})" for (a, b), how in sorted(crossings.items()))


def test_the_allowed_crossings_are_still_there():
    # A crossing removed from the code leaves the list too, so the list stays the truth.
    gone = set(ALLOWED) - set(_upward())
    assert not gone, sorted(gone)


def test_decode_imports_nothing_but_protocol_and_itself():
    # The stage this rule began with (decode/autobaud.py imported sinks/pipeline.py for its Sink).
    for path in sorted((PACKAGE / "decode").rglob("*.py")):
        module = module_name(path)
        assert {_stage(m) for m in _imports(path, module)} <= {"decode", "protocol"}, module
