"""`rs30x-sniff plugin sigrok|saleae|wireshark -o DIR`: write a plug-in for another tool, made from the memory maps."""

from __future__ import annotations

import argparse
import importlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from ..plugins.maps import plugin_maps
from ..errors import CliError

# Tool -> (module of rs30x_sniff.plugins with generate(maps) -> {path: text} and install_hint(out) -> str, what).
TOOLS = {
    "sigrok": ("sigrok", "a protocol decoder for sigrok-cli and PulseView, stacked on sigrok's uart"),
    "saleae": ("saleae", "a High Level Analyzer extension for Saleae Logic 2, on the Async Serial analyzer"),
    "wireshark": ("wireshark", "a Lua dissector for Wireshark and tshark (for `convert -o OUT.pcapng` files)"),
}


def add_parser(sub: Any) -> None:  # argparse's subparsers action (no public name for its type)
    p = sub.add_parser(
        "plugin", help="write a plug-in for sigrok/PulseView, Saleae Logic 2 or Wireshark",
        description="Write a self-contained plug-in for another tool, generated from every memory map known "
                    "(the bundled ones and those on $RS30X_DECODERS), and say where to install it. "
                    + " ".join(f"{k}: {what}." for k, (_, what) in TOOLS.items()))
    p.add_argument("tool", choices=tuple(TOOLS), help="the tool to write the plug-in for")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="the folder to write (made; see --force)")
    p.add_argument("--force", action="store_true", help="replace DIR if it exists")
    p.set_defaults(run=run)


def generator(tool: str):
    """The generator module of ``tool`` (rs30x_sniff.plugins.<name>)."""
    return importlib.import_module(f"rs30x_sniff.plugins.{TOOLS[tool][0]}")


def write_folder(out: Path, files: dict[str, str], force: bool) -> None:
    """``files`` (relative path -> text) as the folder ``out``, whole or not at all: written beside it under a
    temporary name and renamed into place; an existing ``out`` is replaced only with ``force``."""
    if os.path.lexists(out):
        if not out.is_dir() or out.is_symlink():
            raise CliError(f"{out}: exists and is not a folder")
        if not force:
            raise CliError(f"{out}: already exists (use --force to replace it)")
    parent = out.resolve().parent
    if not parent.is_dir():
        raise CliError(f"{out}: no folder {parent} to write it in")
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
    old = None
    try:
        for rel, text in files.items():
            path = tmp / rel
            if path.resolve().parent != tmp.resolve() and tmp.resolve() not in path.resolve().parents:
                raise ValueError(f"{rel}: outside the plug-in's folder")
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
        os.chmod(tmp, 0o755)
        if os.path.lexists(out):
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=parent))
            os.rename(out, old / "was")
        os.rename(tmp, out)
    except BaseException as e:  # a full disk, Ctrl-C, a generator's bad path: nothing half-written is left
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None and (old / "was").exists() and not os.path.lexists(out):
            os.rename(old / "was", out)  # put the old one back
        if isinstance(e, OSError):
            raise CliError(f"{out}: cannot write: {e.strerror or e}; nothing written") from None
        raise
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


def run(args: argparse.Namespace) -> int:
    if args.output == "-":
        raise CliError("a plug-in is a folder: give -o DIR, not - (stdout)")
    gen = generator(args.tool)
    out = Path(args.output)
    files = gen.generate(plugin_maps())
    write_folder(out, files, args.force)
    print(gen.install_hint(out))
    return 0
