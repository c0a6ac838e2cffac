"""`rs30x-sniff lint`: check captures against the rule catalog, with reports and exit codes for CI."""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any
from collections.abc import Callable

from ..sources.captures import CaptureError
from ..lint.config import FAIL_ON, FORMATS
from ..lint.linter import Linter
from ..lint.report import FileResult, append_step_summary, fails, write_report, write_step_summary
from ..protocol.memmap import ModelError
from ..decode.decoder import Decoder, Sink

if TYPE_CHECKING:
    from ..decode.blocks import Block
    from ..decode.pairing import Record
    from ..lint.baseline import Baseline, BaselineReport
from ..sinks.pipeline import columnar_for, drive
from ..settings import Settings
from ..sinks.lines import FindingsSink, ProgressSink
from .common import (CliError, check_positive, config_layer, is_live, lint_config, live_sinks, no_data, open_input,
                     settings_for)
from .options import add_decode_options, add_format_option, add_lint_selection, add_live_options
from ..sinks.outputs import check_output, output_stream
from .outputs import add_output_options

PROGRESS_MIN_BYTES = 1 << 20  # a progress bar only for inputs worth waiting for


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
    add_format_option(p, FORMATS, default=None,
                      help="report format (default text)")
    p.add_argument("-j", "--jobs", type=int, default=1, metavar="N", help="lint N files in parallel (default 1)")
    add_output_options(p)
    p.add_argument("--allow-empty", action="store_true",
                   help="an input that holds no data is a warning, not an error (exit 2)")
    p.add_argument("--baseline", metavar="FILE",
                   help="fail only on findings FILE does not hold (written by --write-baseline); the report "
                        "counts the findings it absorbed and lists its entries no longer seen")
    p.add_argument("--write-baseline", metavar="FILE",
                   help="record the findings in FILE (- for stdout) instead of reporting them, for a later "
                        "--baseline; exit 0 unless an input cannot be read")
    p.set_defaults(run=run)


def lint_file(path: str, fmt: str | None, settings: Settings,
              progress: Callable[[int], None] | None = None, duration: float | None = None,
              allow_empty: bool = False) -> FileResult:
    """Lint one capture (or a port, live); an unreadable input, or one that holds no data (unless
    ``allow_empty``), gives a result with ``error`` set (findings so far kept)."""
    opts = settings.decode_options()
    cfg = lint_config(settings)
    linter = Linter(cfg, keep_findings=False)
    found = FindingsSink()
    sinks: list[Sink[Record | Block]] = [found] if progress is None else [found, ProgressSink(progress)]
    # Figure checks ([[expect]]) need info's figures: CaptureStats runs as one more sink, only for them.
    enabled, severities = set(cfg.enabled_codes()), cfg.severities()
    checks = [replace(c, severity=severities[c.code]) for c in settings.expects if c.code in enabled]
    stats = None
    if checks:
        from ..sinks.stats import CaptureStats  # here: info's figures cost every other lint's start-up 4 ms

        stats = CaptureStats(opts.baud, ranges=any(c.reads_ranges for c in checks))
        stats.timing_unsupported = settings.timing_unsupported
        sinks.append(stats)
    result = FileResult(path, rules=[r.code for r in linter.rules], rule_set=cfg.rules)
    source = None
    try:
        source = open_input(path, fmt, settings, duration=duration, locate=True)  # findings by line
        result.format = getattr(source, "format", None)  # SARIF regions: lines of text, bytes of a binary file
        # A file takes the columnar path (same findings, a fraction of the time); a port, record by record.
        dec = drive(source, Decoder(opts, linter, columnar=columnar_for(source)), *sinks,
                    *live_sinks(settings, source, path))
    except (CaptureError, ModelError) as e:
        result.error = str(e)
    else:
        # CI must not pass a recording that holds nothing.
        if not dec.bytes_in and not allow_empty:
            what = "no bytes received from the port" if is_live(source) else "no data (the capture is empty)"
            result.error = f"{path}: {what}; --allow-empty to accept that"
        elif not dec.bytes_in:
            no_data(path, dec, source)
        if stats is not None and dec.bytes_in:
            stats.stalls = getattr(source, "stalls", stats.stalls)
            from ..expect import evaluate  # a config with [[expect]] checks only (stats is None without one)
            from ..expect import findings as check_findings

            results = evaluate(checks, stats.as_dict(), [r.code for r in linter.rules])
            found.findings.extend(check_findings(results, stats.bytes, stats.last_t if stats.timed else None))
    result.findings = found.findings
    locate = getattr(source, "locate", None)  # text captures: findings by line and column, as ruff does
    if locate is not None:
        for f in result.findings:
            loc = locate(f.offset)
            if loc is not None:
                result.locations[f.offset] = loc
    result.skipped = list(linter.skipped)
    result.records = found.records
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
    check_positive("--duration", args.duration)
    baseline = _baseline_options(args)
    if args.output:
        check_output(args.output, args.force, tuple(args.inputs))  # before the work, not after
    config = config_layer(args)
    per_file = [settings_for(args, p, config=config) for p in args.inputs]
    cfg = lint_config(per_file[0])
    fmt = args.format or per_file[0].report_format or "text"
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
            jobs = [(p, args.input_format, st, None, None, args.allow_empty) for p, st in zip(args.inputs, per_file)]
            from concurrent.futures import ProcessPoolExecutor  # here: only --jobs pays for it

            with ProcessPoolExecutor(max_workers=min(args.jobs, len(jobs))) as pool:
                for path, res in zip(args.inputs, pool.map(_lint_job, jobs)):
                    results.append(res)
                    if advance:
                        advance(_size(path))
        else:
            for p, st in zip(args.inputs, per_file):
                results.append(lint_file(p, args.input_format, st, advance, args.duration, args.allow_empty))
    finally:
        if progress_ctx is not None:
            progress_ctx.stop()
    errors = [r.error for r in results if r.error]
    readable = [r for r in results if not r.error]
    if args.write_baseline:
        return _write_baseline(args, results, errors)
    report = None
    if baseline is not None:
        report = apply_baseline(baseline, readable)
    # After an input error, no report file: it would read as a clean pass of every input. On stdout the
    # readable files are still reported (the unreadable ones are not counted), and the exit code is 2.
    if readable and not (errors and args.output):
        with output_stream(args.output, force=args.force, inputs=tuple(args.inputs)) as out:
            write_report(fmt, readable, out, cfg.fail_on, baseline=report)
    if fmt == "github":  # in a workflow, the run's summary too (nothing when GITHUB_STEP_SUMMARY is unset)
        warning = append_step_summary(lambda md: write_step_summary(readable, md, cfg.fail_on, report, errors))
        if warning:
            print(f"rs30x-sniff: warning: {warning}", file=sys.stderr)
    for e in errors:
        print(f"rs30x-sniff: error: {e}", file=sys.stderr)
    if errors:
        return 2
    return 1 if any(fails(f, cfg.fail_on) for r in results for f in r.findings) else 0


