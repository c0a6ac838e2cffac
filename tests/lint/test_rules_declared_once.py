"""Each rule is said in one place (issue 23): its findings come from its own module, and the column linter
(lint/batch.py) keeps no list of rules of its own: each rule declares its column form on itself."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import rs30x_sniff
from rs30x_sniff.lint import batch
from rs30x_sniff.lint.registry import RULES

PACKAGE = Path(rs30x_sniff.__file__).parent
CODE = re.compile(r"[FPMBSQ]\d{3}")


def _calls(name: str):
    """(module, code) of every call ``name("X123", ...)`` or ``obj.name("X123", ...)`` in the package."""
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant):
                f = node.func
                called = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)
                if called == name and isinstance(node.args[0].value, str) and CODE.fullmatch(node.args[0].value):
                    yield path.relative_to(PACKAGE).as_posix(), node.args[0].value


def test_every_finding_comes_from_the_module_of_its_rule():
    declared = dict((code, module) for module, code in _calls("rule"))
    assert set(declared) == set(RULES.codes())
    stray = [(module, code) for kind in ("emit", "emit_at") for module, code in _calls(kind)
             if module != declared[code]]
    assert not stray


def test_b006_is_written_once():
    # The record path and the column path share its test (rules/bus.py latency_off, expected_latency).
    assert [m for m, code in _calls("emit") if code == "B006"] == ["lint/rules/bus.py"]


def test_the_column_linter_names_no_rule():
    tree = ast.parse(Path(batch.__file__).read_text())
    docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                  if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef)) and n.body
                  and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
    named = [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)
             and id(n) not in docstrings and CODE.search(n.value)]
    assert not named, f"lint/batch.py classifies rules by code {named}: declare it on the rule (column=)"
