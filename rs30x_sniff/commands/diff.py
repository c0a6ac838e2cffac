"""`rs30x-sniff diff BEFORE AFTER`: two captures' figures side by side, and the regressions past `[regress]`."""

from __future__ import annotations

import argparse
import json
import sys
from typing import IO, Any

from ..compare import Change, Comparison, ThresholdError, Threshold, change_text, compare, parse_threshold, \
    parse_thresholds, show
from ..decode.decoder import Decoder
from ..lint.report import append_step_summary, github_escape, md_cell, md_code
from ..sinks.pipeline import columnar_for, drive
from ..sinks.stats import CaptureStats
from .common import (CliError, config_layer, is_live, live_sinks, make_linter, open_input,
                     say_deprecations, settings_for)
from .options import add_decode_options, add_format_option, add_lint_options
from ..sinks.outputs import STDOUT, check_output, output_stream
from .outputs import add_output_options

REGRESS = "regress"  # the configuration's table of thresholds


def add_parser(sub: Any) -> None:  # argparse's subparsers action (no public name for its type)
    p = sub.add_parser("diff", help="compare two captures: poll rates, latencies, missing replies, findings, load",
                       description="Two captures of any format side by side: per-servo poll rates, missing and "
                                   "unsolicited replies and register ranges, reply latency percentiles, bus load, "
                                   "and findings by rule (new, gone, changed). Thresholds come from the "
                                   "configuration's [regress] table (or --threshold); with --fail-on-regress a "
                                   "threshold crossed exits 1.")
    p.add_argument("before", metavar="BEFORE", help="the reference capture (e.g. recorded on main)")
    p.add_argument("after", metavar="AFTER", help="the capture to compare with it")
    add_decode_options(p, channel=False)  # two captures of one bus: no port to time, no logic channel to pick
    add_lint_options(p)
    add_format_option(p, ("text", "json", "markdown", "github"), default="text",
                      help="output format (default text); github: the text with a workflow annotation per threshold "
                           "crossed (an error with --fail-on-regress, else a warning), and the markdown table "
                           "appended to the file GITHUB_STEP_SUMMARY names")
    p.add_argument("--threshold", action="append", default=[], metavar="FIGURE=LIMIT",
                   help="a threshold as in [regress], e.g. latency_p95=+20%% or missing_replies=+0; "
                        "replaces the configuration's for that figure; repeatable")
    p.add_argument("--fail-on-regress", action="store_true",
                   help="exit 1 when a threshold is crossed, or when one could be checked on nothing (not "
                        "checkable: a figure neither capture gives), or when there is no threshold (default: "
                        "report only, exit 0)")
    p.add_argument("--allow-unchecked", action="store_true",
                   help="with --fail-on-regress: a threshold that is not checkable (or no threshold at all) is a "
                        "warning, not a failure")
    add_output_options(p)
    p.set_defaults(run=run)


def thresholds_from(conf: dict[str, Any], specs: list[str]) -> dict[str, Threshold]:
    """The configuration's [regress] thresholds, then --threshold's over them (one line for a bad one)."""
    out: dict[str, Threshold] = {}
    try:
        table = conf.get(REGRESS)
        if table is not None:
            out.update(parse_thresholds(table, str(conf.get("source", "config"))))
        for spec in specs:
            key, eq, value = spec.partition("=")
            if not eq or not key.strip():
                raise CliError(f"--threshold {spec}: expected FIGURE=LIMIT, e.g. latency_p95=+20%")
            t = parse_threshold(key.strip(), value.strip(), "--threshold")
            out[t.figure] = t
    except ThresholdError as e:
        raise CliError(str(e)) from None
    return out


def figures_of(args: argparse.Namespace, path: str, conf: dict[str, Any]) -> dict[str, Any]:
    """One capture's figures as `info --format json` gives them, from one drive loop (the linter in the
    same pass), with ``unsolicited_counted``: whether rule B003 ran."""
    settings = settings_for(args, path, config=conf)
    linter = make_linter(args, settings)
    source = open_input(path, args.input_format, settings)
    stats = CaptureStats(settings.baud)
    stats.timing_unsupported = getattr(settings, "timing_unsupported", None)
    stats.stalls = getattr(source, "stalls", stats.stalls)
    drive(source, Decoder(settings.decode_options(), linter, columnar=columnar_for(source)), stats,
          *live_sinks(settings, source, path))
    if not stats.bytes_in:  # an empty capture is no session: comparing it would pass as "everything better"
        what = "no bytes received from the port" if is_live(source) else "no data (the capture is empty)"
        raise CliError(f"{path}: {what}: nothing to compare")
    codes = linter.config.enabled_codes() if linter is not None else []
    return {"input": path, "linted": linter is not None, "unsolicited_counted": "B003" in codes, **stats.as_dict()}


