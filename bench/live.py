"""The live path's cost and timing: each reader of a port against a bare pyserial loop, and latencies from a pty.

Cost (issue 31, 5). The simulator plays a scenario (the hexapod at 230400 baud: the bus about 83 % busy) onto one
pty pair, once per reader, one after the other: a bare pyserial loop that appends what `in_waiting` says to a
file (the floor: what reading the port costs at all); plain `record` to one MCAP; `record --print` (its lines
read from a pipe); `monitor` on the port, in a terminal of its own (a pty, 160x48, its screen read and dropped).
Each reader's CPU time (with its children: the port's reader process) is taken from /proc over the playing, its
resident memory every half second, and the bytes it kept are checked.
Targets, as ratios to the bare loop in the same run: record <= 1.5x, record --print <= 2.5x, monitor <= 3x;
memory flat (the second half's peak at most 2 % over the first half's). A run of ten minutes or more also prints
the median RSS of each tenth, which says when it grew.

Timing (issue 31, 4). The docs' "No hardware? Simulate the bus" recipe: `simulate --port` onto one end of a socat
pty pair, `record` on the other; `info` of the recording against `info` of the same scenario written to a file.
Target: at least 80 % of the replies timed, with p50 within 0.15 ms of the file's. (The timing needs the
machine's scheduler to wake the writer and the reader within about 0.05 ms: on a loaded machine it is not met.)

Run: .venv/bin/python bench/live.py [--duration 15] [--baud 230400] [--no-monitor] [--no-latency] [--no-cost]
     [--only bare,record]
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import termios
import threading
import time
import tty
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rs30x_sniff.protocol.wire import byte_time  # noqa: E402
from rs30x_sniff.sim import run  # noqa: E402
from rs30x_sniff.sim.port import play  # noqa: E402
from rs30x_sniff.sources.mcap_reader import read_mcap_raw  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")
PAGE = os.sysconf("SC_PAGE_SIZE")
PY = sys.executable
CLI = [PY, "-m", "rs30x_sniff"]

# The floor: read what has arrived (at least one byte, waiting for it), append it to a file.
BARE_LOOP = """
import sys, serial
ser = serial.serial_for_url(sys.argv[1], baudrate=int(sys.argv[2]), timeout=0.05)
with open(sys.argv[3], "ab", buffering=0) as out:
    print("ready", flush=True)
    while True:
        data = ser.read(ser.in_waiting or 1)
        if data:
            out.write(data)
"""


def tree(pid: int) -> list[int]:
    """``pid`` and its descendants (Linux /proc)."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        try:
            for task in os.listdir(f"/proc/{p}/task"):
                with open(f"/proc/{p}/task/{task}/children") as f:
                    todo += [int(c) for c in f.read().split()]
        except OSError:
            pass
    return out


