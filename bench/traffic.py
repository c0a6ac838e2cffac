"""Realistic hexapod bus traffic for the benchmarks: long-packet goals at 50 Hz and round-robin polls."""

from __future__ import annotations

import math
import random

from rs30x_sniff.protocol.wire import byte_time, encode_long, encode_return, encode_short

SERVOS = 18
POLLS_PER_CYCLE = 3  # 42-59 polls fitted into each 20 ms cycle at 115200 baud


def hexapod_frames(frames: int, baud: int = 115200, seed: int = 0) -> list[tuple[bytes, float]]:
    """``frames`` frames as (bytes, start time) chunks: per 20 ms cycle one long packet of
    goal_position + goal_time to 18 servos, then POLLS_PER_CYCLE flag-09 polls with their returns."""
    rng = random.Random(seed)
    bt = byte_time(baud)
    out: list[tuple[bytes, float]] = []
    t = 0.0
    cycle = 0
    poll_id = 1
    while len(out) < frames:
        t0 = cycle * 0.020
        t = max(t, t0)
        records = []
        for sid in range(1, SERVOS + 1):
            angle = int(300 * math.sin(cycle / 25 + sid))
            records.append((sid, angle.to_bytes(2, "little", signed=True) + (2).to_bytes(2, "little")))
        frame = encode_long(30, records)
        out.append((frame, t))
        t += len(frame) * bt + 0.0002
        for _ in range(POLLS_PER_CYCLE):
            if len(out) >= frames:
                break
            req = encode_short(poll_id, 0x09, 0, b"", length=0, count=1)
            out.append((req, t))
            t += len(req) * bt + 0.0001 + rng.random() * 0.00005  # 100 us return delay (table 4.6 No. 7)
            if len(out) >= frames:
                break
            pos = int(300 * math.sin(cycle / 25 + poll_id))
            data = (pos.to_bytes(2, "little", signed=True) + (2).to_bytes(2, "little")
                    + rng.randint(-60, 60).to_bytes(2, "little", signed=True)
                    + rng.randint(5, 400).to_bytes(2, "little") + rng.randint(30, 45).to_bytes(2, "little")
                    + rng.randint(720, 760).to_bytes(2, "little") + bytes(6))
            ret = encode_return(poll_id, 42, data)
            out.append((ret, t))
            t += len(ret) * bt + 0.0002
            poll_id = poll_id % SERVOS + 1
        cycle += 1
    return out


def hexapod_bytes(frames: int, baud: int = 115200, seed: int = 0) -> bytes:
    """The same traffic as one byte string (no timestamps)."""
    return b"".join(d for d, _ in hexapod_frames(frames, baud, seed))


def bench_inputs(frames: int) -> tuple[list[tuple[bytes, float]], bytes, list[tuple[bytes, None]]]:
    """The benchmarks' three views of one capture: timestamped per-frame chunks, all the bytes, and
    the bytes in untimed 4 KiB blocks (as a file or serial reader delivers them)."""
    chunks = hexapod_frames(frames)
    data = b"".join(d for d, _ in chunks)
    return chunks, data, [(data[i:i + 4096], None) for i in range(0, len(data), 4096)]
