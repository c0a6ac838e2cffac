"""Foxglove WebSocket server sink: the MCAP channels, with the same schemas, bodies and log times, live."""

from __future__ import annotations

import os
import socket
import struct
import sys
import time
from collections.abc import Callable
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


# Before the server stops, its subscribed clients are sent what is queued for them. The SDK has no flush (foxglove-sdk
# 0.30: WebSocketServer.stop() ends each client's send loop at once and drops its queue; no queue length, no callback
# per message sent), so the kernel tells: the SDK writes a queued message to its client's socket as soon as it can,
# so once every connection of this server has had nothing in flight and no byte written for QUIET_S, the queues are
# sent. A client that reads slowly is waited for up to FLUSH_MAX_S. Where the sockets cannot be seen (not Linux),
# the server waits FLUSH_BLIND_S, as it did always before.
QUIET_S = 0.2
FLUSH_MAX_S = 3.0
FLUSH_BLIND_S = 0.5
FLUSH_POLL_S = 0.01
TCP_INFO_BYTES_ACKED = 120  # struct tcp_info (linux/tcp.h): 8 u8 fields, 24 u32, pacing_rate, max_pacing_rate, then it


def _connections(port: int) -> list[socket.socket] | None:
    """Copies of this process's TCP connections whose local port is ``port`` (the server's clients); None when the
    process's sockets cannot be listed."""
    try:
        fds = [int(fd) for fd in os.listdir("/proc/self/fd")]
    except OSError:
        return None
    out = []
    for fd in fds:
        try:
            if not os.readlink(f"/proc/self/fd/{fd}").startswith("socket:"):
                continue
            sock = socket.socket(fileno=os.dup(fd))
        except OSError:
            continue  # closed meanwhile, or not a socket
        try:
            if (sock.family in (socket.AF_INET, socket.AF_INET6) and sock.type == socket.SOCK_STREAM
                    and sock.getsockname()[1] == port and sock.getpeername()):
                out.append(sock)
                continue
        except OSError:
            pass  # the listening socket (no peer), or one closing
        sock.close()
    return out


def _written(sock: socket.socket) -> tuple[int, int] | None:
    """(bytes written to the connection so far, bytes of them not yet acknowledged by the client), or None."""
    try:
        import fcntl  # POSIX only, as TCP_INFO and SIOCOUTQ are Linux's
        import termios

        info = sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, TCP_INFO_BYTES_ACKED + 8)
        acked = struct.unpack_from("=Q", info, TCP_INFO_BYTES_ACKED)[0]
        queued = struct.unpack("i", fcntl.ioctl(sock.fileno(), termios.TIOCOUTQ, b"\0" * 4))[0]  # SIOCOUTQ
    except (ImportError, OSError, struct.error, AttributeError):
        return None
    return acked + queued, queued


def flush_clients(port: int, clock: Callable[[], float] = time.monotonic) -> bool:
    """Wait until the server's client connections on ``port`` are quiet (see QUIET_S), at most FLUSH_MAX_S; False
    when they cannot be watched (then waited FLUSH_BLIND_S) or stayed busy."""
    socks = _connections(port) if sys.platform == "linux" else None
    if socks is not None and not socks:
        return True  # subscribed a moment ago, gone now: nobody to send to
    if socks is None or any(_written(sock) is None for sock in socks):
        for sock in socks or ():
            sock.close()
        time.sleep(FLUSH_BLIND_S)
        return False
    try:
        start = last_change = clock()
        before: list[tuple[int, int]] = []
        while clock() - start < FLUSH_MAX_S:
            now = [w for w in map(_written, socks) if w is not None]
            if len(now) < len(socks):
                return False  # a connection closed meanwhile: its client is gone
            if now != before:
                before, last_change = now, clock()
            elif all(queued == 0 for _, queued in now) and clock() - last_change >= QUIET_S:
                return True
            time.sleep(FLUSH_POLL_S)
        return False
    finally:
        for sock in socks:
            sock.close()


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
            options: dict[str, Any] = {} if backlog is None else {"message_backlog_size": backlog}
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
        """Stop the server (clients see it close); idempotent. A client still subscribed is sent what is queued
        for it first (flush_clients): the server sends from its own thread, and stopping it drops what is still
        queued (the last records and the end-of-input findings, logged just before)."""
        if self._closed:
            return
        self._closed = True
        if any(ch.has_sinks() for ch in self._channels.values()):
            flush_clients(self.port)
        self.server.stop()
