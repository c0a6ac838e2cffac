"""Options and helpers shared by the subcommands: settings from every layer, inputs, output files."""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any, Iterator

from ..io.captures import FORMATS, MCAP, MCAP_MAGIC, Chunk
from ..io.inputs import read_input
from ..timebase import TIME_REFS
from ..settings import Settings, SettingsError, find_config, load_config, resolve


class CliError(Exception):
    """A usage, configuration or input error: printed as one line, exit code 2."""


def add_decode_options(p: argparse.ArgumentParser) -> None:
    """--model, --baud and the timing knobs every decoding command shares."""
    p.add_argument("--model", action="append", default=[], metavar="[ID=]MODEL",
                   help="servo model for every ID (RS303MR, RS304MD) or for one ID (3=RS304MD); repeatable")
    p.add_argument("--baud", type=int, default=None, metavar="BPS",
                   help="bus baud rate, one of table 4.7's (default 115200, or what an MCAP capture recorded)")
    p.add_argument("--baud-any", action="store_true", default=None,
                   help="accept a --baud that is not one of the manual's rates")
    p.add_argument("--input-format", choices=FORMATS, default=None,
                   help="capture format, when the extension and content do not tell")
    p.add_argument("--gap-bytes", type=float, default=None, metavar="N",
                   help="idle byte times inside a frame that end it as truncated (default 20; 0 turns it off)")
    p.add_argument("--reply-timeout", type=float, default=None, metavar="S",
                   help="seconds after a request before its reply counts as missing (default 0.05)")
    p.add_argument("--time-ref", choices=TIME_REFS, default=None,
                   help="what a timestamped hex capture's times mark: each line's first byte, or its arrival "
                        "(the end of its last byte, as serial loggers stamp reads); default: told by the content")


def add_lint_selection(p: argparse.ArgumentParser) -> None:
    """--select / --ignore and the settings file options (every command that lints)."""
    p.add_argument("--select", action="append", default=None, metavar="RULES",
                   help="only these rules: codes, prefixes (Q, B00) or names, comma-separated; repeatable")
    p.add_argument("--ignore", action="append", default=None, metavar="RULES",
                   help="skip these rules (same forms as --select); repeatable")
    add_config_options(p)


def add_config_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", metavar="FILE",
                   help="settings file (default: the nearest rs30x-sniff.toml or pyproject.toml [tool.rs30x-sniff])")
    p.add_argument("--isolated", action="store_true", help="ignore configuration files")


def add_lint_options(p: argparse.ArgumentParser) -> None:
    """The linter's rule selection, as `lint` takes it, and --no-lint."""
    add_lint_selection(p)
    p.add_argument("--no-lint", action="store_true", help="do not run the linter")


def add_live_options(p: argparse.ArgumentParser) -> None:
    """--duration, for commands whose INPUT may be a serial port (a device or a pyserial URL)."""
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="when INPUT is a serial port: stop after S seconds (default: run until Ctrl-C)")


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
        if sep:
            out.setdefault("models", {})[key.strip()] = name.strip()
        else:
            out["model"] = spec.strip()
    for key in ("baud", "baud_any", "gap_bytes", "reply_timeout", "fail_on", "time_ref"):
        v = getattr(args, key, None)
        if v is not None:
            out[key] = v
    for key in ("select", "ignore"):
        v = _split(getattr(args, key, None))
        if v is not None and (key == "select" or v):
            out[key] = v
    sev = {}
    for spec in getattr(args, "severity", None) or []:
        key, eq, level = spec.partition("=")
        if not eq:
            raise CliError(f"--severity {spec}: expected RULE=LEVEL")
        sev[key.strip()] = level.strip()
    if sev:
        out["severity"] = sev
    return out


def config_layer(args: argparse.Namespace) -> dict[str, Any]:
    """The config file's settings (checked), or {} when there is none or --isolated."""
    if getattr(args, "isolated", False):
        return {}
    path = getattr(args, "config", None) or find_config()
    if path is None:
        return {}
    try:
        return load_config(path)
    except SettingsError as e:
        raise CliError(str(e)) from None


def capture_layer(path: str | None, fmt: str | None = None) -> dict[str, Any]:
    """What a capture records about how it was made (an MCAP file of ours: baud, models); {} otherwise."""
    if not path or path == "-" or not os.path.isfile(path):
        return {}
    if fmt is None:
        try:
            with open(path, "rb") as f:
                if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                    return {}
        except OSError:
            return {}
    elif fmt != MCAP:
        return {}
    from ..io.mcap_source import McapRawReader  # only MCAP inputs need the mcap library
    from ..memmap import ModelError, default_registry

    reader = McapRawReader(path, warn=None)
    try:
        meta = reader.read_metadata()
    except Exception:  # noqa: BLE001 - unreadable metadata: the reader says why when the data is read
        return {}
    out: dict[str, Any] = {}
    if reader.baud:
        out["baud"] = reader.baud
    reg = default_registry()
    try:
        models = {sid: reg.get(name).name for sid, name in reader.models.items() if 1 <= sid <= 127}
        default = meta.get("rs30x", {}).get("default_model")
        if default:
            out["model"] = reg.get(default).name
    except ModelError:
        models = {}  # a model this installation does not know: decode with the others' defaults
    if models:
        out["models"] = models
    return out


def settings_for(args: argparse.Namespace, path: str | None = None, *, config: dict | None = None) -> Settings:
    """The settings for one input: command line > config file > what the capture records > defaults."""
    try:
        return resolve(command_line_layer(args), config_layer(args) if config is None else config,
                       capture_layer(path, getattr(args, "input_format", None)))
    except SettingsError as e:
        raise CliError(str(e)) from None


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

    return Linter(lint_config(settings))


def check_positive(option: str, value: float | None) -> None:
    """A command-only number (--duration, --speed, ...): finite and positive, or a one-line error."""
    if value is not None and not (value > 0 and value != float("inf")):
        raise CliError(f"{option} {value:g}: must be a finite, positive number")


# ---- inputs ----------------------------------------------------------------------------------------
def open_input(path: str, fmt: str | None, settings: Settings, *, duration: float | None = None) -> Iterator[Chunk]:
    """Chunks from a capture file (or '-' for stdin), or live from a serial port, as ``settings`` say.

    A port (a character device such as /dev/ttyUSB0, or a pyserial URL such as socket://host:port)
    is read passively at the settings' baud until Ctrl-C, SIGTERM, SIGHUP or ``duration`` seconds;
    the returned source then has ``live = True`` and, after iteration, ``lost`` tells whether the
    port failed. A timestamped capture's times are read by the settings' time reference.
    """
    if fmt is None:
        from ..io.serial_tap import is_port  # no pyserial import unless INPUT is a port

        if is_port(path):
            from ..io.serial_tap import LiveSource

            check_positive("--duration", duration)
            return LiveSource(path, settings.baud, duration=duration).start()
    return read_input(path, fmt, baud=settings.baud, time_ref=settings.time_ref)


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
