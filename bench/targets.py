"""Benchmark: every target of issue 35 as whole processes, each a ratio to a floor measured in the same run.

Run: .venv/bin/python bench/targets.py [--runs 3] [--inputs DIR] [--only lint-random,info,...] [--allocator]
     [--live-minutes 10]

Each row prints what was run (the command and its floor), the best of --runs runs of each (command and floor in
turn, after a warm-up of each; a shared machine only adds time, so the best run is the least disturbed; the
median of the pairs is shown beside it), the target and whether it is met. Speed rows are
floor time / command time (1.0: as fast as the floor); start-up rows are seconds over `python -c pass`; memory rows
are the peak RSS of the 10 MB input over the 1 MB one (the same scenario, 300 s and 30 s of it).

Inputs (made once into --inputs, or a temporary directory; never into the tree):
  random.bin     300k random frames: a third long packets of goal position and time to the same 18 servos, a third
                 short writes, a third polls with their returns; random IDs, values and kinds (seeded), goal times
                 long enough for the servos' top speed (Q007 checks every long-packet record and finds nothing)
  hexapod.bin    300k frames of bench/traffic.py's hexapod (as bench/jsonl.py uses)
  hexapod300.thex, hexapod30.thex, tiny.thex
                 `rs30x-sniff simulate --scenario hexapod`, 300 s (about 10 MB), 30 s (about 1 MB), 0.05 s (38 lines):
                 RS304MD coxae and RS303MR femurs and tibias on one bus (two models), timestamped text
  big.thex       1M hexapod frames, timestamped (the monitor's row only)

The floors, each a `python -c` of its own: the split+XOR loop of bench/decode.py over a file's bytes; for a
timestamped capture, that loop after parsing each line's time and hex; for `decode --format jsonl`, bench/jsonl.py's
split+XOR+json.dumps loop. `convert` is timed in-process against the Foxglove SDK's MCAP writer writing the same
messages pre-encoded (bench/convert.py); `monitor` opening 1M frames headless (bench/monitor.py) against `lint` of
the same file as a process. Children run with their bytecode cached (PYTHONPYCACHEPREFIX in the inputs directory):
an installed package has its .pyc files, and a stale one would be compiled on every start.

--allocator adds rows for lint, info and decode with glibc's default thresholds (rs30x_sniff.allocator not called),
the same command with them set as the floor. --live-minutes N feeds N minutes of hexapod traffic through Decoder,
Linter and McapSink in a child process, as `record` does, with and without the thresholds, sampling RSS: the
slope says whether a long recording's memory grows because of them.
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from decode import bare_loop  # noqa: E402
from jsonl import BARE as JSONL_FLOOR  # noqa: E402
from traffic import hexapod_bytes, hexapod_frames  # noqa: E402

from rs30x_sniff.protocol.wire import encode_long, encode_return, encode_short  # noqa: E402

PY = sys.executable
CLI = [PY, "-m", "rs30x_sniff"]

# The split+XOR loop of bench/decode.py (bare_loop), over the bytes of a file: its own source, run as a script.
SPLIT_XOR = ("import sys\nfrom functools import reduce\nfrom operator import xor\n"
             + inspect.getsource(bare_loop) + "frames = bare_loop\n")
BINARY_FLOOR = SPLIT_XOR + 'print(frames(open(sys.argv[1], "rb").read()))\n'
# A timestamped capture: each line's time read as a float and its hex as bytes, then the same loop over the bytes.
TEXT_FLOOR = SPLIT_XOR + r'''
times, parts = [], []
with open(sys.argv[1]) as f:
    for line in f:
        t, _, text = line.partition(" ")
        times.append(float(t))
        parts.append(bytes.fromhex(text))
print(frames(b"".join(parts)), len(times))
'''
# `rs30x-sniff ARGS` with glibc's default thresholds: the allocator is not told (for --allocator's rows), and the
# same with it told, so the two differ in that alone.
ALLOCATOR_OFF = ("import sys\nimport rs30x_sniff.allocator as a\na.keep_large_buffers = lambda libc=None: False\n"
                 "from rs30x_sniff.cli import main\nsys.exit(main(sys.argv[1:]))\n")
ALLOCATOR_ON = "import sys\nfrom rs30x_sniff.cli import main\nsys.exit(main(sys.argv[1:]))\n"
# `rs30x-sniff ARGS` (the first argument: "on", or "off" for glibc's default thresholds), then its own peak RSS
# (VmHWM, kB) as stderr's last line: a child's ru_maxrss would carry the peak of the process it was forked from,
# which survives exec.
PEAK = """
import sys
import rs30x_sniff.allocator as a
if sys.argv[1] == "off":
    a.keep_large_buffers = lambda libc=None: False
