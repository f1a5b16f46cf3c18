"""Archives of 10 to 1,000 hours on one machine: import, SQL annotate, keyframe search (issue 20).

Run: ``nice python benchmarks/bench_scale.py --hours 10 100 300 [--work DIR] [--keep]``.

The archives are built from the real features of ../shared/data, as 60 s
takes in the ``export-features`` layout (``DIR/motions.parquet``,
``DIR/features/motion_id=N/*.parquet``): every ASF/AMC take of the shared
data is ingested once, its 30 Hz words concatenated into one stream of
about 13 minutes, and take k is the 1,800 frames of that stream from offset
k·1,801 on (read circularly), so consecutive takes differ. Each measured
step then runs through the CLI in a fresh process, as a user runs it:

* ``import-features DIR`` into a new database file;
* ``SELECT motion_id, annotate(motion_id, keyframes := false) FROM motions``
  and the same with ``keyframes := true`` (the shipped default model; its
  classes with a keyframe query are preselected), every row computed and
  its segments counted (``sum(len(s))``: nothing to print);
* ``SELECT count(*) FROM keyframe_search('kickLFront1Reps')``;
* ``SELECT sum(list_count(mt_distance(motion_id, 'cmuWalk2Steps'))) FROM motions``;
* ``ingest`` of the 232 hdm05_cut clips into the archive's database.

Each gives wall seconds, the process's peak RSS (VmHWM, read by the process
itself at exit: ``ru_maxrss`` of a child counts its parent's pages at fork)
and feature frames per second. The issue's "Today" figures (c55b76d) are
printed beside them. ``--ray`` adds ``ray-annotate`` on one node against two
(see :func:`ray_nodes`).
"""
import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_annotate import DATA, REPO, ingest_all, load_now, machine_header  # noqa: E402

TAKE_FRAMES = 1800          # 60 s at 30 Hz
TAKES_PER_HOUR = 60
#: the issue's figures at c55b76d: hours -> {step: (seconds, peak GB)}
TODAY = {10: {"import": (2.0, 0.53), "annotate": (3.4, 0.54)},
         100: {"import": (8.5, 2.1), "annotate": (20.5, 1.9), "keyframe_search": (None, 1.4)},
         300: {"import": (25.5, 5.5), "annotate": (71.0, 4.4)}}
#: targets of issue 20 item 1
TARGET_GB = {300: 1.5, 1000: 2.0}
TARGET_FPS = 400_000

#: a child process that runs the mocapdb CLI and writes its own peak RSS (VmHWM) to $BENCH_RSS_FILE
CLI_CHILD = """
import atexit, os, sys
def _hwm():
    with open('/proc/self/status') as f:
        for line in f:
            if line.startswith('VmHWM:'):
                open(os.environ['BENCH_RSS_FILE'], 'w').write(line.split()[1])
atexit.register(_hwm)
from mocapdb.cli import main
sys.argv[0] = 'mocapdb'
main()
"""


def real_stream(cache: Path) -> np.ndarray:
    """The 30 Hz words of every ASF/AMC take of ../shared/data, concatenated (cached as .npy)."""
    f = cache / "real_words.npy"
    if not f.exists():
        from timing import stored_words

        with tempfile.TemporaryDirectory() as tmp:
            con, _ = ingest_all(Path(tmp) / "real.duckdb")
            words, _ = stored_words(con)
            con.close()
        cache.mkdir(parents=True, exist_ok=True)
        np.save(f, np.asarray(words, np.uint64))
    return np.load(f)


