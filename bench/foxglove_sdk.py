"""Benchmark: MCAP through the Foxglove SDK against the mcap Writer, and what the live server costs the capture.

Run: python bench/foxglove_sdk.py [--frames N]
Writers: the messages `convert` writes for N hexapod frames, pre-encoded, through the bare mcap Writer
and through foxglove.open_mcap (zstd both, convert's 1 MiB chunks), the SDK two ways: its defaults
with the Channel wrapper's log(), and as McapSink uses it (the channel's own log(), appending through
_SdkFile, no compression thread pool, chunks cut by McapSink every CHUNK_SIZE); messages/s, best of 3.
(McapSink writes through the SDK since this measure: bench/convert.py times the whole conversion.)
Server: the drive loop (its thread's CPU time) with a FoxgloveSink, with no client (nothing is
encoded), and with a client that subscribed to every channel advertised when it connected (raw,
packets, transactions, diagnostics) and then stopped reading (its messages are dropped; the loop
must not wait for it).
"""

from __future__ import annotations

import argparse
import asyncio
import gc
import io
import json
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from traffic import hexapod_frames  # noqa: E402

import foxglove  # noqa: E402
from foxglove.mcap import MCAPWriteOptions  # noqa: E402
from mcap.reader import make_reader  # noqa: E402
from mcap.writer import CompressionType, Writer  # noqa: E402

from rs30x_sniff.commands.convert import CHUNK_SIZE  # noqa: E402
from rs30x_sniff.sinks.mcap.foxglove import FoxgloveSink  # noqa: E402
from rs30x_sniff.sinks.mcap.writer import McapSink  # noqa: E402
from rs30x_sniff.lint import Linter  # noqa: E402
from rs30x_sniff.decode.decoder import Decoder  # noqa: E402
from rs30x_sniff.sinks.pipeline import drive


def plan_of(frames: list) -> tuple[list, dict]:
    """The messages (channel id, log time, data) and channels {id: (topic, schema name, schema)} of a conversion."""
    buf = io.BytesIO()
    with McapSink(buf, source="bench", baud=115200, time_base="capture", chunk_size=CHUNK_SIZE) as sink:
        drive(iter(frames), Decoder(linter=Linter()), sink)
    reader = make_reader(io.BytesIO(buf.getvalue()))
    summary = reader.get_summary()
    channels = {cid: (ch.topic, summary.schemas[ch.schema_id].name, summary.schemas[ch.schema_id].data)
                for cid, ch in summary.channels.items()}
    plan = [(c.id, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)]
    return plan, channels


def bare_writer(plan: list, channels: dict, path: str) -> float:
    gc.collect()
    t0 = time.perf_counter()
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
        w.start()
        ids = {cid: w.register_channel(topic, "json", w.register_schema(name, "jsonschema", data))
               for cid, (topic, name, data) in channels.items()}
        add = w.add_message
        for cid, log_time, data in plan:
            add(ids[cid], log_time, data, log_time)
        w.finish()
    return time.perf_counter() - t0


def sdk_as_mcap_sink(plan: list, channels: dict, path: str) -> float:
    """The SDK's writer with McapSink's options and calls, on the same messages (its own chunk cuts by
    size only: the plan's log times are those of a capture, so time cuts would be the same)."""
    from rs30x_sniff.sinks.mcap.writer import _SdkFile

    gc.collect()
    t0 = time.perf_counter()
    ctx = foxglove.Context()
    with open(path, "wb") as f:
        out = _SdkFile(f, library="rs30x-sniff bench")
        writer = foxglove.open_mcap(out, context=ctx, writer_options=MCAPWriteOptions(
            chunk_size=None, disable_seeking=True, calculate_data_section_crc=False, compression_threads=0))
        logs = {cid: foxglove.Channel(topic, schema=foxglove.Schema(name=name, encoding="jsonschema", data=data),
                                      message_encoding="json", context=ctx).base.log
                for cid, (topic, name, data) in channels.items()}
        size = 0
        for cid, log_time, data in plan:
            logs[cid](data, log_time)
            size += len(data) + 31
            if size >= CHUNK_SIZE:
                writer.flush()
                size = 0
        writer.close()
    return time.perf_counter() - t0


