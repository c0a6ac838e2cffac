"""`serve --simulate`: the simulator's live stream is stamped at the wall clock, not from 1970."""

from __future__ import annotations

import asyncio
import json
import time

import pytest

pytest.importorskip("foxglove", reason="foxglove-sdk is not installed")
pytest.importorskip("websockets", reason="websockets is not installed (the test extra)")

from rs30x_sniff.commands.live import live_start_time  # noqa: E402
from rs30x_sniff.sim.source import SimulatorSource  # noqa: E402
from tests.e2e.test_foxglove import Client, start_serve, stop  # noqa: E402


def test_simulator_stream_log_times_are_wall_clock():
    before = time.time_ns()
    proc, url = start_serve("--simulate", "overheat")
    try:
        client = Client(url)
        asyncio.run(client.run(lambda c: len(c.messages) >= 300
                               and any(t == "/rs30x/diagnostics" for t, _, _ in c.messages), seconds=20))
    finally:
        stop(proc)
    after = time.time_ns()
    times = [t for _, t, _ in client.messages]
    assert len(times) >= 300
    # Bus time counts from when the server started, so every message falls within this test's run
    # (the simulator runs at real speed: no time can lead the wall clock by more than the pacing slack).
    assert before <= min(times) and max(times) <= after + 1_000_000_000, (before, min(times), max(times), after)
    # A finding's own timestamp (foxglove.Log) is on the same clock as its log time.
    logs = [(t, json.loads(p)) for topic, t, p in client.messages if topic == "/rs30x/diagnostics"]
    for t, log in logs:
        assert log["timestamp"]["sec"] * 1_000_000_000 + log["timestamp"]["nsec"] == t


def test_only_the_simulator_is_moved_to_the_wall_clock():
    sim = SimulatorSource("hexapod", 115200, duration=1.0)
    try:
        now = time.time()
        assert abs(live_start_time(sim) - now) < 5.0
    finally:
        sim.close()

    class Replay:  # a replayed capture keeps its own times; a port's are the wall clock already
        kind = "replay"

    class Port:
        kind = "port"

    assert live_start_time(Replay()) is None and live_start_time(Port()) is None