def build_archive(out: Path, hours: int, stream: np.ndarray) -> int:
    """Write an ``export-features`` archive of ``hours`` hours of 60 s takes; returns the frames."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    n = hours * TAKES_PER_HOUR
    if (out / "motions.parquet").exists():
        return int(pq.read_table(out / "motions.parquet", columns=["n_frames"]).column(0).to_numpy().sum())
    tmp = out.with_name(out.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    (tmp / "features").mkdir(parents=True)
    ring = np.concatenate([stream, stream[:TAKE_FRAMES]])
    frame = pa.array(np.arange(1, TAKE_FRAMES + 1, dtype=np.int32))
    shas = []
    for k in range(n):
        o = (k * (TAKE_FRAMES + 1)) % len(stream)
        words = ring[o:o + TAKE_FRAMES]
        shas.append(hashlib.sha256(words.tobytes() + k.to_bytes(8, "little")).hexdigest())
        part = tmp / "features" / f"motion_id={k + 1}"
        part.mkdir()
        pq.write_table(pa.table({"frame": frame, "bits": pa.array(words, pa.uint64())}), part / "data_0.parquet")
    ids = np.arange(1, n + 1, dtype=np.int32)
    motions = pa.table({
        "motion_id": pa.array(ids), "name": pa.array([f"take_{i:06d}" for i in ids]),
        "source_path": pa.array([f"/archive/take_{i:06d}.amc" for i in ids]),
        "format": pa.array(["amc"] * n), "sha256": pa.array(shas), "skeleton_sha256": pa.array([None] * n, pa.string()),
        "source_fps": pa.array(np.full(n, 120.0)), "fps": pa.array(np.full(n, 30.0)),
        "n_source_frames": pa.array(np.full(n, 4 * TAKE_FRAMES - 3, np.int32)),
        "n_frames": pa.array(np.full(n, TAKE_FRAMES, np.int32)),
        "skeleton": pa.array([None] * n, pa.string()), "skeleton_path": pa.array([None] * n, pa.string()),
        "reader_options": pa.array([None] * n, pa.string())})
    pq.write_table(motions, tmp / "motions.parquet")
    tmp.rename(out)
    return n * TAKE_FRAMES


def run_cli(args, *, env=None) -> dict:
    """``mocapdb ARGS`` in a fresh process: wall and CPU seconds, peak RSS (GB) and stdout."""
    with tempfile.NamedTemporaryFile(suffix=".rss") as rss:
        e = dict(os.environ, PYTHONPATH=str(REPO), BENCH_RSS_FILE=rss.name, **(env or {}))
        t = time.perf_counter()
        with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
            p = subprocess.Popen([sys.executable, "-P", "-c", CLI_CHILD, *map(str, args)], env=e, stdout=out,
                                 stderr=err, text=True)
            _, status, usage = os.wait4(p.pid, 0)
            dt = time.perf_counter() - t
            out.seek(0)
            err.seek(0)
            stdout, stderr = out.read(), err.read()
        if os.waitstatus_to_exitcode(status) != 0:
            raise RuntimeError(f"mocapdb {' '.join(map(str, args))} failed:\n{stderr[-3000:]}")
        kb = int(Path(rss.name).read_text() or 0)
    # CPU seconds of the child (user + system, its threads included): steadier than wall time on a busy machine
    return {"s": dt, "cpu_s": usage.ru_utime + usage.ru_stime, "gb": kb / 2**20, "stdout": stdout}


STEPS = {
    "annotate": "SELECT motion_id, annotate(motion_id, keyframes := false) AS s FROM motions",
    "annotate_kf": "SELECT motion_id, annotate(motion_id, keyframes := true) AS s FROM motions",
    "keyframe_search": "SELECT count(*) FROM keyframe_search('kickLFront1Reps')",
    "mt_distance": "SELECT sum(list_count(mt_distance(motion_id, 'cmuWalk2Steps'))) FROM motions",
}


def sql_step(db: Path, query: str) -> dict:
    """A query in a fresh process through ``mocapdb sql``."""
    if query.startswith("SELECT motion_id"):  # every row's segments, summed up (nothing to print)
        query = f"SELECT count(*) AS motions, sum(len(s)) AS segments FROM ({query})"
    return run_cli(["--db", db, "sql", "--format", "csv", query])


def measure(hours: int, work: Path, stream: np.ndarray, steps) -> dict:
    archive = work / f"archive_{hours}h"
    t = time.perf_counter()
    frames = build_archive(archive, hours, stream)
    print(f"{hours} h: archive built in {time.perf_counter() - t:.1f} s ({frames:,} frames); {load_now()}",
          flush=True)
    db = work / f"archive_{hours}h.duckdb"
    for f in (db, db.with_name(db.name + ".wal")):
        f.unlink(missing_ok=True)
    out = {"hours": hours, "frames": frames}
    r = run_cli(["--db", db, "import-features", archive])
    out["import"] = r
    print(f"  import-features    {r['s']:8.1f} s  {r['cpu_s']:8.1f} CPU-s  {r['gb']:5.2f} GB  {frames / r['s']:>11,.0f} frames/s  "
          f"({r['stdout'].strip()}); {load_now()}", flush=True)
    for name in steps:
        if name == "ingest":
            r = run_cli(["--db", db, "ingest", "--silent", DATA / "hdm05_cut"])
            fr = 56_733 // 4
        else:
            r = sql_step(db, STEPS[name])
            fr = frames
        out[name] = r
        print(f"  {name:18s} {r['s']:8.1f} s  {r['cpu_s']:8.1f} CPU-s  {r['gb']:5.2f} GB  {fr / r['s']:>11,.0f} frames/s  "
              f"-> {r['stdout'].strip().splitlines()[-1]}; {load_now()}", flush=True)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=int, nargs="+", default=[10, 100, 300])
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "mocapdb-scale")
    ap.add_argument("--steps", nargs="+", default=["annotate", "annotate_kf", "keyframe_search", "mt_distance",
                                                   "ingest"])
    ap.add_argument("--keep", action="store_true", help="keep the archives and databases (default: delete)")
    args = ap.parse_args()
    machine_header("bench_scale: archives of 60 s takes built from the real features of ../shared/data")
    stream = real_stream(args.work)
    print(f"real stream: {len(stream):,} frames ({len(stream) / 1800:.1f} min)")
    results = []
    for h in args.hours:
        results.append(measure(h, args.work, stream, args.steps))
        if not args.keep:
            shutil.rmtree(args.work / f"archive_{h}h", ignore_errors=True)
            for f in args.work.glob(f"archive_{h}h.duckdb*"):
                f.unlink()
    print("\n| archive | step | s | CPU-s | peak GB | frames/s | today (c55b76d) |")
    print("|---|---|---:|---:|---:|---:|---|")
    for r in results:
        h = r["hours"]
        for name in ["import", *args.steps]:
            x = r[name]
            fr = 56_733 // 4 if name == "ingest" else r["frames"]
            today = TODAY.get(h, {}).get(name)
            tt = "" if today is None else f"{today[0] or '—'} s, {today[1]} GB"
            print(f"| {h} h | {name} | {x['s']:.1f} | {x['cpu_s']:.1f} | {x['gb']:.2f} | {fr / x['s']:,.0f} | {tt} |")
    print(json.dumps([{k: (v if not isinstance(v, dict) else {kk: vv for kk, vv in v.items() if kk != "stdout"})
                       for k, v in r.items()} for r in results]))


if __name__ == "__main__":
    main()
