"""C3D ingest throughput next to ezc3d's raw read (issue 10).

Run: ``python benchmarks/bench_c3d.py``. For every C3D file of
``../shared/data`` with a full-body marker set (HDM05 and CMU Vicon files,
the Qualisys landmark take) it prints, in source frames per second (best of
``--repeat`` runs, numba compile excluded by a warm-up pass):

* **ezc3d raw**: ``ezc3d.c3d(path)`` and its point array, the library's own read;
* **points**: :func:`mocapdb.readers.read_c3d_points` (layout guard + ezc3d +
  labels, units, gap mask);
* **joints**: :func:`mocapdb.readers.read_c3d` (marker rules, gap filling,
  axes, the bone-length fit);
* **features**: :func:`mocapdb.features.motion_features` on those joints;
* **ingest**: ``mocapdb.storage.ingest.ingest_files`` (what ``mocapdb.ingest`` runs) of the file alone into a new database file
  (hashing, reading, features, one transaction), one worker;

then the same for all files in one call (one and two
workers). The ASF/AMC ingest figure (RESULTS.md, issue 2) is the yardstick:
178,399 source frames/s end to end on one core.
"""
import argparse
import os
import tempfile
import time
from pathlib import Path

from timing import best_seconds  # benchmarks/timing.py

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"
FILES = [DATA / "hdm05_full" / "HDM_dg_06-03_03_120.c3d", DATA / "hdm05_full" / "HDM_mm_01-02_03_120.c3d",
         DATA / "cmu" / "c3d" / "85_02.c3d", DATA / "cmu" / "c3d" / "85_12.c3d",
         DATA / "cmu" / "c3d" / "135_02.c3d", DATA / "foreign" / "c3d" / "ezc3d_Qualisys.c3d"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    import ezc3d

    import mocapdb
    from mocapdb.features import motion_features
    from mocapdb.readers import read_c3d, read_c3d_points
    from mocapdb.storage.ingest import ingest_files

    def raw(path):
        c = ezc3d.c3d(str(path))
        return c["data"]["points"]

    def ingest(paths, workers=1):
        times = []
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory() as tmp:
                con = mocapdb.connect(Path(tmp) / "bench.duckdb")
                t = time.perf_counter()
                report = ingest_files(con, paths, workers=workers)
                times.append(time.perf_counter() - t)
                assert len(report.ingested) == len(paths), report.failed
                con.close()
        return min(times)

    motions = {p: read_c3d(p) for p in FILES}            # warm-up (numba compile, caches)
    for m in motions.values():
        motion_features(m)
    rows = []
    for p in FILES:
        m = motions[p]
        n_markers = len(read_c3d_points(p).labels)
        rows.append((p.name, m.n_frames, n_markers, m.fps,
                     best_seconds(lambda: raw(p), args.repeat),
                     best_seconds(lambda: read_c3d_points(p), args.repeat),
                     best_seconds(lambda: read_c3d(p), args.repeat),
                     best_seconds(lambda: motion_features(m), args.repeat),
                     ingest([p])))
    n = sum(r[1] for r in rows)
    total1, total2 = ingest(FILES, 1), ingest(FILES, 2)

    print(f"{len(FILES)} C3D files, {n:,} source frames; source frames/s (best of {args.repeat})")
    head = (f"{'file':28s} {'frames':>6s} {'mk':>3s} {'Hz':>4s} {'ezc3d raw':>10s} {'points':>10s} "
            f"{'joints':>10s} {'features':>10s} {'ingest':>10s}")
    print(head)
    for name, frames, mk, fps, *ts in rows:
        print(f"{name:28s} {frames:6d} {mk:3d} {fps:4.0f} " + " ".join(f"{frames / t:10,.0f}" for t in ts))
    sums = [sum(r[k] for r in rows) for k in range(4, 9)]
    print(f"{'all files (sum of per-file)':28s} {n:6d} {'':3s} {'':4s} " + " ".join(f"{n / t:10,.0f}" for t in sums))
    print(f"one ingest of all files: {n / total1:,.0f} frames/s with 1 worker ({total1:.3f} s), "
          f"{n / total2:,.0f} with 2 workers ({total2:.3f} s); ezc3d alone reads {n / sums[0]:,.0f} frames/s")


if __name__ == "__main__":
    main()
