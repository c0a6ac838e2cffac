"""`serve` and `--foxglove`: a Foxglove WebSocket client sees the MCAP channels, their schemas and log times, live."""

from __future__ import annotations

import asyncio
import io
import json
import re
import struct
import subprocess
import threading
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
                except websockets.ConnectionClosed:
                    break  # the server stopped (the command ended)
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


def in_thread(client: Client, until, seconds: float = 30.0, abort: bool = False) -> threading.Thread:
    """Run ``client`` in a thread of its own (the test meanwhile plays the bus)."""
    thread = threading.Thread(target=lambda: asyncio.run(client.run(until, seconds, abort)), daemon=True)
    thread.start()
    return thread


def file_messages(path) -> list[tuple[str, int, bytes]]:
    """(topic, log time, payload) of every message of an MCAP file (a path or a file object), in file order."""
    from mcap.reader import make_reader

    f = path if hasattr(path, "read") else open(path, "rb")
    with f:
        return [(c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages(log_time_order=False)]


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
        advertised = {ch["topic"] for ch in first.channels.values()}
        # The fixed channels from the start, and one state channel per servo of the hexapod.
        assert advertised == {"/rs30x/raw", "/rs30x/packets", "/rs30x/transactions", "/rs30x/diagnostics",
                              *(f"/rs30x/servo/{i}/state" for i in range(1, 19))}, advertised
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
    # The SDK's own words (the first client left without a closing handshake) come as our lines too.
    assert all(line.startswith("rs30x-sniff: ") for line in err.splitlines()), err


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

    from rs30x_sniff.sinks.mcap.foxglove import FoxgloveSink
    from rs30x_sniff.sinks.mcap.writer import McapSink
    from rs30x_sniff.lint import Linter
    from rs30x_sniff.decode.decoder import Decoder
    from rs30x_sniff.sinks.pipeline import drive
    from rs30x_sniff.sim import run

    chunks = list(run("overheat", baud=115200, seed=1, duration=6.0))
    buf = io.BytesIO()
    with McapSink(buf, source="overheat", baud=115200, time_base="capture") as mcap:
        drive(iter(chunks), Decoder(linter=Linter()), mcap)
    reader = make_reader(io.BytesIO(buf.getvalue()))
    expected = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)]

    published: list[tuple[str, int, bytes]] = []

    class Recording(FoxgloveSink):
        _every_message = True  # as if every channel had a subscriber

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
    proc = cli("record", pty.path, "-o", str(out), "--foxglove", "127.0.0.1:0", "--decoded")
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


def test_record_loses_no_bytes_to_a_client_that_leaves_or_comes_late(tmp_path):
    """`record --foxglove` with one client that drops its connection mid-stream (no closing handshake)
    and one that connects late: the file holds every byte played, and each client saw only what the
    file holds, in the file's order."""
    from tests.e2e.helpers import Pty, recorded_bytes

    pty = Pty()
    out = tmp_path / "bus.mcap"
    proc = cli("record", pty.path, "-o", str(out), "--baud", "230400", "--foxglove", "127.0.0.1:0", "--decoded")
    try:
        line = proc.stderr.readline().decode()
        m = SERVER_LINE.search(line)
        assert m, line + proc.stderr.read().decode()
        url = m.group(1)
        leaver = Client(url)
        t_leaver = in_thread(leaver, lambda c: sum(t == "/rs30x/packets" for t, _, _ in c.messages) >= 300,
                             abort=True)
        end = time.monotonic() + 10
        while len(leaver.subs) < 4 and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(0.2)  # the subscriptions reach the server
        late = Client(url)
        done = threading.Event()
        played: dict[str, bytes] = {}
        player = threading.Thread(target=lambda: played.update(
            sent=pty.write_sim("hexapod", duration=4.0, baud=230400)))
        player.start()
        time.sleep(1.5)
        t_late = in_thread(late, lambda c: done.is_set(), seconds=300)  # until done: the deadline only guards a hang
        player.join(timeout=30)
        seen = -1
        while len(late.messages) != seen:  # until the late client has caught up
            seen = len(late.messages)
            time.sleep(0.5)
        done.set()
        t_late.join(timeout=20)
        t_leaver.join(timeout=20)
        assert proc.poll() is None, "the recorder stopped"
        proc.send_signal(2)
        _, err = proc.communicate(timeout=20)
        assert proc.returncode == 0, err
    finally:
        if proc.poll() is None:
            proc.kill()
        pty.close()
    assert recorded_bytes(out) == played["sent"]  # not a byte lost to either client
    written = file_messages(out)
    index = {msg: i for i, msg in enumerate(written)}
    file_packets = [msg for msg in written if msg[0] == "/rs30x/packets"]
    for client in (leaver, late):
        _validate(client)
        assert client.messages and all(msg in index for msg in client.messages)
        # Per channel, in the file's order (the server sends one queue per client, in log order).
        for topic in client.topics():
            seen = [index[msg] for msg in client.messages if msg[0] == topic]
            assert seen == sorted(seen), topic
    left = [msg for msg in leaver.messages if msg[0] == "/rs30x/packets"]
    assert 300 <= len(left) < len(file_packets) // 2  # it left early...
    assert left == file_packets[:len(left)]           # ...having missed nothing before it did
    came = [msg for msg in late.messages if msg[0] == "/rs30x/packets"]
    assert came and came[0][1] > left[0][1] and len(came) < len(file_packets)
    # And it saw the stream to its end (but for a last record only the recorder's stop may decode).
    assert file_packets.index(came[-1]) >= len(file_packets) - 2


