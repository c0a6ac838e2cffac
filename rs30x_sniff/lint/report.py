"""Lint reports: text for people, and json, junit, sarif 2.1.0 and github annotations for CI; with github, a
Markdown summary appended to the file ``GITHUB_STEP_SUMMARY`` names (``append_step_summary``)."""

from __future__ import annotations

import io
import json
import os
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any
from collections.abc import Callable, Iterable, Mapping
from urllib.parse import quote

from ..version import __version__
from .registry import RULES, SEVERITY_RANK, Finding, Registry

if TYPE_CHECKING:
    from .baseline import BaselineReport

SARIF_SCHEMA = "https://json.schemastore.org/sarif-2.1.0.json"
_SARIF_LEVEL = {"error": "error", "warning": "warning", "info": "note"}
_GITHUB_LEVEL = {"error": "error", "warning": "warning", "info": "notice"}


@dataclass
class FileResult:
    """What linting one capture gave: its findings, the rules that ran and those skipped."""

    path: str
    findings: list[Finding] = field(default_factory=list)
    rules: list[str] = field(default_factory=list)     # codes of the rules that were enabled
    skipped: list[str] = field(default_factory=list)   # codes skipped for lack of timestamps
    records: int = 0
    error: str | None = None                           # one line, when the file could not be read
    # (line, column) of a finding's offset in a text capture, as its reader located it (none for
    # binary and MCAP captures, whose findings keep their byte offsets).
    locations: dict[int, tuple[int, int]] = field(default_factory=dict)
    # The capture's format as it was read ("bin", "hex", "mcap", ...); None: told by the path's extension.
    format: str | None = None
    # With --baseline: the findings the baseline held, moved out of ``findings`` (which keeps the new ones,
    # the only ones that count toward the exit code); SARIF still lists them, as "unchanged".
    absorbed: list[Finding] = field(default_factory=list)
    # The rule set the capture was linted with (LintConfig.rules: the built-in rules and the run's user rules).
    rule_set: Registry = field(default_factory=lambda: RULES, repr=False)

    def where(self, f: Finding) -> str:
        """``FILE:LINE:COL`` in a text capture, else ``FILE:OFFSET``."""
        loc = self.locations.get(f.offset)
        return f"{self.path}:{loc[0]}:{loc[1]}" if loc else f"{self.path}:{f.offset}"


def fails(f: Finding, fail_on: str) -> bool:
    """Whether a finding is at or above the --fail-on level."""
    return fail_on != "never" and SEVERITY_RANK[f.severity] >= SEVERITY_RANK[fail_on]


def _sorted(r: FileResult) -> list[Finding]:
    return sorted(r.findings, key=lambda f: (f.offset, f.code))


def _t(f: Finding) -> str:
    return f" (t={f.t:.6f})" if f.t is not None else ""


def write_text(results: list[FileResult], out: IO[str], fail_on: str = "error",
               baseline: BaselineReport | None = None) -> None:
    """``FILE:OFFSET (t=SECONDS) CODE name: message``, the packet under it, then a summary table (and,
    with a baseline, how many findings it absorbed and its entries no longer seen)."""
    counts: Counter = Counter()
    for r in results:
        for f in _sorted(r):
            out.write(f"{r.where(f)}{_t(f)} {f.code} {f.name}: {f.message}\n")
            if f.raw:  # a finding about the capture's clock has no packet of its own
                raw = f.raw[:32].hex(" ").upper() + (" ..." if len(f.raw) > 32 else "")
                out.write(f"    {raw}\n")
            counts[f.code] += 1
    total = sum(counts.values())
    if counts:
        out.write("\n")
        rules = _rules(results)
        w = max(len(rules[c].name) for c in counts)
        out.write(f"{'count':>6}  code  {'name':<{w}}  severity\n")
        for code in sorted(counts, key=lambda c: (-SEVERITY_RANK[_severity(results, c)], c)):
            out.write(f"{counts[code]:>6}  {code}  {rules[code].name:<{w}}  {_severity(results, code)}\n")
    by_sev = Counter(f.severity for r in results for f in r.findings)
    files = len(results)
    parts = ", ".join(f"{by_sev[s]} {s}{'s' if by_sev[s] != 1 else ''}"
                      for s in ("error", "warning", "info") if by_sev[s])
    out.write(f"\n{total} finding{'s' if total != 1 else ''}{f' ({parts})' if parts else ''} in {files} "
              f"file{'s' if files != 1 else ''}.\n")
    order = _rules(results).codes()
    skipped = sorted({c for r in results for c in r.skipped}, key=order.index)
    if skipped:
        which = [r.path for r in results if r.skipped]
        out.write(f"Skipped (no timestamps in {', '.join(which)}): {', '.join(skipped)}.\n")
    failing = sum(1 for r in results for f in r.findings if fails(f, fail_on))
    if failing:
        out.write(f"{failing} finding{'s' if failing != 1 else ''} at or above --fail-on {fail_on}.\n")
    if baseline is not None:
        write_baseline_summary(baseline, out)


