"""Every example in README.md and docs/*.md runs as it says (issue 32 §5), as docs/ci.md's workflow does
(tests/commands/test_ci_doc.py).

The examples are the fenced shell blocks (```sh, ```console: a console block's commands are its ``$ `` lines,
and what follows each is the output it shows) and the inline code spans that give a whole rs30x-sniff command
with its arguments. Each page's rs30x-sniff commands run in order in a folder of their own that holds the
bundled captures and the files a page names without making them (:func:`world`). Every line a console
block shows must be printed, in that order (a block may be an excerpt; ``...`` marks lines left out).

What is not run is listed with its reason (``SKIP``): a serial port or other hardware, the full-screen
monitor, a server that runs until stopped, other tools than rs30x-sniff, and words in capitals that stand
for your own values (BEFORE, DIR, FILE).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SHELLS = ("sh", "console", "bash", "shell")

# Why an example is not run: the first pattern that matches it names the reason.
SKIP: list[tuple[str, str]] = [
    (r"/dev/|socket://", "needs a serial port (hardware, or a pty another program drives)"),
    (r"^rs30x-sniff monitor\b", "the monitor is a full-screen terminal UI"),
    (r"^rs30x-sniff serve\b", "a Foxglove server that runs until stopped"),
    (r"\b[A-Z]{2,}\b|\.\.\.|<[a-z]+>", "a placeholder for your own values (BEFORE, DIR, ...)"),
    (r"^rs30x-sniff decode --format jsonl$", "names an option of decode in prose, with no input"),
]
# Files the pages read without making them: made here from the bundled captures.
MIXED = ROOT / "captures" / "session-mixed.thex"


@dataclass
class Example:
    page: str
    line: int
    command: str
    shown: str | None = None  # a console block's output

    def __str__(self) -> str:
        return f"{self.page}:{self.line}: {self.command}"


def _joined(lines: list[str]) -> list[tuple[int, str]]:
    """(index, line) with backslash continuations joined."""
    out: list[tuple[int, str]] = []
    pending, start = "", 0
    for i, line in enumerate(lines):
        if not pending:
            start = i
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        out.append((start, pending + line))
        pending = ""
    return out


def _commands(text: str) -> list[str]:
    """The rs30x-sniff commands of one shell line (``a && b``: both; other tools are not run)."""
    text = text.split(" # ")[0].split("   #")[0].strip()
    return [part.strip() for part in text.split("&&") if part.strip().startswith("rs30x-sniff ")]


def examples(page: Path) -> list[Example]:
    text = page.read_text()
    name = page.relative_to(ROOT).as_posix()
    out: list[Example] = []
    for m in re.finditer(r"^[ \t]*```(\w*)[ \t]*\n(.*?)^[ \t]*```", text, re.S | re.M):
        lang, body = m.group(1), m.group(2)
        if lang not in SHELLS:
            continue
        first = text[:m.start(2)].count("\n") + 1
        lines = body.splitlines()
        if lang == "console":
            for k, line in enumerate(lines):
                if not line.lstrip().startswith("$ "):
                    continue
                shown = []
                for later in lines[k + 1:]:
                    if later.lstrip().startswith("$ "):
                        break
                    shown.append(later)
                cmds = _commands(line.lstrip()[2:])
                for j, cmd in enumerate(cmds):  # what is shown is the last command's output (a && b)
                    out.append(Example(name, first + k, cmd, "\n".join(shown) if j == len(cmds) - 1 else None))
            continue
        for k, line in _joined(lines):
            for cmd in _commands(line.strip()):
                out.append(Example(name, first + k, cmd))
    for m in re.finditer(r"`(rs30x-sniff [^`]+)`", text):
        cmd = m.group(1)
        if len(shlex.split(cmd)) <= 2:
            continue  # a command's name in prose (`rs30x-sniff lint`), not an example
        line = text[:m.start()].count("\n") + 1
        if not any(e.line == line and e.command == cmd for e in out):
            out += [Example(name, line, c) for c in _commands(cmd)]
    return out


def skip_reason(e: Example) -> str | None:
    for pattern, why in SKIP:
        if re.search(pattern, e.command):
            return why
    return None


ALL = [e for page in PAGES for e in examples(page)]
RUN = [e for e in ALL if skip_reason(e) is None]


def world(tmp_path: Path) -> Path:
    """A folder with what the pages read: the bundled captures and the files they name without making."""
    d = tmp_path / "world"
    shutil.copytree(ROOT / "captures", d / "captures")
    for name in ("session.thex", "capture.thex", "captures/rig.thex"):  # docs/ci.md's rig: as test_ci_doc's
        shutil.copy(MIXED, d / name)
    (d / "docs").mkdir()  # docs/architecture.md regenerates docs/rules.md
    box = d / "blackbox"
    box.mkdir()
    # docs/black-box.md reads a window the black box saved: an overheat, as its trigger.
    hot = tmp_path / "hot.thex"
    _run_ok(["simulate", "--scenario", "overheat", "-o", str(hot)], tmp_path)
    _run_ok(["convert", str(hot), "-o", str(box / "2026-11-26T01-45-05.947Z-present_temperature-gt-70.mcap")],
            tmp_path)
    return d


def _bin(tmp_path: Path) -> Path:
    """A folder whose rs30x-sniff is this checkout's, run by this interpreter."""
    b = tmp_path / "bin"
    b.mkdir(exist_ok=True)
    exe = b / "rs30x-sniff"
    exe.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m rs30x_sniff "$@"\n')
    exe.chmod(0o755)
    return b


