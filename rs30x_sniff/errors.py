"""The one error every stage may raise for the user to read: one line, exit code 2 (commands, outputs, parts)."""

from __future__ import annotations


class CliError(Exception):
    """A usage, configuration, input or output error: printed as one line, exit code 2."""
