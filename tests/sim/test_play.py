"""simulate --port's pacing: each frame written when its last byte is on the line, never late for making the next."""

from __future__ import annotations

import pytest

from rs30x_sniff.protocol.wire import byte_time
from rs30x_sniff.sim import run
from rs30x_sniff.sim.port import COALESCE, play

BT = byte_time(115200)


class FakeTime:
    def __init__(self) -> None:
        self.now = 100.0

    def clock(self) -> float:
        return self.now

    def sleep(self, s: float) -> None:
        self.now += s


def _dues(chunks, writes) -> list[float]:
    """Each write's due time: the end of the last of the whole chunks it holds (checked to be whole)."""
    ends = [t + len(d) * BT for d, t in chunks]
    out, k = [], 0
    for _, w in writes:
        n, first = 0, k
        while n < len(w):
            n += len(chunks[k][0])
            k += 1
        assert n == len(w)
        assert ends[k - 1] - ends[first] <= COALESCE + 1e-12  # run together only within COALESCE
        out.append(max(ends[first:k]))
    return out


def test_each_frame_is_written_when_its_last_byte_is_in():
    chunks = list(run("hexapod", duration=1.0))
    ft = FakeTime()
    writes: list[tuple[float, bytes]] = []
    sent = play(chunks, lambda b: writes.append((ft.now, bytes(b))), byte_seconds=BT, clock=ft.clock, sleep=ft.sleep)
    data = b"".join(d for d, _ in chunks)
    assert sent == len(data) and b"".join(w for _, w in writes) == data
    for (when, _), due in zip(writes, _dues(chunks, writes)):
        assert when - 100.0 == pytest.approx(due, abs=1e-9)
    assert len(writes) > 0.9 * len(chunks)  # frames 100 us apart or more are not run together


def test_making_the_chunks_never_delays_a_write():
    """A generator taking 0.4 ms per chunk (the simulator's servo model, at worst) is run ahead, while waiting."""
    chunks = list(run("hexapod", duration=2.0))
    ft = FakeTime()

    def slow():
        for c in chunks:
            ft.now += 0.0004
            yield c

    writes: list[tuple[float, bytes]] = []
    play(slow(), lambda b: writes.append((ft.now, bytes(b))), byte_seconds=BT, clock=ft.clock, sleep=ft.sleep)
    assert b"".join(w for _, w in writes) == b"".join(d for d, _ in chunks)
    dues = _dues(chunks, writes)
    start = writes[0][0] - dues[0]
    late = [when - start - due for (when, _), due in zip(writes, dues)]
    assert max(late) < 1e-9 and min(late) > -1e-9, (min(late), max(late))
