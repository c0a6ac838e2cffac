"""Benchmark: megasamples per second reading a sigrok .sr capture (zip, channel bits, 8N1 decode, chunks).

Run: python bench/sigrok.py [--seconds 10] [--rate 4000000] [--baud 115200] [--channels 8]
Target (issue 13): well above 10 MS/s; a 10 s capture at 4 MHz must not take minutes.

The capture is the simulator's hexapod, encoded as samples here and written the way sigrok-cli writes a
session (4 MiB logic chunks); with ``--sigrok-cli`` it is converted by sigrok-cli itself.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

from rs30x_sniff.sources.captures import read_capture
from rs30x_sniff.sources.uart import encode
from rs30x_sniff.decode.decoder import Decoder
from rs30x_sniff.sinks.pipeline import drive
from rs30x_sniff.sim import run
from rs30x_sniff.protocol.wire import BAUD_RATES

CHUNK = 4 << 20  # bytes per logic-1-N file, as sigrok-cli writes them


def simulated(baud: int, seconds: float) -> list[tuple[bytes, float]]:
    if baud in BAUD_RATES:
        return list(run("hexapod", baud=baud, duration=seconds))
    k = 115200 / baud  # a rate the servos cannot run at: the 115200 bus sped up
    return [(d, t * k) for d, t in run("hexapod", baud=115200, duration=seconds / k)]


def write_sr(path: Path, line: np.ndarray, rate: int, channels: int, use_cli: bool) -> None:
    units = line.astype(np.uint8)
    if channels > 1:
        units |= np.uint8(0xFE & ((1 << channels) - 1))  # the other probes idle high
    if use_cli:
        raw = path.with_suffix(".bin")
        units.tofile(raw)
        names = ",".join(f"{k}=D{k}" for k in range(channels))
        subprocess.run(["sigrok-cli", "-I", f"binary:numchannels={channels}:samplerate={rate}", "-i", str(raw),
                        "-C", names, "-o", str(path)], check=True)
        raw.unlink()
        return
    probes = "".join(f"probe{k + 1}=D{k}\n" for k in range(channels))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("version", "2")
        z.writestr("metadata", f"[global]\nsigrok version=0.5.2\n\n[device 1]\ncapturefile=logic-1\n"
                               f"total probes={channels}\nsamplerate={rate}\ntotal analog=0\n{probes}unitsize=1\n")
        data = units.tobytes()
        for n, i in enumerate(range(0, len(data), CHUNK), 1):
            z.writestr(f"logic-1-{n}", data[i:i + CHUNK])


def timed(label: str, samples: int, fn) -> float:
    t0 = time.perf_counter()
    out = fn()
    dt = time.perf_counter() - t0
    print(f"{label:<44} {dt:7.3f} s  {samples / dt / 1e6:8.1f} MS/s  ({out})")
    return dt


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rate", type=int, default=4_000_000)
    ap.add_argument("--baud", type=int, default=115200)
    ap.add_argument("--channels", type=int, default=8)
    ap.add_argument("--sigrok-cli", action="store_true", help="make the .sr with sigrok-cli (if installed)")
    args = ap.parse_args()
    use_cli = args.sigrok_cli and shutil.which("sigrok-cli") is not None

    chunks = simulated(args.baud, args.seconds)
    sent = sum(len(d) for d, _ in chunks)
    line = encode(chunks, args.rate, args.baud, lead=1e-3, trail=max(0.0, args.seconds - chunks[-1][1]))
    n = len(line)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.sr"
        write_sr(path, line, args.rate, args.channels, use_cli)
        del line
        size = path.stat().st_size
        print(f"{n / 1e6:.1f} Msamples ({n / args.rate:.2f} s at {args.rate / 1e6:g} MHz, {args.channels} channels), "
              f"{sent} bytes at {args.baud} bit/s on D0; .sr {size / 1e6:.2f} MB"
              f"{' (sigrok-cli)' if use_cli else ''}")

        def read(**options) -> str:
            got = sum(len(c[0]) for c in read_capture(str(path), options=options))
            assert got == sent, (got, sent)
            return f"{got} bytes"

        def pipeline() -> str:
            src = read_capture(str(path), options={"channel": "D0", "baud": args.baud})
            dec = drive(src, Decoder())
            return f"{dec.bytes_in} bytes decoded into records"

        timed(".sr -> chunks, --baud given", n, lambda: read(channel="D0", baud=args.baud))
        timed(".sr -> chunks, rate found from the samples", n, lambda: read())
        timed(".sr -> chunks -> decoder (framing, pairing)", n, pipeline)
    return 0


if __name__ == "__main__":
    sys.exit(main())