def run(args: argparse.Namespace) -> int:
    if args.allow_unchecked and not args.fail_on_regress:
        raise CliError("--allow-unchecked: only with --fail-on-regress (what it allows is its failure)")
    if args.before == STDOUT and args.after == STDOUT:
        raise CliError("BEFORE and AFTER are both - (stdin): at most one of them can be read from stdin")
    inputs = (args.before, args.after)
    if args.output:
        check_output(args.output, args.force, inputs)  # before the work, not after
    conf = dict(config_layer(args))
    thresholds = thresholds_from(conf, args.threshold)
    say_deprecations()  # an old figure name of --threshold (the file's were said as it was read)
    conf.pop(REGRESS, None)
    before = figures_of(args, args.before, conf)
    after = figures_of(args, args.after, conf)
    result = compare(before, after, thresholds)
    with output_stream(args.output, force=args.force, inputs=inputs) as out:
        if args.format == "json":
            out.write(json.dumps(result.as_dict(), indent=2) + "\n")
        elif args.format == "markdown":
            write_markdown(out, result)
        else:
            write_text(out, result)
            if args.format == "github":
                write_annotations(out, result, "error" if args.fail_on_regress else "warning", args.after,
                                  "error" if args.fail_on_regress and not args.allow_unchecked else "warning")
    if args.format == "github":  # in a workflow, the run's summary too (nothing when GITHUB_STEP_SUMMARY is unset)
        warning = append_step_summary(lambda md: write_markdown(md, result))
        if warning:
            print(f"rs30x-sniff: warning: {warning}", file=sys.stderr)
    if args.fail_on_regress:
        # A gate that cannot be run never passes (as an [[expect]] that cannot be measured fails), unless
        # --allow-unchecked says that is fine.
        level = "warning" if args.allow_unchecked else "error"
        if not thresholds:
            print(f"rs30x-sniff: {level}: --fail-on-regress: not checkable: no thresholds ([regress] in the "
                  f"configuration, or --threshold)", file=sys.stderr)
        for name in result.blind:
            why = "; ".join(u.describe() for u in result.unchecked if u.figure == name)
            print(f"rs30x-sniff: {level}: not checkable: {why}", file=sys.stderr)
        for c in result.crossings:
            print(f"rs30x-sniff: regression: {c.describe()}", file=sys.stderr)
        if result.regressed:
            return 1
        return 0 if args.allow_unchecked or (thresholds and not result.blind) else 1
    return 0


# ---- text -------------------------------------------------------------------------------------------
def _side(d: Any) -> str:
    timing = f"{d.get('duration_s', 0):.3f} s" + ("" if d.get("timed") else " of line time (no timestamps)")
    lint = "" if d.get("linted", True) else ", not linted"
    return f"{d.get('input')}: {timing}, {d.get('bytes', 0)} bytes at {d.get('baud')} bit/s{lint}"


def _cells(c: Change) -> tuple[str, str, str]:
    """(before, after, change) in words; an absent figure says why instead of a change."""
    b, a = show(c.before.value, c.unit), show(c.after.value, c.unit)
    if c.absent is not None:
        return b, a, f"absent: {c.absent}"
    text = change_text(c)
    trend = c.trend
    return b, a, text + (f", {trend}" if trend in ("worse", "better") else "")


def _changed(rows: list[Change]) -> list[Change]:
    """The rows that differ, or that one side cannot give (absent on both: json has them)."""
    return [c for c in rows if c.delta != 0 and (c.before.value is not None or c.after.value is not None)]