def test_a_client_that_subscribes_late_gets_the_files_bodies():
    """With no client, the server encodes nothing (nobody would get it); a client that subscribes
    mid-stream then gets exactly the messages the MCAP file gets from that point, whole servo states
    included (the registers that changed while nobody watched are in them). One process, an MCAP sink
    and the server side by side, as in `record --foxglove`: neither sees the other's messages."""
    from rs30x_sniff.sinks.mcap.foxglove import FIXED_CHANNELS, FoxgloveSink
    from rs30x_sniff.sinks.mcap.writer import McapSink
    from rs30x_sniff.lint import Linter
    from rs30x_sniff.decode.decoder import Decoder
    from rs30x_sniff.sinks.pipeline import Pipeline
    from rs30x_sniff.sim import run

    chunks = list(run("overheat", baud=115200, seed=1, duration=6.0))
    half = len(chunks) // 2
    buf = io.BytesIO()
    mcap = McapSink(buf, source="overheat", baud=115200, time_base="capture")
    # A backlog the whole second half fits in: this drive loop outruns any client.
    fox = FoxgloveSink("127.0.0.1", 0, source="overheat", baud=115200, backlog=1 << 20)
    pipeline = Pipeline(Decoder(linter=Linter()), [mcap, fox])
    try:
        for data, t in chunks[:half]:
            pipeline.feed(data, t)
        assert fox.messages == 0 and mcap.messages > 1000
        before = mcap.messages
        client = Client(fox.ws_url)
        done = threading.Event()
        # The client runs until told (done): its own deadline only guards against a hung test, and must not
        # cut it short while a loaded machine (CI's parallel tests) plays the second half slowly.
        thread = in_thread(client, lambda c: done.is_set(), seconds=300)
        end = time.monotonic() + 60
        channels = list(fox._channels.values()) + list(fox._state_channels.values())
        while not all(ch.has_sinks() for ch in channels) and time.monotonic() < end:
            time.sleep(0.02)
        assert fox._state_channels and all(ch.has_sinks() for ch in channels)
        known = set(fox._channels)
        for data, t in chunks[half:]:
            pipeline.feed(data, t)
        # The end of input to both sinks, but the server kept open until the client has it all: closing the
        # pipeline would stop the server at once, and the last messages still queued for the client with it.
        last = pipeline.decoder.close()
        for sink in (mcap, fox):
            sink.batch(last)
        end = time.monotonic() + 120
        while len(client.messages) < fox.messages and time.monotonic() < end:
            time.sleep(0.05)
        done.set()
        thread.join(timeout=20)
    finally:
        fox.close()
        mcap.finish()
    expected = file_messages(io.BytesIO(buf.getvalue()))[before:]
    assert {t for t, _, _ in expected} >= {t for t, _ in FIXED_CHANNELS}  # findings in this half too
    assert {t for t, _, _ in expected} <= known  # no servo first seen after the client subscribed
    assert fox.messages == len(expected)
    assert client.messages == expected


