"""The linter's configuration: which rules run, their severities, and the timing rules' thresholds."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..protocol.wire import DEFAULT_BAUD
from .registry import RULES, SEVERITIES, Registry

FAIL_ON = ("error", "warning", "info", "never")
FORMATS = ("text", "json", "junit", "sarif", "github")


class ConfigError(ValueError):
    """A bad option or configuration file; the message names the file (or option) and the key."""


@dataclass
class LintConfig:
    """Which rules run, how severe they are, and the thresholds the timing rules use."""

    select: list[str] | None = None          # selectors (codes, prefixes, names, ALL); None = every rule
    ignore: list[str] = field(default_factory=list)
    severity: dict[str, str] = field(default_factory=dict)  # code or name -> level
    fail_on: str = "error"
    baud: int = DEFAULT_BAUD
    reply_timeout: float = 0.050     # s after a request within which a reply is still due (B001/B002)
    latency_margin: float = 0.002    # s a reply may stray from the servo's return delay (B006)
    inter_byte_gap: float = 5.0      # byte times of idle line allowed inside a frame (F004)
    gap_bytes: float = 20.0          # byte times of idle line that end a frame (the decoder's cut, B007)
    flash_write_time: float = 0.1    # s a flash write is given before a reboot (Q003)
    max_servos: int = 24             # TTL servos one bus may carry (chapter 3, Systems) (Q008)
    source: str = "options"          # where the values came from, for error messages
    # The run's rule set: the built-in rules and this run's user rules (RULES.with_user), never RULES changed.
    rules: Registry = field(default_factory=lambda: RULES, repr=False)

    def enabled_codes(self) -> list[str]:
        """Codes of the rules to run, in the rule set's order; raises ConfigError on an unknown selector."""
        rules = self.rules
        chosen = (set(resolve(self.select, "select", self.source, rules)) if self.select is not None
                  else set(rules.codes()))
        chosen -= set(resolve(self.ignore, "ignore", self.source, rules))
        return [c for c in rules.codes() if c in chosen]

    def severities(self) -> dict[str, str]:
        """code -> severity, defaults overridden by ``severity``."""
        out = {r.code: r.severity for r in self.rules}
        for key, level in self.severity.items():
            if level not in SEVERITIES:
                raise ConfigError(f"{self.source}: severity {key}={level}: level must be one of "
                                  f"{', '.join(SEVERITIES)}")
            codes = resolve([key], "severity", self.source, self.rules)
            for c in codes:
                out[c] = level
        return out


def resolve(selectors: list[str], key: str, source: str = "options", rules: Registry = RULES) -> list[str]:
    """The codes ``selectors`` pick in the rule set ``rules``; ConfigError naming an unknown one."""
    out: list[str] = []
    for s in selectors:
        codes = rules.match(s)
        if not codes:
            raise ConfigError(f"{source}: {key}: unknown rule {s!r} (see `rs30x-sniff rules`)")
        out += codes
    return out