def write_baseline_summary(baseline: BaselineReport, out: IO[str]) -> None:
    """The absorbed count and the stale entries, in words."""
    n = baseline.absorbed
    out.write(f"{n} finding{'s' if n != 1 else ''} absorbed by the baseline {baseline.path}"
              f"{' (not counted above)' if n else ''}.\n")
    if baseline.stale:
        k = len(baseline.stale)
        out.write(f"{k} baseline entr{'ies' if k != 1 else 'y'} no longer seen (stale; --write-baseline "
                  f"to drop {'them' if k != 1 else 'it'}):\n")
        for e in baseline.stale:
            out.write(f"    {e.code} {'ID ' + str(e.id) if e.id is not None else 'bus'}: {e.message} "
                      f"({e.count} before)\n")


def _severity(results: list[FileResult], code: str) -> str:
    for r in results:
        for f in r.findings:
            if f.code == code:
                return f.severity
    return _rules(results)[code].severity


def _rules(results: list[FileResult]) -> Registry:
    """The rule set the results were linted with (one run's: the first result's)."""
    return results[0].rule_set if results else RULES


def json_findings(results: list[FileResult]) -> list[dict]:
    return [{"file": r.path, **f.as_json()} for r in results for f in _sorted(r)]


def write_json(results: list[FileResult], out: IO[str], fail_on: str = "error",
               baseline: BaselineReport | None = None) -> None:
    """A list of the findings; with a baseline, an object: ``findings`` (the new ones) and ``baseline``
    (its file, the count it absorbed, its stale entries)."""
    if baseline is not None:
        json.dump({"findings": json_findings(results), "baseline": baseline.as_json()}, out, indent=1)
        out.write("\n")
        return
    json.dump(json_findings(results), out, indent=1)
    out.write("\n")


def write_junit(results: list[FileResult], out: IO[str], fail_on: str = "error",
                baseline: BaselineReport | None = None) -> None:
    """One test case per rule and file; a failure for each rule with findings at or above --fail-on."""
    import xml.etree.ElementTree as ET  # JUnit output only

    suites = ET.Element("testsuites", name="rs30x-sniff lint")
    total_tests = total_fail = 0
    for r in results:
        by_code: dict[str, list[Finding]] = {}
        for f in _sorted(r):
            by_code.setdefault(f.code, []).append(f)
        suite = ET.SubElement(suites, "testsuite", name=r.path)
        tests = failures = skipped = 0
        if r.error:
            case = ET.SubElement(suite, "testcase", classname=r.path, name="read")
            ET.SubElement(case, "error", message=r.error)
            tests += 1
        for code in r.rules:
            rule = r.rule_set[code]
            case = ET.SubElement(suite, "testcase", classname=r.path, name=f"{code} {rule.name}")
            tests += 1
            found = by_code.get(code, [])
            if code in r.skipped:
                ET.SubElement(case, "skipped", message="the capture has no timestamps")
                skipped += 1
                continue
            bad = [f for f in found if fails(f, fail_on)]
            lines = "\n".join(f"{r.where(f)}{_t(f)} {f.code} {f.name}: {f.message}" for f in found)
            if bad:
                failures += 1
                fail = ET.SubElement(case, "failure", message=f"{len(bad)} finding(s): {bad[0].message}",
                                     type=bad[0].severity)
                fail.text = lines
            elif found:
                ET.SubElement(case, "system-out").text = lines
        suite.set("tests", str(tests))
        suite.set("failures", str(failures))
        suite.set("errors", "1" if r.error else "0")
        suite.set("skipped", str(skipped))
        total_tests += tests
        total_fail += failures
    suites.set("tests", str(total_tests))
    suites.set("failures", str(total_fail))
    ET.indent(suites)
    out.write('<?xml version="1.0" encoding="UTF-8"?>\n')
    out.write(ET.tostring(suites, encoding="unicode"))
    out.write("\n")


