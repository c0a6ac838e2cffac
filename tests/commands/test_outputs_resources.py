"""Outputs and resources of every writing command: `-` is stdout, the umask, a full disk, SIGINT, a closed pipe, bounds."""

from __future__ import annotations

import errno
import io
import os
import signal
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from rs30x_sniff import cli
from rs30x_sniff.sinks import outputs
from rs30x_sniff.sinks.mcap import writer as mcap_sink
from rs30x_sniff.settings import KEYS
from tests.e2e.helpers import Pty, wait_opened

ROOT = Path(__file__).resolve().parents[2]
SESSION = ROOT / "captures" / "session-mixed.thex"


def run(*args: str, cwd: Path, **kw) -> subprocess.CompletedProcess:
    kw.setdefault("stdout", subprocess.PIPE)
    kw.setdefault("stderr", subprocess.PIPE)
    return subprocess.run([sys.executable, "-m", "rs30x_sniff", *args], cwd=cwd, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)}, **kw)


def mcap_messages(data: bytes) -> int:
    return sum(1 for _ in make_reader(io.BytesIO(data)).iter_messages())


@pytest.fixture(scope="module")
def log(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("log") / "session.mcap"
    assert cli.main(["convert", str(SESSION), "-o", str(out)]) == 0
    return out


# ---- `-` is stdout, and a file named `-` is never written ------------------------------------------
def test_dash_is_stdout_for_every_writing_command(tmp_path, log):
    precious = tmp_path / "-"
    precious.write_text("precious")
    commands = {
        "convert": (["convert", str(SESSION), "-o", "-"], "mcap"),
        "simulate mcap": (["simulate", "--scenario", "hexapod", "--duration", "0.5", "-o", "-",
                           "--output-format", "mcap"], "mcap"),
        "simulate hex": (["simulate", "--duration", "0.5", "-o", "-", "--output-format", "hex"], "text"),
        "export": (["export", str(log), "-o", "-", "--format", "timestamped"], "text"),
        "export --table": (["export", str(log), "--table", "transactions", "-o", "-"], "csv"),
        "table csv": (["table", str(SESSION), "--of", "packets", "-o", "-"], "csv"),
        "table parquet": (["table", str(SESSION), "--of", "states", "-o", "-", "--format", "parquet"], "parquet"),
        "decode": (["decode", str(SESSION), "-o", "-"], "text"),
        "lint": (["lint", str(SESSION), "-o", "-"], "text"),
        "info": (["info", str(SESSION), "-o", "-"], "text"),
        "rules": (["rules", "-o", "-"], "text"),
    }
    for name, (args, kind) in commands.items():
        done = run(*args, cwd=tmp_path)
        assert done.returncode in (0, 1), (name, done.stderr)  # lint exits 1 on its findings
        assert b"Traceback" not in done.stderr, name
        out = done.stdout
        if kind == "mcap":
            assert mcap_messages(out) > 100, name
        elif kind == "parquet":
            import pyarrow.parquet as pq

            assert pq.read_table(io.BytesIO(out)).num_rows > 0, name
        else:
            assert out.strip(), name
            if kind == "csv":
                assert out.split(b"\n", 1)[0].startswith(b"t,"), name
        assert precious.read_text() == "precious", name
        assert sorted(p.name for p in tmp_path.iterdir()) == ["-"], name  # nothing else left behind


def test_record_streams_mcap_to_stdout(tmp_path):
    pty = Pty()
    try:
        (tmp_path / "-").write_text("precious")
        proc = subprocess.Popen([sys.executable, "-m", "rs30x_sniff", "record", pty.path, "-o", "-", "--duration",
                                 "2.5", "--no-lint"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                env={**os.environ, "PYTHONPATH": str(ROOT)})
        wait_opened(pty.path, proc)
        sent = pty.write_sim("hexapod", duration=0.6)
        out, err = proc.communicate(timeout=30)
    finally:
        pty.close()
    assert proc.returncode == 0, err
    assert (tmp_path / "-").read_text() == "precious"
    raw = b"".join(m.data for _, ch, m in make_reader(io.BytesIO(out)).iter_messages() if ch.topic == "/rs30x/raw")
    assert raw and b"stdout" in err
    assert len(sent) > 0


def test_record_to_stdout_refuses_what_needs_a_file(tmp_path):
    for extra, word in ((["--split-size", "1"], "--split-size"), (["--print"], "--print")):
        done = run("record", "/dev/null", "-o", "-", *extra, cwd=tmp_path)
        assert done.returncode == 2
        lines = done.stderr.decode().strip().splitlines()
        assert len(lines) == 1 and word in lines[0], lines
        assert list(tmp_path.iterdir()) == []


# ---- the umask ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("mask", [0o022, 0o077, 0o002])
def test_outputs_get_the_umask_mode(tmp_path, log, mask):
    old = os.umask(mask)
    try:
        outs = {
            "convert": ["convert", str(SESSION), "-o", str(tmp_path / "a.mcap")],
            "export": ["export", str(log), "-o", str(tmp_path / "a.hex")],
            "table": ["table", str(SESSION), "--of", "packets", "-o", str(tmp_path / "a.csv")],
            "decode": ["decode", str(SESSION), "-o", str(tmp_path / "a.txt")],
            "simulate": ["simulate", "--duration", "0.3", "-o", str(tmp_path / "b.thex")],
        }
        for name, args in outs.items():
            assert cli.main(args) == 0, name
            path = Path(args[args.index("-o") + 1])
            assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~mask, name
    finally:
        os.umask(old)


def test_force_keeps_the_mode_of_the_file_it_replaces(tmp_path):
    out = tmp_path / "a.txt"
    out.write_text("old")
    out.chmod(0o640)
    assert cli.main(["decode", str(SESSION), "-o", str(out), "--force"]) == 0
    assert stat.S_IMODE(out.stat().st_mode) == 0o640 and "READ" in out.read_text()


# ---- a full disk ---------------------------------------------------------------------------------------
LEAKS = (b"Traceback", b"FoxgloveError", b"Failed to close", b"RuntimeError")


@pytest.mark.parametrize("args", [
    ["convert", str(SESSION)],
    ["simulate", "--duration", "0.5", "--output-format", "mcap"],
    ["simulate", "--duration", "0.5", "--output-format", "hex"],
    ["table", str(SESSION), "--of", "packets", "--format", "csv"],
    ["decode", str(SESSION)],
], ids=lambda a: " ".join(a[:1] + a[-1:]))
def test_dev_full_is_written_in_place_and_reported_in_one_line(tmp_path, args):
    done = run(*args, "-o", "/dev/full", cwd=tmp_path)
    assert done.returncode != 0
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert b"/dev/full" in lines[0] and b"No space left on device" in lines[0]
    assert not any(leak in done.stderr for leak in LEAKS)
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)


def test_stdout_on_a_full_disk_is_named(tmp_path):
    with open("/dev/full", "wb") as full:
        for args in (["convert", str(SESSION), "-o", "-"], ["info", str(SESSION)],
                     ["simulate", "--duration", "0.3", "-o", "-", "--output-format", "bin"]):
            done = run(*args, cwd=tmp_path, stdout=full, stderr=subprocess.PIPE)
            lines = done.stderr.strip().splitlines()
            assert done.returncode != 0 and len(lines) == 1, (args, lines)
            assert b"stdout" in lines[0] and b"No space left" in lines[0], lines
            assert not any(leak in done.stderr for leak in LEAKS)


class _Full(io.FileIO):
    """A file on a disk with ``room`` bytes free: a write past it fails with ENOSPC."""

    room = 20_000

    def write(self, b):
        if self.tell() + len(b) > self.room:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return super().write(b)


def test_convert_on_a_full_disk_names_the_file_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(outputs, "open", lambda path, mode="r", **kw: _Full(path, "w"), raising=False)
    out = tmp_path / "big.mcap"
    assert cli.main(["convert", str(SESSION), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert str(out) in err[0] and "No space left on device" in err[0] and "nothing saved" in err[0]
    assert "bytes written, then removed" in err[0] and ".part" not in err[0]
    assert list(tmp_path.iterdir()) == []


def test_record_on_a_full_disk_leaves_a_finalized_file_and_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(mcap_sink, "open", lambda path, mode="r", **kw: _Full(path, "w"), raising=False)
    out = tmp_path / "rec.mcap"
    pty = Pty()
    try:
        # Fed while the recorder runs in this process: 6 s of the gait is far more than 20 kB of MCAP.
        def feed():
            time.sleep(0.5)
            try:
                pty.write_sim("hexapod", duration=6)
            except OSError:
                pass  # the recorder stopped and the pty closed first

        threading.Thread(target=feed, daemon=True).start()
        rc = cli.main(["record", pty.path, "-o", str(out), "--duration", "30", "--no-lint"])
    finally:
        pty.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert rc != 0
    assert len(err) == 1, err
    assert str(out) in err[0] and "No space left on device" in err[0] and "is finalized" in err[0], err
    readable = int(err[0].split("finalized: ")[1].split(" bytes")[0].replace(",", ""))
    assert readable == out.stat().st_size <= _Full.room
    with out.open("rb") as f:
        got = list(make_reader(f).iter_messages())  # a whole file, footer and all
    assert any(ch.topic == "/rs30x/raw" for _, ch, _ in got)


# ---- signals and a closed stdout ----------------------------------------------------------------------
def test_sigint_stops_a_command_that_inherited_it_ignored(tmp_path):
    proc = subprocess.Popen([sys.executable, "-m", "rs30x_sniff", "decode", "-"], cwd=tmp_path,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env={**os.environ, "PYTHONPATH": str(ROOT)},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        proc.stdin.write(bytes.fromhex("FA AF 01 00 1E 00 00 01 1E"))
        proc.stdin.flush()
        time.sleep(1.5)  # started and reading stdin, which stays open
        proc.send_signal(signal.SIGINT)
        rc = proc.wait(timeout=15)
    finally:
        proc.kill()
        proc.communicate()
    assert rc == 130


@pytest.mark.parametrize("args", [["info", str(SESSION)], ["decode", str(SESSION)], ["rules"],
                                  ["lint", str(SESSION)], ["export", "LOG", "-o", "-"],
                                  ["simulate", "--duration", "0.3", "-o", "-", "--output-format", "hex"],
                                  ["convert", str(SESSION), "-o", "-"]], ids=lambda a: a[0] + str(len(a)))
def test_a_closed_stdout_ends_with_exit_0(tmp_path, log, args):
    args = [str(log) if a == "LOG" else a for a in args]
    r, w = os.pipe()
    os.close(r)  # no reader at all: every write to stdout fails with EPIPE
    try:
        done = run(*args, cwd=tmp_path, stdout=w, stderr=subprocess.PIPE)
    finally:
        os.close(w)
    assert done.returncode == 0 or (args[0] == "lint" and done.returncode == 1), done.stderr
    assert b"Traceback" not in done.stderr and b"Broken pipe" not in done.stderr, done.stderr


# ---- every number has a bound ---------------------------------------------------------------------------
def test_every_numeric_option_has_an_upper_bound():
    parser = cli.build_parser()
    settings_options = {k.option for k in KEYS.values()}
    for name, command in parser.commands.items():
        for option, _ in command.numbers:
            assert option in cli.OPTION_MAX or option in settings_options, f"{name} {option}: no upper bound"


@pytest.mark.parametrize("args,word", [
    (["record", "/dev/null", "-o", "x.mcap", "--split-size", "1e308"], "--split-size 1e+308: must be at most"),
    (["record", "/dev/null", "-o", "x.mcap", "--duration", "1e308"], "--duration 1e+308: must be at most"),
    (["decode", str(SESSION), "--duration", "inf"], "--duration inf: expected a duration"),
    (["decode", str(SESSION), "--gap-bytes", "1e308"], "--gap-bytes 1e+308: must be at most"),
    (["decode", str(SESSION), "--reply-timeout", "1e9"], "--reply-timeout 1000000000.0: must be at most"),
    (["decode", str(SESSION), "--baud", "99999999999", "--baud-any"], "--baud 99999999999: must be at most"),
    (["decode", str(SESSION), "--id", "100000"], "--id 100000: not a servo ID"),
    (["lint", str(SESSION), "-j", "100000"], "--jobs 100000: must be at most"),
    (["monitor", str(SESSION), "--speed", "1e300"], "--speed 1e+300: must be at most"),
    (["simulate", "-o", "x.hex", "--seed", str(2**70)], f"--seed {2**70:g}: must be at most"),
])
def test_out_of_range_numbers_are_one_line_errors(tmp_path, monkeypatch, capsys, args, word):
    monkeypatch.chdir(tmp_path)
    assert cli.main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_config_file_numbers_are_bounded_too(tmp_path, capsys):
    conf = tmp_path / "rs30x-sniff.toml"
    conf.write_text("reply-timeout = 1e300\n")
    assert cli.main(["decode", str(SESSION), "--config", str(conf)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "reply-timeout = 1e+300: must be at most 1h" in err[0], err


def test_a_stop_before_the_first_byte_says_so(tmp_path):
    """`convert` of a FIFO whose writer has sent nothing yet, stopped: one line saying it stopped, exit 130, no OUT."""
    fifo, out = tmp_path / "bus.fifo", tmp_path / "bus.mcap"
    os.mkfifo(fifo)
    proc = subprocess.Popen([sys.executable, "-m", "rs30x_sniff", "convert", str(fifo), "-o", str(out)],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    writer = os.open(fifo, os.O_WRONLY)  # convert has opened it and waits for its first byte
    try:
        time.sleep(1.0)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=15)
    finally:
        os.close(writer)
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    assert err.decode().splitlines() == ["rs30x-sniff: stopped (SIGTERM)"]
    assert not out.exists()
