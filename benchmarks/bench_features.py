"""Speed of the 40 relational features (mocapdb.features) on one core.

Prints frames/s of ``relational_features`` (native 120 Hz frames) and of the
whole ``motion_features`` pipeline on all hdm05_cut clips (read with
mocapdb.readers), and the cold / warm numba compile time of the feature
kernels measured in fresh processes with an empty / filled cache directory.

Usage: python benchmarks/bench_features.py [--repeat 5]
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
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared")).resolve()
DATA = SHARED / "data"

# one call on a tiny synthetic motion triggers (or loads) every kernel
_COMPILE_SNIPPET = """
import time
t0 = time.perf_counter()
import numpy as np
from mocapdb import features as F
t1 = time.perf_counter()
rng = np.random.default_rng(0)
F.relational_features(rng.normal(size=(40, 24, 3)), None, 120.0)
F.relational_features(rng.normal(size=(40, 24, 3)), np.tile(np.eye(3), (40, 1, 1)), 120.0)
t2 = time.perf_counter()
print(f"{t1 - t0:.3f} {t2 - t1:.3f}")
"""


def compile_times():
    """(import s, first call s) in a fresh process: cold cache, then warm cache."""
    out = []
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, OMP_NUM_THREADS="1",
                   NUMBA_NUM_THREADS="1")
        for _ in range(2):
            res = subprocess.run([sys.executable, "-c", _COMPILE_SNIPPET], env=env,
                                 capture_output=True, text=True, check=True, cwd=REPO)
            out.append(tuple(float(x) for x in res.stdout.split()))
    return out


def load_clips():
    from mocapdb.readers import read_motion

    clips = []
    for amc in sorted((DATA / "hdm05_cut").glob("*/*.amc")):
        actor = amc.name.split("_")[1]
        clips.append(read_motion(amc, asf=DATA / "hdm05_cut" / f"HDM_{actor}.asf"))
    return clips


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    (imp_c, cold), (imp_w, warm) = compile_times()
    print(f"compile, cold cache : {cold:6.2f} s first call (import {imp_c:.2f} s)")
    print(f"compile, warm cache : {warm:6.2f} s first call (import {imp_w:.2f} s)")

    from mocapdb import features as F

    t0 = time.perf_counter()
    clips = load_clips()
    t_read = time.perf_counter() - t0
    n_frames = sum(c.n_frames for c in clips)
    print(f"hdm05_cut: {len(clips)} clips, {n_frames} frames at 120 Hz "
          f"(read in {t_read:.2f} s, {n_frames / t_read:,.0f} frames/s)")

    F.relational_features(clips[0].joints, clips[0].root_rotation, clips[0].fps)  # load

    def features_all():
        for c in clips:
            F.relational_features(c.joints, c.root_rotation, c.fps)

    def pipeline_all():
        for c in clips:
            F.motion_features(c)

    def hip_axis_all():
        for c in clips:
            F.relational_features(c.joints, None, c.fps)

    for label, fn in (("relational_features", features_all),
                      ("relational_features, #40 from hip axis", hip_axis_all),
                      ("motion_features (to 30 Hz words)", pipeline_all)):
        t = best_seconds(fn, args.repeat)
        print(f"{label:40s}: {t * 1000:8.1f} ms, {n_frames / t:12,.0f} frames/s")

    long = max(clips, key=lambda c: c.n_frames)
    t = best_seconds(lambda: F.relational_features(long.joints, long.root_rotation, long.fps),
                  args.repeat * 4)
    print(f"{'longest clip (' + str(long.n_frames) + ' frames)':40s}: {t * 1000:8.2f} ms, "
          f"{long.n_frames / t:12,.0f} frames/s")


if __name__ == "__main__":
    main()
