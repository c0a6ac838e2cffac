"""Options and helpers shared by the subcommands: input selection, model options, output files."""

from __future__ import annotations

import argparse
import sys
from contextlib import contextmanager
from typing import IO, Iterator

from ..io.captures import FORMATS, Chunk, read_capture
from ..memmap import ModelError, default_registry
from ..pipeline import DecodeOptions
from ..wire import BAUD_RATES, DEFAULT_BAUD


class CliError(Exception):
    """A usage, configuration or input error: printed as one line, exit code 2."""


def add_decode_options(p: argparse.ArgumentParser) -> None:
    """--model, --baud and the timing knobs every decoding command shares."""
    p.add_argument("--model", action="append", default=[], metavar="[ID=]MODEL",
                   help="servo model for every ID (RS303MR, RS304MD) or for one ID (3=RS304MD); repeatable")
    p.add_argument("--baud", type=int, default=None, metavar="BPS",
                   help="bus baud rate, for byte times and gap detection (default 115200)")
    p.add_argument("--input-format", choices=FORMATS, default=None,
                   help="capture format, when the extension and content do not tell")
    p.add_argument("--gap-bytes", type=float, default=None, metavar="N",
                   help="idle byte times inside a frame that end it as truncated (default 20)")
    p.add_argument("--reply-timeout", type=float, default=None, metavar="S",
                   help="seconds after a request before its reply counts as missing (default 0.05)")


def parse_models(specs: list[str]) -> tuple[str | None, dict[int, str]]:
    """``["RS304MD", "3=RS303MR"]`` -> (default model, {3: "RS303MR"}), checked against the registry."""
    reg = default_registry()
    default, per_id = None, {}
    for spec in specs:
        key, sep, name = spec.partition("=")
        try:
            if sep:
                try:
                    sid = int(key, 0)
                except ValueError:
                    raise CliError(f"--model {spec}: {key!r} is not a servo ID") from None
                per_id[sid] = reg.get(name).name
            else:
                default = reg.get(spec).name
        except ModelError as e:
            raise CliError(f"--model {spec}: {e}") from None
    return default, per_id


def decode_options(args: argparse.Namespace, config: dict | None = None) -> DecodeOptions:
    """DecodeOptions from the shared options (config values fill what the command line leaves out)."""
    config = config or {}
    default, per_id = parse_models(getattr(args, "model", []))
    opts = DecodeOptions()
    if config.get("models"):
        for k, v in config["models"].items():
            opts.models[int(k)] = v
    if config.get("model"):
        opts.default_model = config["model"]
    opts.models.update(per_id)
    if default:
        opts.default_model = default
    baud = args.baud if getattr(args, "baud", None) is not None else config.get("baud")
    if baud is not None:
        if baud <= 0:
            raise CliError(f"--baud {baud}: must be positive (the bus runs at one of {BAUD_RATES})")
        opts.baud = baud
    if getattr(args, "gap_bytes", None) is not None:
        opts.gap_bytes = args.gap_bytes if args.gap_bytes > 0 else None
    elif "gap_bytes" in config:
        opts.gap_bytes = config["gap_bytes"]
    if getattr(args, "reply_timeout", None) is not None:
        opts.reply_timeout = args.reply_timeout
    elif "reply_timeout" in config:
        opts.reply_timeout = config["reply_timeout"]
    return opts


def add_live_options(p: argparse.ArgumentParser) -> None:
    """--duration, for commands whose INPUT may be a serial port (a device or a pyserial URL)."""
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="when INPUT is a serial port: stop after S seconds (default: run until Ctrl-C)")


def open_input(path: str, fmt: str | None = None, *, baud: int | None = None,
               duration: float | None = None) -> Iterator[Chunk]:
    """Chunks from a capture file (or '-' for raw bytes on stdin), or live from a serial port.

    A port (a character device such as /dev/ttyUSB0, or a pyserial URL such as socket://host:port)
    is read passively at ``baud`` until Ctrl-C, SIGTERM or ``duration`` seconds; the returned
    source then has ``live = True`` and, after iteration, ``lost`` tells whether the port failed.
    """
    if fmt is None:
        from ..io.serial_tap import is_port  # no pyserial import unless INPUT is a port

        if is_port(path):
            from ..io.serial_tap import LiveSource

            if duration is not None and duration <= 0:
                raise CliError(f"--duration {duration:g}: must be positive")
            return LiveSource(path, baud or DEFAULT_BAUD, duration=duration).start()
    return read_capture(path, fmt)


def is_live(chunks: object) -> bool:
    """Whether an input from :func:`open_input` is a live port (flush output per batch, then)."""
    return bool(getattr(chunks, "live", False))


@contextmanager
def output_stream(path: str | None) -> Iterator[IO[str]]:
    """stdout, or a file opened for writing text (with a one-line error if it cannot be)."""
    if not path or path == "-":
        yield sys.stdout
        return
    try:
        f = open(path, "w", encoding="utf-8")
    except OSError as e:
        raise CliError(f"{path}: cannot write: {e.strerror}") from None
    with f:
        yield f