def sarif_log(results: list[FileResult], baseline: BaselineReport | None = None) -> dict:
    """A SARIF 2.1.0 log: the registry as the driver's rules, one result per finding. With a baseline,
    each result has its ``baselineState`` (SARIF 2.1.0 3.27.24): "new", or "unchanged" for a finding the
    baseline absorbed; the absorbed count and the stale entries go in the run's property bag."""
    rules = list(_rules(results))
    index = {r.code: k for k, r in enumerate(rules)}
    driver = {
        "name": "rs30x-sniff",
        "version": __version__,
        "informationUri": "https://pypi.org/project/rs30x-sniff/",
        "rules": [{
            "id": r.code,
            "name": r.name,
            "shortDescription": {"text": r.summary},
            "fullDescription": {"text": r.section("What it does")},
            "help": {"text": r.section("Why it matters"), "markdown": r.doc},
            "defaultConfiguration": {"level": _SARIF_LEVEL[r.severity]},
            "properties": {"family": r.family},
        } for r in rules],
    }
    out = []
    for res in results:
        found = [(f, "new") for f in res.findings]
        if baseline is not None:
            found += [(f, "unchanged") for f in res.absorbed]
        for f, state in sorted(found, key=lambda fs: (fs[0].offset, fs[0].code)):
            props = {"t": f.t, "servoId": f.id, "severity": f.severity}
            # A finding's offset is in the decoded byte stream (decode's @N), kept as a property: it is
            # a position in the file only for a binary capture.
            props["streamOffset"] = f.offset
            physical: dict = {"artifactLocation": {"uri": sarif_uri(res.path)}}
            region = _region(res, f)
            if region:
                physical["region"] = region
            result = {
                "ruleId": f.code,
                "ruleIndex": index[f.code],
                "level": _SARIF_LEVEL[f.severity],
                "message": {"text": f.message},
                "locations": [{"physicalLocation": physical}],
                "properties": props,
            }
            if baseline is not None:
                result["baselineState"] = state
            out.append(result)
    invocation: dict[str, Any] = {"executionSuccessful": not any(r.error for r in results)}
    notes = [{"level": "error", "message": {"text": r.error}} for r in results if r.error]
    if notes:
        invocation["toolExecutionNotifications"] = notes
    run = {"tool": {"driver": driver}, "results": out, "invocations": [invocation],
           "artifacts": [{"location": {"uri": sarif_uri(r.path)}} for r in results]}
    if baseline is not None:
        run["properties"] = {"baseline": baseline.as_json()}
    return {"$schema": SARIF_SCHEMA, "version": "2.1.0", "runs": [run]}


_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*://")  # a pyserial URL (socket://host:port) is a URI already
_BINARY_SUFFIXES = (".bin", ".raw")                 # read as raw bytes unless --input-format says otherwise


def sarif_uri(path: str) -> str:
    """``path`` as a SARIF artifact URI: an absolute path as a ``file://`` URI, a relative one as a
    percent-encoded relative reference (a space, ``#`` or ``%`` in a name would otherwise end or
    change the URI)."""
    if _URL.match(path):
        return path
    p = Path(path)
    if p.is_absolute():
        return p.as_uri()
    # A colon in the first segment would read as a URI scheme, so it is encoded too.
    return quote(p.as_posix(), safe="/")


