"""`rs30x-sniff lint`: check captures against the rule catalog, with reports and exit codes for CI."""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any, Callable

from ..io.captures import CaptureError
from ..lint.config import FAIL_ON, FORMATS, ConfigError, LintConfig, check_settings, find_config, load_config, lint_config
from ..lint.linter import Linter
from ..lint.report import FileResult, fails, write_report
from ..memmap import ModelError, default_registry
from ..pipeline import DecodeOptions, Decoder
from .common import CliError, add_decode_options, add_live_options, decode_options, open_input, output_stream

PROGRESS_MIN_BYTES = 1 << 20  # a progress bar only for inputs worth waiting for


def add_lint_selection(p: argparse.ArgumentParser) -> None:
    """--select / --ignore (shared with decode) and --config."""
    p.add_argument("--select", action="append", default=None, metavar="RULES",
                   help="only these rules: codes, prefixes (Q, B00) or names, comma-separated; repeatable")
    p.add_argument("--ignore", action="append", default=None, metavar="RULES",
                   help="skip these rules (same forms as --select); repeatable")
    p.add_argument("--config", metavar="FILE",
                   help="settings file (default: the nearest rs30x-sniff.toml or pyproject.toml [tool.rs30x-sniff])")
    p.add_argument("--isolated", action="store_true", help="ignore configuration files")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("lint", help="check captures against the rule catalog (exit 1 on findings)",
                       description="Lint captures: protocol, memory-map, bus and sequence rules, with reports for CI. "
                                   "Exit 0: nothing at or above --fail-on; 1: findings at or above it; 2: usage, "
                                   "config or input error.")
    p.add_argument("inputs", nargs="+", metavar="INPUT", help="capture files (.bin/.raw, .hex, timestamped hex, .mcap)")
    add_decode_options(p)
    add_live_options(p)
    add_lint_selection(p)
    p.add_argument("--severity", action="append", default=[], metavar="RULE=LEVEL",
                   help="change a rule's severity (error, warning, info); repeatable")
    p.add_argument("--fail-on", choices=FAIL_ON, default=None,
                   help="lowest severity that makes the exit code 1 (default error)")
    p.add_argument("--format", choices=FORMATS, default=None, help="report format (default text)")
    p.add_argument("-j", "--jobs", type=int, default=1, metavar="N", help="lint N files in parallel (default 1)")
    p.add_argument("-o", "--output", metavar="OUT", help="write the report to OUT instead of stdout")
    p.set_defaults(run=run)


def _split(values: list[str] | None) -> list[str] | None:
    if values is None:
        return None
    return [v.strip() for item in values for v in item.split(",") if v.strip()]


def settings_from(args: argparse.Namespace) -> dict[str, Any]:
    """The config file's settings (checked), or {} when there is none or --isolated."""
    if getattr(args, "isolated", False):
        return {}
    path = args.config or find_config()
    if path is None:
        return {}
    try:
        settings = load_config(path)
    except ConfigError as e:
        raise CliError(str(e)) from None
    reg = default_registry()
    where = settings["source"]
    try:
        if "model" in settings:
            settings["model"] = reg.get(settings["model"]).name
        for sid, name in settings.get("models", {}).items():
            settings["models"][sid] = reg.get(name).name
    except ModelError as e:
        raise CliError(f"{where}: {e}") from None
    return settings


def build_config(args: argparse.Namespace, settings: dict[str, Any], opts: DecodeOptions) -> LintConfig:
    """LintConfig from the file's settings with the command line on top (--select replaces, --ignore adds)."""
    merged = dict(settings)
    try:
        cli: dict[str, Any] = {}
        sel = _split(getattr(args, "select", None))
        if sel is not None:
            cli["select"] = sel
        ign = _split(getattr(args, "ignore", None))
        if ign:
            cli["ignore"] = ign
        sev = {}
        for spec in getattr(args, "severity", None) or []:
            key, eq, level = spec.partition("=")
            if not eq:
                raise ConfigError(f"--severity {spec}: expected RULE=LEVEL")
            sev[key.strip()] = level.strip()
        if sev:
            cli["severity"] = sev
        if getattr(args, "fail_on", None):
            cli["fail_on"] = args.fail_on
        cli = check_settings(cli, "command line")
        cli.pop("source")
        merged["ignore"] = list(settings.get("ignore", [])) + cli.pop("ignore", [])
        merged["severity"] = {**settings.get("severity", {}), **cli.pop("severity", {})}
        merged.update(cli)
        cfg = lint_config(merged)
        cfg.baud = opts.baud
        cfg.reply_timeout = opts.reply_timeout
        if opts.gap_bytes:
            cfg.gap_bytes = opts.gap_bytes
        cfg.enabled_codes()
        cfg.severities()
    except ConfigError as e:
        raise CliError(str(e)) from None
    return cfg


