"""`serve` and `--foxglove`: a Foxglove WebSocket client sees the MCAP channels, their schemas and log times, live."""

from __future__ import annotations

import asyncio
import io
import json
import re
import struct
import subprocess
import time

import pytest

foxglove = pytest.importorskip("foxglove", reason="foxglove-sdk is not installed")
websockets = pytest.importorskip("websockets", reason="websockets is not installed (the test extra)")
jsonschema = pytest.importorskip("jsonschema")

from rs30x_sniff.schemas import schema  # noqa: E402
from tests.e2e.helpers import cli  # noqa: E402

SUBPROTOCOL = "foxglove.sdk.v1"  # the SDK refuses foxglove.websocket.v1
MESSAGE_DATA = 0x01
SERVER_LINE = re.compile(r"Foxglove server on (ws://\S+?);")


def start_serve(*args: str) -> tuple[subprocess.Popen, str]:
    """``serve ARGS`` on a free port (port 0): the process and the ws:// URL it prints."""
    proc = cli("serve", *args, "--foxglove", "127.0.0.1:0")
    end = time.monotonic() + 20
    while time.monotonic() < end:
        line = proc.stderr.readline().decode()
        m = SERVER_LINE.search(line)
        if m:
            assert "https://app.foxglove.dev" in line
            return proc, m.group(1)
        if not line and proc.poll() is not None:
            break
    proc.kill()
    raise AssertionError(f"no server line: {proc.communicate()}")


def stop(proc: subprocess.Popen) -> str:
    if proc.poll() is None:
        proc.terminate()
    _, err = proc.communicate(timeout=20)
    return err.decode()


class Client:
    """A minimal Foxglove WebSocket client: serverInfo, advertisements, subscribe to every channel."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.info: dict | None = None
        self.channels: dict[int, dict] = {}   # channel id -> advertisement
        self.subs: dict[int, int] = {}        # subscription id -> channel id
        self.messages: list[tuple[str, int, bytes]] = []  # (topic, log time, payload)

    async def run(self, until, seconds: float = 20.0, abort: bool = False) -> None:
        """Receive until ``until(self)`` holds (or ``seconds`` pass); ``abort`` drops the TCP connection
        without a closing handshake, as a crashed client would."""
        # close_timeout: frames still queued behind the closing handshake would hold close() for 10 s.
        ws = await websockets.connect(self.url, subprotocols=[SUBPROTOCOL], max_size=None, close_timeout=1)
        try:
            end = time.monotonic() + seconds
            while not until(self) and time.monotonic() < end:
                try:
                    # A short wait, so ``until`` is asked again while the bus is quiet.
                    frame = await asyncio.wait_for(ws.recv(), 0.1)
                except asyncio.TimeoutError:
                    continue
                if isinstance(frame, bytes):
                    op, sub, log_time = struct.unpack_from("<BIQ", frame)
                    assert op == MESSAGE_DATA
                    self.messages.append((self.channels[self.subs[sub]]["topic"], log_time, frame[13:]))
                    continue
                msg = json.loads(frame)
                if msg["op"] == "serverInfo":
                    self.info = msg
                elif msg["op"] == "advertise":
                    new = []
                    for ch in msg["channels"]:
                        self.channels[ch["id"]] = ch
                        sid = len(self.subs) + 1
                        self.subs[sid] = ch["id"]
                        new.append({"id": sid, "channelId": ch["id"]})
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))
        finally:
            if abort:
                ws.transport.abort()
            else:
                await ws.close()

    def topics(self) -> set[str]:
        return {t for t, _, _ in self.messages}


def _validate(client: Client) -> None:
    """Every payload is JSON valid against its channel's advertised schema (the package's own), and
    each channel's log times never go back."""
    validators = {}
    for ch in client.channels.values():
        assert ch["encoding"] == "json" and ch["schemaEncoding"] == "jsonschema"
        assert json.loads(ch["schema"]) == schema(ch["schemaName"])
        validators[ch["topic"]] = jsonschema.Draft202012Validator(json.loads(ch["schema"]))
    last: dict[str, int] = {}
    for topic, log_time, payload in client.messages:
        validators[topic].validate(json.loads(payload))
        assert log_time >= last.get(topic, 0), topic
        last[topic] = log_time


def test_serve_simulator_to_a_client_then_a_late_one():
    proc, url = start_serve("--simulate", "hexapod")
    try:
        first = Client(url)
        wanted = {"/rs30x/raw", "/rs30x/packets", "/rs30x/transactions", "/rs30x/servo/1/state"}
        # Leaves mid-stream, abruptly: the server must neither stop nor stall for it.
        asyncio.run(first.run(lambda c: len(c.messages) >= 600 and wanted <= c.topics(), abort=True))
        assert first.info is not None and first.info["name"] == "rs30x-sniff"
        assert wanted <= first.topics(), first.topics()
        _validate(first)
        times = [t for topic, t, _ in first.messages if topic == "/rs30x/packets"]
        assert times[-1] > times[0]
        state = [json.loads(p) for topic, _, p in first.messages if topic == "/rs30x/servo/1/state"]
        assert all(s["id"] == 1 for s in state) and any("present_position" in s for s in state)

        time.sleep(0.5)
        assert proc.poll() is None, stop(proc)
        late = Client(url)
        asyncio.run(late.run(lambda c: len(c.messages) >= 200))
        assert len(late.messages) >= 200
        _validate(late)
        # A later client sees the stream where it is now, not a replay of what it missed.
        assert min(t for _, t, _ in late.messages) > max(t for _, t, _ in first.messages)
        assert proc.poll() is None
    finally:
        err = stop(proc)
    assert "messages published" in err, err


