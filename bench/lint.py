"""Benchmark: decode + lint with every rule on, against the bare split-and-XOR loop (and plain decode).

Run: python bench/lint.py [--frames N] [--repeat R]
Target (issues 3, 12): linting reaches at least 0.5 of the bare loop's frames/s; with --user-rules (issue 24)
also with five user rules ([[rule]]) and three figure checks ([[expect]], info's figures at the end) on the
columnar path, as `rs30x-sniff lint` runs them. Both paths are
measured: the record path (a live port) and the columnar path (a file: `rs30x-sniff lint`), where a
Block no rule speaks about is linted on its columns (rs30x_sniff.lint.batch). The columnar path runs
as the command runs it: drive() groups the chunks (about 64 KiB at a time) and hands each step to a
sink that counts its records.
"""

from __future__ import annotations

import argparse
import functools
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from decode import Count, bare_loop, best_of  # noqa: E402
from traffic import bench_inputs  # noqa: E402

from rs30x_sniff.lint import LintConfig, Linter  # noqa: E402
from rs30x_sniff.decode.decoder import Decoder  # noqa: E402
from rs30x_sniff.sinks.pipeline import drive


def decode_only(chunks, columnar: bool = False) -> int:
    dec = Decoder(columnar=columnar)
    if columnar:
        return _driven(dec, chunks)
    n = 0
    for data, t in chunks:
        n += len(dec.feed(data, t))
    return n + len(dec.close())


def decode_lint(chunks, columnar: bool = False) -> tuple[int, int]:
    linter = Linter(LintConfig())  # every rule
    dec = Decoder(None, linter, columnar=columnar)
    if columnar:
        return _driven(dec, chunks), len(linter.findings)
    n = 0
    for data, t in chunks:
        n += len(dec.feed(data, t))
    n += len(dec.close())
    return n, len(linter.findings)


# Five rules and three checks a robot's CI might keep (none fires on the healthy benchmark traffic).
USER_CONFIG = {
    "rule": [
        {"code": "U001", "name": "too-hot", "when": "kind:return present_temperature>60"},
        {"code": "U002", "name": "over-current", "when": "kind:return present_current>1500"},
        {"code": "U003", "name": "low-voltage", "when": "kind:return present_voltage<6"},
        {"code": "U004", "name": "slow-reply", "when": "latency>5ms"},
        {"code": "U005", "name": "wrist-write", "when": "id:18 kind:short goal_position>150"},
    ],
    "expect": [
        {"code": "U101", "name": "polled", "check": "poll_hz >= 1", "for": "each"},
        {"code": "U102", "name": "replies-fast", "check": "latency_p95 < 10 ms"},
        {"code": "U103", "name": "few-missing", "check": "missing_replies == 0", "for": "id:1-18"},
    ],
}


@functools.cache
def user_config() -> dict:
    """USER_CONFIG checked and compiled, once: the set-up a command does once per process (timed apart)."""
    from rs30x_sniff.settings import check

    return check(USER_CONFIG, "bench")


def decode_lint_user(chunks) -> tuple[int, int]:
    """The columnar path with USER_CONFIG's rules and checks: the rules in the run's rule set, info's figures as one
    more sink, the checks evaluated at the end (as rs30x_sniff.commands.lint does)."""
    from rs30x_sniff.expect import evaluate, findings
    from rs30x_sniff.lint.registry import RULES
    from rs30x_sniff.settings import own_rules
    from rs30x_sniff.sinks.stats import CaptureStats

    conf = user_config()
    linter = Linter(LintConfig(rules=RULES.with_user(own_rules(conf))))  # this run's rule set
    dec = Decoder(None, linter, columnar=True)
    checks = conf.get("expect", ())
    count, stats = Count(), CaptureStats(115200, ranges=any(c.reads_ranges for c in checks))
    drive(chunks, dec, count, stats)
    results = evaluate(checks, stats.as_dict(), [r.code for r in linter.rules])
    return count.n, len(linter.findings) + len(findings(results, stats.bytes))


def _driven(dec, chunks) -> int:
    """The records of ``chunks`` through a columnar decoder, driven as `rs30x-sniff lint` drives a file."""
    count = Count()
    drive(chunks, dec, count)
    return count.n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--user-rules", action="store_true", help="also the columnar path with five user rules and "
                    "three figure checks (issue 24)")
    args = ap.parse_args()
    chunks, data, blocks = bench_inputs(args.frames)
    t_bare, n_bare = best_of(bare_loop, data, args.repeat)
    rows = []
    for path, columnar in (("record path", False), ("columnar path", True)):
        for label, feed in (("4 KiB blocks, no timestamps", blocks), ("one chunk per frame, timestamped", chunks)):
            t_dec, n_dec = best_of(functools.partial(decode_only, columnar=columnar), feed, args.repeat)
            t_lint, (n_lint, n_find) = best_of(functools.partial(decode_lint, columnar=columnar), feed, args.repeat)
            assert n_dec == n_lint == args.frames, (n_dec, n_lint)
            rows.append((f"{path}, {label}", n_dec / t_dec, n_lint / t_lint, n_find))
    bare = n_bare / t_bare
    print(f"capture: {args.frames} frames, {len(data) / 1e6:.1f} MB (bench/traffic.py hexapod_frames)")
    print(f"bare split+XOR loop:              {bare:12,.0f} frames/s")
    for label, dec, lint, n_find in rows:
        print(f"{label}:")
        print(f"  decode only:                    {dec:12,.0f} frames/s   ratio {dec / bare:.2f}")
        print(f"  decode + lint (all rules):      {lint:12,.0f} frames/s   ratio {lint / bare:.2f}"
              f"   ({lint / dec:.2f} of decode alone, {n_find} findings)")
    if args.user_rules:
        import time

        t0 = time.perf_counter()
        user_config()
        print(f"user rules and checks compiled once in {time.perf_counter() - t0:.2f} s (not in the figures below)")
        for label, feed in (("4 KiB blocks, no timestamps", blocks), ("one chunk per frame, timestamped", chunks)):
            t_user, (n_user, n_find) = best_of(decode_lint_user, feed, args.repeat)
            assert n_user == args.frames, n_user
            user = n_user / t_user
            print(f"columnar path, {label}, + 5 user rules and 3 figure checks:")
            print(f"  decode + lint:                  {user:12,.0f} frames/s   ratio {user / bare:.2f}"
                  f"   ({n_find} findings)")
    print("target: decode + lint ratio >= 0.50")


if __name__ == "__main__":
    main()
