"""Benchmark: capture -> MCAP conversion against the bare mcap Writer, and peak memory on big captures.

Run: python bench/convert.py [--frames N] [--big-mb 100] [--small-mb 10] [--no-rss]
Targets (issue 4): converting reaches at least 0.5 of the messages/s of the bare mcap Writer writing
the same number of messages of the same sizes, pre-encoded; converting a 100 MB capture peaks under
150 MB of RSS and no more than 20 % above a 10 MB one. Since issue 14 the file is written through the
Foxglove SDK's MCAP writer; the same messages through that writer alone are the second reference.
"""

from __future__ import annotations

import argparse
import gc
import io
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from traffic import hexapod_frames  # noqa: E402

from mcap.reader import make_reader  # noqa: E402
from mcap.writer import CompressionType, Writer  # noqa: E402

from rs30x_sniff.commands.convert import CHUNK_SIZE  # noqa: E402
from rs30x_sniff.sinks.mcap.writer import McapSink  # noqa: E402
from rs30x_sniff.sinks.pipeline import drive  # noqa: E402
from rs30x_sniff.lint import Linter  # noqa: E402
from rs30x_sniff.decode.decoder import Decoder  # noqa: E402


def run_convert(frames: list, lint: bool, columnar: bool = True) -> tuple[float, int, bytes]:
    """Seconds to convert ``frames`` (as the convert command does a file: columnar; a port: the record
    path), messages written, the file."""
    buf = io.BytesIO()
    gc.collect()
    t0 = time.perf_counter()
    with McapSink(buf, source="bench", baud=115200, time_base="capture", chunk_size=CHUNK_SIZE) as sink:
        drive(iter(frames), Decoder(linter=Linter() if lint else None, columnar=columnar), sink)
    return time.perf_counter() - t0, sink.messages, buf.getvalue()


def run_bare(blob: bytes) -> tuple[float, int]:
    """Seconds for the bare mcap Writer to write the same messages (same channels, sizes, times), pre-encoded."""
    reader = make_reader(io.BytesIO(blob))
    summary = reader.get_summary()
    plan = [(c.id, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)]
    out = io.BytesIO()
    gc.collect()
    t0 = time.perf_counter()
    w = Writer(out, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
    w.start()
    ids = {}
    for cid, ch in summary.channels.items():
        sch = summary.schemas[ch.schema_id]
        ids[cid] = w.register_channel(ch.topic, "json", w.register_schema(sch.name, sch.encoding, sch.data))
    add = w.add_message
    for cid, log_time, data in plan:
        add(ids[cid], log_time, data, log_time)
    w.finish()
    return time.perf_counter() - t0, len(plan)


def run_bare_sdk(blob: bytes) -> float:
    """Seconds for the SDK's MCAP writer alone (as McapSink drives it) to write the same messages, pre-encoded."""
    from foxglove_sdk import sdk_as_mcap_sink

    reader = make_reader(io.BytesIO(blob))
    summary = reader.get_summary()
    channels = {cid: (ch.topic, summary.schemas[ch.schema_id].name, summary.schemas[ch.schema_id].data)
                for cid, ch in summary.channels.items()}
    plan = [(c.id, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)]
    with tempfile.TemporaryDirectory() as d:
        return sdk_as_mcap_sink(plan, channels, str(Path(d) / "sdk.mcap"))


def write_capture(path: Path, megabytes: float) -> int:
    """A timestamped hex capture of hexapod traffic of about ``megabytes`` MB; returns its frame count."""
    block = hexapod_frames(7_000)  # 1,000 cycles of 20 ms: 20 s of traffic, repeated with shifted times
    period = 1_000 * 0.020
    target = int(megabytes * 1e6)
    size = frames = 0
    with open(path, "w") as f:
        rep = 0
        while size < target:
            lines = "".join(f"{t + rep * period:.6f} {d.hex(' ')}\n" for d, t in block)
            f.write(lines)
            size += len(lines)
            frames += len(block)
            rep += 1
    return frames


# The child reports its own high-water mark: ru_maxrss of a child would include the memory of this
# (large) process that it was forked from, since the figure survives exec; VmHWM does not.
_CHILD = """
import sys
from rs30x_sniff.cli import main
rc = main(sys.argv[1:])
with open("/proc/self/status") as f:
    hwm = next(line.split()[1] for line in f if line.startswith("VmHWM:"))
print(hwm, file=sys.stderr)
sys.exit(rc)
"""


def peak_rss_mb(capture: Path, out: Path) -> tuple[float, float]:
    """(peak RSS in MB, seconds) of `rs30x-sniff convert` on ``capture`` in a fresh child process."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _CHILD, "convert", str(capture), "-o", str(out), "--force"],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"convert failed on {capture} (exit {proc.returncode}): {proc.stderr.strip()}")
    return int(proc.stderr.split()[-1]) / 1024, time.perf_counter() - t0  # VmHWM is in kB


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300_000)
    ap.add_argument("--small-mb", type=float, default=10)
    ap.add_argument("--big-mb", type=float, default=100)
    ap.add_argument("--no-rss", action="store_true", help="skip the memory part")
    ap.add_argument("--no-speed", action="store_true", help="skip the messages/s part")
    args = ap.parse_args()

    if not args.no_speed:
        speed(args.frames)
    if not args.no_rss:
        memory(args.small_mb, args.big_mb)


def speed(n_frames: int) -> None:
    frames = hexapod_frames(n_frames)
    print(f"capture: {n_frames} frames, {sum(len(d) for d, _ in frames)} bytes, "
          f"{frames[-1][1]:.1f} s of hexapod traffic at 115200 bit/s")
    for lint, columnar in ((True, True), (False, True), (True, False)):
        secs, n, blob = run_convert(frames, lint, columnar)
        bare_secs, bare_n = run_bare(blob)
        sdk_secs = run_bare_sdk(blob)
        assert bare_n == n
        ours, bare = n / secs, bare_n / bare_secs
        path = "columnar path (a file)" if columnar else "record path (a port)"
        print(f"convert{'' if lint else ' --no-lint'}, {path}: {n} messages in {secs:.2f} s = {ours:,.0f} msg/s; "
              f"bare mcap Writer: {bare_secs:.2f} s = {bare:,.0f} msg/s; ratio {ours / bare:.2f} (target >= 0.5); "
              f"bare SDK writer: {sdk_secs:.2f} s = {n / sdk_secs:,.0f} msg/s, ratio {sdk_secs / secs:.2f}; "
              f"{len(blob) / 1e6:.1f} MB written")
        del blob


def memory(small_mb: float, big_mb: float) -> None:
    with tempfile.TemporaryDirectory() as d:
        results = {}
        for mb in (small_mb, big_mb):
            cap = Path(d) / f"cap{mb:g}.thex"
            n = write_capture(cap, mb)
            rss, secs = peak_rss_mb(cap, Path(d) / "out.mcap")
            results[mb] = rss
            print(f"convert {cap.stat().st_size / 1e6:.0f} MB timestamped capture ({n} frames): peak RSS "
                  f"{rss:.1f} MB in {secs:.0f} s, MCAP {(Path(d) / 'out.mcap').stat().st_size / 1e6:.0f} MB")
            cap.unlink()
        small, big = results[small_mb], results[big_mb]
        print(f"peak RSS {big_mb:g} MB vs {small_mb:g} MB: {big:.1f} / {small:.1f} MB = {big / small:.2f} "
              f"(targets: < 150 MB, ratio <= 1.20)")


if __name__ == "__main__":
    main()