def _baseline_options(args: argparse.Namespace) -> Baseline | None:
    """Check --baseline and --write-baseline before the work: the baseline read, the file to write free."""
    if args.baseline and args.write_baseline:
        raise CliError("--baseline and --write-baseline: give one (--write-baseline records every finding anew)")
    if args.write_baseline:
        if args.output:
            raise CliError("-o and --write-baseline: the baseline is the output (no report is written)")
        check_output(args.write_baseline, args.force, tuple(args.inputs))
        return None
    if not args.baseline:
        return None
    from ..lint.baseline import BASELINE_VERSION, Baseline, BaselineError  # here: only --baseline reads one

    try:
        baseline = Baseline.load(args.baseline)
    except BaselineError as e:
        raise CliError(str(e)) from None
    if baseline.version < BASELINE_VERSION:  # still read, by the fingerprints its version made
        print(f"rs30x-sniff: {args.baseline}: baseline version {baseline.version}, matched as that version "
              f"fingerprinted (by the text); user rules' messages now carry units: lint --write-baseline to "
              f"write version {BASELINE_VERSION}", file=sys.stderr)
    return baseline


def apply_baseline(baseline: Baseline, results: list[FileResult]) -> BaselineReport:
    """Move each result's findings the baseline holds to its ``absorbed``; what the baseline did."""
    from ..lint.baseline import BaselineReport

    absorbed = []
    for r in results:
        r.findings, r.absorbed = baseline.split(r.findings)
        absorbed += r.absorbed
    return BaselineReport(baseline.path or "", len(absorbed), baseline.stale(absorbed))


def _write_baseline(args: argparse.Namespace, results: list[FileResult], errors: list[str]) -> int:
    """--write-baseline: every input read, or nothing written (a baseline missing a file's findings would
    pass them later)."""
    for e in errors:
        print(f"rs30x-sniff: error: {e}", file=sys.stderr)
    if errors:
        print(f"rs30x-sniff: error: {args.write_baseline}: baseline not written", file=sys.stderr)
        return 2
    from ..lint.baseline import Baseline

    findings = [f for r in results for f in r.findings]
    baseline = Baseline.of(findings)
    with output_stream(args.write_baseline, force=args.force, inputs=tuple(args.inputs)) as out:
        baseline.dump(out)
    where = "stdout" if args.write_baseline == "-" else args.write_baseline
    n, k = len(findings), len(baseline.entries)
    print(f"rs30x-sniff: baseline: {k} entr{'ies' if k != 1 else 'y'} ({n} finding{'s' if n != 1 else ''}) "
          f"to {where}", file=sys.stderr)
    return 0
