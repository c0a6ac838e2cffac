"""Logic captures for the sigrok plug-in's tests: many inputs on one .sr line, sigrok-cli and the reference runs."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from rs30x_sniff.protocol.wire import byte_time
from rs30x_sniff.sim import SCENARIOS, run
from rs30x_sniff.sources.captures import read_capture
from rs30x_sniff.sources.uart import encode
from tests.conftest import CAPTURES

SIGROK_CLI = shutil.which("sigrok-cli")
RATE = 1_000_000   # samples per second: 8.7 samples per bit at 115200 bit/s
BAUD = 115200
PAUSE = 0.02       # idle line between two inputs (s): far more than a frame's gap (20 byte times, 1.7 ms)
SIM_SECONDS = 1.0  # each simulator scenario's length

Chunks = list[tuple[bytes, float | None]]


def inputs() -> list[tuple[str, Chunks]]:
    """The differential test's inputs: every simulator scenario, the manual's examples and the bundled captures."""
    out: list[tuple[str, Chunks]] = [(f"sim:{name}", list(run(name, baud=BAUD, duration=SIM_SECONDS)))
                                     for name in SCENARIOS]
    files = [CAPTURES / "manual-examples.hex", CAPTURES / "session-mixed.thex",
             *sorted((CAPTURES / "lint").glob("*.hex")), *sorted((CAPTURES / "lint").glob("*.thex"))]
    for path in files:
        out.append((str(path.relative_to(CAPTURES)), list(read_capture(str(path), warn=lambda _msg: None))))
    return out


def lay_end_to_end(named: list[tuple[str, Chunks]], baud: int = BAUD,
                   pause: float = PAUSE) -> tuple[Chunks, list[tuple[str, float, float]]]:
    """One timed stream of all inputs, each starting ``pause`` after the previous one's last stop bit (its own
    times kept relative to its first chunk; untimed bytes back to back), and where each input lies (s)."""
    bt = byte_time(baud)
    stream: Chunks = []
    spans = []
    t_next = 0.0
    for name, chunks in named:
        base = t_next + pause
        first = next((t for _, t in chunks if t is not None), None)
        begin = None
        for data, t in chunks:
            if not data:
                continue
            at = base + (t - first) if t is not None else t_next
            at = max(at, t_next, base)
            begin = at if begin is None else begin
            stream.append((data, at))
            t_next = at + len(data) * bt
        spans.append((name, base if begin is None else begin, t_next))
        t_next = max(t_next, base)
    return stream, spans


def write_sr(path: Path, chunks: Chunks, *, rate: int = RATE, baud: int = BAUD, trail: float = PAUSE,
             tx: Chunks | None = None, broken_stop: list[tuple[float, int]] = ()) -> Path:
    """A .sr of ``chunks`` on D0 (and ``tx`` on D1 if given) made by sigrok-cli's binary input, as
    captures/foreign/sigrok.md makes its sample; ``broken_stop``: (chunk time, byte index) of D0 bytes whose
    stop bit is held low (a framing error)."""
    lead = 0.001
    d0 = encode(chunks, rate, baud, lead=lead, trail=trail)
    for t, k in broken_stop:
        stop = lead + t + (k * 10 + 9) / baud  # 8N1: the stop bit is a byte's tenth bit
        d0[int(round(stop * rate)):int(round((stop + 1 / baud) * rate))] = False
    lines = [d0]
    if tx is not None:
        d1 = encode(tx, rate, baud, lead=lead, trail=trail)
        n = max(len(d0), len(d1))
        lines = [np.pad(x, (0, n - len(x)), constant_values=True) for x in (d0, d1)]
    raw = np.zeros(len(lines[0]), np.uint8)
    for k, line in enumerate(lines):
        raw |= line.astype(np.uint8) << k
    binary = path.with_suffix(".bin")
    raw.tofile(binary)
    names = ",".join(f"{k}=D{k}" for k in range(len(lines)))
    subprocess.run([SIGROK_CLI, "-I", f"binary:numchannels={len(lines)}:samplerate={rate}", "-i", str(binary),
                    "-C", names, "-o", str(path)], check=True, capture_output=True)
    binary.unlink()
    return path


def sigrok(sr: Path, decoders: Path, stack: str, *args: str, env: dict | None = None) -> bytes:
    """sigrok-cli run on ``sr`` with the decoder stack ``stack``, our plug-in found in ``decoders``: its stdout."""
    full_env = {**os.environ, **(env or {}), "SIGROKDECODE_DIR": str(decoders)}
    done = subprocess.run([SIGROK_CLI, "-i", str(sr), "-P", stack, *args], env=full_env,
                          capture_output=True, timeout=300)
    if done.returncode != 0 or b"Traceback" in done.stderr or b"rror" in done.stderr:
        raise AssertionError(f"sigrok-cli failed ({done.returncode}): {done.stderr.decode(errors='replace')}")
    return done.stdout


def frames_json(sr: Path, decoders: Path, stack: str = f"uart:rx=D0:baudrate={BAUD},rs30x", *opts: str,
                env: dict | None = None) -> list[dict]:
    """Our decoder's frames: its binary output 'frames' (JSON lines) as sigrok-cli writes it."""
    out = sigrok(sr, decoders, stack, "-B", "rs30x=frames", *opts, env=env)
    return [json.loads(line) for line in out.decode("utf-8").splitlines() if line.strip()]


def annotations(sr: Path, decoders: Path, rows: str, stack: str = f"uart:rx=D0:baudrate={BAUD},rs30x",
                env: dict | None = None) -> list[tuple[int, int, str]]:
    """Our decoder's annotations of ``rows`` (sigrok-cli's -A): (start sample, end sample, text)."""
    out = sigrok(sr, decoders, stack, "-A", f"rs30x={rows}", "--protocol-decoder-samplenum", env=env)
    found = []
    for line in out.decode("utf-8").splitlines():
        span, _, rest = line.partition(" ")
        ss, _, es = span.partition("-")
        _name, _, text = rest.partition(": ")
        found.append((int(ss), int(es), text))
    return found


def reference(sr: Path, *args: str, env: dict | None = None) -> list[dict]:
    """`rs30x-sniff decode --format jsonl` of the same .sr: the events the plug-in must agree with."""
    done = subprocess.run([sys.executable, "-m", "rs30x_sniff", "decode", str(sr), "--channel", "D0", "--baud",
                           str(BAUD), "--format", "jsonl", "--no-lint", *args],
                          env={**os.environ, **(env or {})}, capture_output=True, text=True, check=True, timeout=300)
    return [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
