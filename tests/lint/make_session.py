"""Writes captures/session-mixed.thex (and docs/lint-example.md, its lint report): a realistic timestamped session with healthy traffic and some faults.

Run from the repository root: python tests/lint/make_session.py. A six-servo leg rig at 115200 bit/s:
start-up (model numbers, torque on), two seconds of gait (a long packet of goals every 20 ms and one
42-59 poll per cycle with its return), then a baud-rate change that is never applied. Faults are
placed at fixed cycles; `rs30x-sniff lint captures/session-mixed.thex` finds them.
"""

from __future__ import annotations

import math
import random
from pathlib import Path

from rs30x_sniff.protocol.wire import byte_time, encode_long, encode_read, encode_return, encode_short

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "captures" / "session-mixed.thex"
DOC = ROOT / "docs" / "lint-example.md"
BT = byte_time(115200)
IDS = range(1, 7)


def status(pos: int, rng: random.Random, temp: int = 38) -> bytes:
    return (pos.to_bytes(2, "little", signed=True) + (2).to_bytes(2, "little")
            + rng.randint(-40, 40).to_bytes(2, "little", signed=True) + rng.randint(20, 300).to_bytes(2, "little")
            + temp.to_bytes(2, "little") + rng.randint(735, 745).to_bytes(2, "little") + bytes(6))


def build() -> list[tuple[float, bytes, str]]:
    rng = random.Random(3)
    out: list[tuple[float, bytes, str]] = []
    t = 0.5

    def put(frame: bytes, note: str = "", gap: float = 0.0002) -> None:
        nonlocal t
        out.append((t, frame, note))
        t += len(frame) * BT + gap

    # Start-up: ask each servo for addresses 0-29 (model number, ID, limits ...).
    for sid in IDS:
        put(encode_short(sid, 0x03, 0, b"", length=0, count=1), "", 0.0001)
        rom = bytearray(30)
        rom[0:2] = (0x3030).to_bytes(2, "little")
        rom[2], rom[4], rom[6] = 0x03, sid, 7
        rom[8:10] = (1500).to_bytes(2, "little", signed=True)
        rom[10:12] = (-1500).to_bytes(2, "little", signed=True)
        rom[14], rom[23], rom[24], rom[25], rom[26], rom[27] = 0x4D, 200, 2, 2, 8, 8
        rom[28:30] = (100).to_bytes(2, "little")
        put(encode_return(sid, 0, bytes(rom)), "start-up: ROM area of each servo" if sid == 1 else "")
    t += 0.05
    put(encode_short(255, 0, 0x24, b"\x01"), "torque on, all servos")
    t = math.ceil(t * 50) / 50
    poll = 1
    pos = {sid: 0 for sid in IDS}
    for cycle in range(100):
        t = max(t, 1.0 + cycle * 0.020)
        temp = 38
        for sid in IDS:
            pos[sid] = int(250 * math.sin(cycle / 12 + sid))
        long = encode_long(0x1E, [(sid, pos[sid].to_bytes(2, "little", signed=True) + (2).to_bytes(2, "little"))
                                  for sid in IDS])
        if cycle == 70:
            bad = bytearray(long)
            bad[12] ^= 0x10  # one bit flipped on the wire
            put(bytes(bad), "a bit flipped in the goal packet")
        else:
            put(long, "gait: goals for six servos every 20 ms" if cycle == 0 else "")
        if cycle == 60:
            put(bytes.fromhex("00 F0 00"), "noise on the line", 0.0003)
        if cycle == 80:
            put(encode_short(6, 0, 0x23, bytes((120,))), "max_torque 120 %: out of range")
        req = encode_short(poll, 0x09, 0, b"", length=0, count=1)
        if cycle == 20:
            put(req, "this poll is never answered", 0.0052)
            t = max(t, 1.0 + cycle * 0.020 + 0.012)
            poll = poll % 6 + 1
            continue
        if cycle == 35:
            put(req, "the host polls the next servo without waiting", 0.0002)
            poll = poll % 6 + 1
            req = encode_short(poll, 0x09, 0, b"", length=0, count=1)
        lat = 0.0001 + rng.random() * 0.00004
        if cycle == 45:
            lat = 0.0081
        put(req, "", lat)
        if 50 <= cycle <= 62 and poll == 3:
            temp = 68
        flags = 0x20 if temp >= 68 else 0
        note = "ID 3 runs hot: temperature alarm" if flags and cycle < 56 else ("a return 8 ms late" if cycle == 45 else "")
        put(encode_return(poll, 42, status(pos[poll], rng, temp), flags), note)
        poll = poll % 6 + 1
    t += 0.05
    put(encode_short(2, 0, 0x1E, (900).to_bytes(2, "little") + (5).to_bytes(2, "little")), "ID 2: 90 deg in 50 ms")
    t += 0.1
    put(encode_short(1, 0, 0x1C, (200).to_bytes(2, "little")), "punch 2.00 % on ID 1, then flash and reboot")
    put(encode_short(1, 0x40, 0xFF, b"", length=0, count=0), "", 0.004)
    put(encode_short(1, 0x20, 0xFF, b"", length=0, count=0), "rebooted 4 ms after the flash write")
    t += 0.1
    put(encode_short(5, 0, 0x06, b"\x09"), "ID 5 to 230400 bit/s, never flashed nor rebooted")
    put(encode_read(5, 0x06, 1), "", 0.0001)
    put(encode_return(5, 0x06, b"\x09"), "")
    # A second more of polling: the capture runs on long enough to show the change was never applied
    # (a capture that stopped right after the write could not tell, Q001).
    for k in range(20):
        t += 0.05
        put(encode_read(5, 42, 2), "still polled at the old rate" if k == 0 else "", 0.0001)
        put(encode_return(5, 42, pos[5].to_bytes(2, "little", signed=True)), "")
    return out