def _region(res: FileResult, f: Finding) -> dict | None:
    """Where in the file ``f`` is: the line and column of a text capture, the byte range of a binary
    one, else nothing (an MCAP's or another tool's log's stream offsets are no place in the file)."""
    loc = res.locations.get(f.offset)
    if loc:
        return {"startLine": loc[0], "startColumn": loc[1]}
    binary = res.format == "bin" if res.format else Path(res.path).suffix.lower() in _BINARY_SUFFIXES
    if binary:
        return {"byteOffset": f.offset, "byteLength": max(len(f.raw), 1)}
    return None


def write_sarif(results: list[FileResult], out: IO[str], fail_on: str = "error",
                baseline: BaselineReport | None = None) -> None:
    json.dump(sarif_log(results, baseline), out, indent=1)
    out.write("\n")


def github_escape(s: str, prop: bool = False) -> str:
    """``s`` as a workflow command's message (``prop``: a property's value, where ``:`` and ``,`` end it)."""
    s = s.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")
    return s.replace(":", "%3A").replace(",", "%2C") if prop else s


def write_github(results: list[FileResult], out: IO[str], fail_on: str = "error",
                 baseline: BaselineReport | None = None) -> None:
    """GitHub Actions workflow commands: ``::error file=F,title=CODE name::message``."""
    for r in results:
        if r.error:
            out.write(f"::error file={github_escape(r.path, True)}::{github_escape(r.error)}\n")
        for f in _sorted(r):
            title = github_escape(f"{f.code} {f.name}", True)
            at = f", t={f.t:.6f}" if f.t is not None else ""
            msg = github_escape(f"{f.message} (offset {f.offset}{at})")
            loc = r.locations.get(f.offset)
            at = f",line={loc[0]},col={loc[1]}" if loc else ""
            out.write(f"::{_GITHUB_LEVEL[f.severity]} file={github_escape(r.path, True)}{at},title={title}::{msg}\n")


# ---- the step summary (GitHub Actions: Markdown appended to the file GITHUB_STEP_SUMMARY names) -------
STEP_SUMMARY = "GITHUB_STEP_SUMMARY"


def md_cell(text: str) -> str:
    """``text`` as one Markdown table cell: a ``|`` (and the backslash that could escape it) escaped, a line
    break as ``<br>``, so no message breaks its row."""
    text = text.replace("\\", "\\\\").replace("|", "\\|")
    return text.replace("\r\n", "<br>").replace("\r", "<br>").replace("\n", "<br>")


def md_code(text: str) -> str:
    """``text`` as a Markdown code span, whatever backticks it holds (one line)."""
    text = " ".join(text.splitlines())
    longest = max((len(m) for m in re.findall(r"`+", text)), default=0)
    fence = "`" * (longest + 1)
    pad = " " if longest or text.startswith(" ") or text.endswith(" ") else ""
    return f"{fence}{pad}{text}{pad}{fence}"


def step_summary_path(env: Mapping[str, str] | None = None) -> str | None:
    """The file GITHUB_STEP_SUMMARY names, or None (unset or empty)."""
    return (os.environ if env is None else env).get(STEP_SUMMARY) or None


def append_step_summary(write: Callable[[IO[str]], None], env: Mapping[str, str] | None = None) -> str | None:
    """Append what ``write`` writes to the step summary file (appended, never replaced: each step of a job
    adds its own). Nothing when GITHUB_STEP_SUMMARY is unset. Returns a one-line warning when the file
    cannot be written (the caller's result stands), else None."""
    path = step_summary_path(env)
    if path is None:
        return None
    buf = io.StringIO()
    write(buf)
    text = buf.getvalue()
    try:
        with open(path, "a", encoding="utf-8") as f:
            # A blank line first after what other steps wrote: their last line cannot run into the heading.
            f.write(("\n" if f.tell() else "") + (text if text.endswith("\n") else text + "\n"))
    except (OSError, ValueError) as e:  # ValueError: a path with a NUL byte
        why = getattr(e, "strerror", None) or str(e)
        return f"{STEP_SUMMARY}={path}: cannot append the summary: {why}".replace("\n", " ")
    return None


def _plural(n: int, word: str, many: str | None = None) -> str:
    return f"{n} {word if n == 1 else (many or word + 's')}"


