"""Write the seed corpus of a fuzz target, made from captures/, into a directory (not committed)."""

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from targets import TARGETS, write_seeds  # noqa: E402


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("target", choices=sorted(TARGETS))
    p.add_argument("directory", help="corpus directory to write the seeds into (created)")
    args = p.parse_args()
    n = write_seeds(args.target, args.directory)
    print(f"{args.directory}: {n} seeds for {args.target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
