"""Ingest throughput: parse, FK, features and store, separately and together.

Run: ``python benchmarks/bench_ingest.py``. Reads every 120 Hz ASF/AMC file of
``../shared/data/hdm05_cut`` and ``../shared/data/cmu`` (cmu/13 and cmu/14
with cmu/02/02.asf, as they ship without a skeleton) and prints source
frames per second of each stage on one core (numba compile excluded: a
warm-up pass runs first; the cold compile is measured in a fresh process
with an empty numba cache and reported separately), then the end-to-end
``mocapdb.ingest`` into a new database file, with one and with two worker
threads. The paper: 74 min of 120 Hz data (532,076 frames) in 250 s of
feature extraction ≈ 2,100 frames/s (Matlab + C, Athlon X2 5000+).
Target (DESIGN.md §7): ≥ 100,000 source frames/s end to end on one core.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from timing import best_seconds  # benchmarks/timing.py

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"
PAPER_FPS = 532_076 / 250


def inputs():
    """(amc, asf) pairs: every 120 Hz ASF/AMC take of hdm05_cut and cmu."""
    from mocapdb.readers import find_skeleton

    out = []
    for amc in sorted((DATA / "hdm05_cut").rglob("*.amc")) + sorted((DATA / "cmu").rglob("*.amc")):
        out.append((amc, find_skeleton(amc) or DATA / "cmu" / "02" / "02.asf"))
    return out


def cold_start_seconds():
    """First read+features call in a fresh process with an empty numba cache."""
    code = ("import time; t = time.perf_counter(); import mocapdb; "
            f"m = mocapdb.read_motion(r'{DATA / 'cmu' / '86' / '86_09.amc'}'); mocapdb.motion_features(m); "
            "print(time.perf_counter() - t)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        cold = float(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                                    check=True).stdout)
        warm = float(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                                    check=True).stdout)
    return cold, warm


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-cold", action="store_true", help="skip the cold-compile measurement")
    args = ap.parse_args()

    import numpy as np

    import mocapdb
    from mocapdb.readers.amc import read_amc
    from mocapdb.features import downsample, pack_words, relational_features
    from mocapdb.storage.ingest import store_words
    from mocapdb.readers.kinematics import asf_forward_kinematics
    from mocapdb.readers import load_skeleton

    pairs = inputs()
    skels = {asf: load_skeleton(asf) for _, asf in pairs}
    amcs = [read_amc(amc, skels[asf]) for amc, asf in pairs]                      # warm-up
    fk = [asf_forward_kinematics(skels[asf], m) for (_, asf), m in zip(pairs, amcs)]
    feats = [relational_features(j, r, m.fps) for (j, r), m in zip(fk, amcs)]
    words = [pack_words(downsample(f)) for f in feats]
    n = sum(m.n_frames for m in amcs)

    t_parse = best_seconds(lambda: [read_amc(amc, skels[asf]) for amc, asf in pairs], args.repeat)
    t_fk = best_seconds(lambda: [asf_forward_kinematics(skels[asf], m) for (_, asf), m in zip(pairs, amcs)], args.repeat)
    t_feat = best_seconds(lambda: [pack_words(downsample(relational_features(j, r, m.fps)))
                           for (j, r), m in zip(fk, amcs)], args.repeat)

    def store():
        with tempfile.TemporaryDirectory() as tmp:
            con = mocapdb.connect(Path(tmp) / "bench.duckdb")
            named = [(f"{amc.stem}_{i}", w) for i, ((amc, _), w) in enumerate(zip(pairs, words))]
            t = time.perf_counter()
            for k in range(0, len(named), 64):  # ingest's batches: rows, features, postings per transaction
                store_words(con, dict(named[k:k + 64]), fps=120.0)
            dt = time.perf_counter() - t
            con.close()
            return dt

    t_store = min(store() for _ in range(args.repeat))

    def end_to_end(workers):
        times = []
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory() as tmp:
                con = mocapdb.connect(Path(tmp) / "bench.duckdb")
                t = time.perf_counter()
                r1 = mocapdb.ingest(con, [DATA / "hdm05_cut", DATA / "cmu" / "02", DATA / "cmu" / "86"],
                                    workers=workers)
                r2 = mocapdb.ingest(con, [DATA / "cmu" / "13", DATA / "cmu" / "14"],
                                    asf=DATA / "cmu" / "02" / "02.asf", workers=workers)
                times.append(time.perf_counter() - t)
                assert not r1.failed and not r2.failed and r1.source_frames + r2.source_frames == n
                con.close()
        return min(times)

    t_e2e1 = end_to_end(1)
    t_e2e2 = end_to_end(2)

    print(f"input: {len(pairs)} ASF/AMC takes (hdm05_cut + cmu), {n:,} source frames at 120 Hz "
          f"({n / 120 / 60:.1f} min)")
    print(f"{'stage':34s} {'frames/s':>12s} {'seconds':>9s}")
    for name, t in (("parse (read_amc, incl. file read)", t_parse), ("forward kinematics", t_fk),
                    ("features (40 + hysteresis + pack)", t_feat), ("store (DuckDB file, batches of 64)", t_store),
                    ("sum of the stages", t_parse + t_fk + t_feat + t_store),
                    ("ingest end to end, 1 worker", t_e2e1), ("ingest end to end, 2 workers", t_e2e2)):
        print(f"{name:34s} {n / t:12,.0f} {t:9.3f}")
    print(f"{'paper (feature extraction)':34s} {PAPER_FPS:12,.0f}   (74 min in 250 s)")
    print(f"speed-up over the paper, 1 worker: {n / t_e2e1 / PAPER_FPS:.0f}x; target >= 100,000 frames/s: "
          f"{'met' if n / t_e2e1 >= 100_000 else 'NOT met'}")
    if not args.no_cold:
        cold, warm = cold_start_seconds()
        print(f"numba: first read+features call in a fresh process {cold:.1f} s with an empty cache "
              f"(compile), {warm:.2f} s with the cache")


if __name__ == "__main__":
    main()