from rs30x_sniff.cli import main
rc = main(sys.argv[2:])
with open("/proc/self/status") as f:
    print(next(line.split()[1] for line in f if line.startswith("VmHWM:")), file=sys.stderr)
sys.exit(rc)
"""


@dataclass
class Run:
    wall: float
    cpu: float


@dataclass
class Row:
    what: str
    command: str
    floor: str
    value: float
    target: str
    met: bool
    unit: str = "ratio"
    note: str = ""


def timed(cmd: list[str], env: dict[str, str]) -> Run:
    """One whole process: wall seconds, and user + system CPU seconds of it and its children (os.wait4)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    err = proc.stderr.read() if proc.stderr else b""
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode not in (0, 1):  # lint: 1 is "findings"
        raise SystemExit(f"{' '.join(cmd)}: exit {proc.returncode}: {err.decode(errors='replace').strip()[-400:]}")
    return Run(wall, usage.ru_utime + usage.ru_stime)


def paired(a: list[str], b: list[str], runs: int, env: dict[str, str]) -> tuple[list[Run], list[Run]]:
    """``a`` and ``b`` in turn, ``runs`` times each after one warm-up of each."""
    timed(a, env)
    timed(b, env)
    ra, rb = [], []
    for _ in range(runs):
        ra.append(timed(a, env))
        rb.append(timed(b, env))
    return ra, rb


def median_ratio(floor: list[Run], ours: list[Run], field: str) -> float:
    """The median of the pairs' floor/ours ratios."""
    return statistics.median(getattr(f, field) / getattr(o, field) for f, o in zip(floor, ours))


def best_ratio(floor: list[Run], ours: list[Run], field: str) -> float:
    """The floor's best run over ours (a shared machine only ever adds time: the best run is the least disturbed)."""
    return min(getattr(f, field) for f in floor) / min(getattr(o, field) for o in ours)


def shown(cmd: list[str]) -> str:
    out = []
    for word in cmd:
        if word == PY:
            out.append("python")
        elif "\n" in word:
            out[-1:] = ["-c <" + {BINARY_FLOOR: "split+XOR loop", TEXT_FLOOR: "parse text + split+XOR loop",
                                 JSONL_FLOOR: "split+XOR+json.dumps loop", ALLOCATOR_OFF: "cli.main, allocator off",
                                 ALLOCATOR_ON: "cli.main", PEAK: "cli.main + VmHWM"}.get(word, "script") + ">"]
        else:
            out.append(word)
    return " ".join(out)


# --- inputs -----------------------------------------------------------------------------------------------------

def random_frames(frames: int, seed: int = 35) -> Iterator[bytes]:
    """``frames`` valid frames of random kinds and values (see the module's docstring)."""
    rng = random.Random(seed)
    made = 0
    while made < frames:
        kind = rng.randrange(3)
        if kind == 0:  # goal position (30-31) and goal time (32-33) to servos 1-18 (table 4.6 Nos. 19-20)
            # Goal times of 0.6-5 s: 300 degrees at most in 0.6 s is within an RS303MR's top speed, so Q007 checks
            # every record but fires on none (random times would make it fire on most, and lint their findings).
            records = [(sid, rng.randint(-1500, 1500).to_bytes(2, "little", signed=True)
                        + rng.randint(60, 500).to_bytes(2, "little")) for sid in range(1, 19)]
            yield encode_long(30, records)
            made += 1
        elif kind == 1:  # a short write of goal position to one servo
            yield encode_short(rng.randint(1, 18), 0, 30, rng.randint(-1500, 1500).to_bytes(2, "little", signed=True))
            made += 1
        else:  # a poll of 42-59 (flag 09) and its return
            sid = rng.randint(1, 18)
            yield encode_short(sid, 0x09, 0, b"", length=0, count=1)
            values = [rng.randint(-1500, 1500), rng.randint(0, 500), rng.randint(-60, 60), rng.randint(5, 400),
                      rng.randint(30, 45), rng.randint(720, 760)]  # position, time, speed, current, temp., voltage
            yield encode_return(sid, 42, b"".join(v.to_bytes(2, "little", signed=True) for v in values) + bytes(6))
            made += 2


