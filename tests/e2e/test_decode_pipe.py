"""decode reading a pipe prints each line as its bytes come (the record path), not 64 KiB later."""

import os
import subprocess
import sys
import time

from rs30x_sniff.commands.common import is_whole_file
from rs30x_sniff.protocol.wire import encode_read, encode_return


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
    assert is_whole_file(str(f), None)
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert not is_whole_file(str(fifo), None)
    assert not is_whole_file(str(tmp_path / "missing"), None)
