"""The tap's ChunkQueue: what queue.Queue gave the live source (order, timeouts, Empty), without a lock per chunk."""

from __future__ import annotations

import queue
import threading
import time

import pytest

from rs30x_sniff.sources.serial_tap import ChunkQueue


def test_order_take_all_and_empty():
    q = ChunkQueue()
    assert q.empty() and q.take_all() == []
    for k in range(5):
        q.put(k)
    assert q.get() == 0 and q.get_nowait() == 1 and q.take_all() == [2, 3, 4] and q.empty()
    with pytest.raises(queue.Empty):
        q.get_nowait()
    with pytest.raises(queue.Empty):
        q.get(timeout=0.01)


def test_a_waiting_get_wakes_for_a_put_from_another_thread_and_nothing_is_lost():
    q = ChunkQueue()
    n = 20000
    threading.Thread(target=lambda: [q.put(k) for k in range(n)], daemon=True).start()
    got: list[int] = []
    deadline = time.monotonic() + 60  # a guard for a hung test only
    while len(got) < n and time.monotonic() < deadline:
        try:
            got.append(q.get(timeout=0.05))
        except queue.Empty:
            continue
        got += q.take_all()
    assert got == list(range(n))
