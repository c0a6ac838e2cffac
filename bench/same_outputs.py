"""Whether two trees give byte-identical outputs on every bundled capture: a check for restructuring.

    python bench/same_outputs.py REF        # this tree against git REF (checked out in a temporary worktree)

Runs `decode` (text and jsonl), `lint --format json`, `info --format json` and `table --of` every table on
each capture under captures/ and on each simulator scenario (written by `simulate` in both trees, which must
agree too), and `convert`'s MCAP messages, in both trees, and prints each difference.
Exit code 1 when anything differs.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TABLES = ("states", "transactions", "findings", "packets")


def captures() -> list[Path]:
    return sorted(p for p in (ROOT / "captures").rglob("*") if p.is_file() and p.suffix not in (".md",))


def run(tree: Path, argv: list[str]) -> bytes:
    env = dict(os.environ, PYTHONPATH=str(tree))
    done = subprocess.run([sys.executable, "-m", "rs30x_sniff", *argv], cwd=tree, env=env, capture_output=True)
    return done.stdout + b"\n--- stderr ---\n" + done.stderr.replace(str(tree).encode(), b"TREE") + \
        f"\n--- exit {done.returncode}".encode()


def scenarios(tree: Path) -> list[str]:
    done = subprocess.run([sys.executable, "-c", "from rs30x_sniff.sim import SCENARIOS; print(*SCENARIOS)"],
                          cwd=tree, env=dict(os.environ, PYTHONPATH=str(tree)), capture_output=True, text=True,
                          check=True)
    return done.stdout.split()


def simulated(tmp: Path, other: Path) -> tuple[list[Path], int]:
    """Each scenario as a timestamped capture under ``tmp`` (written by this tree), and how many differ from the
    other tree's."""
    out, differ = [], 0
    for name in scenarios(ROOT):
        mine, theirs = tmp / f"sim-{name}.thex", tmp / f"sim-{name}-ref.thex"
        run(ROOT, ["simulate", "--scenario", name, "--seed", "7", "-o", str(mine), "--force"])
        run(other, ["simulate", "--scenario", name, "--seed", "7", "-o", str(theirs), "--force"])
        if not mine.exists() or not theirs.exists() or mine.read_bytes() != theirs.read_bytes():
            differ += 1
            print(f"differs: simulate --scenario {name}")
        out.append(mine)
    return out, differ


def mcap_messages(tree: Path, capture: Path, out: Path) -> bytes:
    run(tree, ["convert", str(capture), "-o", str(out), "--force"])  # capture: relative, as the messages name it
    if not out.exists():
        return b"(no file)"
    from mcap.reader import make_reader

    with open(out, "rb") as f:
        return b"\n".join(f"{c.topic} {m.log_time} ".encode() + m.data for _, c, m in make_reader(f).iter_messages())


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("ref", help="the git revision to compare with")
    args = p.parse_args()
    differ = 0
    with tempfile.TemporaryDirectory() as tmp:
        other = Path(tmp) / "other"
        subprocess.run(["git", "worktree", "add", "--detach", str(other), args.ref], cwd=ROOT, check=True,
                       capture_output=True)
        try:
            sims, differ = simulated(Path(tmp), other)
            for cap in captures() + sims:
                rel = cap.relative_to(ROOT) if cap.is_relative_to(ROOT) else cap
                jobs = [["decode", str(rel)], ["decode", str(rel), "--format", "jsonl"],
                        ["lint", str(rel), "--format", "json", "--isolated", "--fail-on", "never"],
                        ["info", str(rel), "--format", "json", "--isolated"],
                        *(["table", str(rel), "--of", t, "-o", "-"] for t in TABLES)]
                for argv in jobs:
                    a, b = run(ROOT, argv), run(other, argv)
                    if a != b:
                        differ += 1
                        print(f"differs: {' '.join(argv)}")
                a = mcap_messages(ROOT, rel, Path(tmp) / "a.mcap")
                b = mcap_messages(other, rel, Path(tmp) / "b.mcap")
                if a != b:
                    differ += 1
                    print(f"differs: convert {rel} (MCAP messages)")
                print(f"checked {rel}", file=sys.stderr)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(other)], cwd=ROOT, capture_output=True)
    print("identical" if not differ else f"{differ} outputs differ")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
