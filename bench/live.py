"""Live capture under load: the simulator saturates a pty at 230400 baud while `record --print` reads it.

Prints bytes sent and recorded (target: equal), the recorder's CPU use (target: under 25 % of one
core) and the delay from a frame's arrival on the pty to its decoded line on the recorder's stdout
(p50, p99). Run: .venv/bin/python bench/live.py [--duration 60] [--baud 230400] [--no-lint]
"""

from __future__ import annotations

import argparse
import bisect
import os
import resource
import select
import signal
import subprocess
import sys
import tempfile
import threading
import time
import tty
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rs30x_sniff.sources.mcap_reader import read_mcap_raw  # noqa: E402
from rs30x_sniff.sim import run  # noqa: E402
from rs30x_sniff.sim.port import play  # noqa: E402
from rs30x_sniff.protocol.wire import byte_time  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a running process so far (Linux /proc)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(q * len(s)))] if s else float("nan")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0, help="simulated (and real) seconds (default 60)")
    ap.add_argument("--baud", type=int, default=230400)
    ap.add_argument("--scenario", default="hexapod")
    ap.add_argument("--no-lint", action="store_true", help="record without the linter")
    args = ap.parse_args()

    chunks = list(run(args.scenario, baud=args.baud, duration=args.duration))
    total = sum(len(d) for d, _ in chunks)
    span = chunks[-1][1] + len(chunks[-1][0]) * byte_time(args.baud)
    master, slave = os.openpty()
    tty.setraw(slave)
    out = Path(tempfile.mkdtemp()) / "live.mcap"
    cmd = [sys.executable, "-m", "rs30x_sniff", "record", os.ttyname(slave), "-o", str(out), "--print",
           "--baud", str(args.baud)] + (["--no-lint"] if args.no_lint else [])
    t_spawn = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    while not out.exists():
        if proc.poll() is not None:
            print(proc.stderr.read().decode(), file=sys.stderr)
            return 1
        time.sleep(0.02)
    time.sleep(0.2)

    writes_off: list[int] = []
    writes_t: list[float] = []

    def on_write(offset: int, when: float) -> None:
        writes_off.append(offset)
        writes_t.append(when)

    result = {}

    def writer() -> None:
        result["sent"] = play(chunks, lambda b: os.write(master, b), on_write=on_write)

    cpu0 = cpu_seconds(proc.pid)
    t0 = time.monotonic()
    th = threading.Thread(target=writer)
    th.start()
    lines: list[tuple[float, str]] = []
    buf = b""
    fd = proc.stdout.fileno()
    stop_at = None
    while True:
        if stop_at is None and not th.is_alive():
            stop_at = time.monotonic() + 1.0
            cpu1, t1 = cpu_seconds(proc.pid), time.monotonic()
        if stop_at is not None and time.monotonic() >= stop_at:
            break
        r, _, _ = select.select([fd], [], [], 0.05)
        if r:
            now = time.monotonic()
            data = os.read(fd, 1 << 16)
            if not data:
                break
            buf += data
            *complete, buf = buf.split(b"\n")
            lines += [(now, ln.decode()) for ln in complete]
    proc.send_signal(signal.SIGINT)
    rest, err = proc.communicate(timeout=60)
    t_end = time.monotonic()
    lines += [(time.monotonic(), ln) for ln in (buf + rest).decode().splitlines()]
    os.close(master)
    os.close(slave)

    recorded = sum(len(d) for d, _ in read_mcap_raw(str(out)))
    delays, reply_delays = [], []
    for when, line in lines:
        try:
            off = int(line.split("@", 1)[1].split()[0])
        except (IndexError, ValueError):
            continue
        k = bisect.bisect_right(writes_off, off) - 1
        if k < 0 or when - writes_t[k] > 30:  # lines printed after the stop are not live figures
            continue
        d = when - writes_t[k]
        delays.append(d)
        if " servo " in line or " LONG " in line:  # not held back waiting for a reply
            reply_delays.append(d)

    window = t1 - t0
    print(f"scenario {args.scenario} at {args.baud} baud for {args.duration:g} s "
          f"(lint {'off' if args.no_lint else 'on'})")
    print(f"bus load            : {total * byte_time(args.baud) / span * 100:.1f} % of the line")
    print(f"bytes sent          : {result['sent']:,}")
    print(f"bytes recorded      : {recorded:,}  ({'equal' if recorded == result['sent'] else 'DIFFERENT'})")
    print(f"decoded lines       : {len(lines):,}")
    print(f"recorder CPU        : {(cpu1 - cpu0) / window * 100:.1f} % of one core while capturing "
          f"({cpu1 - cpu0:.2f} s in {window:.1f} s); whole run incl. start-up and finish "
          f"{cpu_children():.2f} s in {t_end - t_spawn:.1f} s")
    print(f"arrival -> line     : p50 {pct(delays, 0.5) * 1e3:.2f} ms, p99 {pct(delays, 0.99) * 1e3:.2f} ms "
          f"(all lines; requests wait for their reply)")
    print(f"  returns and longs : p50 {pct(reply_delays, 0.5) * 1e3:.2f} ms, p99 {pct(reply_delays, 0.99) * 1e3:.2f} ms")
    print(f"recorder said       : {err.decode().strip()}")
    return 0 if recorded == result["sent"] else 1


def cpu_children() -> float:
    """CPU seconds of finished children: the recorder is this bench's only child."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


if __name__ == "__main__":
    sys.exit(main())
