"""The passive tap: arrival stamps, a slow consumer losing nothing, pyserial URLs, duration and lost ports."""

from __future__ import annotations

import os
import socket
import threading
import time

import pytest

from rs30x_sniff.sources.captures import CaptureError
from rs30x_sniff.sources.ports import is_port
from rs30x_sniff.sources.serial_tap import DURATION, LOST, LiveSource, SerialTap
from rs30x_sniff.protocol.wire import byte_time
from tests.e2e.helpers import Pty


def test_first_byte_time_is_back_computed_and_chunks_never_overlap():
    tap = SerialTap("loop://", 115200)
    bt = byte_time(115200)
    tap.start_ns = 0
    tap._stamp(b"\x00" * 10, 1_000_000_000)          # 10 bytes that finished arriving at 1 s
    tap._stamp(b"\x00" * 4, 1_000_000_000 + 100_000)  # 4 more, 100 us later: they cannot start earlier
    (_, t1), (_, t2) = tap.queue.get(), tap.queue.get()
    assert t1 == pytest.approx(1.0 - 10 * bt)
    assert t2 == pytest.approx(t1 + 10 * bt)  # clamped to the end of the first chunk
    assert tap.bytes_read == 14


def test_rates_of_table_4_7_and_460800_only():
    for baud in (9600, 115200, 230400, 460800):
        SerialTap("loop://", baud)
    with pytest.raises(CaptureError, match="table 4.7"):
        SerialTap("loop://", 12345)


def test_what_counts_as_a_port(tmp_path):
    f = tmp_path / "cap.bin"
    f.write_bytes(b"\xfa\xaf")
    p = Pty()
    try:
        assert is_port(p.path)
    finally:
        p.close()
    assert is_port("socket://127.0.0.1:9") and is_port("rfc2217://localhost:2217") and is_port("loop://")
    assert not is_port(str(f)) and not is_port("/dev/null") and not is_port(str(tmp_path / "nope"))


def test_a_slow_consumer_loses_nothing():
    p = Pty()
    src = LiveSource(p.path, 460800, announce=False).start()
    data = bytes(range(256)) * 800  # 200 KiB, far more than the pty's own buffer holds
    writer = threading.Thread(target=lambda: [os.write(p.master, data[i:i + 4096])
                                              for i in range(0, len(data), 4096)])
    try:
        writer.start()
        writer.join(10)
        assert not writer.is_alive()  # the reader thread kept draining while nobody consumed
        time.sleep(0.5)               # the consumer is busy elsewhere
        got = bytearray()
        deadline = time.monotonic() + 5
        while len(got) < len(data) and time.monotonic() < deadline:
            for chunk, _ in src.poll(0.1):
                got += chunk
        assert bytes(got) == data
    finally:
        src.close()
        p.close()
    assert src.reason == "stopped"


def tap_now(src: LiveSource) -> float:
    """Now on the tap's own clock (its chunks' stamps: the monotonic clock anchored to the wall when it opened)."""
    return (src.tap.wall_start_ns + src.tap.clock() - src.tap.start_ns) / 1e9


def test_a_busy_port_is_handed_out_in_batches_each_chunk_with_its_own_stamp():
    p = Pty()
    src = LiveSource(p.path, 115200, announce=False, gather=1.0).start()
    try:
        os.write(p.master, b"\x07")
        assert [c for c, _ in src.poll(2.0)] == [b"\x07"]
        os.write(p.master, b"\x08")
        time.sleep(0.1)
        between = tap_now(src)
        time.sleep(0.1)
        os.write(p.master, b"\x07\x07")
        batch = src.poll(2.0)
        handed_out = tap_now(src)
        # The second poll waited out the gather time: the byte that was there before `between` came out with the
        # bytes written after it, in one batch...
        assert b"".join(c for c, _ in batch) == b"\x08\x07\x07" and len(batch) == 2
        # ...each stamped as it arrived, on either side of `between`, not when they were handed out.
        assert batch[0][1] < between < batch[1][1] < handed_out
    finally:
        src.close()
        p.close()


def test_duration_ends_the_capture():
    p = Pty()
    writing = threading.Event()
    written = bytearray()

    def write():
        """A line that never goes quiet: a byte every 10 ms until the test is over."""
        k = 0
        while writing.is_set():
            os.write(p.master, bytes([k % 256]))
            written.append(k % 256)
            k += 1
            time.sleep(0.01)

    writing.set()
    writer = threading.Thread(target=write)
    writer.start()
    try:
        src = LiveSource(p.path, 115200, duration=0.3, announce=False)
        got = b"".join(c for c, _ in src)
        assert writer.is_alive()  # the line was still busy: the duration ended the capture, not the line
        assert src.reason == DURATION and not src.lost and src.message == "0.3 s elapsed"
        assert got and got in bytes(written)  # what came while the port was open, in order, none lost
    finally:
        writing.clear()
        writer.join(5)
        p.close()


def test_socket_url_then_the_far_end_goes_away(capsys):
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    port = server.getsockname()[1]
    payload = bytes.fromhex("FA AF 01 09 00 00 01 09") * 50

    def serve():
        conn, _ = server.accept()
        time.sleep(0.3)  # pyserial discards what is already waiting when it opens a port
        for i in range(0, len(payload), 40):
            conn.sendall(payload[i:i + 40])
            time.sleep(0.01)
        conn.close()

    th = threading.Thread(target=serve)
    th.start()
    try:
        src = LiveSource(f"socket://127.0.0.1:{port}", 115200)
        chunks = list(src)
    finally:
        th.join(5)
        server.close()
    assert b"".join(d for d, _ in chunks) == payload
    ts = [t for _, t in chunks]
    assert ts == sorted(ts)
    assert src.reason == LOST and src.lost
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "port lost" in err[0] and f"{len(payload)} bytes" in err[0]


def test_a_port_that_cannot_be_opened_is_one_line():
    with pytest.raises(CaptureError, match=r"^/dev/ttyNOPE0: cannot open port: "):
        LiveSource("/dev/ttyNOPE0", 115200).start()
