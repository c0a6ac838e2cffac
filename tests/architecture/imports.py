"""What the architecture tests read of the package's modules: their names and the modules they import from."""

from __future__ import annotations

import ast
from pathlib import Path

import rs30x_sniff

PACKAGE = Path(rs30x_sniff.__file__).parent


def module_name(path: Path) -> str:
    """``rs30x_sniff/decode/framing.py`` -> ``rs30x_sniff.decode.framing`` (a package: its folder's name)."""
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_from(node: ast.ImportFrom, module: str, is_package: bool) -> str | None:
    """The absolute name of the module ``node`` imports from (None: not under rs30x_sniff)."""
    if node.level:
        base = module.split(".")
        if not is_package:
            base = base[:-1]
        base = base[:len(base) - (node.level - 1)]
        name = ".".join(base + ([node.module] if node.module else []))
    else:
        name = node.module or ""
    return name if name == "rs30x_sniff" or name.startswith("rs30x_sniff.") else None


def _checking_only(node: ast.AST) -> bool:
    """``if TYPE_CHECKING:`` (or ``typing.TYPE_CHECKING``): a block the type checker reads and Python never runs."""
    if not isinstance(node, ast.If):
        return False
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def run_time_nodes(tree: ast.AST):
    """Every node of ``tree`` as ast.walk gives them, but for the bodies of ``if TYPE_CHECKING:`` blocks (their
    ``else`` runs, and is walked)."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        if _checking_only(node):
            assert isinstance(node, ast.If)
            todo.extend([node.test, *node.orelse])
        else:
            todo.extend(ast.iter_child_nodes(node))
