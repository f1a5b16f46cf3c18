"""Crash consistency at scale: many seeded SIGKILLs of ingest, annotate, import-features, ray-annotate.

    python benchmarks/bench_crash.py --trials 20 [--seed 0] [--commands ingest,annotate]

Prints trials / killed / consistent per command (tests/crash.py does the work;
tests/test_crash.py runs a few trials of each in the suite). Run it with ``nice``
on a shared machine.
"""
import argparse
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from crash import WINDOWS, CrashHarness, summary  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=10, help="kills per command")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--commands", default=",".join(WINDOWS), help="comma-separated, of: " + ", ".join(WINDOWS))
    ap.add_argument("--data", default=str(REPO.parent / "shared" / "data"))
    args = ap.parse_args(argv)
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="mocapdb-crash-") as tmp:
        harness = CrashHarness(tmp, args.data)
        # each command's kills fall within its own writing time on this machine (measured first)
        results = harness.run(args.trials, seed=args.seed, commands=args.commands.split(","), calibrate=True)
    print(summary(results))
    for r in results:
        if not r.consistent:
            print(f"INCONSISTENT: {r.command} killed {r.delay} s into its work: {r.broken}")
    print(f"{len(results)} trials, {sum(r.consistent for r in results)} consistent, "
          f"{time.monotonic() - start:.0f} s")
    return 0 if all(r.consistent for r in results) else 1


if __name__ == "__main__":
    raise SystemExit(main())
