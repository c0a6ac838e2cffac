"""Options and helpers shared by the subcommands: settings from every layer (a capture's: sources/probe), inputs."""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from typing import Any

from .. import language
from ..errors import CliError
from ..sources import probe
from ..sources.captures import BINARY, HEX, MCAP, TIMESTAMPED, CaptureError, detect_format
from ..sources.inputs import read_input
from ..sources.protocol import Source
from ..protocol.wire import DEFAULT_BAUD
from ..sinks.baud_watch import BaudWatchWarning
from ..sinks.pipeline import Sink
from ..lint.registry import RULES
from ..render.times import TimeForm
from ..settings import COMMAND_LINE, DEFAULTS, Settings, SettingsError, find_config, load_config, own_rules, resolve


def time_form(settings: Settings, anchor: Any = None) -> TimeForm:
    """The settings' --time-format for one capture; ``anchor``: the epoch time of its time 0 where its format
    says it (a callable, asked at its first timed byte); a note that it cannot be shown goes to stderr."""
    return TimeForm(settings.time_format, anchor,
                    say=lambda line: print(f"rs30x-sniff: {line}", file=sys.stderr, flush=True))


# ---- settings: one precedence for every command ------------------------------------------------------
def _split(values: list[str] | None) -> list[str] | None:
    if values is None:
        return None
    return [v.strip() for item in values for v in item.split(",") if v.strip()]


def command_line_layer(args: argparse.Namespace) -> dict[str, Any]:
    """The settings the command line gives (raw values: :func:`rs30x_sniff.settings.check` checks them)."""
    out: dict[str, Any] = {}
    for spec in getattr(args, "model", None) or []:
        key, sep, name = spec.partition("=")
        # The same ID (or every ID) given twice is refused, never the last one silently taken.
        before = out.get("models", {}).get(key.strip()) if sep else out.get("model")
        given = name.strip() if sep else spec.strip()
        if before is not None and before.upper() != given.upper():
            who = f"{key.strip()}=" if sep else ""
            raise CliError(f"--model {who}{before} and --model {who}{given}: two models for "
                           f"{'ID ' + key.strip() if sep else 'every ID'}; give one")
        if sep:
            out.setdefault("models", {})[key.strip()] = given
        else:
            out["model"] = given
    for key in ("baud", "baud_any", "gap_bytes", "reply_timeout", "fail_on", "time_ref", "time_unit", "channel",
                "time_format"):
        v = getattr(args, key, None)
        if v is not None:
            out[key] = v
    for key in ("select", "ignore"):
        v = _split(getattr(args, key, None))
        if v is not None and (key == "select" or v):
            out[key] = v
    sev: dict[str, str] = {}
    for spec in getattr(args, "severity", None) or []:
        key, eq, level = spec.partition("=")
        if not eq:
            raise CliError(f"--severity {spec}: expected RULE=LEVEL")
        if sev.get(key.strip(), level.strip()) != level.strip():
            raise CliError(f"--severity {key.strip()}={sev[key.strip()]} and --severity {spec.strip()}: two levels "
                           f"for {key.strip()}; give one")
        sev[key.strip()] = level.strip()
    if sev:
        out["severity"] = sev
    return out


def config_layer(args: argparse.Namespace) -> dict[str, Any]:
    """The config file's settings (checked), or {} when there is none or --isolated.

    Its user rules (``[[rule]]``, and ``[[expect]]`` figure checks as rules) are checked here to make one rule
    set with the built-in rules; each run carries its own (Settings.rule_set, LintConfig.rules), and the
    process-wide registry (RULES) keeps the built-in rules alone.
    """
    _said.clear()  # a new command: its notes are said once more
    conf = _config_file(args)
    say_deprecations()
    try:
        RULES.with_user(own_rules(conf))
    except ValueError as e:  # two of the file's own rules under one code or name
        raise CliError(f"{conf.get('source', 'config')}: {e}") from None
    return conf


_said: set[str] = set()


def say_deprecations() -> None:
    """Print each note about an old spelling read so far (language.deprecation_notes: a name, unit or form that
    still works for one release) that this command has not said yet, one line each."""
    for text in language.deprecation_notes:
        if text not in _said:
            _said.add(text)
            print(f"rs30x-sniff: warning: {text}", file=sys.stderr)
    language.deprecation_notes.clear()


def _config_file(args: argparse.Namespace) -> dict[str, Any]:
    if getattr(args, "isolated", False):
        return {}
    path = getattr(args, "config", None) or find_config()
    if path is None:
        return {}
    try:
        return load_config(path)
    except SettingsError as e:
        raise CliError(str(e)) from None