def write_step_summary(results: list[FileResult], out: IO[str], fail_on: str = "error",
                       baseline: BaselineReport | None = None, errors: Iterable[str] = ()) -> None:
    """The lint run in Markdown: the files, the findings by rule (code, name, severity, count; with a
    baseline the new and absorbed counts), what fails --fail-on, and the baseline's stale entries."""
    errors = list(errors)
    w = out.write
    rule_set = _rules(results)
    new = [f for r in results for f in r.findings]
    absorbed = [f for r in results for f in r.absorbed] if baseline is not None else []
    by_sev = Counter(f.severity for f in new)
    parts = ", ".join(_plural(by_sev[s], s) for s in ("error", "warning", "info") if by_sev[s])
    head = _plural(len(new), "new finding" if baseline is not None else "finding") + (f" ({parts})" if parts else "")
    w(f"### rs30x-sniff lint: {head}\n\n")
    w(f"{_plural(len(results), 'file')} linted:\n\n")
    for r in results:
        counts = f"{_plural(len(r.findings), 'new finding' if baseline is not None else 'finding')}"
        if baseline is not None:
            counts += f", {len(r.absorbed)} absorbed"
        w(f"- {md_code(r.path)}: {_plural(r.records, 'record')}, {counts}\n")
    for e in errors:
        w(f"- :x: not read: {md_cell(e)}\n")
    w("\n")
    rows: dict[tuple[str, str], list[int]] = {}
    for f in new:
        rows.setdefault((f.code, f.severity), [0, 0])[0] += 1
    for f in absorbed:
        rows.setdefault((f.code, f.severity), [0, 0])[1] += 1
    if rows:
        order = sorted(rows, key=lambda k: (-SEVERITY_RANK[k[1]], k[0]))
        if baseline is None:
            w("| code | rule | severity | count |\n|---|---|---|---:|\n")
        else:
            w("| code | rule | severity | new | absorbed |\n|---|---|---|---:|---:|\n")
        for code, sev in order:
            name = rule_set[code].name if code in rule_set else ""
            n, a = rows[(code, sev)]
            w(f"| {md_cell(code)} | {md_cell(name)} | {sev} | {n} |" + (f" {a} |" if baseline is not None else "")
              + "\n")
        w("\n")
    else:
        w("No findings.\n\n")
    failing = sum(1 for f in new if fails(f, fail_on))
    if failing:
        w(f"**{_plural(failing, 'finding')} at or above --fail-on {fail_on}.**\n")
    else:
        w(f"Nothing at or above --fail-on {fail_on}.\n")
    order_codes = rule_set.codes()
    skipped = sorted({c for r in results for c in r.skipped}, key=lambda c: order_codes.index(c)
                     if c in order_codes else len(order_codes))
    if skipped:
        which = ", ".join(md_code(r.path) for r in results if r.skipped)
        w(f"\nSkipped for lack of timestamps (in {which}): {', '.join(skipped)}.\n")
    if baseline is not None:
        w(f"\nBaseline {md_code(baseline.path)}: {len(new)} new, {baseline.absorbed} absorbed "
          f"(not counted toward the exit code).\n")
        if baseline.stale:
            w(f"\n{_plural(len(baseline.stale), 'baseline entry', 'baseline entries')} no longer seen (stale; "
              f"--write-baseline to drop them):\n\n")
            w("| code | servo | message | count before |\n|---|---:|---|---:|\n")
            for entry in baseline.stale:  # not ``e``: the errors' loop above holds strings in it
                sid = str(entry.id) if entry.id is not None else "bus"
                w(f"| {md_cell(entry.code)} | {sid} | {md_cell(entry.message)} | {entry.count} |\n")


WRITERS = {"text": write_text, "json": write_json, "junit": write_junit, "sarif": write_sarif,
           "github": write_github}


def write_report(fmt: str, results: Iterable[FileResult], out: IO[str], fail_on: str = "error",
                 baseline: BaselineReport | None = None) -> None:
    """Write the report; with a baseline, ``results`` hold only the new findings in ``findings`` (the
    absorbed ones in ``absorbed``), and the text, json and sarif reports say what the baseline did."""
    WRITERS[fmt](list(results), out, fail_on, baseline=baseline)