def write_text(out: IO[str], r: Comparison) -> None:
    w = out.write
    w(f"before  {_side(r.before)}\n")
    w(f"after   {_side(r.after)}\n")
    w("\nbus\n")
    for c in [*r.bus, *r.changes]:
        b, a, ch = _cells(c)
        w(f"  {c.figure:<27} {b:>13} -> {a:<13} {ch}\n")
    w("\nservos" + " (figures that are the same before and after are left out; --format json has all)\n")
    for sid, rows in r.servos.items():
        shown = _changed(rows)
        if not shown:
            w(f"  ID {sid}: the same\n")
            continue
        w(f"  ID {sid}\n")
        for c in shown:
            b, a, ch = _cells(c)
            w(f"    {c.figure:<25} {b:>13} -> {a:<13} {ch}\n")
    if r.only_before:
        w(f"  only BEFORE: ID {', '.join(r.only_before)}\n")
    if r.only_after:
        w(f"  only AFTER: ID {', '.join(r.only_after)}\n")
    w("\nfindings by rule\n")
    f = r.findings
    if f.absent is not None:
        w(f"  absent: {f.absent}\n")
    elif not (f.new or f.gone or f.changed or f.same):
        w("  none in either capture\n")
    else:
        for status, rule, nb, na in f.rows():
            counts = f"{nb} -> {na}" if status == "changed" else f"{na if status != 'gone' else nb}"
            w(f"  {status:<8} {rule:<40} {counts}\n")
    w("\nthresholds")
    if not r.thresholds:
        w(": none ([regress] in the configuration, or --threshold)\n")
        return
    w(": " + ", ".join(f"{k} {t.text}" for k, t in r.thresholds.items()) + "\n")
    if r.crossings:
        for x in r.crossings:
            w(f"  crossed      {x.describe()}\n")
    elif len(r.blind) == len(r.thresholds):
        w("  none checkable\n")
    else:
        w("  none crossed\n")
    for u in r.unchecked:
        w(f"  not checked  {u.describe()}\n")


# ---- github (workflow commands) ----------------------------------------------------------------------
def write_annotations(out: IO[str], r: Comparison, level: str, after: str, blind_level: str | None = None) -> None:
    """``::warning file=AFTER,title=...::`` (or ``::error``) for each threshold crossed, and (at
    ``blind_level``) for each one checked on nothing."""
    where = "" if after == STDOUT else f"file={github_escape(after, True)},"
    for c in r.crossings:
        ch = c.change
        what = ch.figure + ("" if ch.servo is None else f" of servo {ch.servo}")
        title = github_escape(f"rs30x-sniff diff: {what} regressed", True)
        out.write(f"::{level} {where}title={title}::{github_escape(c.describe())}\n")
    for name in r.blind:
        why = "; ".join(u.describe() for u in r.unchecked if u.figure == name)
        title = github_escape(f"rs30x-sniff diff: {name} not checkable", True)
        out.write(f"::{blind_level or level} {where}title={title}::{github_escape(why)}\n")


# ---- markdown (a pull request's comment) ------------------------------------------------------------
def _md(text: str) -> str:
    return md_cell(text)


def write_markdown(out: IO[str], r: Comparison) -> None:
    w = out.write
    crossed = len({c.threshold.figure for c in r.crossings})  # a threshold crossed on the bus and servos is one
    verdict = (f"**{crossed} threshold{'s' if crossed != 1 else ''} crossed**" if r.crossings
               else "no thresholds set" if not r.thresholds
               else "**no threshold checkable**" if len(r.blind) == len(r.thresholds)
               else "no threshold crossed")
    w(f"### rs30x-sniff diff: {verdict}\n\n")
    w(f"- before: {md_code(_side(r.before))}\n- after: {md_code(_side(r.after))}\n\n")
    if r.crossings:
        for x in r.crossings:
            w(f"- :x: {_md(x.describe())}\n")
        w("\n")
    if r.unchecked:
        for u in r.unchecked:
            w(f"- not checked: {_md(u.describe())}\n")
        w("\n")
    w("| bus | before | after | change |\n|---|---:|---:|---|\n")
    for c in [*r.bus, *r.changes]:
        b, a, ch = _cells(c)
        w(f"| {c.figure} | {b} | {a} | {_md(ch)} |\n")
    rows = [(sid, c) for sid, cs in r.servos.items() for c in _changed(cs)]
    w("\n| servo | figure | before | after | change |\n|---:|---|---:|---:|---|\n")
    for sid, c in rows:
        b, a, ch = _cells(c)
        w(f"| {sid} | {c.figure} | {b} | {a} | {_md(ch)} |\n")
    same = [sid for sid, cs in r.servos.items() if not _changed(cs)]
    notes = []
    if same:
        notes.append(f"the same before and after: ID {', '.join(same)}")
    if r.only_before:
        notes.append(f"only BEFORE: ID {', '.join(r.only_before)}")
    if r.only_after:
        notes.append(f"only AFTER: ID {', '.join(r.only_after)}")
    if notes:
        w("\n" + "; ".join(notes) + "\n")
    f = r.findings
    w("\n| findings by rule | before | after | |\n|---|---:|---:|---|\n")
    if f.absent is not None:
        w(f"| absent: {_md(f.absent)} | - | - | |\n")
    else:
        for status, rule, nb, na in f.rows():
            w(f"| {_md(rule)} | {nb} | {na} | {status} |\n")
