"""One settings object for every command: command line > config file > what the capture records > defaults."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from collections.abc import Callable, Iterable, Mapping

from .language import LanguageError, parse_duration, say_duration
from .decode.pairing import DEFAULT_REPLY_TIMEOUT
from .decode.framing import DEFAULT_GAP_BYTES
from .lint.config import FAIL_ON, FORMATS, ConfigError, LintConfig
from .lint.config import resolve as resolve_rules
from .lint.registry import RULES, SEVERITIES, Registry
from .protocol.memmap import ModelError, ModelRegistry, bus_rates, default_registry
from .decode.decoder import DecodeOptions
from .sources.timebase import TIME_REFS
from .sources.timeunit import UNITS as TIME_UNITS
from .render.times import DEFAULT_TIME_FORMAT, TIME_FORMATS
from .protocol.wire import DEFAULT_BAUD

CONFIG_NAME = "rs30x-sniff.toml"
TABLE = "tool.rs30x-sniff"
MAX_SERVO_ID = 127  # table 4.6 No. 4: IDs 1 to 127 (7FH); 0 is the long packet, 255 the broadcast

# Layers, lowest precedence first; Settings.origin names one of these (or a config file's path).
DEFAULTS, CAPTURE, CONFIG, COMMAND_LINE = "defaults", "capture", "config", "command line"

SettingsError = ConfigError  # one error type for a bad option or config value (exit code 2)


# ---- what a value may be: one check per key, the same for the command line and a config file ----
def _finite(v: Any) -> str | None:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return "must be a number"
    if not math.isfinite(v):
        return "must be a finite number"
    return None


def _positive(v: Any) -> str | None:
    return _finite(v) or (None if v > 0 else "must be positive")


def _not_negative(v: Any) -> str | None:
    return _finite(v) or (None if v >= 0 else "must be 0 or more")


def _count(v: Any) -> str | None:
    if isinstance(v, bool) or not isinstance(v, int):
        return "must be a whole number"
    return None if v > 0 else "must be positive"


def _at_most(limit: float, check: Callable[[Any], str | None], *, time: bool = False) -> Callable[[Any], str | None]:
    """``check``, and no more than ``limit`` (``time``: seconds, said as a duration, 1h): a typo such as 1e308 is a
    one-line error, never an OverflowError deep in a command."""
    said = say_duration(limit) if time else f"{limit:g}"

    def bounded(v: Any) -> str | None:
        return check(v) or (None if v <= limit else f"must be at most {said}")
    return bounded


# Upper bounds, each far beyond any real bus: the fastest USB-UARTs run at 12 Mbit/s; an hour is
# longer than any reply, flash write or margin; a million byte times is seconds even at 9600 bit/s.
MAX_BAUD = 12_000_000
MAX_SECONDS = 3600.0
MAX_SECONDS_SAID = say_duration(MAX_SECONDS)  # 1h
MAX_BYTE_TIMES = 1_000_000
MAX_CHANNEL = 1023


AUTO = "auto"


def _baud(v: Any) -> str | None:
    if v == AUTO:
        return None
    # The manual's rates are checked against baud-any once every layer is merged.
    return _at_most(MAX_BAUD, _count)(v)


def _one_of(choices: tuple[str, ...]) -> Callable[[Any], str | None]:
    def check(v: Any) -> str | None:
        return None if v in choices else f"must be one of {', '.join(choices)}"
    return check


def _rules(v: Any) -> str | None:
    if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
        return "expected a list of rule codes or names"
    return None


def _flag(v: Any) -> str | None:
    return None if isinstance(v, bool) else "must be true or false"


def _severity(v: Any) -> str | None:
    return None if isinstance(v, dict) else "expected a table of RULE = LEVEL"


def _model_name(v: Any) -> str | None:
    return None if isinstance(v, str) else "expected a model name"


def _models(v: Any) -> str | None:
    return None if isinstance(v, dict) else "expected a table of ID = MODEL"


def _rule_tables(v: Any) -> str | None:
    # Each table is checked key by key when it is compiled (rs30x_sniff.user_rules).
    return None if isinstance(v, list) and all(isinstance(t, dict) for t in v) else "expected [[rule]] tables"


def _channel(v: Any) -> str | None:
    if isinstance(v, int) and not isinstance(v, bool):
        return None if 0 <= v <= MAX_CHANNEL else f"must be a channel name or an index from 0 to {MAX_CHANNEL}"
    return None if isinstance(v, str) and v.strip() else "expected a channel name or an index from 0"


@dataclass(frozen=True)
class Key:
    """One setting: how to check a value, and its name on the command line."""

    check: Callable[[Any], str | None]
    option: str          # the command-line spelling, for messages
    doc: str


KEYS: dict[str, Key] = {
    "baud": Key(_baud, "--baud", f"bus baud rate (table 4.7; at most {MAX_BAUD} with baud-any), or auto"),
    "baud_any": Key(_flag, "--baud-any", "accept a baud rate outside table 4.7"),
    "model": Key(_model_name, "--model", "model of every servo"),
    "models": Key(_models, "--model ID=", "model per servo ID"),
    "gap_bytes": Key(_at_most(MAX_BYTE_TIMES, _not_negative), "--gap-bytes",
                     f"idle byte times that end a frame (0: off; at most {MAX_BYTE_TIMES})"),
    "reply_timeout": Key(_at_most(MAX_SECONDS, _positive, time=True), "--reply-timeout",
                         f"time before a reply counts as missing (50ms, or seconds; at most {MAX_SECONDS_SAID})"),
    "time_ref": Key(_one_of(TIME_REFS), "--time-ref", "what timestamped hex times mark: first byte or arrival"),
    "time_unit": Key(_one_of(TIME_UNITS), "--time-unit", "the unit of timestamped hex times: s, ms, us or ns"),
    "channel": Key(_channel, "--channel", "the logic capture's channel to decode: a name or an index from 0"),
    "time_format": Key(_one_of(TIME_FORMATS), "--time-format",
                       "how text lines show times: relative (since the capture's start), absolute, delta or epoch"),
    "select": Key(_rules, "--select", "rules to run"),
    "ignore": Key(_rules, "--ignore", "rules to skip"),
    "severity": Key(_severity, "--severity", "severity per rule"),
    "fail_on": Key(_one_of(FAIL_ON), "--fail-on", "lowest severity that fails lint"),
    "format": Key(_one_of(FORMATS), "--format", "lint report format"),
    "latency_margin": Key(_at_most(MAX_SECONDS, _positive, time=True), "latency-margin",
                          f"time a reply may stray from its return delay (B006; at most {MAX_SECONDS_SAID})"),
    "inter_byte_gap": Key(_at_most(MAX_BYTE_TIMES, _positive), "inter-byte-gap",
                          f"idle byte times allowed inside a frame (F004; at most {MAX_BYTE_TIMES})"),
    "flash_write_time": Key(_at_most(MAX_SECONDS, _positive, time=True), "flash-write-time",
                            f"time a flash write takes (Q003; at most {MAX_SECONDS_SAID})"),
    "max_servos": Key(_at_most(MAX_SERVO_ID, _count), "max-servos",
                      f"servos one bus may carry (Q008; at most {MAX_SERVO_ID}, one per ID)"),
    "rule": Key(_rule_tables, "[[rule]]", "the project's own lint rules (rs30x_sniff.user_rules); config files only"),
    "expect": Key(_rule_tables, "[[expect]]", "figure checks over info's figures (docs/checks.md); config files only"),
    "regress": Key(lambda v: None if isinstance(v, dict) else "expected a table of FIGURE = THRESHOLD", "regress",
                   "thresholds of `diff --fail-on-regress` (each checked by rs30x_sniff.compare)"),
}
LINT_THRESHOLDS = ("latency_margin", "inter_byte_gap", "flash_write_time", "max_servos")
# The keys that are times: a number of seconds, or a duration in language.py's grammar ("50ms", "2min").
DURATIONS = ("reply_timeout", "latency_margin", "flash_write_time")


def _label(key: str, value: Any, where: str) -> str:
    """How a message names the value: ``--baud 12345`` or ``rs30x-sniff.toml: baud = 12345``."""
    if where == COMMAND_LINE:
        opt = KEYS[key].option
        return f"{opt} {value}" if opt.startswith("--") else f"{opt} {value!r}"
    return f"{where}: {key.replace('_', '-')} = {value!r}"


def _as_rules(checks: Iterable[Any]) -> tuple:
    """Figure checks ([[expect]]) as rules (expect.as_rule), importing expect only for a config that has some."""
    checks = tuple(checks)
    if not checks:
        return ()
    from .expect import as_rule

    return tuple(as_rule(c) for c in checks)


def own_rules(conf: Mapping[str, Any]) -> tuple:
    """A checked config's own rules for the registry: its [[rule]]s, and its [[expect]]s as rules (so that
    selections, severities, reports and `rules` know them)."""
    return (*conf.get("rule", ()), *_as_rules(conf.get("expect", ())))


def check(table: Mapping[str, Any], where: str, registry: ModelRegistry | None = None,
          rules: Registry | None = None) -> dict[str, Any]:
    """Checked settings with snake_case keys (kebab-case accepted); ``where`` names the layer in messages.
    Rule selections are checked in ``rules`` (the run's rule set), by default the built-in rules and the
    table's own user rules."""
    reg = registry or default_registry()
    out: dict[str, Any] = {}
    for raw_key, value in table.items():
        key = raw_key.replace("-", "_")
        spec = KEYS.get(key)
        if spec is None:
            known = ", ".join(sorted(k.replace("_", "-") for k in KEYS))
            raise SettingsError(f"{where}: unknown key {raw_key!r} (known: {known})")
        if key in DURATIONS and isinstance(value, str):  # "50ms": language.py's grammar, as on the command line
            try:
                value = parse_duration(value)
            except LanguageError as e:  # its text begins with the value, which the label says already
                why = str(e).removeprefix(value.strip() + ": ")
                raise SettingsError(f"{_label(key, value, where)}: {why}") from None
        problem = spec.check(value)
        if problem:
            raise SettingsError(f"{_label(key, value, where)}: {problem}")
        out[key] = value
    if "rule" in out:
        if where == COMMAND_LINE:
            raise SettingsError("user rules ([[rule]]) come from a config file only")
        from .user_rules import compile_rules  # a config's own rules, and figure checks, and thresholds below:
        # imported only for a file that has them (a tenth of each start-up otherwise)

        out["rule"] = compile_rules(out["rule"], where, reg)
    if "expect" in out:
        if where == COMMAND_LINE:
            raise SettingsError("figure checks ([[expect]]) come from a config file only")
        from .expect import check_clashes, load_checks

        out["expect"] = load_checks(out["expect"], where)
        check_clashes(out.get("rule", ()), out["expect"], where)  # one registry holds both: one line, exit 2
    if "regress" in out:  # checked for every command that reads the file, as diff reads it
        from .compare import ThresholdError, parse_thresholds

        try:
            parse_thresholds(out["regress"], where)
        except ThresholdError as e:
            raise SettingsError(str(e)) from None
    # A config file's selections may name its own user rules and figure checks: checked in its rule set.
    if rules is None:
        rules = rule_set(own_rules(out), where)
    for key in ("select", "ignore"):
        if key in out:
            resolve_rules(out[key], key, where, rules)
    for k, level in out.get("severity", {}).items():
        if level not in SEVERITIES:
            name = f"--severity {k}={level}" if where == COMMAND_LINE else f"{where}: severity.{k}"
            raise SettingsError(f"{name}: level must be one of {', '.join(SEVERITIES)}")
        resolve_rules([k], "severity", where, rules)
    _refuse_conflicts(out, where, rules)
    try:
        if "model" in out:
            out["model"] = reg.get(out["model"]).name
    except ModelError as e:
        raise SettingsError(f"{_label('model', out['model'], where)}: {e}") from None
    if "models" in out:
        models: dict[int, str] = {}
        for k, name in out["models"].items():
            label = f"--model {k}={name}" if where == COMMAND_LINE else f"{where}: models.{k} = {name!r}"
            try:
                sid = k if isinstance(k, int) else int(str(k), 0)
            except ValueError:
                raise SettingsError(f"{label}: {k!r} is not a servo ID") from None
            if not 1 <= sid <= MAX_SERVO_ID:
                raise SettingsError(f"{label}: servo IDs run from 1 to {MAX_SERVO_ID} (table 4.6 No. 4)")
            if not isinstance(name, str):
                raise SettingsError(f"{label}: expected a model name")
            try:
                model = reg.get(name).name
            except ModelError as e:
                raise SettingsError(f"{label}: {e}") from None
            if models.get(sid, model) != model:  # 3 and 0x3: one ID, never the last one silently taken
                raise SettingsError(f"{label}: ID {sid} is given two models ({models[sid]} and {model}): give one")
            models[sid] = model
        out["models"] = models
    return out


def rule_set(own: tuple, where: str) -> Registry:
    """The rule set of a run: the built-in rules and ``own`` (a config's user rules and figure checks,
    :func:`own_rules`); SettingsError naming ``where`` on a code or name given twice."""
    if not own:
        return RULES
    try:
        return RULES.with_user(own)
    except ValueError as e:
        raise SettingsError(f"{where}: {e}") from None


def _refuse_conflicts(out: Mapping[str, Any], where: str, rules: Registry = RULES) -> None:
    """One layer's options that contradict each other are an error, never resolved silently: a rule named
    in ``select`` and dropped by ``ignore``; one rule given two severities (by its code and by its name).
    Across layers the higher one wins instead (the command line over the config file)."""
    cli = where == COMMAND_LINE
    if "select" in out and "ignore" in out:
        named = {r.code: s for s in out["select"] if (r := rules.get(s)) is not None}
        for code in resolve_rules(out["ignore"], "ignore", where, rules):
            if code in named:
                said = (f"--select {named[code]} and --ignore {', '.join(out['ignore'])}" if cli
                        else f"{where}: select names {named[code]} and ignore drops it")
                raise SettingsError(f"{said}: {code} is both selected and ignored; give one")
    levels: dict[str, tuple[str, str]] = {}
    for k, level in out.get("severity", {}).items():
        r = rules.get(k)
        if r is None:
            continue  # a prefix (B, Q00) or ALL: a rule named on its own refines it
        if r.code in levels and levels[r.code][1] != level:
            k0, l0 = levels[r.code]
            said = (f"--severity {k0}={l0} and --severity {k}={level}" if cli
                    else f"{where}: severity.{k0} = {l0!r} and severity.{k} = {level!r}")
            raise SettingsError(f"{said}: two levels for {r.code}; give one")
        levels[r.code] = (k, level)


# ---- config files ----------------------------------------------------------------------------------
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
                text = py.read_text(encoding="utf-8")
            except (OSError, UnicodeDecodeError):
                return py  # broken: let load_config say so rather than silently skip the project's settings
            if not _may_hold_our_table(text):
                continue  # its tables cannot name ours
            import tomllib  # only where a pyproject.toml may name us: most start-ups parse no TOML

            try:
                doc = tomllib.loads(text)
            except tomllib.TOMLDecodeError:
                return py
            if "rs30x-sniff" in doc.get("tool", {}):
                return py
    return None


def _may_hold_our_table(text: str) -> bool:
    """Whether a pyproject.toml's text may hold [tool.rs30x-sniff], so it is worth parsing: it names us, and a key
    tool. names ours, or a [tool] table or tool = {...} may. A project that only depends on us, or runs our
    command from its [project.scripts], is not parsed (tomllib: 3 ms of a start-up)."""
    if "rs30x-sniff" not in text:
        return False
    import re

    return re.search(r"""\btool["']?\s*(?:\.\s*["']?rs30x-sniff|\]|=)""", text) is not None


def load_config(path: Path | str) -> dict[str, Any]:
    """The checked settings of a config file (snake_case keys), with ``source`` naming the file."""
    import tomllib

    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SettingsError(f"{path}: no such config file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise SettingsError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from None
    except tomllib.TOMLDecodeError as e:
        raise SettingsError(f"{path}: not valid TOML: {e}") from None
    if path.name == "pyproject.toml" or "tool" in doc:
        table = doc.get("tool", {}).get("rs30x-sniff")
        if table is None:
            raise SettingsError(f"{path}: no [{TABLE}] table")
        where = f"{path}: [{TABLE}]"
    else:
        table, where = doc, str(path)
    out = check(table, where)
    out["source"] = where
    return out


# ---- the settings ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Settings:
    """Every option that changes how a capture is decoded and linted, merged from its layers.

    Build it with :func:`resolve`; ``origin`` says which layer each decode value came from.
    ``timing_unsupported`` is not a layer's value: :func:`rs30x_sniff.commands.common.settings_for`
    sets it to why the capture's timing figures (latencies, durations, rates, bus load) cannot be
    stated, e.g. ``the timestamps contradict --baud 9600: they show 115200 bit/s``; None when nothing
    is known against them. Commands leave those figures out, with this reason, rather than print them.
    """

    baud: int = DEFAULT_BAUD
    default_model: str | None = None
    models: Mapping[int, str] = field(default_factory=dict)
    gap_bytes: float | None = DEFAULT_GAP_BYTES   # None: gap detection off
    reply_timeout: float = DEFAULT_REPLY_TIMEOUT
    time_ref: str | None = None                    # None: told by the content (rs30x_sniff.sources.timebase)
    time_unit: str | None = None                   # None: told by the content (rs30x_sniff.sources.timeunit)
    channel: str | None = None                     # a logic capture's channel (name or index); None: its reader picks
    baud_auto: bool = False                        # --baud auto: a port is scanned, a capture's times tell
    lint: Mapping[str, Any] = field(default_factory=dict)  # select, ignore, severity, fail_on, thresholds
    report_format: str | None = None
    origin: Mapping[str, str] = field(default_factory=dict)
    config_path: str | None = None
    timing_unsupported: str | None = None          # why timing figures are left out (see above)
    user_rules: tuple = ()                         # the config file's [[rule]]s (rs30x_sniff.lint.registry.Rule)
    expects: tuple = ()                            # the config file's [[expect]]s (rs30x_sniff.expect.Check)
    time_format: str = DEFAULT_TIME_FORMAT         # how text lines show times (rs30x_sniff.render.times)

    def decode_options(self, registry: ModelRegistry | None = None) -> DecodeOptions:
        return DecodeOptions(baud=self.baud, default_model=self.default_model, models=dict(self.models),
                             gap_bytes=self.gap_bytes, reply_timeout=self.reply_timeout, registry=registry)

    def rule_set(self) -> Registry:
        """The run's rule set: the built-in rules, the config file's [[rule]]s and its [[expect]]s as rules."""
        return rule_set((*self.user_rules, *_as_rules(self.expects)), self.config_path or CONFIG)

    def lint_config(self) -> LintConfig:
        """The linter's configuration; its timing thresholds follow the decode options."""
        cfg = LintConfig()
        for key, value in self.lint.items():
            setattr(cfg, key, value)
        cfg.baud = self.baud
        cfg.reply_timeout = self.reply_timeout
        if self.gap_bytes:
            cfg.gap_bytes = self.gap_bytes
        cfg.source = self.config_path or "options"
        cfg.rules = self.rule_set()
        try:
            cfg.enabled_codes()
            cfg.severities()
        except ConfigError as e:
            raise SettingsError(str(e)) from None
        return cfg

    def as_json(self) -> dict[str, Any]:
        """The decode settings with where each came from (``info --format json``, MCAP metadata)."""
        return {"baud": self.baud, "default_model": self.default_model,
                "models": {str(k): v for k, v in sorted(self.models.items())}, "gap_bytes": self.gap_bytes,
                "reply_timeout": self.reply_timeout, "time_ref": self.time_ref, "origin": dict(self.origin),
                "config": self.config_path, **({"channel": self.channel} if self.channel is not None else {}),
                **({"time_unit": self.time_unit} if self.time_unit is not None else {})}


def resolve(command_line: Mapping[str, Any] | None = None, config: Mapping[str, Any] | None = None,
            capture: Mapping[str, Any] | None = None) -> Settings:
    """Merge the layers: command line > config file > capture > defaults.

    ``command_line`` holds raw values (checked here, named by their options in messages); ``config``
    comes from :func:`load_config` (already checked); ``capture`` is what a capture file records
    (``baud``, ``model``, ``models``). Per-ID models merge ID by ID; ``select`` replaces, ``ignore``
    adds up and ``severity`` merges rule by rule.
    """
    cli = check(command_line or {}, COMMAND_LINE, rules=rule_set(own_rules(config or {}), COMMAND_LINE))
    conf = dict(config or {})
    where_conf = conf.pop("source", CONFIG)
    cap = dict(capture or {})
    cap_origin = cap.pop("origin", {})  # why the capture says what it says (its metadata, its timestamps)
    layers = [(CAPTURE, cap), (where_conf, conf), (COMMAND_LINE, cli)]
    values: dict[str, Any] = {"baud": DEFAULT_BAUD, "model": None, "gap_bytes": DEFAULT_GAP_BYTES,
                              "reply_timeout": DEFAULT_REPLY_TIMEOUT, "baud_any": False, "time_ref": None,
                              "time_unit": None, "channel": None, "time_format": DEFAULT_TIME_FORMAT}
    origin = {k: DEFAULTS for k in ("baud", "model", "gap_bytes", "reply_timeout")}
    models: dict[int, str] = {}
    lint: dict[str, Any] = {}
    ignore: list[str] = []
    severity: dict[str, str] = {}
    for where, layer in layers:
        for key in ("baud", "model", "gap_bytes", "reply_timeout", "baud_any", "time_ref", "time_unit", "channel",
                    "time_format"):
            if key in layer:
                values[key] = layer[key]
                origin[key] = cap_origin.get(key, where) if layer is cap else where
        for sid, name in layer.get("models", {}).items():
            models[sid] = name
            origin[f"models.{sid}"] = where
        if "select" in layer:
            lint["select"] = list(layer["select"])
        ignore += layer.get("ignore", [])
        severity.update(layer.get("severity", {}))
        for key in ("fail_on", *LINT_THRESHOLDS):
            if key in layer:
                lint[key] = layer[key]
    if ignore:
        lint["ignore"] = ignore
    if severity:
        lint["severity"] = severity
    baud = values["baud"]
    baud_auto = baud == AUTO
    if baud_auto:
        # The capture's own word (an MCAP's metadata, a timed capture's spacing) if it has one; a port
        # is scanned by the command once the settings are known.
        baud = cap.get("baud", DEFAULT_BAUD)
        origin["baud"] = cap_origin.get("baud", CAPTURE) if "baud" in cap else f"{DEFAULTS} (auto: nothing to tell by)"
    elif baud not in bus_rates() and not values["baud_any"] and ("baud" in conf or "baud" in cli):
        # A capture records the rate it was made at; only a rate someone typed is held to the servos' tables
        # (table 4.7, and 460800 where a model's map has it).
        rates = ", ".join(map(str, bus_rates()))
        raise SettingsError(f"{_label('baud', baud, origin['baud'])}: not a rate the servos run at ({rates}); "
                            f"add --baud-any (baud-any = true) to use it anyway")
    fmt = cli.get("format", conf.get("format"))
    return Settings(baud=baud, baud_auto=baud_auto, default_model=values["model"], models=models,
                    gap_bytes=values["gap_bytes"] or None, reply_timeout=values["reply_timeout"],
                    time_ref=values["time_ref"], time_unit=values["time_unit"], lint=lint,
                    channel=None if values["channel"] is None else str(values["channel"]).strip(),
                    report_format=fmt, origin=origin,
                    config_path=where_conf if config else None, user_rules=tuple(conf.get("rule", ())),
                    expects=tuple(conf.get("expect", ())), time_format=values["time_format"])
