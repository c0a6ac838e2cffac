"""The RS30x linter: a rule registry, the rules by family, configuration, and report formats."""

from .rules import (  # noqa: F401  (they register the rules)
    bus, direction, framing, memory, sequences, status, structure, timebase, uart)
from .config import ConfigError, LintConfig
from .linter import Linter
from .registry import RULES, SEVERITIES, SEVERITY_RANK, Finding, Rule, rule

__all__ = ["ConfigError", "Finding", "LintConfig", "Linter", "RULES", "Rule", "SEVERITIES", "SEVERITY_RANK", "rule"]
