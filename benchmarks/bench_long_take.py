"""One long repetitive take: a real walk looped to 10 and 60 minutes (issue 22 item 1); one very long
take and one of very many markers, ingested (issue 27 item 3).

Run: ``nice python benchmarks/bench_long_take.py [--minutes 10 60] [--work DIR]``, or
``nice python benchmarks/bench_long_take.py --frames 1000000 --fps 30 --markers 5000 [--repo DIR]``
for the ingest of one take of ``--frames`` frames at ``--fps`` (the looped walk's motion lines
repeated, a BVH) and of one C3D take of ``--markers`` markers (HDM_mm_01-02_03's 44 markers and
copies of them moved, 3,990 frames at 120 Hz): wall and CPU seconds, peak RSS; ``--repo`` runs another
checkout's CLI (the figures before a change).

CMU 02_01 (a walk, 343 frames at 120 Hz) is looped: its AMC values repeated,
each repetition's root moved on by the distance the walk covers, so the
walker goes on walking. Each take is written as a BVH file
(``mocapdb.writers.write_bvh``) and goes through the CLI in fresh processes,
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
    from mocapdb.writers import write_bvh
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


def long_bvh(frames, fps, path):
    """A BVH of ``frames`` frames at ``fps`` Hz: a minute of the looped walk, its motion lines repeated."""
    minute = path.with_name("minute.bvh")
    looped_walk(1, minute)
    head, _, body = minute.read_bytes().partition(b"MOTION")
    lines = body.split(b"\n", 3)[3].splitlines(keepends=True)
    minute.unlink()
    with open(path, "wb") as fh:
        fh.write(head + b"MOTION\nFrames: %d\nFrame Time: %.7f\n" % (frames, 1 / fps))
        block = b"".join(lines)
        for _ in range(frames // len(lines)):
            fh.write(block)
        fh.write(b"".join(lines[:frames % len(lines)]))
    return path


def many_markers_c3d(markers, path):
    """HDM_mm_01-02_03 (44 markers, 3,990 frames) with copies of its markers, each moved by a few cm,
    up to ``markers`` points: one take of a dense marker set."""
    import ezc3d

    src = ezc3d.c3d(str(DATA / "hdm05_full" / "HDM_mm_01-02_03_120.c3d"))
    pts = src["data"]["points"]
    labels = list(src["parameters"]["POINT"]["LABELS"]["value"])
    reps = -(-markers // pts.shape[1])
    rng = np.random.default_rng(27)
    out = ezc3d.c3d()
    out["parameters"]["POINT"]["RATE"]["value"] = [120]
    out["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    shift = np.concatenate([np.zeros((1, 3))] + [rng.normal(0, 30, (1, 3)) for _ in range(reps - 1)])
    out["parameters"]["POINT"]["LABELS"]["value"] = (labels + [f"X{k:04d}" for k in range(markers)])[:markers]
    data = np.tile(pts, (1, reps, 1))[:, :markers]
    data[:3] += np.repeat(shift, pts.shape[1], axis=0)[:markers].T[:, :, None]
    out["data"]["points"] = data
    out.write(str(path))
    return path


def one_take(args):
    """--frames/--markers: the ingest of one very long BVH take and one C3D take of very many markers."""
    import bench_scale

    if args.repo is not None:
        bench_scale.REPO = args.repo.resolve()   # the CLI of that checkout
    print(f"checkout {bench_scale.REPO}")
    takes = []
    if args.frames:
        t = time.perf_counter()
        bvh = long_bvh(args.frames, args.fps, args.work / "long.bvh")
        print(f"{args.frames:,} frames at {args.fps:g} Hz: {bvh.stat().st_size / 1e9:.2f} GB written in "
              f"{time.perf_counter() - t:.0f} s", flush=True)
        takes.append((f"BVH, {args.frames:,} frames at {args.fps:g} Hz ({bvh.stat().st_size / 1e9:.2f} GB)", bvh))
    if args.markers:
        c3d = many_markers_c3d(args.markers, args.work / "markers.c3d")
        takes.append((f"C3D, {args.markers:,} markers × 3,990 frames ({c3d.stat().st_size / 1e6:.0f} MB)", c3d))
    warm = args.work / "warm.duckdb"   # compile once, outside the figures
    run_cli(["--db", warm, "ingest", "--silent", "--sample"])
    rows = []
    for what, path in takes:
        db = args.work / "take.duckdb"
        for f in args.work.glob("take.duckdb*"):
            f.unlink()
        try:
            r = run_cli(["--db", db, "ingest", "--silent", path])
            result = r["stdout"].strip().splitlines()[-1]
        except RuntimeError as exc:
            r, result = {"s": float("nan"), "cpu_s": float("nan"), "gb": float("nan")}, str(exc).splitlines()[-1]
        print(f"  {what}: {r['s']:.1f} s, {r['cpu_s']:.1f} CPU-s, peak {r['gb']:.2f} GB; {result}; {load_now()}",
              flush=True)
        rows.append((what, r, result))
        path.unlink()
    print("\n| take | ingest s | CPU-s | peak GB | result |")
    print("|---|---:|---:|---:|---|")
    for what, r, result in rows:
        print(f"| {what} | {r['s']:.1f} | {r['cpu_s']:.1f} | {r['gb']:.2f} | {result} |")
    shutil.rmtree(args.work, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--minutes", type=int, nargs="+", default=[10, 60])
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "mocapdb-long-take")
    ap.add_argument("--frames", type=int, default=0, help="ingest one BVH take of this many frames")
    ap.add_argument("--fps", type=float, default=30.0, help="its rate")
    ap.add_argument("--markers", type=int, default=0, help="ingest one C3D take of this many markers")
    ap.add_argument("--repo", type=Path, help="the checkout whose CLI runs (default: this one)")
    args = ap.parse_args()
    if args.frames or args.markers:
        machine_header("bench_long_take: one very long take, one take of very many markers (issue 27)")
        args.work.mkdir(parents=True, exist_ok=True)
        return one_take(args)
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