def settings_for(args: argparse.Namespace, path: str | None = None, *, config: dict | None = None) -> Settings:
    """The settings for one input: command line > config file > what the capture records > defaults.

    With ``--baud auto`` a port is scanned at the rates of table 4.7 (listening only) and a capture
    goes by what it records; without it, a timestamped capture's own rate is used when neither the
    command line nor a config file gives one (the default 115200 gives way to the rate its spacing
    allows when the spacing rules the default out), and a rate that the timestamps contradict is
    warned about and sets ``timing_unsupported``. A timestamped capture's times are read in the unit
    the content tells (said on stderr when not seconds) unless ``--time-unit`` says otherwise.
    """
    cli = command_line_layer(args)
    if "time_unit" in cli and path:
        _time_unit_applies(path, getattr(args, "input_format", None), cli["time_unit"])
    conf = config_layer(args) if config is None else config
    # A logic capture's probe decodes its samples to find the rate: it needs the channel, and can skip
    # the search when the rate is given (the layers' own precedence, before they are checked). A
    # timestamped capture's sample is read in the unit given, if one is.
    given = next((layer["baud"] for layer in (cli, conf) if "baud" in layer), None)
    capture = probe.capture_layer(path, getattr(args, "input_format", None),
                            {"channel": cli.get("channel", conf.get("channel")),
                             "baud": given if isinstance(given, int) else None,
                             "time_unit": cli.get("time_unit", conf.get("time_unit"))})
    estimate = capture.pop("estimate", None)
    fit = capture.pop("fit", None)
    note = capture.pop("note", None)
    unit_note = capture.pop("unit_note", None)
    recorded = capture.pop("recorded", False)  # an MCAP's rate is its record, not read off its times
    try:
        settings = resolve(cli, conf, capture)
    except SettingsError as e:
        raise CliError(str(e)) from None
    told = capture.get("origin", {})
    if unit_note is not None and settings.origin.get("time_unit") == told.get("time_unit"):
        print(f"rs30x-sniff: {path}: {unit_note} (--time-unit to say otherwise)", file=sys.stderr)
    from_capture = "baud" in capture and settings.origin["baud"] == told.get("baud")
    if settings.baud_auto and path and is_port_path(path):
        settings = _scan(path, settings)
    elif note is not None and from_capture:
        print(f"rs30x-sniff: {path}: {settings.baud} bit/s, {note} (--baud to say otherwise)", file=sys.stderr)
    elif from_capture and not recorded and settings.baud != DEFAULT_BAUD:
        why = "" if estimate is not None and estimate.baud == settings.baud or fit is None else \
            f": {fit.evidence(DEFAULT_BAUD)}"
        print(f"rs30x-sniff: {path}: {settings.baud} bit/s, from its timestamps{why} (--baud to say otherwise)",
              file=sys.stderr)
    elif (recorded or not from_capture) and (estimate is not None or fit is not None):
        settings = _contradicted(path, settings, estimate, fit)
    return settings


def _time_unit_applies(path: str, fmt: str | None, unit: str) -> None:
    """--time-unit is read only by timestamped hex: given for another input it would be silently ignored,
    so it is refused (a config file's time-unit stays a default for the captures it fits)."""
    if is_port_path(path):
        raise CliError(f"--time-unit {unit}: {path} is a serial port, timed by this machine's clock: "
                       f"--time-unit is for timestamped hex captures")
    if path == "-" or not os.path.isfile(path):
        return  # stdin is sniffed once, by its reader; a missing file: the reading command says so
    if fmt is None:
        try:
            fmt = detect_format(path)
        except CaptureError:
            return  # the reading command says why, with the line
    if fmt != TIMESTAMPED:
        what = {BINARY: "a binary capture (no times)", HEX: "an untimed hex capture",
                MCAP: "an MCAP capture (its times are its own)"}.get(fmt, f"a {fmt} capture")
        raise CliError(f"--time-unit {unit}: {path} is {what}: --time-unit is for timestamped hex captures")


def _contradicted(path: str | None, settings: Settings, estimate: Any, fit: Any) -> Settings:
    """``settings`` with ``timing_unsupported`` set, and a warning on stderr, when the capture's timestamps
    contradict the rate it is decoded at: chunks would overlap at it, or back-to-back bytes name another."""
    from ..protocol.baud import contradiction

    baud = settings.baud
    found = contradiction(estimate, fit, baud)
    if found is None:
        return settings
    shown, evidence = found
    where = settings.origin.get("baud", DEFAULTS)
    if where == COMMAND_LINE:
        label, given = f"--baud {baud}", f"the {baud} given ({where})"
    elif where.startswith(DEFAULTS):
        label = given = f"the default {baud} bit/s"
    else:
        label, given = f"baud = {baud} ({where})", f"the {baud} given ({where})"
    if shown is not None:
        said, reason = f"its timestamps show {shown} bit/s, not {given}", f"they show {shown} bit/s"
    else:
        said, reason = f"its timestamps fit no rate of table 4.7, not even {given}", "they fit no rate of table 4.7"
    print(f"rs30x-sniff: warning: {path}: {said}: {evidence}", file=sys.stderr)
    return dataclasses.replace(settings, timing_unsupported=f"the timestamps contradict {label}: {reason}")


