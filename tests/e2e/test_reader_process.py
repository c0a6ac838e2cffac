"""The port's reader stamps arrivals in a process of its own: a busy interpreter here never runs a request and its
reply together (issue 31, 4), and a reply read apart from its request gets a latency."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.protocol.wire import byte_time, encode_return, encode_short
from rs30x_sniff.sources.serial_tap import LiveSource, SerialTap
from tests.e2e.helpers import Pty

BAUD = 115200
BT = byte_time(BAUD)
REQUEST = encode_short(1, 0x09, 0, b"", length=0, count=1)
REPLY = encode_return(1, 42, bytes(18))
PAIRS = 60


def _busy(stop: threading.Event) -> None:
    """Python work holding the interpreter lock, as decoding a busy bus does."""
    while not stop.is_set():
        sum(i * i for i in range(20000))


WRITER = """
import os, sys, time
master, gap, pairs = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
request, reply = bytes.fromhex(sys.argv[4]), bytes.fromhex(sys.argv[5])
for _ in range(pairs):
    os.write(master, request)
    time.sleep(gap)
    os.write(master, reply)
    time.sleep(0.02)
"""


def _play_pairs(master: int) -> None:
    """Request, then its reply when its last byte would be in (a 100 us return delay, table 4.6 No. 7), 20 ms apart,
    from a process of its own (this one is busy)."""
    subprocess.run([sys.executable, "-c", WRITER, str(master), str(0.0001 + len(REPLY) * BT), str(PAIRS),
                    REQUEST.hex(), REPLY.hex()], pass_fds=(master,), check=True, timeout=60)


def _read_while_busy(process: bool) -> list[tuple[bytes, float]]:
    p = Pty()
    src = LiveSource(p.path, BAUD, announce=False, tap=SerialTap(p.path, BAUD, process=process)).start()
    stop = threading.Event()
    hogs = [threading.Thread(target=_busy, args=(stop,)) for _ in range(2)]
    got: list[tuple[bytes, float]] = []
    try:
        for h in hogs:
            h.start()
        writer = threading.Thread(target=_play_pairs, args=(p.master,))
        writer.start()
        writer.join(60)
        deadline = time.monotonic() + 10
        while sum(len(d) for d, _ in got) < PAIRS * (len(REQUEST) + len(REPLY)) and time.monotonic() < deadline:
            got += src.poll(0.1)
    finally:
        stop.set()
        for h in hogs:
            h.join()
        src.close()
        p.close()
    return got


def test_a_busy_interpreter_does_not_run_requests_and_replies_together():
    got = _read_while_busy(process=True)
    data = b"".join(d for d, _ in got)
    assert data == (REQUEST + REPLY) * PAIRS
    together = sum(1 for d, _ in got if REQUEST in d and REPLY[:2] in d)
    # Generous bounds for a loaded machine: a reader thread here ran 45-48 of 60 together (and timed 8-12), the
    # reader process none (timed 53-60).
    assert together <= PAIRS // 6, together
    dec = Decoder()
    replies = [r for d, t in got for r in dec.feed(d, t)] + list(dec.close())
    timed = [r for r in replies if getattr(r, "latency", None) is not None]
    assert len(timed) >= PAIRS // 2, len(timed)