def _env(tmp_path: Path) -> dict[str, str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT), HOME=str(tmp_path / "world"))  # ~/ stays in the folder
    env["PATH"] = f"{_bin(tmp_path)}{os.pathsep}{env.get('PATH', '')}"
    # The pages show what a command prints to a file or a pipe: at the default width, outside CI.
    for key in ("GITHUB_STEP_SUMMARY", "CI", "RS30X_DECODERS", "COLUMNS", "LINES"):
        env.pop(key, None)
    return env


def _run_ok(argv: list[str], cwd: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "rs30x_sniff", *argv], cwd=cwd, capture_output=True, text=True,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert done.returncode == 0, done.stderr


# lint exits 1 on findings and diff on a regression: that is the example working. 2 is a usage or input error.
FINDS = ("lint", "diff")


def shows(actual: str, shown: str) -> str | None:
    """The first line of ``shown`` (a console block's output: an excerpt, ``...`` where lines are left out)
    that ``actual`` does not print in that order, or None: every line shown is printed, in order."""
    lines = [x.rstrip() for x in actual.splitlines()]
    at = 0
    for line in shown.splitlines():
        line = line.rstrip()
        if not line.strip() or line.strip() in ("...", "…"):
            continue
        try:
            at = lines.index(line, at) + 1
        except ValueError:
            return line
    return None


def test_the_pages_have_examples_and_each_skip_has_a_reason():
    assert len(RUN) >= 20, [str(e) for e in RUN]
    pages = {e.page for e in RUN}
    assert {"README.md", "docs/ci.md", "docs/integrations.md", "docs/live-capture.md"} <= pages, pages
    for e in ALL:
        assert e in RUN or skip_reason(e)


@pytest.mark.parametrize("page", sorted({e.page for e in RUN}))
def test_every_example_of_the_page_runs_as_it_says(tmp_path, page):
    cwd = world(tmp_path)
    env = _env(tmp_path)
    problems = []
    for e in (x for x in RUN if x.page == page):
        done = subprocess.run(e.command, shell=True, cwd=cwd, env=env, capture_output=True, text=True, timeout=300,
                              stdin=subprocess.DEVNULL)
        sub = shlex.split(e.command)[1]
        ok = (0, 1) if sub in FINDS else (0,)
        if done.returncode not in ok or "Traceback" in done.stderr:
            problems.append(f"{e}\n  exit {done.returncode}: {done.stderr.strip()[-600:]}")
            continue
        if e.shown:
            missing = shows(done.stdout, e.shown)
            if missing is not None:
                problems.append(f"{e}\n  the page shows a line the command does not print (in that order):\n"
                                f"{missing}\n  it printed:\n{done.stdout[-3000:]}")
    assert not problems, "\n\n".join(problems)


def test_a_console_blocks_output_is_compared_line_by_line_in_order():
    assert shows("a\nb\nc\nd\n", "a\nb\n...\nd") is None
    assert shows("a\nb\nc\n", "a\nc") is None             # an excerpt
    assert shows("a\nb\n", "b\n...\na") == "a"              # out of order
    assert shows("a\nb\n", "a\nx") == "x"                    # a line never printed


def configurations() -> list[tuple[str, int, str]]:
    """(page, line, text) of every ```toml block: a configuration, or part of one."""
    out = []
    for page in PAGES:
        text = page.read_text()
        for m in re.finditer(r"^[ \t]*```toml[ \t]*\n(.*?)^[ \t]*```", text, re.S | re.M):
            out.append((page.relative_to(ROOT).as_posix(), text[:m.start()].count("\n") + 1, m.group(1)))
    return out


@pytest.mark.parametrize("page, line, body", configurations(), ids=lambda v: str(v) if isinstance(v, (str, int))
                         and not str(v).count("\n") else "")
def test_every_configuration_of_the_pages_loads_and_lints(tmp_path, page, line, body):
    (tmp_path / "rs30x-sniff.toml").write_text(body)
    done = subprocess.run([sys.executable, "-m", "rs30x_sniff", "lint", str(MIXED), "--fail-on", "never"],
                          cwd=tmp_path, capture_output=True, text=True, env=_env(tmp_path))
    assert done.returncode == 0 and "Traceback" not in done.stderr, f"{page}:{line}: {done.stderr}"


def test_the_configurations_are_found():
    assert len(configurations()) >= 5


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark is not installed")
def test_the_wireshark_filters_of_integrations_md_select_what_they_say(tmp_path):
    """Each filter the page lists runs in tshark with the plug-in; the temperature alarm's selects the replies
    with the flag set (the overheat scenario's ID 2), not every reply (the field alone is in each one)."""
    text = (ROOT / "docs" / "integrations.md").read_text()
    listed = text[text.index("**Filters**"):].split("\n\n")[0]
    filters = re.findall(r"^- `(rs30x\.[^`]+)`", listed, re.M)
    assert any("temperature_alarm" in f for f in filters), filters
    _run_ok(["simulate", "--scenario", "overheat", "-o", "hot.thex"], tmp_path)
    _run_ok(["convert", "hot.thex", "-o", "hot.pcapng"], tmp_path)
    _run_ok(["plugin", "wireshark", "-o", "ws"], tmp_path)

    def count(flt: str) -> int:
        done = subprocess.run(["tshark", "-X", f"lua_script:{tmp_path / 'ws' / 'rs30x.lua'}", "-r",
                               str(tmp_path / "hot.pcapng"), "-Y", flt], capture_output=True, text=True,
                              env=dict(os.environ, HOME=str(tmp_path)))
        assert done.returncode == 0, f"{flt}: {done.stderr}"
        return len(done.stdout.splitlines())

    counts = {f: count(f) for f in filters}
    replies = count('rs30x.kind == "return"')
    alarm = next(f for f in filters if "temperature_alarm" in f)
    assert 0 < counts[alarm] < replies, counts
    assert count("rs30x.return_flag.temperature_alarm") == replies  # why the page says == 1