def write() -> None:
    lines = ["# A six-servo leg rig at 115200 bit/s: start-up, 2 s of gait, then a baud-rate change.",
             "# Timestamped hex: <seconds> <bytes>. Healthy traffic with a few faults; try:",
             "#   rs30x-sniff lint captures/session-mixed.thex",
             "# Written by tests/lint/make_session.py."]
    for t, frame, note in build():
        text = f"{t:.6f} {frame.hex(' ').upper()}"
        lines.append(f"{text}  # {note}" if note else text)
    OUT.write_text("\n".join(lines) + "\n")


def lint_example() -> str:
    """docs/lint-example.md: the lint report of the session, as a person running it from the root sees it."""
    import contextlib
    import io
    import os

    from rs30x_sniff.cli import main

    buf = io.StringIO()
    here = os.getcwd()
    os.chdir(ROOT)
    try:
        with contextlib.redirect_stdout(buf):
            code = main(["lint", "--isolated", "captures/session-mixed.thex"])
    finally:
        os.chdir(here)
    return f"""# `rs30x-sniff lint` on a recorded session

`captures/session-mixed.thex` is a timestamped capture of a six-servo leg rig at 115200 bit/s: start-up
(each servo's ROM area read back, torque on), two seconds of gait (a long packet of goals every 20 ms, one
42-59 poll per cycle with its return), then some configuration. Most of it is healthy; a few faults are
mixed in. Linting it:

```console
$ rs30x-sniff lint captures/session-mixed.thex
{buf.getvalue().rstrip()}
$ echo $?
{code}
```

Each finding names the file, the byte offset and capture time of the packet, the rule code and name, and
says what is wrong; the packet's bytes are under it. `rs30x-sniff rules CODE` explains a rule, and
`rs30x-sniff decode captures/session-mixed.thex` shows the same findings beside each packet. The exit
code is 1 because some findings are errors (`--fail-on error`, the default).

Both this page and the capture are written by `python tests/lint/make_session.py`; a test checks that
the page still matches what `lint` prints.
"""


if __name__ == "__main__":
    write()
    DOC.write_text(lint_example())
