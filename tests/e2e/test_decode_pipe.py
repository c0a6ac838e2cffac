"""decode reading a pipe prints each line as its bytes come (the record path), not 64 KiB later."""

import os
import subprocess
import sys
import time

from rs30x_sniff.protocol.wire import encode_read, encode_return
from rs30x_sniff.sinks.pipeline import columnar_for
from rs30x_sniff.sources.captures import read_capture
from rs30x_sniff.sources.serial_tap import LiveSource


def test_a_line_per_frame_as_the_pipe_delivers_it():
    proc = subprocess.Popen([sys.executable, "-m", "rs30x_sniff", "decode", "-", "--input-format", "bin"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        proc.stdin.write(encode_read(1, 42, 2) + encode_return(1, 42, b"\x10\x00"))
        proc.stdin.flush()
        os.set_blocking(proc.stdout.fileno(), False)
        got = b""
        deadline = time.monotonic() + 20
        while got.count(b"\n") < 2 and time.monotonic() < deadline:
            got += proc.stdout.read() or b""
            time.sleep(0.05)
        assert got.count(b"\n") >= 2, got  # both lines out while the pipe is still open
        assert b"READ" in got and b"RETURN" in got
    finally:
        proc.stdin.close()
        proc.wait(timeout=20)


def test_whole_files_and_streams(tmp_path):
    f = tmp_path / "x.bin"
    f.write_bytes(b"\x00")
    assert not read_capture(str(f), "bin").streamed
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert read_capture(str(fifo), "bin").streamed  # not opened: a format given, nothing read yet
    assert read_capture(str(tmp_path / "missing"), "bin").streamed


def test_the_columnar_choice(tmp_path):
    """A file takes the columnar path in every command; a port too, a gather at a time (its batches end with an
    empty chunk); a live source that is not batched (the monitor's replay) never; a pipe unless the command's
    output follows its input (decode's lines)."""
    f = tmp_path / "x.bin"
    f.write_bytes(b"\x00")
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    file, pipe = read_capture(str(f), "bin"), read_capture(str(fifo), "bin")
    assert columnar_for(file) and columnar_for(file, follow=True)
    assert columnar_for(pipe) and not columnar_for(pipe, follow=True)
    port = LiveSource.__new__(LiveSource)  # not opened: only what the class says of itself
    assert columnar_for(port) and columnar_for(port, follow=True)

    class Paced:  # live, its chunks not in batches (a source declares all three: sources.protocol.Pacing)
        live = True
        streamed = False
        batched = False

    assert not columnar_for(Paced()) and not columnar_for(Paced(), follow=True)


def test_stdin_redirected_from_a_file_is_a_file(tmp_path):
    f = tmp_path / "x.bin"
    f.write_bytes(b"\x00")
    code = "from rs30x_sniff.sources.captures import read_capture; print(read_capture('-', 'bin').streamed)"
    with open(f, "rb") as stdin:
        assert subprocess.run([sys.executable, "-c", code], stdin=stdin, capture_output=True, text=True,
                              check=True).stdout.strip() == "False"
    assert subprocess.run([sys.executable, "-c", code], input="", capture_output=True, text=True,
                          check=True).stdout.strip() == "True"
