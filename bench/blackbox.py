"""The black box's cost: `record` with triggers and a ring against a bare pyserial loop, on one saturated pty.

The simulator plays a scenario onto a pty at its baud-rate pacing (230400 baud, the hexapod: the bus near
full) once per reader: a bare pyserial loop that appends what `in_waiting` says to a file (the floor: what
reading the port costs at all); `record` with triggers on records, a pre-trigger ring and windows saved to a
folder (the black box); the same with `sev>=error` too, a trigger on findings, which lints the bus as it goes;
and plain `record` to one MCAP (for reference). Each reader's CPU time (with its children: the port's reader
process) is taken from /proc while the bytes flow, and its resident memory every half second (flat: bounded by
--pre).

Target (issue 26): the black box at most 1.5x the bare loop's CPU; memory flat over the run (bounded by
--pre: the ring, plus about 50 MB of interpreter and libraries).
Run: .venv/bin/python bench/blackbox.py [--duration 30] [--baud 230400] [--scenario hexapod]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import tty
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rs30x_sniff.protocol.wire import byte_time  # noqa: E402
from rs30x_sniff.sim import run  # noqa: E402

# The floor and the /proc readings are bench/live.py's: one bare loop and one way of counting CPU and memory.
from live import BARE_LOOP, played  # noqa: E402  (bench/ is on the path: run as a script)


def measure(cmd: list[str], ready: Path | None, chunks, master: int, baud: int) -> dict:
    """Start ``cmd``, wait until it reads the port (``ready`` exists, or it prints "ready"), play the chunks,
    and return its CPU seconds over the playing, the wall time and its memory samples."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        if ready is None:
            assert proc.stdout.readline().strip() == b"ready", proc.stderr.read().decode()
        else:
            while not ready.exists():
                if proc.poll() is not None:
                    raise SystemExit(proc.stderr.read().decode())
                time.sleep(0.02)
        time.sleep(0.5)  # its start-up is not what is measured
        cpu, _, wall, rss = played(proc.pid, chunks, master, baud)
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=60)
    return {"cpu": cpu, "wall": wall, "rss": rss, "stderr": err.decode()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=30.0, help="simulated (and real) seconds per reader")
    ap.add_argument("--baud", type=int, default=230400)
    ap.add_argument("--scenario", default="hexapod")
    ap.add_argument("--trigger", action="append", default=None,
                    help="the black box's triggers on records (default: present_temperature>70, 'id:3 latency>5ms')")
    args = ap.parse_args()
    triggers = args.trigger or ["present_temperature>70", "id:3 latency>5ms"]
    chunks = list(run(args.scenario, baud=args.baud, duration=args.duration))
    total = sum(len(d) for d, _ in chunks)
    span = chunks[-1][1] + len(chunks[-1][0]) * byte_time(args.baud)
    tmp = Path(tempfile.mkdtemp(prefix="blackbox-"))
    master, slave = os.openpty()
    tty.setraw(slave)
    port = os.ttyname(slave)
    py = sys.executable
    runs = {
        "bare pyserial loop": ([py, "-c", BARE_LOOP, port, str(args.baud), str(tmp / "bare.bin")], None),
        "record, triggers + ring": ([py, "-m", "rs30x_sniff", "record", port, "--baud", str(args.baud),
                                     "-o", str(tmp / "windows") + "/", "--pre", "60s", "--post", "10s",
                                     *[a for t in triggers for a in ("--trigger", t)]],
                                    tmp / "windows"),
        "record, + sev>=error (lints)": ([py, "-m", "rs30x_sniff", "record", port, "--baud", str(args.baud),
                                          "-o", str(tmp / "windows-lint") + "/", "--pre", "60s", "--post", "10s",
                                          *[a for t in [*triggers, "sev>=error"] for a in ("--trigger", t)]],
                                         tmp / "windows-lint"),
        "record, plain MCAP": ([py, "-m", "rs30x_sniff", "record", port, "--baud", str(args.baud),
                                "-o", str(tmp / "plain.mcap")], tmp / "plain.mcap"),
    }
    got = {}
    for name, (cmd, ready) in runs.items():
        got[name] = measure(cmd, ready, chunks, master, args.baud)
    os.close(master)
    os.close(slave)
    print(f"{args.scenario} at {args.baud} baud, {args.duration:g} s per reader: {total:,} bytes, "
          f"bus load {total * byte_time(args.baud) / span * 100:.0f} %")
    floor = got["bare pyserial loop"]["cpu"]
    for name, r in got.items():
        rss = r["rss"]
        mem = f"RSS {rss[0]:.0f} -> {rss[-1]:.0f} MB (max {max(rss):.0f})" if rss else "RSS -"
        print(f"  {name:30s} CPU {r['cpu']:6.2f} s = {r['cpu'] / r['wall'] * 100:5.1f} % of a core, "
              f"{r['cpu'] / floor:4.2f}x the bare loop; {mem}")
    print("target: record with triggers + ring <= 1.50x the bare loop; memory flat")
    return 0


if __name__ == "__main__":
    sys.exit(main())
