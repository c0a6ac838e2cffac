"""Lint options, and [tool.rs30x-sniff] in the nearest pyproject.toml or an rs30x-sniff.toml."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..wire import DEFAULT_BAUD
from .registry import RULES, SEVERITIES

FAIL_ON = ("error", "warning", "info", "never")
FORMATS = ("text", "json", "junit", "sarif", "github")
CONFIG_NAME = "rs30x-sniff.toml"
TABLE = "tool.rs30x-sniff"


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

    def enabled_codes(self) -> list[str]:
        """Codes of the rules to run, in registry order; raises ConfigError on an unknown selector."""
        chosen = set(resolve(self.select, "select", self.source)) if self.select is not None else set(RULES.codes())
        chosen -= set(resolve(self.ignore, "ignore", self.source))
        return [c for c in RULES.codes() if c in chosen]

    def severities(self) -> dict[str, str]:
        """code -> severity, defaults overridden by ``severity``."""
        out = {r.code: r.severity for r in RULES}
        for key, level in self.severity.items():
            if level not in SEVERITIES:
                raise ConfigError(f"{self.source}: severity {key}={level}: level must be one of {', '.join(SEVERITIES)}")
            codes = resolve([key], "severity", self.source)
            for c in codes:
                out[c] = level
        return out


def resolve(selectors: list[str], key: str, source: str = "options") -> list[str]:
    out: list[str] = []
    for s in selectors:
        codes = RULES.match(s)
        if not codes:
            raise ConfigError(f"{source}: {key}: unknown rule {s!r} (see `rs30x-sniff rules`)")
        out += codes
    return out


# ---- files --------------------------------------------------------------------------------------
# Keys of the file, as on the command line (kebab-case; snake_case is accepted too).
_KEYS: dict[str, type | tuple[type, ...]] = {
    "select": list, "ignore": list, "severity": dict, "fail-on": str, "format": str, "model": str,
    "models": dict, "baud": int, "gap-bytes": (int, float), "reply-timeout": (int, float),
    "latency-margin": (int, float), "inter-byte-gap": (int, float), "flash-write-time": (int, float),
    "max-servos": int,
}


def find_config(start: Path | None = None) -> Path | None:
    """The nearest rs30x-sniff.toml, or pyproject.toml with a [tool.rs30x-sniff] table, from ``start`` up."""
    d = (start or Path.cwd()).resolve()
    for folder in (d, *d.parents):
        own = folder / CONFIG_NAME
        if own.is_file():
            return own
        py = folder / "pyproject.toml"
        if py.is_file():
            try:
                doc = tomllib.loads(py.read_text(encoding="utf-8"))
            except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
                return py  # broken: let load_config say so rather than silently skip the project's settings
            if "rs30x-sniff" in doc.get("tool", {}):
                return py
    return None


def load_config(path: Path | str) -> dict[str, Any]:
    """The settings of a config file as a dict with snake_case keys, every key and rule checked."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such config file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: not valid TOML: {e}") from None
    if path.name == "pyproject.toml" or "tool" in doc:
        table = doc.get("tool", {}).get("rs30x-sniff")
        if table is None:
            raise ConfigError(f"{path}: no [{TABLE}] table")
        where = f"{path}: [{TABLE}]"
    else:
        table = doc
        where = str(path)
    return check_settings(table, where)


def check_settings(table: dict[str, Any], where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for raw_key, value in table.items():
        key = raw_key.replace("_", "-")
        want = _KEYS.get(key)
        if want is None:
            raise ConfigError(f"{where}: unknown key {raw_key!r} (known: {', '.join(sorted(_KEYS))})")
        if not isinstance(value, want) or isinstance(value, bool):
            raise ConfigError(f"{where}: {raw_key}: wrong type {type(value).__name__}")
        out[key.replace("-", "_")] = value
    for key in ("select", "ignore"):
        if key in out:
            if not all(isinstance(s, str) for s in out[key]):
                raise ConfigError(f"{where}: {key}: expected a list of rule codes or names")
            resolve(out[key], key, where)
    if "severity" in out:
        for k, v in out["severity"].items():
            if v not in SEVERITIES:
                raise ConfigError(f"{where}: severity.{k}: level must be one of {', '.join(SEVERITIES)}")
            resolve([k], "severity", where)
    if out.get("fail_on", "error") not in FAIL_ON:
        raise ConfigError(f"{where}: fail-on: must be one of {', '.join(FAIL_ON)}")
    if out.get("format", "text") not in FORMATS:
        raise ConfigError(f"{where}: format: must be one of {', '.join(FORMATS)}")
    if "models" in out:
        models = {}
        for k, v in out["models"].items():
            try:
                models[int(k, 0)] = v
            except ValueError:
                raise ConfigError(f"{where}: models.{k}: not a servo ID") from None
            if not isinstance(v, str):
                raise ConfigError(f"{where}: models.{k}: expected a model name")
        out["models"] = models
    for key in ("gap_bytes", "reply_timeout", "latency_margin", "inter_byte_gap", "flash_write_time",
                "max_servos", "baud"):
        if key in out and out[key] <= 0:
            raise ConfigError(f"{where}: {key.replace('_', '-')}: must be positive")
    out["source"] = where
    return out


def lint_config(settings: dict[str, Any]) -> LintConfig:
    """A LintConfig from checked settings (file values, with command-line values already merged)."""
    cfg = LintConfig()
    for key in ("select", "ignore", "severity", "fail_on", "baud", "reply_timeout", "latency_margin",
                "inter_byte_gap", "gap_bytes", "flash_write_time", "max_servos", "source"):
        if settings.get(key) is not None:
            setattr(cfg, key, settings[key])
    return cfg