def cpu_seconds(pid: int, children: bool = True) -> float:
    """User + system CPU time of a running process (and its running children) so far."""
    total = 0
    for p in tree(pid) if children else [pid]:
        try:
            with open(f"/proc/{p}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            total += int(fields[11]) + int(fields[12])
        except OSError:
            pass
    return total / TICK


def rss_mb(pid: int) -> float:
    total = 0
    for p in tree(pid):
        try:
            with open(f"/proc/{p}/statm") as f:
                total += int(f.read().split()[1])
        except OSError:
            pass
    return total * PAGE / 1e6


def rss_by_tenth(rss: list[float]) -> str:
    """The median of each tenth of ``rss``'s samples, in order: a level a late batch's brief peak does not move."""
    n = len(rss)
    tenths = [sorted(rss[i * n // 10:(i + 1) * n // 10]) for i in range(10)]
    return " ".join(f"{t[len(t) // 2]:.1f}" for t in tenths if t)


def drain(fd: int) -> threading.Thread:
    """Read and drop what ``fd`` gives until it closes (a reader's stdout, a terminal's screen)."""
    def loop() -> None:
        try:
            while os.read(fd, 1 << 16):
                pass
        except OSError:
            pass

    th = threading.Thread(target=loop, daemon=True)
    th.start()
    return th


WRITER_LATE = 0.002  # a write this much past its time makes a reply B006 names (its latency-margin)


def played(pid: int, chunks, master: int, baud: int) -> tuple[float, float, float, list[float], list[float]]:
    """Play ``chunks`` onto the pty's ``master`` at the line rate while the reader ``pid`` reads it: its CPU seconds
    (with its children, and its own), the wall time, its memory every half second, and how late the writer woke
    for each write it waited for (a late reply on the pty is the writer's, and B006 rightly names it)."""
    rss: list[float] = []
    late: list[float] = []

    def sleep(seconds: float) -> None:
        woke = time.monotonic() + seconds
        time.sleep(seconds)
        late.append(time.monotonic() - woke)

    done = threading.Event()

    def sample() -> None:
        while not done.wait(0.5):
            rss.append(rss_mb(pid))

    sampler = threading.Thread(target=sample)
    sampler.start()
    cpu0, own0, t0 = cpu_seconds(pid), cpu_seconds(pid, False), time.monotonic()
    play(chunks, lambda b: os.write(master, b), byte_seconds=byte_time(baud), sleep=sleep)
    time.sleep(0.3)  # the last bytes read
    cpu1, own1, t1 = cpu_seconds(pid), cpu_seconds(pid, False), time.monotonic()
    done.set()
    sampler.join()
    return cpu1 - cpu0, own1 - own0, t1 - t0, rss, late


def measure(name: str, cmd: list[str], ready, chunks, master: int, baud: int, terminal: bool = False) -> dict:
    """Start ``cmd``, wait until it reads the port (``ready()``), play the chunks, and return its CPU seconds over
    the playing, the wall time and its memory samples."""
    term = None
    if terminal:  # a screen of its own: stdin/stdout/stderr on a pty, 160x48
        term_master, term_slave = os.openpty()
        fcntl.ioctl(term_slave, termios.TIOCSWINSZ, struct.pack("HHHH", 48, 160, 0, 0))
        env = dict(os.environ, TERM="xterm-256color", COLUMNS="160", LINES="48")
        proc = subprocess.Popen(cmd, stdin=term_slave, stdout=term_slave, stderr=term_slave, env=env,
                                start_new_session=True)
        os.close(term_slave)
        term = drain(term_master)
    else:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        drain(proc.stderr.fileno())
    try:
        ready(proc)
        if not terminal:
            drain(proc.stdout.fileno())  # record --print's lines
        time.sleep(0.5)  # its start-up is not what is measured
        cpu, own, wall, rss, late = played(proc.pid, chunks, master, baud)
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if term is not None:
            os.close(term_master)
    return {"name": name, "cpu": cpu, "children": cpu - own, "wall": wall, "rss": rss, "code": proc.returncode,
            "late": late}


def cost(args: argparse.Namespace) -> int:
    chunks = list(run(args.scenario, baud=args.baud, duration=args.duration))
    total = sum(len(d) for d, _ in chunks)
    span = chunks[-1][1] + len(chunks[-1][0]) * byte_time(args.baud)
    tmp = Path(tempfile.mkdtemp(prefix="live-"))
    master, slave = os.openpty()
    tty.setraw(slave)
    port = os.ttyname(slave)
    baud = str(args.baud)

    def printed_ready(proc):
        assert proc.stdout.readline().strip() == b"ready"

    def file_ready(path: Path):
        def wait(proc):
            while not path.exists():
                if proc.poll() is not None:
                    raise SystemExit(f"{path.name}: the reader ended ({proc.returncode})")
                time.sleep(0.02)
        return wait

    def started(proc):
        time.sleep(4.0)  # the monitor's screen is up and its port open
        if proc.poll() is not None:
            raise SystemExit(f"monitor ended ({proc.returncode})")

    runs = [
        ("bare pyserial loop", [PY, "-c", BARE_LOOP, port, baud, str(tmp / "bare.bin")], printed_ready, False, None),
        ("record", [*CLI, "record", port, "--baud", baud, "-o", str(tmp / "plain.mcap")],
         file_ready(tmp / "plain.mcap"), False, tmp / "plain.mcap"),
        ("record --print", [*CLI, "record", port, "--baud", baud, "--print", "-o", str(tmp / "print.mcap")],
         file_ready(tmp / "print.mcap"), False, tmp / "print.mcap"),
    ]
    if not args.no_monitor:
        runs.append(("monitor", [*CLI, "monitor", port, "--baud", baud], started, True, None))
    if args.only:
        keep = set(args.only.split(","))
        runs = [r for r in runs if r[0] in keep or (r[0].startswith("bare") and "bare" in keep)]
        if not runs:
            raise SystemExit(f"--only {args.only}: no such reader (bare, record, record --print, monitor)")
    got = []
    for name, cmd, ready, terminal, out in runs:
        r = measure(name, cmd, ready, chunks, master, args.baud, terminal)
        if out is not None:
            r["kept"] = sum(len(d) for d, _ in read_mcap_raw(str(out)))
        elif name.startswith("bare"):
            r["kept"] = (tmp / "bare.bin").stat().st_size
        got.append(r)
    os.close(master)
    os.close(slave)
    shutil.rmtree(tmp, ignore_errors=True)
    print(f"{args.scenario} at {args.baud} baud, {args.duration:g} s per reader: {total:,} bytes, "
          f"bus load {total * byte_time(args.baud) / span * 100:.0f} %")
    floor = got[0]["cpu"] if got[0]["name"].startswith("bare") else None  # no floor, no ratios
    targets = {"record": 1.5, "record --print": 2.5, "monitor": 3.0}
    ok = True
    for r in got:
        rss = r["rss"]
        mem = f"RSS {rss[0]:.0f} -> {rss[-1]:.0f} MB (max {max(rss):.0f})" if rss else "RSS -"
        if len(rss) >= 8:  # flat: the last half grows no more than 2 % over the first half's peak
            half = len(rss) // 2
            first, last = max(rss[:half]), max(rss[half:])
            mem += f", {'flat' if last <= first * 1.02 else 'GROWING'} (peak {first:.0f} MB in the first half, " \
                   f"{last:.0f} MB in the second)"
        kept = r.get("kept")
        kept_s = "" if kept is None else f"; kept {'every byte' if kept == total else f'{kept:,} of {total:,} B'}"
        target = None if floor is None else targets.get(r["name"])
        verdict = "" if target is None else (f" (target <= {target}x: {'met' if r['cpu'] / floor <= target else 'NOT met'})")
        if target is not None and r["cpu"] / floor > target:
            ok = False
        reader = f" (its port reader {r['children']:.2f} s)" if r["children"] > 0 else ""
        ratio = "" if floor is None else f", {r['cpu'] / floor:4.2f}x the bare loop{verdict}"
        late = [x for x in r["late"] if x > WRITER_LATE]
        writer = (f"; the writer woke over {WRITER_LATE * 1e3:g} ms late {len(late)} times (max {max(late) * 1e3:.1f} ms:"
                  " a late reply on the pty, which B006 names)" if late else "")
        print(f"  {r['name']:20s} CPU {r['cpu']:6.2f} s{reader} = {r['cpu'] / r['wall'] * 100:5.1f} % of a core"
              f"{ratio}; {mem}{kept_s}{writer}")
        if len(rss) >= 1200:  # ten minutes and more: where it grew (a peak alone does not say when)
            print(f"  {'':20s} RSS by tenth of the run (median, MB): {rss_by_tenth(rss)}")
    return 0 if ok else 1


def info_latency(path: str) -> dict:
    out = subprocess.run([*CLI, "info", path, "--format", "json"], capture_output=True, text=True, check=True).stdout
    d = json.loads(out)
    return {"replies": d["by_type"].get("return", 0), "timed": d["latency_s"]["count"],
            "p50": d["latency_s"].get("p50")}


def latency(args: argparse.Namespace) -> int:
    """The docs' recipe, on a socat pty pair: `simulate --port` on one end, `record` on the other."""
    if shutil.which("socat") is None:
        print("latency: needs socat")
        return 0
    tmp = Path(tempfile.mkdtemp(prefix="live-latency-"))
    a, b = tmp / "a", tmp / "b"
    subprocess.run([*CLI, "simulate", "--scenario", args.latency_scenario, "-o", str(tmp / "file.mcap")],
                   check=True, capture_output=True)
    socat = subprocess.Popen(["socat", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"],
                             stderr=subprocess.DEVNULL)
    try:
        while not (a.exists() and b.exists()):
            time.sleep(0.05)
        live = tmp / "live.mcap"
        rec = subprocess.Popen([*CLI, "record", str(b), "-o", str(live)], stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE)
        while not live.exists():
            time.sleep(0.05)
        time.sleep(0.5)
        subprocess.run([*CLI, "simulate", "--scenario", args.latency_scenario, "--port", str(a)], check=True,
                       capture_output=True)
        time.sleep(0.5)
        rec.send_signal(signal.SIGINT)
        rec.communicate(timeout=60)
    finally:
        socat.terminate()
        socat.wait(5)
    f, lv = info_latency(str(tmp / "file.mcap")), info_latency(str(live))
    shutil.rmtree(tmp, ignore_errors=True)
    share = lv["timed"] / lv["replies"] if lv["replies"] else 0.0
    diff = None if lv["p50"] is None or f["p50"] is None else abs(lv["p50"] - f["p50"])
    met = share >= 0.8 and diff is not None and diff <= 0.15e-3
    p50 = "-" if lv["p50"] is None else f"{lv['p50'] * 1e3:.3f} ms"
    print(f"latency, {args.latency_scenario} through `simulate --port` and `record` on a socat pty pair: "
          f"{lv['timed']} of {lv['replies']} replies timed ({share * 100:.0f} %), p50 {p50}; "
          f"the file: p50 {f['p50'] * 1e3:.3f} ms (target >= 80 % timed, p50 within 0.15 ms: "
          f"{'met' if met else 'NOT met'}; load average {os.getloadavg()[0]:.1f})")
    return 0 if met else 1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=15.0, help="simulated (and real) seconds per reader")
    ap.add_argument("--baud", type=int, default=230400)
    ap.add_argument("--scenario", default="hexapod")
    ap.add_argument("--latency-scenario", default="hexapod", help="the timing check's scenario (at 115200)")
    ap.add_argument("--no-monitor", action="store_true", help="leave out the monitor")
    ap.add_argument("--only", metavar="NAMES", help="these readers alone, by name, comma-separated (bare, record, "
                                                    "'record --print', monitor); without bare, no ratios: an "
                                                    "hour of `record`'s memory is --duration 3600 --only record")
    ap.add_argument("--no-cost", action="store_true", help="only the timing check")
    ap.add_argument("--no-latency", action="store_true", help="only the cost")
    args = ap.parse_args()
    code = 0
    if not args.no_cost:
        code |= cost(args)
    if not args.no_latency:
        code |= latency(args)
    return code


if __name__ == "__main__":
    sys.exit(main())
