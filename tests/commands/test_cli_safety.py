"""Never lose or fake data: outputs that never replace inputs or files unasked, empty inputs, bad numbers."""

from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

import pytest

from rs30x_sniff.cli import main

ROOT = Path(__file__).resolve().parents[2]
SESSION = ROOT / "captures" / "session-mixed.thex"
EXAMPLES = ROOT / "captures" / "manual-examples.hex"


def _digest(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _one_line(capsys, *needles: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err
    return err


@pytest.fixture
def session(tmp_path) -> Path:
    p = tmp_path / "session.thex"
    p.write_bytes(SESSION.read_bytes())
    return p


@pytest.mark.parametrize("argv", [
    ["decode", "{X}", "-o", "{X}"],
    ["decode", "{X}", "-o", "{X}", "--force"],
    ["lint", "{X}", "-o", "{X}"],
    ["lint", "{X}", "-o", "{X}", "--force"],
    ["info", "{X}", "-o", "{X}"],
    ["convert", "{X}", "-o", "{X}", "--force"],
])
def test_an_output_never_replaces_its_input(capsys, session, argv):
    before = _digest(session)
    assert main([a.replace("{X}", str(session)) for a in argv]) == 2
    _one_line(capsys, "is the input file")
    assert _digest(session) == before


@pytest.mark.parametrize("argv", [
    ["decode", str(EXAMPLES), "-o", "{O}"],
    ["lint", str(EXAMPLES), "-o", "{O}"],
    ["info", str(EXAMPLES), "-o", "{O}"],
    ["rules", "-o", "{O}"],
    ["convert", str(EXAMPLES), "-o", "{O}"],
    ["simulate", "--scenario", "setup", "-o", "{O}"],
    ["record", "/dev/ttyNOSUCHPORT", "-o", "{O}"],
])
def test_an_existing_file_is_replaced_only_with_force(capsys, tmp_path, argv):
    out = tmp_path / "existing.out"
    out.write_bytes(b"precious")
    assert main([a.replace("{O}", str(out)) for a in argv]) == 2
    _one_line(capsys, "already exists (use --force")
    assert out.read_bytes() == b"precious"
    if argv[0] not in ("record", "convert", "simulate"):
        assert main([a.replace("{O}", str(out)) for a in argv] + ["--force"]) in (0, 1)
        assert out.read_bytes() != b"precious"


def test_decode_x_o_x_from_a_fresh_clone_leaves_the_capture_byte_identical(tmp_path):
    """The issue's exact command, in a child process from the repository's own captures/."""
    before = _digest(SESSION)
    proc = subprocess.run([sys.executable, "-m", "rs30x_sniff", "decode", "captures/session-mixed.thex", "-o",
                           "captures/session-mixed.thex"], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert _digest(SESSION) == before


def test_a_failed_run_leaves_nothing_behind(capsys, tmp_path):
    ne = tmp_path / "ne.bin"
    assert main(["export", str(tmp_path / "missing.mcap"), "-o", str(ne)]) == 2
    _one_line(capsys, "missing.mcap")
    assert list(tmp_path.iterdir()) == []  # no 0-byte ne.bin, no temporary file
    # ... so the retry does not fail with "already exists".
    mcap = tmp_path / "m.mcap"
    assert main(["convert", str(EXAMPLES), "-o", str(mcap)]) == 0
    assert main(["export", str(mcap), "-o", str(ne)]) == 0 and ne.exists()


def test_lint_o_after_an_input_error_writes_no_report(capsys, tmp_path):
    report = tmp_path / "report.txt"
    assert main(["lint", str(EXAMPLES), str(tmp_path / "nope.hex"), "-o", str(report)]) == 2
    assert not report.exists() and list(tmp_path.iterdir()) == []
    err = capsys.readouterr().err
    assert "nope.hex: no such file" in err


def test_lint_of_an_unreadable_file_does_not_count_it(capsys, tmp_path):
    assert main(["lint", str(tmp_path / "nope.hex")]) == 2
    cap = capsys.readouterr()
    assert "0 findings in 1 file" not in cap.out and cap.out == ""
    assert cap.err.count("\n") == 1


@pytest.mark.parametrize("command", ["decode", "info", "lint", "convert"])
def test_an_empty_capture_is_not_a_clean_pass(capsys, tmp_path, command):
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"")
    argv = [command, str(empty)] + (["-o", str(tmp_path / "x.mcap")] if command == "convert" else [])
    code = main(argv)
    err = capsys.readouterr().err
    assert "no data" in err and err.count("\n") == 1, err
    if command in ("lint", "convert"):
        assert code == 2
        assert not (tmp_path / "x.mcap").exists()
    else:
        assert code == 0 and "warning" in err


def test_lint_allow_empty(capsys, tmp_path):
    empty = tmp_path / "empty.hex"
    empty.write_text("# nothing here\n")
    assert main(["lint", str(empty), "--allow-empty"]) == 0
    assert "no data" in capsys.readouterr().err


def test_stdin_empty_is_reported(tmp_path):
    for argv in (["decode", "-"], ["lint", "-"], ["convert", "-", "-o", str(tmp_path / "x.mcap")]):
        proc = subprocess.run([sys.executable, "-m", "rs30x_sniff", *argv], stdin=subprocess.DEVNULL,
                              capture_output=True, text=True)
        assert "no data" in proc.stderr, (argv, proc.stderr)
        assert proc.returncode == (0 if argv[0] == "decode" else 2)
    assert not (tmp_path / "x.mcap").exists()


@pytest.mark.parametrize("argv, needle", [
    (["decode", str(EXAMPLES), "--id", "999"], "--id 999: not a servo ID"),
    (["decode", str(EXAMPLES), "--id", "1-200"], "--id 1-200: 128 is not a servo ID"),
    (["decode", str(EXAMPLES), "--duration", "-1"], "--duration -1: must be a finite, positive duration"),
    (["info", str(EXAMPLES), "--duration", "nan"], "--duration nan: expected a duration"),
    (["simulate", "--duration", "nan", "-o", "-"], "--duration nan: expected a duration"),
    (["simulate", "--duration", "inf", "-o", "-"], "--duration inf: expected a duration"),
    (["monitor", str(EXAMPLES), "--speed", "0"], "--speed 0: must be a finite, positive number"),
    (["decode", str(EXAMPLES), "--reply-timeout", "inf"], "--reply-timeout inf: expected a duration"),
    (["decode", str(EXAMPLES), "--reply-timeout", "0"], "--reply-timeout 0: must be a finite, positive duration"),
])
def test_numbers_are_checked(capsys, argv, needle):
    assert main(argv) == 2
    _one_line(capsys, needle)


def test_baud_any_allows_an_odd_rate(capsys):
    assert main(["decode", str(EXAMPLES), "--baud", "12345", "--baud-any"]) == 0


def test_simulate_o_dash_writes_stdout(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "rs30x_sniff", "simulate", "--scenario", "setup", "--duration", "0.5",
                           "-o", "-", "--output-format", "hex"], cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("FA AF") and not (tmp_path / "-").exists()


@pytest.mark.parametrize("argv", [["decode", "{cap}", "--format", "jsonl"], ["convert", "{cap}"], ["lint", "{cap}"]])
def test_a_device_or_fifo_is_written_in_place_never_replaced(capsys, tmp_path, argv):
    import os
    import stat
    import threading

    cap = str(Path(__file__).resolve().parents[2] / "captures" / "session-mixed.thex")
    fifo = tmp_path / "out.fifo"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    args = [a.format(cap=cap) for a in argv]
    assert main([*args, "-o", str(fifo)]) in (0, 1)  # lint exits 1 on its findings
    reader.join(10)
    assert got and got[0] and stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.fifo"]  # no temporary file beside it
    # /dev/null too, without --force, and it stays the device it was (a rename once replaced it).
    assert main([*args, "-o", os.devnull]) in (0, 1)
    assert stat.S_ISCHR(os.stat(os.devnull).st_mode)