def sdk_writer(plan: list, channels: dict, path: str) -> float:
    gc.collect()
    t0 = time.perf_counter()
    ctx = foxglove.Context()  # its own: nothing else in the process writes to this file
    writer = foxglove.open_mcap(path, allow_overwrite=True, context=ctx,
                                writer_options=MCAPWriteOptions(chunk_size=CHUNK_SIZE))
    chans = {cid: foxglove.Channel(topic, schema=foxglove.Schema(name=name, encoding="jsonschema", data=data),
                                   message_encoding="json", context=ctx)
             for cid, (topic, name, data) in channels.items()}
    logs = {cid: ch.log for cid, ch in chans.items()}
    for cid, log_time, data in plan:
        logs[cid](data, log_time=log_time)
    writer.close()
    return time.perf_counter() - t0


def sdk_count(path: str) -> int:
    with open(path, "rb") as f:
        return make_reader(f).get_summary().statistics.message_count


def drive_seconds(frames: list, sink_factory) -> tuple[float, int]:
    """CPU seconds of the thread running the drive loop (wall time means little on a loaded machine;
    a client that made log() wait would show as wall time, the SDK's own threads as neither)."""
    sink = sink_factory()
    gc.collect()
    t0 = time.thread_time()
    drive(iter(frames), Decoder(linter=Linter()), *(() if sink is None else (sink,)))
    return time.thread_time() - t0, getattr(sink, "messages", 0)


class StalledClient:
    """Connects, subscribes to every channel, then never reads again (a frozen Foxglove tab)."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.ready = threading.Event()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)
        self.thread.start()
        self.ready.wait(10)

    async def _run(self) -> None:
        import websockets

        async with websockets.connect(self.url, subprotocols=["foxglove.sdk.v1"], max_size=None, max_queue=1,
                                      close_timeout=0.1) as ws:
            subs = []
            while True:
                # The server may advertise its channels in several messages: every one until it is quiet.
                try:
                    msg = json.loads(await asyncio.wait_for(ws.recv(), 0.3))
                except asyncio.TimeoutError:
                    if subs:
                        break
                    continue
                if msg["op"] == "advertise":
                    # One subscription id per channel (the same id twice is one subscription).
                    subs += [{"id": len(subs) + i + 1, "channelId": c["id"]} for i, c in enumerate(msg["channels"])]
            await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            await asyncio.sleep(0.2)
            ws.transport.pause_reading()  # stop reading: the server's socket and queue fill up
            self.ready.set()
            while not self.stop.is_set():
                await asyncio.sleep(0.05)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60_000, help="hexapod frames (about 5 messages each)")
    args = ap.parse_args()
    frames = hexapod_frames(args.frames)
    plan, channels = plan_of(frames)
    n = len(plan)
    size = sum(len(d) for _, _, d in plan)
    print(f"{n:,} messages ({size / 1e6:.1f} MB of JSON) on {len(channels)} channels")
    with tempfile.TemporaryDirectory() as tmp:
        a, b, c = (os.path.join(tmp, name) for name in ("bare.mcap", "sdk.mcap", "ours.mcap"))
        bare = min(bare_writer(plan, channels, a) for _ in range(3))
        sdk = min(sdk_writer(plan, channels, b) for _ in range(3))
        ours = min(sdk_as_mcap_sink(plan, channels, c) for _ in range(3))
        assert sdk_count(b) == n == sdk_count(c), (sdk_count(b), sdk_count(c), n)
        print(f"mcap Writer               {n / bare:12,.0f} msg/s  {os.path.getsize(a) / 1e6:6.1f} MB")
        print(f"foxglove MCAP, defaults   {n / sdk:12,.0f} msg/s  {os.path.getsize(b) / 1e6:6.1f} MB  "
              f"({bare / sdk:.2f}x the mcap Writer)")
        print(f"foxglove MCAP, as McapSink{n / ours:12,.0f} msg/s  {os.path.getsize(c) / 1e6:6.1f} MB  "
              f"({bare / ours:.2f}x the mcap Writer)")

    base, _ = min(drive_seconds(frames, lambda: None) for _ in range(2))
    print(f"decode+lint alone           {len(frames) / base:10,.0f} frames/s")
    none, msgs = min(drive_seconds(frames, lambda: FoxgloveSink("127.0.0.1", 0, source="b", baud=115200))
                     for _ in range(2))
    print(f"+ Foxglove, no client       {len(frames) / none:10,.0f} frames/s  ({msgs / none:,.0f} msg/s published)")
    sink = FoxgloveSink("127.0.0.1", 0, source="b", baud=115200)
    client = StalledClient(sink.ws_url)
    stalled, msgs = drive_seconds(frames, lambda: sink)
    client.stop.set()
    print(f"+ Foxglove, stalled client  {len(frames) / stalled:10,.0f} frames/s  ({msgs / stalled:,.0f} msg/s published)")


if __name__ == "__main__":
    main()
