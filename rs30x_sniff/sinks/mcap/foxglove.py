"""Foxglove WebSocket server sink: the MCAP channels, with the same schemas, bodies and log times, live."""

from __future__ import annotations

import time

from typing import Any

import foxglove

from ...schemas import schema_bytes
from ...protocol.mcap_names import (DIAGNOSTICS_TOPIC, LOG_SCHEMA, PACKET_SCHEMA, PACKETS_TOPIC, RAW_SCHEMA, RAW_TOPIC,
                                    TRANSACTION_SCHEMA, TRANSACTIONS_TOPIC)
from .writer import JsonChannels

DEFAULT_HOST = "127.0.0.1"  # this machine only: the bus is not published to the network unless asked
DEFAULT_PORT = 8765         # Foxglove's own default
SERVER_NAME = "rs30x-sniff"
FIXED_CHANNELS = ((RAW_TOPIC, RAW_SCHEMA), (PACKETS_TOPIC, PACKET_SCHEMA),
                  (TRANSACTIONS_TOPIC, TRANSACTION_SCHEMA), (DIAGNOSTICS_TOPIC, LOG_SCHEMA))


class FoxgloveError(Exception):
    """The server cannot start: the address cannot be bound."""


def parse_address(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` -> (host, port); HOST defaults to 127.0.0.1 and may be [IPv6]."""
    host, sep, port = text.strip().rpartition(":")
    if not sep:
        host = DEFAULT_HOST
    host = host.strip("[]") or DEFAULT_HOST
    try:
        number = int(port)
    except ValueError:
        raise ValueError(f"{text!r}: expected [HOST:]PORT") from None
    if not 0 <= number <= 65535:
        raise ValueError(f"{text!r}: port must be 0-65535")
    return host, number


# How long a server with a subscribed client stays up after the last message, so that the client gets it.
LINGER_S = 0.5


class FoxgloveSink(JsonChannels):
    """Publishes the bus on a Foxglove WebSocket server, one channel per MCAP channel.

    The SDK's ``log`` queues each message per subscribed client and never waits for one: a slow
    client loses its oldest messages (``backlog`` per client), a gone one is dropped. A message on a
    channel no client is subscribed to is not even encoded (``_live``, the SDK's ``has_sinks``), so
    a server nobody watches costs little more than the decoding. Its own context keeps these channels
    away from anything else in the process that logs through the SDK (an MCAP file of ``record``).
    """

    _every_message = False

    def __init__(self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *, source: str, baud: int,
                 models: dict[int, str] | None = None, start_time: float | None = None,
                 backlog: int | None = None) -> None:
        super().__init__(source=source, baud=baud, models=models, start_time=start_time)
        self._context = foxglove.Context()
        try:
            # The SDK's own default backlog unless asked: passing None is not the same as leaving it out.
            options = {} if backlog is None else {"message_backlog_size": backlog}
            self.server = foxglove.start_server(name=SERVER_NAME, host=host, port=port, context=self._context,
                                                **options)
        except Exception as e:  # noqa: BLE001 - the SDK raises its own error types for a busy port
            raise FoxgloveError(f"cannot serve on {host}:{port}: {e}") from None
        self.host = host
        self.port = self.server.port  # the one bound (port 0 asks for any free one)
        self._channels: dict[str, Any] = {}
        self.messages = 0
        self._closed = False
        # Advertised now, not at their first message: a client subscribes on an advertisement, so a
        # channel made lazily would lose its first message (the first finding) to every client.
        for topic, schema_name in FIXED_CHANNELS:
            self.channel(topic, schema_name)

    @property
    def ws_url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    def app_url(self) -> str | None:
        """The Foxglove app's URL that opens this server as its data source."""
        return self.server.app_url()

    # ---- JsonChannels --------------------------------------------------------------------------
    def channel(self, topic: str, schema_name: str) -> Any:
        ch = self._channels.get(topic)
        if ch is None:
            schema = foxglove.Schema(name=schema_name, encoding="jsonschema", data=schema_bytes(schema_name))
            # The SDK's channel object: its log() and has_sinks() without the wrapper's per-call checks.
            ch = self._channels[topic] = foxglove.Channel(topic, schema=schema, message_encoding="json",
                                                          context=self._context).base
        return ch

    def _live(self, cid: Any) -> bool:
        return cid.has_sinks()

    def _write(self, cid: Any, log_time: int, data: bytes) -> None:
        cid.log(data, log_time)
        self.messages += 1

    # chunk, batch and idle (the drive loop's sink protocol) are JsonChannels'.
    def close(self) -> None:
        """Stop the server (clients see it close); idempotent. A client still subscribed is given LINGER_S
        first: the server sends from its own thread, and stopping it drops what is still queued (the last
        records and the end-of-input findings, logged just before)."""
        if self._closed:
            return
        self._closed = True
        if any(ch.has_sinks() for ch in self._channels.values()):
            time.sleep(LINGER_S)
        self.server.stop()
