"""Speed of the ASF/AMC reader and the forward kinematics (one core, warm).

Run: ``python benchmarks/bench_readers.py [--repeat 5]``. Prints frames/s over
all of ``../shared/data/hdm05_cut`` (232 clips, 56,733 frames at 120 Hz):

* parse: AMC bytes already in memory -> DOF array (numba kernel + Python glue);
* parse+io: the same including reading the files;
* FK: DOF array -> 24 joints + root rotation;
* read_motion: the whole public call (io, parse, FK; skeletons cached);
* BVH: write each clip as BVH once, then time reading them back.

Numba compile time is excluded (one warm-up pass). Best of ``--repeat`` runs.
Targets (brief): parse >= 300,000 frames/s, FK >= 500,000 frames/s.
"""
import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from timing import best_seconds  # benchmarks/timing.py

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from mocapdb.readers.amc import parse_amc, read_amc  # noqa: E402
from mocapdb.readers.asf import read_asf  # noqa: E402
from mocapdb.readers import read_bvh  # noqa: E402
from mocapdb.writers import write_bvh
from mocapdb.bodies.kinematics import asf_forward_kinematics  # noqa: E402
from mocapdb.readers import read_motion  # noqa: E402

SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
CUT = SHARED / "data" / "hdm05_cut"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    files = sorted(CUT.glob("*/*.amc"))
    skels = {a: read_asf(CUT / f"HDM_{a}.asf") for a in ("bd", "bk", "dg", "mm")}
    pairs = [(f, skels[f.name.split("_")[1]]) for f in files]
    blobs = [(f.read_bytes(), s) for f, s in pairs]
    motions = [(s, parse_amc(b, s)) for b, s in blobs]           # warm-up (compile/cache)
    for s, m in motions:
        asf_forward_kinematics(s, m)
    n = sum(m.n_frames for _, m in motions)
    mb = sum(len(b) for b, _ in blobs) / 1e6

    t_parse = best_seconds(lambda: [parse_amc(b, s) for b, s in blobs], args.repeat)
    t_io = best_seconds(lambda: [read_amc(f, s) for f, s in pairs], args.repeat)
    t_fk = best_seconds(lambda: [asf_forward_kinematics(s, m) for s, m in motions], args.repeat)
    [read_motion(f) for f in files[:3]]
    t_all = best_seconds(lambda: [read_motion(f) for f in files], args.repeat)

    print(f"hdm05_cut: {len(files)} clips, {n} frames, {mb:.1f} MB of AMC text")
    print(f"AMC parse (bytes in memory): {n / t_parse:12,.0f} frames/s  ({t_parse:.3f} s, "
          f"{mb / t_parse:.0f} MB/s)")
    print(f"AMC parse incl. file read  : {n / t_io:12,.0f} frames/s  ({t_io:.3f} s)")
    print(f"forward kinematics         : {n / t_fk:12,.0f} frames/s  ({t_fk:.3f} s)")
    print(f"read_motion (io+parse+FK)  : {n / t_all:12,.0f} frames/s  ({t_all:.3f} s)")

    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for (f, s), (_, m) in zip(pairs, motions):
            paths.append(write_bvh(Path(tmp) / (f.stem + ".bvh"), s, m, precision=9))
        read_bvh(paths[0])
        t_bvh = best_seconds(lambda: [read_bvh(p) for p in paths], args.repeat)
        bmb = sum(p.stat().st_size for p in paths) / 1e6
        print(f"BVH read (parse+FK, 9 digits): {n / t_bvh:10,.0f} frames/s  ({t_bvh:.3f} s, "
              f"{bmb:.1f} MB)")
    np.testing.assert_equal(n, 56733)


if __name__ == "__main__":
    main()