def test_monitor_with_foxglove_streams_to_a_client(tmp_path):
    """`monitor --foxglove` in a real terminal (a pty): the URL is said before the screen starts, a
    client gets the channels and the findings while the timeline runs, a client that drops its
    connection leaves no SDK message on the screen, and `q` ends both (terminal restored, exit 0)."""
    import fcntl
    import os
    import sys
    import termios

    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    env = dict(os.environ, TERM="xterm-256color", COLUMNS="120", LINES="40")
    proc = subprocess.Popen([sys.executable, "-m", "rs30x_sniff", "monitor", "--simulate", "overheat",
                             "--foxglove", "127.0.0.1:0", "--record-dir", str(tmp_path)],
                            stdin=slave, stdout=slave, stderr=slave, env=env, cwd=tmp_path, start_new_session=True)
    os.close(slave)
    screen = bytearray()
    reading = threading.Event()

    def drain() -> None:
        # The screen is read all along, as a terminal would: a full pty would stall the monitor.
        while not reading.is_set():
            try:
                data = os.read(master, 65536)
            except OSError:
                return
            if not data:
                return
            screen.extend(data)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    try:
        end = time.monotonic() + 30
        while not SERVER_LINE.search(screen.decode(errors="replace")) and time.monotonic() < end:
            time.sleep(0.05)
        m = SERVER_LINE.search(screen.decode(errors="replace"))
        assert m, bytes(screen[-500:])
        leaver = Client(m.group(1))
        asyncio.run(leaver.run(lambda c: len(c.messages) >= 50, abort=True))
        client = Client(m.group(1))
        asyncio.run(client.run(lambda c: any(t == "/rs30x/diagnostics" for t, _, _ in c.messages), seconds=30))
        time.sleep(0.5)
        assert proc.poll() is None
        os.write(master, b"q")
        assert proc.wait(20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
        reading.set()
        reader.join(timeout=5)
        os.close(master)
    shown = bytes(screen)
    assert b"\x1b[?1049l" in shown  # the alternate screen was left: the terminal is back
    assert b"Error receiving" not in shown and b"Traceback" not in shown
    _validate(leaver)
    _validate(client)
    assert {"/rs30x/raw", "/rs30x/packets", "/rs30x/transactions"} <= client.topics()
    logs = [json.loads(p) for t, _, p in client.messages if t == "/rs30x/diagnostics"]
    assert logs and all(log["file"] == "overheat" for log in logs)


def test_the_layout_shows_what_we_publish():
    """docs/foxglove-layout.json is JSON whose every topic is one of our channels, and whose every
    plotted field is a key the hexapod's state messages carry (per servo, 1 to 18)."""
    from pathlib import Path

    from rs30x_sniff.protocol.mcap_names import DIAGNOSTICS_TOPIC, PACKETS_TOPIC
    from rs30x_sniff.sinks.mcap.writer import McapSink
    from rs30x_sniff.decode.decoder import Decoder
    from rs30x_sniff.sinks.pipeline import drive
    from rs30x_sniff.sim import run

    layout = json.loads((Path(__file__).resolve().parents[2] / "docs" / "foxglove-layout.json").read_text())
    panels = layout["configById"]
    buf = io.BytesIO()
    with McapSink(buf, source="hexapod", baud=115200, time_base="capture") as mcap:
        drive(iter(run("hexapod", baud=115200, duration=2.0)), Decoder(), mcap)
    keys: dict[str, set[str]] = {}
    for topic, _, payload in file_messages(io.BytesIO(buf.getvalue())):
        keys.setdefault(topic, set()).update(json.loads(payload))
    plotted = {}
    for key, cfg in panels.items():
        if key.startswith("Plot!"):
            for path in cfg["paths"]:
                topic, _, field = path["value"].partition(".")
                assert field in keys.get(topic, ()), path["value"]
                plotted.setdefault(field, set()).add(int(topic.split("/")[3]))
    assert plotted == {f: set(range(1, 19)) for f in ("present_position", "present_current", "present_temperature")}
    [log] = [cfg for key, cfg in panels.items() if key.startswith("RosOut!")]  # Foxglove's Log panel
    assert log["topicToRender"] == DIAGNOSTICS_TOPIC
    assert all(cfg["topicPath"] in keys for key, cfg in panels.items() if key.startswith("RawMessages!"))
    assert PACKETS_TOPIC in keys

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(panels)  # every panel placed, none missing


def test_monitor_takes_foxglove():
    from rs30x_sniff.cli import build_parser

    args = build_parser().parse_args(["monitor", "--simulate", "hexapod", "--foxglove", "0.0.0.0:9000"])
    assert args.foxglove == ("0.0.0.0", 9000)
    args = build_parser().parse_args(["record", "/dev/ttyUSB0", "-o", "x.mcap", "--foxglove", "9001"])
    assert args.foxglove == ("127.0.0.1", 9001)
    assert build_parser().parse_args(["record", "/dev/ttyUSB0", "-o", "x.mcap"]).foxglove is None


def test_a_subscribed_client_gets_the_last_messages_before_the_server_stops():
    """Closing the pipeline closes the server, right after the end of input's messages are logged: a client
    still subscribed gets those too (FoxgloveSink lingers for it), then sees the server close."""
    from rs30x_sniff.sinks.mcap.foxglove import FoxgloveSink
    from rs30x_sniff.lint import Linter
    from rs30x_sniff.decode.decoder import Decoder
    from rs30x_sniff.sinks.pipeline import Pipeline
    from rs30x_sniff.sim import run

    chunks = list(run("bad-checksum", baud=115200, seed=2, duration=1.0))
    fox = FoxgloveSink("127.0.0.1", 0, source="bad-checksum", baud=115200, backlog=1 << 20)
    pipeline = Pipeline(Decoder(linter=Linter()), [fox])
    try:
        client = Client(fox.ws_url)
        # Until the server closes the connection; its own deadline only guards a hung test.
        thread = in_thread(client, lambda c: False, seconds=300)
        channels = list(fox._channels.values())
        end = time.monotonic() + 60
        while not all(ch.has_sinks() for ch in channels) and time.monotonic() < end:
            time.sleep(0.02)
        assert all(ch.has_sinks() for ch in channels)
        for data, t in chunks:
            pipeline.feed(data, t)
        pipeline.close()  # the last records and findings, then the server stops
        thread.join(timeout=60)
    finally:
        fox.close()
    assert not thread.is_alive()
    assert fox.messages > 20 and len(client.messages) == fox.messages
