"""One long repetitive take: a real walk looped to 10 and 60 minutes (issue 22 item 1).

Run: ``nice python benchmarks/bench_long_take.py [--minutes 10 60] [--work DIR]``.

CMU 02_01 (a walk, 343 frames at 120 Hz) is looped: its AMC values repeated,
each repetition's root moved on by the distance the walk covers, so the
walker goes on walking. Each take is written as a BVH file
(``mocapdb.readers.write_bvh``) and goes through the CLI in fresh processes,
as a treadmill session would:

* ``ingest`` of the BVH into a new database;
* ``annotate`` with the default model (its keyframe preselection) and with
  ``--model toolbox`` (the reference templates, no keyframes).

Each gives wall and CPU seconds and the process's peak RSS (VmHWM, read by
the process itself). At c55b76d both models stopped with
``match_num_max=2000 hits reached`` on the 10-minute take (and the 60-minute
one), and nothing was stored for any motion of the database.
"""
import argparse
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_annotate import DATA, load_now, machine_header  # noqa: E402
from bench_scale import run_cli  # noqa: E402


def looped_walk(minutes, path):
    """Write CMU 02_01 looped to ``minutes`` as a BVH file; returns its frames (120 Hz)."""
    from mocapdb.readers import write_bvh
    from mocapdb.readers.amc import read_amc
    from mocapdb.readers.asf import read_asf

    skel = read_asf(DATA / "cmu" / "02" / "02.asf")
    walk = read_amc(DATA / "cmu" / "02" / "02_01.amc", skel)
    n = int(minutes * 60 * walk.fps)
    reps = -(-n // walk.n_frames)
    values = np.tile(walk.values, (reps, 1))[:n]
    root = walk.columns["root"]
    dofs = walk.dof_names["root"]
    for axis in ("tx", "tz"):  # the ground plane: each repetition starts where the last one ended
        c = root.start + dofs.index(axis)
        step = walk.values[-1, c] - walk.values[0, c] + (walk.values[-1, c] - walk.values[-2, c])
        values[:, c] += np.repeat(np.arange(reps) * step, walk.n_frames)[:n]
    long = type(walk)(values=values, columns=walk.columns, dof_names=walk.dof_names, fps=walk.fps,
                      angle_unit=walk.angle_unit, path=str(path))
    write_bvh(path, skel, long)
    return n


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--minutes", type=int, nargs="+", default=[10, 60])
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "mocapdb-long-take")
    args = ap.parse_args()
    machine_header("bench_long_take: CMU 02_01 looped, through the CLI in fresh processes")
    args.work.mkdir(parents=True, exist_ok=True)
    rows = []
    for minutes in args.minutes:
        bvh = args.work / f"walk_{minutes}min.bvh"
        t = time.perf_counter()
        n = looped_walk(minutes, bvh)
        print(f"{minutes} min: {n:,} frames at 120 Hz written in {time.perf_counter() - t:.1f} s "
              f"({bvh.stat().st_size / 2**20:.0f} MB); {load_now()}", flush=True)
        db = args.work / f"walk_{minutes}min.duckdb"
        for f in args.work.glob(f"walk_{minutes}min.duckdb*"):
            f.unlink()
        steps = [("ingest", ["--db", db, "ingest", "--silent", bvh])]
        for model in ("default", "toolbox"):
            steps.append((f"annotate {model}", ["--db", db, "annotate", "--silent", "--model", model,
                                                "--format", "csv", "--out", args.work / f"{minutes}_{model}.csv"]))
        for what, cli in steps:
            r = run_cli(cli)
            segs = ""
            if what.startswith("annotate"):
                lines = (args.work / f"{minutes}_{what.split()[1]}.csv").read_text().splitlines()[1:]
                move = sum(int(x.split(",")[3]) - int(x.split(",")[2]) + 1 for x in lines if x.split(",")[1] == "move")
                segs = f"{len(lines)} segments, {move / (n // 4):.0%} of the frames 'move'"
            print(f"  {what:18s} {r['s']:7.1f} s {r['cpu_s']:7.1f} CPU-s {r['gb']:6.2f} GB  {segs}; {load_now()}",
                  flush=True)
            rows.append((minutes, what, r, segs))
        bvh.unlink()
    print("\n| take | step | s | CPU-s | peak GB | result |")
    print("|---|---|---:|---:|---:|---|")
    for minutes, what, r, segs in rows:
        print(f"| {minutes} min | {what} | {r['s']:.1f} | {r['cpu_s']:.1f} | {r['gb']:.2f} | {segs} |")
    shutil.rmtree(args.work, ignore_errors=True)


if __name__ == "__main__":
    main()
