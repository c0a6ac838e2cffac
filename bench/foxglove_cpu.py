"""Benchmark: the CPU share of `record --foxglove` on a busy bus, with and without a subscribed client.

Run: .venv/bin/python bench/foxglove_cpu.py [--duration 30] [--baud 230400] [--scenario hexapod] [--repeat 3]
Four cases: record without --foxglove; with --foxglove and no client; with a client subscribed to what
docs/foxglove-layout.json shows (every servo's state and the findings); with a client subscribed to
every channel. The client reads every message it is sent. Target (issue 14): with no client, a few
percent of a core at 230400 baud.

Live: the simulator plays SCENARIO in real time onto a pty (from this process, so its CPU is not
counted) and `record PTY -o OUT.mcap` reads it; each line is the recorder's CPU time (all its threads,
the serial reader's and the SDK's server's included) over the time the bus played, as a share of one
core, and the bytes recorded are checked against those played. On a shared machine these figures move
by several points from run to run, hence the repeats and medians.
Drive loop: the same bytes through the decoder and the record command's sinks (McapSink, FoxgloveSink)
in this process, as fast as they go; the CPU time of the thread running the loop (best of the repeats),
per second of bus traffic: the part of the recorder's cost that --foxglove changes, measured closely.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tty
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from live import TICK, cpu_seconds  # noqa: E402

from rs30x_sniff.sources.mcap_reader import read_mcap_raw  # noqa: E402
from rs30x_sniff.sim import run  # noqa: E402
from rs30x_sniff.sim.port import play  # noqa: E402
from rs30x_sniff.protocol.wire import byte_time  # noqa: E402

SERVER_LINE = re.compile(r"Foxglove server on (ws://\S+?);")
LAYOUT_TOPICS = re.compile(r"/rs30x/servo/\d+/state|/rs30x/diagnostics")


def main_thread_cpu(pid: int) -> float:
    """CPU seconds of a process's main thread (the drive loop; the SDK's server runs in threads of its own)."""
    with open(f"/proc/{pid}/task/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


class Client:
    """A Foxglove WebSocket client in a thread: subscribes to the advertised channels ``wanted`` picks
    (new ones too, as servos appear) and counts what it receives."""

    def __init__(self, url: str, wanted) -> None:
        self.url = url
        self.wanted = wanted
        self.messages = 0
        self.bytes = 0
        self.subscribed: set[str] = set()
        self.stop = threading.Event()
        self.ready = threading.Event()
        self.thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)
        self.thread.start()
        if not self.ready.wait(10):
            raise SystemExit(f"no serverInfo from {url}")

    async def _run(self) -> None:
        import websockets

        async with websockets.connect(self.url, subprotocols=["foxglove.sdk.v1"], max_size=None,
                                      close_timeout=1) as ws:
            subs = 0
            while not self.stop.is_set():
                try:
                    frame = await asyncio.wait_for(ws.recv(), 0.2)
                except asyncio.TimeoutError:
                    continue
                except websockets.ConnectionClosed:
                    return  # the recorder stopped first
                if isinstance(frame, bytes):
                    self.messages += 1
                    self.bytes += len(frame)
                    continue
                msg = json.loads(frame)
                if msg["op"] == "serverInfo":
                    self.ready.set()
                elif msg["op"] == "advertise":
                    new = []
                    for ch in msg["channels"]:
                        if self.wanted(ch["topic"]):
                            subs += 1
                            new.append({"id": subs, "channelId": ch["id"]})
                            self.subscribed.add(ch["topic"])
                    if new:
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))


def measure(chunks: list, baud: int, mode: str) -> dict:
    """One recording of ``chunks`` played onto a pty; ``mode``: none (no --foxglove), idle (no client),
    layout or all (a client subscribed to those channels)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    out = Path(tempfile.mkdtemp()) / "bus.mcap"
    cmd = [sys.executable, "-m", "rs30x_sniff", "record", os.ttyname(slave), "-o", str(out), "--baud", str(baud)]
    if mode != "none":
        cmd += ["--foxglove", "127.0.0.1:0"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    client = None
    try:
        if mode != "none":
            line = proc.stderr.readline().decode()
            m = SERVER_LINE.search(line)
            if not m:
                raise SystemExit(f"record --foxglove said: {line}{proc.stderr.read().decode()}")
            if mode in ("layout", "all"):
                client = Client(m.group(1), (lambda t: True) if mode == "all" else LAYOUT_TOPICS.fullmatch)
        while not out.exists():
            if proc.poll() is not None:
                raise SystemExit(proc.stderr.read().decode())
            time.sleep(0.02)
        time.sleep(0.5)  # past the start-up: the figures are the steady state
        cpu0, main0, t0 = cpu_seconds(proc.pid), main_thread_cpu(proc.pid), time.monotonic()
        sent = play(chunks, lambda b: os.write(master, b))
        time.sleep(0.2)  # the last bytes through the decoder
        cpu1, main1, t1 = cpu_seconds(proc.pid), main_thread_cpu(proc.pid), time.monotonic()
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        if client is not None:
            client.stop.set()
            client.thread.join(5)
        os.close(master)
        os.close(slave)
    recorded = sum(len(d) for d, _ in read_mcap_raw(str(out)))
    return {"cpu": cpu1 - cpu0, "main": main1 - main0, "window": t1 - t0, "sent": sent, "recorded": recorded,
            "received": client.messages if client else 0, "received_bytes": client.bytes if client else 0,
            "topics": len(client.subscribed) if client else 0, "said": err.decode().strip().splitlines()[-1:]}


def drive_cpu(chunks: list, baud: int, mode: str) -> tuple[float, int]:
    """CPU seconds of this thread to drive ``chunks`` through the decoder, linter and record's sinks
    (``mode`` as in :func:`measure`), and the messages the client got."""
    import gc
    import io

    from rs30x_sniff.sinks.mcap.foxglove import FoxgloveSink
    from rs30x_sniff.sinks.mcap.writer import McapSink
    from rs30x_sniff.lint import Linter
    from rs30x_sniff.decode.decoder import Decoder
    from rs30x_sniff.sinks.pipeline import Pipeline

    # decoder: no sink at all; serve: the server alone (`serve PORT`), with no client.
    sinks = [] if mode in ("decoder", "serve") else [McapSink(io.BytesIO(), source="bench", baud=baud,
                                                              time_base="wall")]
    client = None
    if mode != "none" and mode != "decoder":
        fox = FoxgloveSink("127.0.0.1", 0, source="bench", baud=baud, backlog=1 << 20)
        sinks.append(fox)
        if mode in ("layout", "all"):
            wanted = (lambda t: True) if mode == "all" else LAYOUT_TOPICS.fullmatch
            # The state channels are made as servos appear: a first few frames through the server
            # have them all advertised, and the client subscribed, before the loop is timed.
            warm = Pipeline(Decoder(), [fox])
            for data, t in chunks[:300]:
                warm.feed(data, t)
            client = Client(fox.ws_url, wanted)
            expected = sum(1 for topic in fox._channels if wanted(topic))
            end = time.monotonic() + 10
            while len(client.subscribed) < expected and time.monotonic() < end:
                time.sleep(0.05)
            time.sleep(0.3)
    pipeline = Pipeline(Decoder(linter=Linter()), sinks)
    gc.collect()
    t0 = time.thread_time()
    for data, t in chunks:
        pipeline.feed(data, t)
    cpu = time.thread_time() - t0
    if client is not None:
        # Until the client has what the server queued for it: closing the pipeline stops the server.
        seen = -1
        while client.messages != seen:
            seen = client.messages
            time.sleep(0.5)
        client.stop.set()
        client.thread.join(5)
    pipeline.close()
    return cpu, client.messages if client else 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=30.0, help="seconds of bus traffic per run (default 30)")
    ap.add_argument("--baud", type=int, default=230400)
    ap.add_argument("--scenario", default="hexapod")
    ap.add_argument("--modes", default="none,idle,layout,all", help="which runs, comma-separated")
    ap.add_argument("--repeat", type=int, default=1,
                    help="rounds of the runs, interleaved; each figure is the median (a shared machine is noisy)")
    ap.add_argument("--no-live", action="store_true", help="only the drive loop part")
    args = ap.parse_args()

    chunks = list(run(args.scenario, baud=args.baud, duration=args.duration))
    total = sum(len(d) for d, _ in chunks)
    span = chunks[-1][1] + len(chunks[-1][0]) * byte_time(args.baud)
    print(f"scenario {args.scenario} at {args.baud} baud for {args.duration:g} s: {total:,} bytes, "
          f"bus load {total * byte_time(args.baud) / span * 100:.1f} %; {args.repeat} run(s) of each case")
    labels = {"none": "record (no --foxglove)", "idle": "--foxglove, no client",
              "layout": "--foxglove, layout client", "all": "--foxglove, client on all",
              "decoder": "decode and lint alone", "serve": "serve, no client"}
    modes = args.modes.split(",")
    bus_seconds = span
    print("drive loop (decode, lint, MCAP, --foxglove) in this process, per second of bus traffic (best run):")
    best: dict[str, float] = {}
    for mode in modes:
        runs = [drive_cpu(chunks, args.baud, mode) for _ in range(max(1, args.repeat))]
        cpu, got = min(runs)
        best[mode] = cpu / bus_seconds * 100
        extra = "" if mode == "none" or "none" not in best else f"  ({best[mode] - best['none']:+.2f} points)"
        client = f"; client got {got:,} messages" if got else ""
        print(f"  {labels[mode]:27s} {best[mode]:6.2f} % of one core ({cpu:.2f} s){extra}{client}")
    if "none" in modes:
        for mode in ("decoder", "serve"):
            cpu = min(drive_cpu(chunks, args.baud, mode)[0] for _ in range(max(1, args.repeat)))
            best[mode] = cpu / bus_seconds * 100
            extra = "" if mode == "decoder" else f"  ({best[mode] - best['decoder']:+.2f} points over decoding alone)"
            print(f"  {labels[mode]:27s} {best[mode]:6.2f} % of one core ({cpu:.2f} s){extra}")
    if args.no_live:
        return 0
    print("live, `record PTY` as a process (median run):")
    results: dict[str, list[dict]] = {m: [] for m in modes}
    for _ in range(args.repeat):
        for mode in modes:
            results[mode].append(measure(chunks, args.baud, mode))
    base = None
    ok = True
    for mode in modes:
        runs = results[mode]
        shares = sorted(r["cpu"] / r["window"] * 100 for r in runs)
        share = statistics.median(shares)
        threads = statistics.median((r["cpu"] - r["main"]) / r["window"] * 100 for r in runs)
        if mode == "none":
            base = share
        extra = "" if base is None or mode == "none" else f"  ({share - base:+.1f} points over record alone)"
        spread = "" if len(runs) == 1 else f" [{shares[0]:.1f}-{shares[-1]:.1f}]"
        print(f"  {labels[mode]:27s} CPU {share:5.1f} %{spread} of one core (threads other than the drive loop: "
              f"{threads:.1f} %){extra}")
        r = runs[-1]
        same = all(x["recorded"] == x["sent"] for x in runs)
        ok &= same
        got = "" if not r["topics"] else (f"; client: {r['topics']} channels, {r['received'] / r['window']:,.0f} "
                                          f"messages/s, {r['received_bytes'] / r['window'] / 1e3:,.0f} kB/s")
        print(f"  {'':27s} bytes recorded {r['recorded']:,} of {r['sent']:,} "
              f"({'equal' if same else 'DIFFERENT'}){got}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