def lint_file(path: str, fmt: str | None, opts: DecodeOptions, cfg: LintConfig,
              progress: Callable[[int], None] | None = None, duration: float | None = None) -> FileResult:
    """Lint one capture (or a port, live); an unreadable input gives a result with ``error`` set
    (findings so far kept)."""
    linter = Linter(cfg)
    dec = Decoder(opts, linter)
    result = FileResult(path, rules=[r.code for r in linter.rules])
    try:
        source = open_input(path, fmt, baud=opts.baud, duration=duration)
        for data, t in source:
            dec.feed(data, t)
            if progress is not None:
                progress(len(data))
        dec.close()  # a lost port has already said so on stderr; its findings so far still count
    except (CaptureError, ModelError) as e:
        result.error = str(e)
    result.findings = list(linter.findings)
    result.skipped = list(linter.skipped)
    result.records = linter.records
    return result


def _lint_job(job: tuple) -> FileResult:
    return lint_file(*job)


def want_progress(stream: Any = None, env: Any = None) -> bool:
    """A progress bar only for a person watching: stderr is a terminal and this is not CI."""
    stream = stream if stream is not None else sys.stderr
    env = env if env is not None else os.environ
    if env.get("CI", "").lower() not in ("", "0", "false"):
        return False
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


def _size(path: str) -> int:
    try:
        return Path(path).stat().st_size
    except OSError:
        return 0


def run(args: argparse.Namespace) -> int:
    settings = settings_from(args)
    opts = decode_options(args, settings)
    cfg = build_config(args, settings, opts)
    fmt = args.format or settings.get("format", "text")
    if args.jobs < 1:
        raise CliError(f"-j {args.jobs}: must be 1 or more")
    total = sum(_size(p) for p in args.inputs)
    show = want_progress() and total >= PROGRESS_MIN_BYTES
    results: list[FileResult] = []
    progress_ctx = None
    if show:
        from rich.progress import BarColumn, DownloadColumn, Progress, TextColumn, TimeRemainingColumn
        from rich.console import Console
        progress_ctx = Progress(TextColumn("linting"), BarColumn(), DownloadColumn(), TimeRemainingColumn(),
                                console=Console(stderr=True), transient=True)
        progress_ctx.start()
        task = progress_ctx.add_task("lint", total=total)
        advance = lambda n: progress_ctx.advance(task, n)  # noqa: E731
    else:
        advance = None
    try:
        if args.jobs > 1 and len(args.inputs) > 1:
            jobs = [(p, args.input_format, opts, cfg) for p in args.inputs]
            with ProcessPoolExecutor(max_workers=min(args.jobs, len(jobs))) as pool:
                for path, res in zip(args.inputs, pool.map(_lint_job, jobs)):
                    results.append(res)
                    if advance:
                        advance(_size(path))
        else:
            for p in args.inputs:
                results.append(lint_file(p, args.input_format, opts, cfg, advance, args.duration))
    finally:
        if progress_ctx is not None:
            progress_ctx.stop()
    with output_stream(args.output) as out:
        write_report(fmt, results, out, cfg.fail_on)
    errors = [r.error for r in results if r.error]
    for e in errors:
        print(f"rs30x-sniff: error: {e}", file=sys.stderr)
    if errors:
        return 2
    return 1 if any(fails(f, cfg.fail_on) for r in results for f in r.findings) else 0