def test_serve_overheat_publishes_findings_on_diagnostics():
    proc, url = start_serve("--simulate", "overheat")
    try:
        client = Client(url)
        asyncio.run(client.run(lambda c: any(t == "/rs30x/diagnostics" for t, _, _ in c.messages), seconds=15))
        _validate(client)
        logs = [json.loads(p) for topic, _, p in client.messages if topic == "/rs30x/diagnostics"]
        assert logs, sorted(client.topics())
        assert all(re.match(r"[A-Z]\d{3} ", log["name"]) for log in logs)
        assert all(log["file"] == "overheat" and log["level"] in (2, 3, 4) for log in logs)
    finally:
        stop(proc)


def test_serve_needs_an_input():
    proc = cli("serve")
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == 2 and "serve needs INPUT" in err.decode()


def test_a_busy_port_is_one_line():
    proc, url = start_serve("--simulate", "hexapod")
    try:
        port = url.rsplit(":", 1)[1]
        other = cli("serve", "--simulate", "hexapod", "--foxglove", f"127.0.0.1:{port}")
        _, err = other.communicate(timeout=20)
        assert other.returncode == 2
        assert err.decode().count("\n") == 1 and "cannot serve on 127.0.0.1" in err.decode()
    finally:
        stop(proc)


def test_the_server_publishes_what_the_mcap_file_holds():
    """Same topics, bodies and log times as McapSink on the same input: one encoding for both."""
    from mcap.reader import make_reader

    from rs30x_sniff.io.foxglove_sink import FoxgloveSink
    from rs30x_sniff.io.mcap_sink import McapSink
    from rs30x_sniff.lint import Linter
    from rs30x_sniff.pipeline import Decoder, drive
    from rs30x_sniff.sim import run

    chunks = list(run("overheat", baud=115200, seed=1, duration=6.0))
    buf = io.BytesIO()
    with McapSink(buf, source="overheat", baud=115200, time_base="capture") as mcap:
        drive(iter(chunks), Decoder(linter=Linter()), mcap)
    reader = make_reader(io.BytesIO(buf.getvalue()))
    expected = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)]

    published: list[tuple[str, int, bytes]] = []

    class Recording(FoxgloveSink):
        def _write(self, cid, log_time, data):
            published.append((cid.topic(), log_time, data))
            super()._write(cid, log_time, data)

    fox = Recording("127.0.0.1", 0, source="overheat", baud=115200)
    drive(iter(chunks), Decoder(linter=Linter()), fox)
    assert any(t == "/rs30x/diagnostics" for t, _, _ in expected)
    assert published == expected
    assert fox.messages == len(expected)


def test_record_with_foxglove_streams_what_it_writes(tmp_path):
    """`record --foxglove`: a client sees the file's own messages (bodies and wall-clock log times) live."""
    import threading

    from mcap.reader import make_reader

    from tests.e2e.helpers import Pty

    pty = Pty()
    out = tmp_path / "bus.mcap"
    proc = cli("record", pty.path, "-o", str(out), "--foxglove", "127.0.0.1:0")
    try:
        line = proc.stderr.readline().decode()
        m = SERVER_LINE.search(line)
        assert m, line + proc.stderr.read().decode()
        client = Client(m.group(1))
        done = threading.Event()
        thread = threading.Thread(target=lambda: asyncio.run(client.run(lambda c: done.is_set(), seconds=20)))
        thread.start()
        time.sleep(0.3)  # subscribed before the bus starts
        pty.write_sim("hexapod", duration=1.0)
        time.sleep(0.3)
        done.set()
        thread.join(timeout=20)
        proc.send_signal(2)
        _, err = proc.communicate(timeout=20)
        assert proc.returncode == 0, err
    finally:
        if proc.poll() is None:
            proc.kill()
        pty.close()
    _validate(client)
    with open(out, "rb") as f:
        written = {(c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages()}
    packets = [msg for msg in client.messages if msg[0] == "/rs30x/packets"]
    # Subscribed before the bus started: every packet the file holds, and nothing it does not.
    assert len(packets) == sum(1 for topic, _, _ in written if topic == "/rs30x/packets") > 0
    assert all(msg in written for msg in client.messages)
    assert packets[0][1] > 1_000_000_000 * 1_000_000_000  # wall clock, in ns since the epoch


def test_monitor_takes_foxglove():
    from rs30x_sniff.cli import build_parser

    args = build_parser().parse_args(["monitor", "--simulate", "hexapod", "--foxglove", "0.0.0.0:9000"])
    assert args.foxglove == ("0.0.0.0", 9000)
    args = build_parser().parse_args(["record", "/dev/ttyUSB0", "-o", "x.mcap", "--foxglove", "9001"])
    assert args.foxglove == ("127.0.0.1", 9001)
    assert build_parser().parse_args(["record", "/dev/ttyUSB0", "-o", "x.mcap"]).foxglove is None
