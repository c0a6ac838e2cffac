"""Pipes, FIFOs and stdin: opened once, sniffed from their head, read in every format."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading

import pytest

from rs30x_sniff.sources.captures import (
    BINARY, HEX, MCAP, TIMESTAMPED, CaptureError, detect_format, read_capture, write_capture)

from .conftest import CAPTURES, ROOT, frames, make_mcap

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pipes and FIFOs by path are POSIX")

MANUAL = CAPTURES / "manual-examples.hex"
SESSION = CAPTURES / "session-mixed.thex"


def _pipe_path(content: bytes) -> str:
    """A /dev/fd/N path of a pipe a thread fills with ``content`` (what ``<(cat file)`` gives a command)."""
    r, w = os.pipe()

    def writer() -> None:
        try:
            os.write(w, content) if len(content) < 60000 else _write_all(w, content)
        finally:
            os.close(w)

    threading.Thread(target=writer, daemon=True).start()
    return f"/dev/fd/{r}"


def _write_all(fd: int, content: bytes) -> None:
    view = memoryview(content)
    while view:
        view = view[os.write(fd, view):]


def _from_file(path) -> list:
    return list(read_capture(str(path)))


@pytest.fixture
def samples(tmp_path):
    """The same capture as a file in each text and binary format."""
    chunks = list(read_capture(str(SESSION)))
    out = {TIMESTAMPED: SESSION, HEX: MANUAL}
    out[BINARY] = tmp_path / "s.bin"
    write_capture(out[BINARY], chunks, BINARY)
    return out


@pytest.mark.parametrize("fmt", [BINARY, HEX, TIMESTAMPED])
def test_a_pipe_is_read_once_in_every_format(samples, fmt):
    path = _pipe_path(samples[fmt].read_bytes())
    reader = read_capture(path)
    assert reader.format == fmt
    got = list(reader)
    expected = _from_file(samples[fmt])
    assert b"".join(d for d, _ in got) == b"".join(d for d, _ in expected)
    assert [t for _, t in got if t is not None] == [t for _, t in expected if t is not None]
    os.close(int(path.rsplit("/", 1)[1]))


@pytest.mark.parametrize("fmt", [BINARY, HEX, TIMESTAMPED])
def test_detect_then_read_uses_the_one_open_pipe(samples, fmt):
    # convert and info ask for the format first, then read: the pipe must not be opened twice.
    path = _pipe_path(samples[fmt].read_bytes())
    assert detect_format(path) == fmt
    assert detect_format(path) == fmt  # asked again: still the same open stream
    got = b"".join(d for d, _ in read_capture(path))
    assert got == b"".join(d for d, _ in _from_file(samples[fmt]))
    os.close(int(path.rsplit("/", 1)[1]))


def test_a_pipe_cannot_be_read_twice_at_once():
    path = _pipe_path(MANUAL.read_bytes())
    first = read_capture(path)
    next(first)
    with pytest.raises(CaptureError, match="read only once"):
        list(read_capture(path))
    first.close()
    os.close(int(path.rsplit("/", 1)[1]))


def test_a_large_binary_pipe_is_read_whole():
    data = bytes(range(256)) * 4000 + b"\xfa\xaf"
    path = _pipe_path(data)
    assert b"".join(d for d, _ in read_capture(path)) == data
    os.close(int(path.rsplit("/", 1)[1]))


def test_mcap_from_a_pipe_is_a_clear_error(tmp_path):
    m = make_mcap(tmp_path / "a.mcap", frames(5))
    path = _pipe_path(m.read_bytes())
    with pytest.raises(CaptureError, match="needs a seekable file"):
        read_capture(path)
    with pytest.raises(CaptureError, match="needs a seekable file"):
        list(read_capture(_pipe_path(m.read_bytes()), MCAP))


def _in_child(code: str, stdin: bytes, timeout: float = 30) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], input=stdin, capture_output=True, timeout=timeout, cwd=ROOT)


READ_STDIN = ("import sys; from rs30x_sniff.sources.captures import read_capture\n"
              "r = read_capture('-')\n"
              "chunks = list(r)\n"
              "print(r.format, b''.join(d for d, _ in chunks).hex(), [t for _, t in chunks if t is not None][:3])\n")


@pytest.mark.parametrize("fmt", [BINARY, HEX, TIMESTAMPED])
def test_stdin_is_sniffed_like_a_file(samples, fmt):
    proc = _in_child(READ_STDIN, samples[fmt].read_bytes())
    assert proc.returncode == 0, proc.stderr.decode()
    got_fmt, got_hex, times = proc.stdout.decode().split(" ", 2)
    expected = _from_file(samples[fmt])
    assert got_fmt == fmt
    assert bytes.fromhex(got_hex) == b"".join(d for d, _ in expected)
    assert times.strip() == str([t for _, t in expected if t is not None][:3])


def test_raw_binary_on_stdin_without_frame_headers_is_still_binary():
    proc = _in_child(READ_STDIN, b"\x01\x02\x03")
    assert proc.stdout.decode().split()[:2] == [BINARY, "010203"]
    proc = _in_child(READ_STDIN, b"")
    assert proc.stdout.decode().split()[0] == BINARY


def test_mcap_on_stdin_is_a_clear_error(tmp_path):
    m = make_mcap(tmp_path / "a.mcap", frames(5))
    proc = _in_child(READ_STDIN, m.read_bytes())
    assert proc.returncode == 1 and b"needs a seekable file" in proc.stderr


def test_a_fifo_is_opened_once(tmp_path, samples):
    # A second open of a FIFO would wait for a second writer forever: a timeout says it happened.
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    code = ("import sys; from rs30x_sniff.sources.captures import detect_format, read_capture\n"
            f"p = {str(fifo)!r}\n"
            "fmt = detect_format(p)\n"
            "print(fmt, sum(len(d) for d, _ in read_capture(p)))\n")
    for fmt in (BINARY, HEX, TIMESTAMPED):
        proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, cwd=ROOT)
        with open(fifo, "wb") as w:
            w.write(samples[fmt].read_bytes())
        out, _ = proc.communicate(timeout=30)
        n = sum(len(d) for d, _ in _from_file(samples[fmt]))
        assert out.decode().split() == [fmt, str(n)]


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash for <(...)")
def test_cli_decode_and_info_of_a_process_substitution():
    # The reproduction: `decode <(cat captures/manual-examples.hex)` printed nothing.
    cli = f"{sys.executable} -m rs30x_sniff"
    direct = subprocess.run(f"{cli} decode {MANUAL}", shell=True, capture_output=True, text=True, cwd=ROOT,
                            timeout=60)
    piped = subprocess.run(["bash", "-c", f"{cli} decode <(cat {MANUAL})"], capture_output=True, text=True,
                           cwd=ROOT, timeout=60)
    assert direct.returncode == 0 and piped.returncode == 0, piped.stderr
    assert piped.stdout == direct.stdout and piped.stdout.count("\n") > 10
    info = subprocess.run(["bash", "-c", f"{cli} info --format json <(cat {SESSION})"], capture_output=True,
                          text=True, cwd=ROOT, timeout=60)
    assert info.returncode == 0, info.stderr
    assert '"bytes": 7903' in info.stdout


# ---- a live pipe of text streams line by line (issue 31) ----------------------------------------------
POLL = "FA AF 01 0F 2A 02 00 26"
REPLY = "FD DF 01 00 2A 02 01 10 00 38"


def _read_while_open(lines: list[bytes], want: int) -> tuple[list, list]:
    """Write ``lines`` to a pipe kept open, read chunks until ``want`` bytes are in, then close it: the
    chunks read while the writer still held the pipe open, and all of them."""
    r, w = os.pipe()
    os.write(w, b"".join(lines))
    got: list = []
    reader = read_capture(f"/dev/fd/{r}", warn=None)
    done = threading.Event()

    def read() -> None:
        for chunk in reader:
            got.append(chunk)
            if sum(len(d) for d, _ in got) >= want:
                done.set()
        done.set()

    t = threading.Thread(target=read, daemon=True)
    t.start()
    done.wait(timeout=30)  # a bound for a loaded machine: the test fails by its assertions, not by this wait
    before = list(got)
    os.close(w)
    t.join(timeout=30)
    os.close(r)
    return before, got


FRAMES = bytes.fromhex(POLL + REPLY)


@pytest.mark.parametrize("lines,fmt,data", [
    ([f"{POLL}\n".encode(), f"{REPLY}\n".encode()], HEX, FRAMES),
    ([b"# a comment first\n", f"{POLL}\n".encode(), f"{REPLY}\n".encode()], HEX, FRAMES),
    ([f"0.500000 {POLL}\n".encode(), f"0.500800 {REPLY}\n".encode()], TIMESTAMPED, FRAMES),
    ([f"1767225600 {POLL}\n".encode()], TIMESTAMPED, bytes.fromhex(POLL)),  # a whole-number time, one line
    ([f"10 {POLL}\n".encode(), f"11 {REPLY}\n".encode()], HEX,              # an ambiguous first column:
     bytes.fromhex("10" + POLL + "11" + REPLY)),                            # waits, then reads as hex
    (["\ufeff0.5 FA AF\r\n".encode("utf-16-le")], TIMESTAMPED, b"\xfa\xaf"),  # UTF-16 with its mark, CRLF
    ([f"{POLL}\r".encode(), f"{REPLY}\r".encode()], HEX, FRAMES),         # CR-only line ends
])
def test_a_text_pipe_gives_its_lines_before_it_ends(lines, fmt, data):
    before, after = _read_while_open(lines, len(data))
    assert b"".join(d for d, _ in before) == data, "not all read while the writer kept the pipe open"
    assert before == after
    path = _pipe_path(b"".join(lines))
    assert detect_format(path) == fmt
    assert b"".join(d for d, _ in read_capture(path, warn=None)) == data  # read to its end: closed
    os.close(int(path.rsplit("/", 1)[1]))


def test_decode_prints_a_text_pipe_line_by_line():
    # `tail -f log.hex | rs30x-sniff decode -`: each line decoded while the writer is still there.
    import time

    proc = subprocess.Popen([sys.executable, "-m", "rs30x_sniff", "decode", "-", "--no-lint", "--isolated"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    try:
        proc.stdin.write(f"{POLL}\n{REPLY}\n".encode())
        proc.stdin.flush()
        os.set_blocking(proc.stdout.fileno(), False)
        got = b""
        deadline = time.monotonic() + 30  # a bound for a loaded machine, not a speed assertion
        while got.count(b"\n") < 2 and time.monotonic() < deadline and proc.poll() is None:
            got += proc.stdout.read() or b""
            time.sleep(0.05)
        assert proc.poll() is None  # still running: the pipe is open
        assert got.count(b"\n") == 2 and b"READ" in got and b"RETURN" in got, got
    finally:
        proc.stdin.close()
        proc.wait(timeout=30)


# ---- an MCAP on stdin ------------------------------------------------------------------------------------
def _cli(argv: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rs30x_sniff", *argv], capture_output=True, cwd=ROOT, timeout=120,
                          **kw)


def test_decode_of_an_mcap_redirected_to_stdin_reads_the_file(tmp_path):
    m = tmp_path / "s.mcap"
    assert _cli(["convert", str(SESSION), "-o", str(m), "--isolated"]).returncode == 0
    direct = _cli(["decode", str(m), "--isolated"])
    for argv in (["decode", "-", "--isolated"], ["info", "-", "--isolated", "--format", "json"],
                 ["lint", "-", "--isolated"]):
        with open(m, "rb") as stdin:
            proc = _cli(argv, stdin=stdin)
        assert proc.returncode in (0, 1) and b"Traceback" not in proc.stderr, proc.stderr
        if argv[0] == "decode":
            assert proc.stdout == direct.stdout and proc.stdout.count(b"\n") > 100
        if argv[0] == "info":
            assert b'"bytes": 7903' in proc.stdout
            assert b"the MCAP's metadata" in proc.stdout  # its recorded rate, read from stdin as from the file


def test_an_mcap_on_a_real_pipe_is_one_line(tmp_path):
    m = make_mcap(tmp_path / "a.mcap", frames(5))
    proc = _cli(["decode", "-", "--isolated"], input=m.read_bytes())
    assert proc.returncode == 2 and proc.stdout == b""
    assert proc.stderr == b"rs30x-sniff: error: -: an MCAP capture needs a seekable file, not a pipe " \
                          b"(save it to a file first)\n"


@pytest.mark.parametrize("fmt", ["thex", "hex", "mcap"])
def test_info_of_a_file_on_stdin_is_info_of_the_file(tmp_path, fmt):
    # A file on stdin is read ahead (its rate, its unit, what its times mark) and then read: each reader opens
    # it anew, so the sample cannot leave the capture's reader at its end (it once read "no data").
    import json

    src = {"thex": SESSION, "hex": MANUAL}.get(fmt)
    if src is None:
        src = tmp_path / "s.mcap"
        assert _cli(["convert", str(SESSION), "-o", str(src), "--isolated"]).returncode == 0
    direct = _cli(["info", str(src), "--isolated", "--format", "json"])
    with open(src, "rb") as stdin:
        given = _cli(["info", "-", "--isolated", "--format", "json"], stdin=stdin)
    assert given.returncode == direct.returncode == 0, given.stderr
    a, b = json.loads(direct.stdout), json.loads(given.stdout)
    a.pop("input"), b.pop("input")
    assert a == b and a["bytes"] > 0
