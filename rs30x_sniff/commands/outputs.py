"""-o/--output and --force, the same for every command that writes a file (the writing: sinks/outputs.py)."""

from __future__ import annotations

import argparse


def add_output_options(p: argparse.ArgumentParser, *, required: bool = False, what: str = "OUT") -> None:
    """-o/--output (``-`` is stdout) and --force, the same for every command that writes a file."""
    p.add_argument("-o", "--output", required=required, metavar=what,
                   help="write to OUT (- for stdout)" if required else "write to OUT instead of stdout")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
