"""A line that always has a byte waiting still yields chunks: the tap's backlog drain is bounded (issue 31, 3)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading
import time

import pytest
import serial

from rs30x_sniff.protocol.wire import byte_time
from rs30x_sniff.sources.serial_tap import DRAIN_SECONDS, LiveSource, SerialTap, TapEnd
from tests.e2e.helpers import recorded_bytes

BAUD = 115200
BT = byte_time(BAUD)
URL = "busywire://"

if "tests.sources" not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append("tests.sources")  # busywire:// (tests/sources/protocol_busywire.py)


class SlowWire:
    """A port on a fake clock: bytes come in at the line rate for ever, and every call takes ``cost`` seconds
    (more than a byte time), so there is always a byte waiting when the reader looks again."""

    def __init__(self, tap: SerialTap, seconds: float, cost: float = 3 * BT) -> None:
        self.tap, self.seconds, self.cost = tap, seconds, cost
        self.now = 0.0
        self.taken = 0

    def clock(self) -> int:
        return round(self.now * 1e9)

    def _due(self) -> int:
        return int(self.now / BT) - self.taken

    @property
    def in_waiting(self) -> int:
        self.now += self.cost
        return self._due()

    def read(self, n: int) -> bytes:
        self.now += self.cost
        if self.now >= self.seconds:
            self.tap.request_stop()
        self.now = max(self.now, (self.taken + n) * BT)  # a blocked read waits for its bytes
        out = bytes((self.taken + i) & 0xFF for i in range(n))
        self.taken += n
        return out

    def close(self) -> None:
        pass


def test_a_line_never_idle_and_a_slow_reader_still_give_a_chunk_per_drain():
    tap = SerialTap("fake", BAUD, process=False)
    wire = SlowWire(tap, seconds=3.0)
    tap.clock = wire.clock
    tap._serial = wire
    tap.wall_start_ns, tap.start_ns = 1_700_000_000 * 10**9, 0
    tap.run()
    items = tap.queue.take_all()
    assert type(items[-1]) is TapEnd
    chunks = items[:-1]
    data = b"".join(d for d, _ in chunks)
    assert data == bytes(i & 0xFF for i in range(len(data)))  # every byte, in order
    assert len(data) * BT > 2.5  # the 3 s of line were read as they came, not held in one drain
    assert len(chunks) > 100
    # No chunk holds more than the line carries in a drain's time (plus what was waiting when it began).
    assert max(len(d) for d, _ in chunks) * BT <= DRAIN_SECONDS + 0.06
    assert not tap.stalls  # nothing fell behind: the reader kept up, one chunk at a time


def test_a_backlog_is_still_drained_into_one_chunk():
    """What waited in the OS while the reader was held up (more than the line carries during the drain) comes
    out as one chunk, laid back at the line rate: the bound stops only live traffic."""
    tap = SerialTap("fake", BAUD, process=False)
    wire = SlowWire(tap, seconds=0.0, cost=0.0)
    wire.now = 2.0  # 2 s of line waiting before the first read
    tap.clock = wire.clock
    tap._serial = wire
    tap.wall_start_ns, tap.start_ns = 1_700_000_000 * 10**9, 0
    tap.run()
    (data, t), end = tap.queue.take_all()
    assert type(end) is TapEnd and len(data) == int(2.0 / BT)
    assert t == pytest.approx(1_700_000_000.0, abs=0.01)


def _poll_for(src: LiveSource, seconds: float) -> tuple[list, float | None]:
    got, first = [], None
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        batch = src.poll(0.1)
        if batch and first is None:
            first = time.monotonic() - t0
        got += batch
    return got, first


@pytest.mark.parametrize("process", [True, False], ids=["reader process", "reader thread"])
def test_a_url_handler_that_always_has_bytes_waiting_is_read_as_it_comes(process):
    src = LiveSource(URL, BAUD, announce=False, tap=SerialTap(URL, BAUD, process=process)).start()
    try:
        got, first = _poll_for(src, 2.0)
    finally:
        src.close()
    data = b"".join(d for d, _ in got)
    assert first is not None and first < 1.0, first  # the first chunk came at once, not after a never-ending drain
    assert len(data) * BT > 0.5  # of the 2 s the line carried (generous: a loaded machine)
    assert len(got) > 20
    ts = [t for _, t in got]
    assert ts == sorted(ts)


@pytest.mark.skipif(shutil.which("socat") is None, reason="needs socat")
def test_a_saturated_socat_pty_keeps_handing_out_chunks(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    socat = subprocess.Popen(["socat", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"],
                             stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 10
        while not (a.exists() and b.exists()) and time.monotonic() < deadline:
            time.sleep(0.05)
        src = LiveSource(str(b), 460800, announce=False).start()
        # 512 KiB over a second or two: ten times what 460800 baud carries, so the line never idles.
        payload = bytes(range(256)) * 2000
        fd = os.open(a, os.O_WRONLY)

        def flood() -> None:
            for i in range(0, len(payload), 1024):
                os.write(fd, payload[i:i + 1024])
                time.sleep(0.002)

        writer = threading.Thread(target=flood)
        got: list = []
        gaps: list[float] = []
        try:
            writer.start()
            last = time.monotonic()
            deadline = time.monotonic() + 60
            while sum(len(d) for d, _ in got) < len(payload) and time.monotonic() < deadline:
                batch = src.poll(0.1)
                now = time.monotonic()
                if batch:
                    gaps.append(now - last)
                    last = now
                got += batch
            writer.join(10)
        finally:
            src.close()
            os.close(fd)
    finally:
        socat.terminate()
        socat.wait(5)
    assert b"".join(d for d, _ in got) == payload
    assert len(gaps) > 5 and max(gaps[1:]) < 1.0, gaps  # chunks kept coming while the flood lasted


def test_record_baud_auto_on_a_never_idle_url_records_bytes(tmp_path):
    out = tmp_path / "busy.mcap"
    code = ("import sys, serial; serial.protocol_handler_packages.append('tests.sources'); "
            "from rs30x_sniff.cli import main; sys.exit(main(sys.argv[1:]))")
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    proc = subprocess.run([sys.executable, "-c", code, "record", URL, "--baud", "auto", "--duration", "4",
                           "--no-reconnect", "-o", str(out)], capture_output=True, text=True, timeout=120, cwd=root)
    assert proc.returncode == 0, proc.stderr
    assert "115200" in proc.stderr
    data = recorded_bytes(out)
    # A fraction of what the line carried after the scan (generous: a loaded machine); was 0 bytes.
    assert len(data) > 2000, proc.stderr
    assert b"\xfa\xaf" in data and b"\xfd\xdf" in data
