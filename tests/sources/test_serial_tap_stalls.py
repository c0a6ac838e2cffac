"""A live reader that fell behind: its backlog drained into one chunk, timed at the line rate from its arrival, and reported."""

from __future__ import annotations

import pytest

from rs30x_sniff.sources.serial_tap import LiveSource, SerialTap
from rs30x_sniff.protocol.wire import byte_time

BAUD = 115200
BT = byte_time(BAUD)
WALL0 = 1_732_550_400.0  # the port's opening on the wall clock
S = 1_000_000_000


class FakePort:
    """A port whose bytes come in at scripted times of a fake monotonic clock.

    ``events`` are ``(seconds, bytes)``: a blocked ``read(1)`` returns when the next one comes in.
    ``visible`` caps what ``in_waiting`` shows, and ``lag`` makes it show nothing once after each read,
    as a tty does while the kernel moves the next few KiB of a backlog into the port's buffer.
    """

    def __init__(self, tap: SerialTap, events, *, visible: int | None = None, lag: bool = False) -> None:
        self.tap = tap
        self.events = list(events)
        self.buffer = bytearray()
        self.now = 0
        self.visible = visible
        self.lag = lag
        self._hidden = False

    def clock(self) -> int:
        return self.now

    def read(self, n: int) -> bytes:
        if not self.buffer:
            if not self.events:
                self.tap._stop.set()
                return b""
            at, data = self.events.pop(0)
            self.now = round(at * S)
            self.buffer += data
        out = bytes(self.buffer[:n])
        del self.buffer[:n]
        self._hidden = self.lag and n > 1
        return out

    @property
    def in_waiting(self) -> int:
        if self._hidden:
            self._hidden = False
            return 0
        return len(self.buffer) if self.visible is None else min(len(self.buffer), self.visible)

    def close(self) -> None:
        pass


def capture(events, **port_options):
    """Run a tap's reader over ``events``: its chunks, and the tap."""
    tap = SerialTap("fake", BAUD)
    port = FakePort(tap, events, **port_options)
    tap.clock = port.clock
    tap._serial = port
    tap.wall_start_ns = round(WALL0 * S)
    tap.start_ns = 0
    tap.run()
    chunks = []
    while not tap.queue.empty():
        item = tap.queue.get_nowait()
        if isinstance(item, tuple):
            chunks.append(item)
    return chunks, tap


def _bus(seconds: float, start: float = 0.0) -> list[tuple[float, bytes]]:
    """A poll and its 10-byte return every 2 ms: what a reader keeping up reads, stamped at arrival."""
    out, t = [], start
    while t < start + seconds:
        out.append((t + 8 * BT, bytes(8)))
        out.append((t + 8 * BT + 100e-6 + 10 * BT, bytes(10)))
        t += 0.002
    return out


@pytest.mark.parametrize("os_buffer", [None, 4095], ids=["all-at-once", "a-tty-buffer-at-a-time"])
def test_a_backlog_after_three_seconds_is_timed_at_the_line_rate_from_its_arrival(os_buffer):
    backlog = bytes(range(256)) * 117 + bytes(48)  # 30 000 bytes that waited in the OS for 3 s
    before = _bus(0.1, start=0.0)
    held_until = 3.1
    after = _bus(0.05, start=held_until + 0.001)
    chunks, tap = capture([*before, (held_until, backlog), *after], visible=os_buffer, lag=os_buffer is not None)

    assert b"".join(d for d, _ in chunks) == b"".join(d for _, d in [*before, (0, backlog), *after])
    big = [(d, t) for d, t in chunks if len(d) > 100]
    assert [len(d) for d, _ in big] == [len(backlog)]  # drained into one chunk, not one per OS buffer
    data, t = big[0]
    assert t - WALL0 == pytest.approx(held_until - len(backlog) * BT, abs=1e-6)  # 0.495 s, not 2.745 s
    times = [t for _, t in chunks]
    assert times == sorted(times)
    assert len(tap.stalls) == 1
    when, behind, n = tap.stalls[0]
    assert n == len(backlog) and when == t and behind == pytest.approx(len(backlog) * BT)


def test_a_read_older_than_the_previous_one_is_a_stall_and_never_runs_time_backwards():
    # The drain missed part of a backlog: the third read holds 0.69 s of bytes 1 ms after the second.
    chunks, tap = capture([(1.0, bytes(8)), (3.0, bytes(4096)), (3.001, bytes(8000))])
    times = [t for _, t in chunks]
    assert times == sorted(times)
    assert chunks[2][1] - WALL0 == pytest.approx(3.0 - 4096 * BT, abs=1e-6)  # kept at the previous chunk's time
    assert chunks[2][1] + 8000 * BT - WALL0 < 3.001 + 0.4  # not pushed past the previous chunk's end (3.0 + 0.69)
    assert [n for _, _, n in tap.stalls] == [8000]


def test_a_reader_that_keeps_up_records_no_stall():
    chunks, tap = capture(_bus(1.0))
    assert tap.stalls == [] and len(chunks) == len(_bus(1.0))
    # A long packet that came in at once (a pty's writer) is no stall either.
    _, tap = capture([(0.5, bytes(98)), (0.5005, bytes(98))])
    assert tap.stalls == []


def test_a_wrong_baud_is_not_a_stall():
    # 115200 traffic read at 9600: far more bytes than the line could carry since the port opened.
    tap = SerialTap("fake", 9600)
    port = FakePort(tap, [(0.01 * i, bytes(180)) for i in range(1, 200)])
    tap.clock, tap._serial, tap.wall_start_ns, tap.start_ns = port.clock, port, round(WALL0 * S), 0
    tap.run()
    assert tap.stalls == []


def test_the_stalls_are_reported_once_at_the_end(capsys):
    _, tap = capture([(0.2, bytes(8)), (3.1, bytes(30000)), (5.0, bytes(8)), (9.0, bytes(12000))])
    src = LiveSource("/dev/ttyFAKE", BAUD, tap=tap)
    assert src.stalls is tap.stalls and len(src.stalls) == 2
    src._close(type("End", (), {"reason": "stopped", "message": "Ctrl-C"})())
    err = capsys.readouterr().err.splitlines()
    assert err == ["rs30x-sniff: /dev/ttyFAKE: the reader fell behind 2 times (longest 2.604 s at 0.496 s); "
                   "their bytes are timed at the line rate",
                   f"rs30x-sniff: Ctrl-C: /dev/ttyFAKE: {tap.bytes_read:,} bytes received"]  # the end line, last


def test_a_reader_pipe_closed_before_its_queue_is_finished_ends_it_quietly():
    """A live source finalized late (its generator collected after the pipe from its reader process was closed)
    finishes its queue with the end it has, not an OSError out of a finalizer."""
    import os

    from rs30x_sniff.sources.port_process import PipeQueue
    from rs30x_sniff.sources.serial_tap import LOST, SerialTap, TapEnd

    r, w = os.pipe()
    os.close(w)
    os.close(r)
    queue = PipeQueue(r, SerialTap("loop://", 115200))
    queue.finish(0.5)
    assert queue.ended
    (end,) = queue.take_all()
    assert type(end) is TapEnd and end.reason == LOST
