"""Features of sources not at 120 Hz: which way to the 30 Hz grid agrees best.

Run: ``python benchmarks/bench_rates.py``. READERS.md §1 leaves two ways:

* ``resample``: resample the joints to 120 Hz (cubic Hermite), toolbox path;
* ``native``: features at the source rate with the millisecond windows,
  sampled at the 30 Hz grid times.

Both are measured on real 120 Hz recordings (all ASF/AMC takes of
../shared/data: HDM05 cut clips and full excerpt, CMU) decimated to 60, 40,
30 and 24 Hz (every 2nd … 5th frame: real samples, no interpolation): the
share of (frame, feature) values equal to the 120 Hz reading on the common
30 Hz grid, overall and for the worst features. Also the timing of both.
"""
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"

from mocapdb.features import FEATURE_NAMES, motion_features, unpack_words  # noqa: E402
from mocapdb.bodies import Motion  # noqa: E402
from mocapdb.readers import read_motion

CMU_ASF = DATA / "cmu" / "02" / "02.asf"
FACTORS = (2, 3, 4, 5)


def takes():
    for p in sorted(DATA.glob("**/*.amc")):
        if "foreign" in p.parts:
            continue
        asf = CMU_ASF if p.parent.name in ("13", "14") else None
        yield read_motion(p, asf=asf)


def decimate(m: Motion, d: int) -> Motion:
    rot = None if m.root_rotation is None else m.root_rotation[::d]
    return Motion(m.joints[::d], rot, m.fps / d, m.name, m.skeleton, m.source_format)


def main():
    motions = list(takes())
    n120 = sum(m.n_frames for m in motions)
    print(f"# bench_rates: {len(motions)} real 120 Hz takes, {n120:,} frames "
          f"({n120 / 120 / 60:.1f} min)")
    ref = [unpack_words(motion_features(m)) for m in motions]
    # warm the kernels of both methods
    motion_features(decimate(motions[0], 2), rate_method="native")
    motion_features(decimate(motions[0], 2), rate_method="resample")
    print("\n| source rate | method | agreement with 120 Hz | worst features (agreement) | s per source minute |")
    print("|---|---|---|---|---|")
    for d in FACTORS:
        for method in ("resample", "native"):
            same = np.zeros(len(FEATURE_NAMES))
            total = 0
            t = time.perf_counter()
            secs = 0.0
            for m, r in zip(motions, ref):
                dm = decimate(m, d)
                got = unpack_words(motion_features(dm, rate_method=method))
                k = min(len(got), len(r))
                same += (got[:k] == r[:k]).sum(axis=0)
                total += k
                secs += dm.n_frames / dm.fps
            elapsed = time.perf_counter() - t
            per = same / total
            worst = np.argsort(per)[:3]
            ws = ", ".join(f"#{i + 1} {per[i]:.1%}" for i in worst)
            print(f"| {120 / d:g} Hz | {method} | {per.mean():.2%} | {ws} | {elapsed / (secs / 60):.4f} |")


if __name__ == "__main__":
    main()