def is_port_path(path: str, *, unplugged: bool = False) -> bool:
    """A serial port (a device or a pyserial URL) rather than a capture file; with ``unplugged``, a /dev
    path that does not exist counts too (an adapter not plugged in: the monitor says so as a port)."""
    from ..sources.ports import is_port

    return is_port(path) or (unplugged and path.startswith("/dev/") and not os.path.exists(path))


def _scan(port: str, settings: Settings) -> Settings:
    """``--baud auto`` on a port: listen at each rate of table 4.7 and take the one with valid frames."""
    from ..decode.autobaud import scan
    from ..sources.serial_tap import port_reader

    result = scan(port_reader(port))  # each rate of table 4.7 in SCAN_ORDER, listened to for SCAN_DWELL
    if not result:
        raise CliError(f"{port}: {result.describe()}")
    assert result.baud is not None  # a result that holds (above) has found its rate
    print(f"rs30x-sniff: {port}: {result.describe()}", file=sys.stderr)
    return dataclasses.replace(settings, baud=result.baud,
                               origin={**settings.origin, "baud": f"--baud auto ({result.score:.1f} frames/s)"})


def live_sinks(settings: Settings, source: object, name: str) -> list[Sink]:
    """The sinks every command adds for a live port: the rate watch of ``--baud auto``."""
    if settings.baud_auto and is_live(source):
        return [BaudWatchWarning(name, settings.baud)]
    return []


def lint_config(settings: Settings) -> Any:
    try:
        return settings.lint_config()
    except SettingsError as e:
        raise CliError(str(e)) from None


def make_linter(args: argparse.Namespace, settings: Settings) -> Any:
    """A Linter configured by ``settings``, or None with --no-lint."""
    if getattr(args, "no_lint", False):
        return None
    from ..lint import Linter  # imported here: only linting commands pay for the rules

    return Linter(lint_config(settings), keep_findings=False)  # the decoder hands them on: none kept here


def check_positive(option: str, value: float | None) -> None:
    """A command-only number (--duration, --speed, ...): finite and positive, or a one-line error."""
    if value is not None and not (value > 0 and value != float("inf")):
        raise CliError(f"{option} {value:g}: must be a finite, positive number")


# ---- inputs ----------------------------------------------------------------------------------------
def open_input(path: str, fmt: str | None, settings: Settings, *, duration: float | None = None,
               locate: bool = False) -> Source:
    """Chunks from a capture file (or '-' for stdin), or live from a serial port, as ``settings`` say.

    A port (a character device such as /dev/ttyUSB0, or a pyserial URL such as socket://host:port)
    is read passively at the settings' baud until Ctrl-C, SIGTERM, SIGHUP or ``duration`` seconds;
    the returned source then has ``live = True`` and, after iteration, ``lost`` tells whether the
    port failed. A timestamped capture's times are read by the settings' time reference. ``locate``
    True: the source's ``locate(offset)`` says where in a text capture a byte was (a line index is
    kept, 16 bytes a line); the commands that report findings by line and column ask for it. An
    error in a text capture names its line either way.
    """
    if fmt is None and is_port_path(path):
        from ..sources.serial_tap import LiveSource

        check_positive("--duration", duration)
        return LiveSource(path, settings.baud, duration=duration).start()
    # A unit the settings do not give is told by the reader itself (a pipe has no capture layer): it says so.
    options = {**input_options(settings), "locate": locate, "say_time_unit": settings.time_unit is None}
    return read_input(path, fmt, baud=settings.baud, time_ref=settings.time_ref, options=options)


def input_options(settings: Settings) -> dict[str, Any]:
    """What a capture's reader is told: the channel, the baud rate unless it is only the default (None:
    a logic capture finds it in its samples), and the unit of a timestamped capture's times (None: the
    reader tells it from the content)."""
    known = not str(settings.origin.get("baud", DEFAULTS)).startswith(DEFAULTS)
    return {"channel": settings.channel, "baud": settings.baud if known else None, "time_unit": settings.time_unit}


def is_live(chunks: object) -> bool:
    """Whether an input from :func:`open_input` is a live port (flush output per batch, then)."""
    return bool(getattr(chunks, "live", False))


def no_data(name: str, counted: Any, source: object = None) -> bool:
    """Warn on stderr when an input held no bytes (an empty file, a silent port); True if so.

    ``counted`` is anything with ``bytes_in`` (a Decoder, CaptureStats).
    """
    if getattr(counted, "bytes_in", 0):
        return False
    if is_live(source):
        why = "no bytes received (is RX on the bus wire, and the baud rate right?)"
    else:
        why = "no data (the capture is empty)"
    print(f"rs30x-sniff: warning: {name}: {why}", file=sys.stderr)
    return True


def capture_start_time(source: object) -> float | None:
    """The wall-clock time (seconds since the epoch) of capture time 0 where the source's format says it
    (a Saleae ISO table, a socat or jpnevulator log: their first stamp), else None. Read after the source
    was read (or peeked at): the reader finds it in the file."""
    found = getattr(getattr(source, "context", None), "found", None) or {}
    when = found.get("start_time")
    return None if when is None else when.timestamp()
