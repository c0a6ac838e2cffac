"""The Foxglove server sends its clients what is queued for them before it stops (flush_clients), even a client that
stopped reading for a while: nothing logged before close() is lost to a client still subscribed."""

from __future__ import annotations

import json
import time

import pytest

pytest.importorskip("foxglove")
pytest.importorskip("websockets")

from rs30x_sniff.protocol.mcap_names import RAW_SCHEMA, RAW_TOPIC  # noqa: E402
from rs30x_sniff.sinks.mcap import foxglove  # noqa: E402
from rs30x_sniff.sinks.mcap.foxglove import FoxgloveSink, flush_clients  # noqa: E402
from tests.e2e.test_foxglove import Client, in_thread  # noqa: E402


def subscribed(fox: FoxgloveSink, client: Client, stall: float = 0.0):
    """``client`` in a thread, subscribed to every channel; with ``stall``, it stops reading for that long after its
    first message (its socket's buffers fill, the rest waits in the server's queue)."""
    stalled = []

    def until(c: Client) -> bool:
        if stall and c.messages and not stalled:
            stalled.append(True)
            time.sleep(stall)  # the client's own loop, blocked: it reads nothing meanwhile
        return False  # until the server closes the connection

    thread = in_thread(client, until, seconds=120)
    channels = [fox.channel(RAW_TOPIC, RAW_SCHEMA)]
    end = time.monotonic() + 30
    while not all(ch.has_sinks() for ch in channels) and time.monotonic() < end:
        time.sleep(0.02)
    assert all(ch.has_sinks() for ch in channels)
    return thread, channels[0]


def test_a_client_that_stopped_reading_gets_everything_before_the_server_stops():
    fox = FoxgloveSink("127.0.0.1", 0, source="flush", baud=115200, backlog=1 << 20)
    client = Client(fox.ws_url)
    try:
        thread, raw = subscribed(fox, client, stall=foxglove.FLUSH_MAX_S / 3)
        # 24 MB: more than the loopback's socket buffers hold, so most of it is still queued at close().
        body = json.dumps({"data": "00" * 32_000}).encode()
        sent = 0
        for k in range(400):
            raw.log(body, 1_000_000 * (k + 1))
            sent += 1
    finally:
        fox.close()
    thread.join(timeout=60)
    assert not thread.is_alive()
    assert len([m for m in client.messages if m[0] == RAW_TOPIC]) == sent


def test_quiet_connections_end_the_wait_and_none_is_nothing_to_wait_for():
    fox = FoxgloveSink("127.0.0.1", 0, source="flush", baud=115200)
    client = Client(fox.ws_url)
    try:
        thread, raw = subscribed(fox, client)
        raw.log(json.dumps({"data": "fa af"}).encode(), 1)
        assert flush_clients(fox.port) is True  # ended by the connections' quiet, not by FLUSH_MAX_S
        assert flush_clients(fox.port + 1 if fox.port < 65535 else fox.port - 1) is True  # nobody to send to
    finally:
        fox.close()
    thread.join(timeout=60)
    assert [m[0] for m in client.messages].count(RAW_TOPIC) == 1