def simulated(path: Path, seconds: float, env: dict[str, str]) -> Path:
    if not path.exists():
        subprocess.run([*CLI, "simulate", "--scenario", "hexapod", "--duration", f"{seconds:g}s", "-o", str(path)],
                       check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return path


def made(path: Path, make: Callable[[], bytes]) -> Path:
    if not path.exists():
        tmp = path.with_suffix(path.suffix + ".part")
        tmp.write_bytes(make())
        tmp.rename(path)
    return path


def big_capture(path: Path, frames: int) -> Path:
    if not path.exists():
        from rs30x_sniff.sources.captures import write_capture

        write_capture(str(path), hexapod_frames(frames), "timestamped")
    return path


# --- rows -------------------------------------------------------------------------------------------------------

def speed_row(what: str, cmd: list[str], floor: list[str], target: float, runs: int, env: dict[str, str]) -> Row:
    ours, base = paired(cmd, floor, runs, env)
    wall = best_ratio(base, ours, "wall")
    return Row(what, shown(cmd), shown(floor), wall, f">= {target:g}", wall >= target,
               note=f"best {min(r.wall for r in ours):.2f} s against {min(r.wall for r in base):.2f} s; cpu ratio "
                    f"{best_ratio(base, ours, 'cpu'):.2f}; median of the pairs' ratios "
                    f"{median_ratio(base, ours, 'wall'):.2f}")


def startup_row(what: str, cmd: list[str], target: float, runs: int, env: dict[str, str]) -> Row:
    floor = [PY, "-c", "pass"]
    ours, base = paired(cmd, floor, runs, env)
    over = min(o.wall for o in ours) - min(b.wall for b in base)
    cpu = min(o.cpu for o in ours) - min(b.cpu for b in base)
    median = statistics.median(o.wall - b.wall for o, b in zip(ours, base))
    return Row(what, shown(cmd), shown(floor), over, f"<= {target:g} s", over <= target, unit="s over",
               note=f"best runs: {min(o.wall for o in ours):.3f} s against {min(b.wall for b in base):.3f} s; cpu "
                    f"{cpu:.3f} s over; median of the pairs {median:.3f} s over")


def peak_kb(args: list[str], env: dict[str, str], allocator: str = "on") -> int:
    proc = subprocess.run([PY, "-c", PEAK, allocator, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          text=True, env=env)
    if proc.returncode not in (0, 1):
        raise SystemExit(f"rs30x-sniff {' '.join(args)}: exit {proc.returncode}: {proc.stderr.strip()[-400:]}")
    return int(proc.stderr.split()[-1])


def rss_row(command: str, small: Path, big: Path, out: Path, runs: int, env: dict[str, str]) -> Row:
    extra = {"decode": ["--format", "jsonl", "-o", str(out), "--force"], "convert": ["-o", str(out), "--force"]}
    args = lambda p: [command, str(p), *extra.get(command, [])]  # noqa: E731
    smalls = [peak_kb(args(small), env) for _ in range(runs)]
    bigs = [peak_kb(args(big), env) for _ in range(runs)]
    s, b = statistics.median(smalls) / 1024, statistics.median(bigs) / 1024
    ratio = b / s
    return Row(f"{command}: peak RSS, {big.stat().st_size / 1e6:.0f} MB input over "
               f"{small.stat().st_size / 1e6:.0f} MB", f"rs30x-sniff {' '.join(args(big.name))}",
               f"the same on {small.name}", ratio, "<= 1.2", ratio <= 1.2, unit="x",
               note=f"{b:.0f} MB against {s:.0f} MB")


def convert_row(frames: int) -> Row:
    from convert import run_bare, run_bare_sdk, run_convert

    chunks = hexapod_frames(frames)
    best_ours = best_bare = best_sdk = float("inf")
    n = 0
    for _ in range(3):
        secs, n, blob = run_convert(chunks, lint=True)
        best_ours = min(best_ours, secs)
        best_bare = min(best_bare, run_bare(blob)[0])
        best_sdk = min(best_sdk, run_bare_sdk(blob))
        del blob
    ratio = best_bare / best_ours  # the same messages: per message, as the ratio of the times
    return Row(f"convert per message ({n} messages, linted, in-process)",
               "McapSink through drive(), as convert does a file (bench/convert.py run_convert)",
               "the bare mcap Writer writing the same messages pre-encoded (bench/convert.py run_bare)", ratio,
               ">= 1.0", ratio >= 1.0, note=f"best of 3: {best_ours:.2f} s against {best_bare:.2f} s; the Foxglove "
               f"SDK's writer alone on the same messages {best_sdk:.2f} s (ratio {best_sdk / best_ours:.2f})")


def monitor_row(path: Path, env: dict[str, str]) -> Row:
    from monitor import open_alone

    lint = timed([*CLI, "lint", str(path)], env)
    opened = open_alone(str(path), 900.0, False)
    ratio = opened["t_open"] / lint.wall
    return Row(f"monitor opening {path.name} ({opened['records']} records), headless", "bench/monitor.py --open",
               shown([*CLI, "lint", str(path)]), ratio, "<= 0.5", ratio <= 0.5,
               note=f"{opened['t_open']:.1f} s against {lint.wall:.1f} s")


# --- a long recording's memory ----------------------------------------------------------------------------------

def live_child(minutes: float, allocator_on: bool, out: str) -> None:
    """N minutes of hexapod traffic through Decoder + Linter + McapSink as `record` writes a port nobody watches
    (the raw bytes, findings and figures; a second's gather at a time; its Linter keeps no finding it has handed
    on); prints (simulated minutes, RSS MB) samples as JSON. The 20 s of traffic is replayed over and over: where it
    starts again, each servo's goal jumps back, and Q007 (a move faster than the top speed) would speak every 20 s
    of a bus that has no such move, so it is left out. The replay's latencies repeat exactly: a live pty's jitter
    (new latency bins) is measured by bench/live.py, not here."""
    if allocator_on:
        from rs30x_sniff import allocator

        allocator.keep_large_buffers()
    from rs30x_sniff.decode.decoder import Decoder
    from rs30x_sniff.lint import LintConfig, Linter
    from rs30x_sniff.sinks.mcap.writer import McapSink
    from rs30x_sniff.sinks.pipeline import drive

    block = hexapod_frames(7_000)  # 20 s of traffic, replayed with its times shifted
    period = 1_000 * 0.020
    page = os.sysconf("SC_PAGE_SIZE")
    samples: list[tuple[float, float]] = []

    def rss() -> float:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * page / 2**20

    def chunks() -> Iterator[tuple[bytes, float]]:
        rep, gather, start = 0, [], 0.0
        while rep * period < minutes * 60:
            for data, t in block:
                t += rep * period
                if t - start >= 1.0 and gather:
                    yield b"".join(gather), start
                    gather, start = [], t
                gather.append(data)
            rep += 1
            samples.append((rep * period / 60, rss()))
        if gather:
            yield b"".join(gather), start

    with McapSink(out, source="bench", baud=115200, time_base="capture", decoded=False) as sink:
        drive(chunks(), Decoder(None, Linter(LintConfig(ignore=["Q007"]), keep_findings=False), columnar=True), sink)
    print(json.dumps(samples))


def slope_mb_per_hour(samples: list[tuple[float, float]]) -> float:
    """The least-squares slope of RSS over the second half of the run (the first fills the buffers), MB/h."""
    half = samples[len(samples) // 2:]
    xs, ys = [m for m, _ in half], [r for _, r in half]
    mx, my = statistics.fmean(xs), statistics.fmean(ys)
    return 60 * sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def live_rows(minutes: float, tmp: Path, env: dict[str, str]) -> list[Row]:
    slopes = {}
    for on in (False, True):
        out = subprocess.run([PY, __file__, "--live-child", str(minutes), "--live-allocator", "on" if on else "off",
                              "--live-out", str(tmp / "live.mcap")], capture_output=True, text=True, check=True,
                             env=env).stdout
        samples = json.loads(out.splitlines()[-1])
        slopes[on] = (slope_mb_per_hour(samples), samples[-1][1], max(r for _, r in samples))
    rows = []
    for on, (slope, last, peak) in slopes.items():
        rows.append(Row(f"{minutes:g} min of live hexapod traffic, Decoder + Linter + McapSink in-process, "
                        f"thresholds {'set' if on else 'glibc default'}", "bench/targets.py --live-child",
                        "its own RSS over the run's second half", slope, "flat (informative)", abs(slope) < 5,
                        unit="MB/h", note=f"RSS at the end {last:.0f} MB, peak {peak:.0f} MB"))
    more = slopes[True][0] - slopes[False][0]
    rows.append(Row("growth the thresholds add to a long recording", "thresholds set", "glibc's defaults", more,
                    "<= 5 MB/h", more <= 5, unit="MB/h"))
    return rows


# --- the run ----------------------------------------------------------------------------------------------------

ROWS = ("startup", "lint-random", "info", "lint-text", "jsonl", "convert", "monitor", "rss")  # issue 35's targets
EXTRAS = ("allocator", "live")  # --allocator, --live-minutes


def children_env(inputs: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(inputs / "pycache")
    return env


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="paired runs of each command and its floor (median)")
    ap.add_argument("--inputs", type=Path, help="make the inputs here once, and use them again (default: a temporary "
                    "directory)")
    ap.add_argument("--only", help="comma-separated rows: " + ",".join(ROWS + EXTRAS) + " (default: the targets)")
    ap.add_argument("--allocator", action="store_true", help="rows with glibc's default thresholds, against set")
    ap.add_argument("--live-minutes", type=float, default=0, help="also a long recording's RSS, with and without the "
                    "thresholds (0: not; --only live: 10)")
    ap.add_argument("--monitor-frames", type=int, default=1_000_000)
    ap.add_argument("--live-child", type=float, help=argparse.SUPPRESS)
    ap.add_argument("--live-allocator", choices=("on", "off"), help=argparse.SUPPRESS)
    ap.add_argument("--live-out", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.live_child is not None:
        live_child(args.live_child, args.live_allocator == "on", args.live_out)
        return
    only = set(args.only.split(",")) if args.only else set(ROWS)
    if only - set(ROWS + EXTRAS):
        ap.error(f"--only: unknown rows {sorted(only - set(ROWS + EXTRAS))}")
    only |= {"allocator"} if args.allocator else set()
    only |= {"live"} if args.live_minutes else set()
    with tempfile.TemporaryDirectory() as tmp_dir:
        inputs = args.inputs or Path(tmp_dir)
        inputs.mkdir(parents=True, exist_ok=True)
        env = children_env(inputs)
        rows = run_rows(only, args, inputs, Path(tmp_dir), env)
    print_rows(rows)


def run_rows(only: set[str], args: argparse.Namespace, inputs: Path, tmp: Path, env: dict[str, str]) -> list[Row]:
    runs = args.runs
    rows: list[Row] = []
    text300 = simulated(inputs / "hexapod300.thex", 300, env) if only - {"convert", "live"} else Path()
    if "startup" in only:
        tiny = simulated(inputs / "tiny.thex", 0.05, env)
        rows.append(startup_row("--help", [*CLI, "--help"], 0.08, max(runs, 5), env))
        rows.append(startup_row(f"lint of a tiny file ({sum(1 for _ in open(tiny))} lines)",
                                [*CLI, "lint", str(tiny)], 0.15, max(runs, 5), env))
    if "lint-random" in only:
        rnd = made(inputs / "random.bin", lambda: b"".join(random_frames(300_000)))
        rows.append(speed_row("lint of 300k random frames", [*CLI, "lint", str(rnd)], [PY, "-c", BINARY_FLOOR,
                              str(rnd)], 0.7, runs, env))
    if "info" in only:
        rows.append(speed_row("info of 300 s timestamped two-model capture", [*CLI, "info", str(text300)],
                              [PY, "-c", TEXT_FLOOR, str(text300)], 0.5, runs, env))
    if "lint-text" in only:
        rows.append(speed_row("lint of the same capture", [*CLI, "lint", str(text300)],
                              [PY, "-c", TEXT_FLOOR, str(text300)], 0.7, runs, env))
    if "jsonl" in only:
        hexapod = made(inputs / "hexapod.bin", lambda: hexapod_bytes(300_000))
        out = tmp / "out.jsonl"
        rows.append(speed_row("decode --format jsonl of 300k hexapod frames",
                              [*CLI, "decode", str(hexapod), "--format", "jsonl", "-o", str(out), "--force"],
                              [PY, "-c", JSONL_FLOOR, str(hexapod), str(out)], 0.5, runs, env))
    if "convert" in only:
        rows.append(convert_row(100_000))
    if "monitor" in only:
        rows.append(monitor_row(big_capture(inputs / "big.thex", args.monitor_frames), env))
    if "rss" in only:
        text30 = simulated(inputs / "hexapod30.thex", 30, env)
        for command in ("lint", "info", "decode", "convert"):
            out = tmp / ("out.mcap" if command == "convert" else "out.jsonl")
            rows.append(rss_row(command, text30, text300, out, runs, env))
    if "allocator" in only:
        rows.extend(allocator_rows(text300, tmp, runs, env))
    if "live" in only:
        rows.extend(live_rows(args.live_minutes or 10, tmp, env))
    return rows


def allocator_rows(capture: Path, tmp: Path, runs: int, env: dict[str, str]) -> list[Row]:
    rows = []
    for args in (["lint", str(capture)], ["info", str(capture)],
                 ["decode", str(capture), "--format", "jsonl", "-o", str(tmp / "out.jsonl"), "--force"]):
        off, on = [PY, "-c", ALLOCATOR_OFF, *args], [PY, "-c", ALLOCATOR_ON, *args]
        ours, base = paired(on, off, runs, env)
        wall = best_ratio(base, ours, "wall")
        on_kb = statistics.median(peak_kb(args, env) for _ in range(runs))
        off_kb = statistics.median(peak_kb(args, env, "off") for _ in range(runs))
        rows.append(Row(f"{args[0]} with the allocator's thresholds, against glibc's defaults", shown(on), shown(off),
                        wall, "> 1 (informative)", wall > 1,
                        note=f"cpu ratio {best_ratio(base, ours, 'cpu'):.2f}; best "
                             f"{min(r.wall for r in ours):.2f} s against {min(r.wall for r in base):.2f} s, "
                             f"cpu {min(r.cpu for r in ours):.2f} s against {min(r.cpu for r in base):.2f} s; "
                             f"peak RSS {on_kb / 1024:.0f} MB "
                             f"against {off_kb / 1024:.0f} MB"))
    return rows


def print_rows(rows: list[Row]) -> None:
    for r in rows:
        value = f"{r.value:.3f} s over" if r.unit == "s over" else (
            f"{r.value:+.1f} MB/h" if r.unit == "MB/h" else f"{r.value:.2f}{'x' if r.unit == 'x' else ''}")
        print(f"{'PASS' if r.met else 'FAIL'}  {r.what}: {value}   target {r.target}")
        print(f"      command: {r.command}")
        print(f"      floor:   {r.floor}")
        if r.note:
            print(f"      {r.note}")


if __name__ == "__main__":
    main()
