"""The Ray path (``ray_annotate``) against the single-process path (``ingest`` + ``annotate``).

Run: ``nice -n 10 python benchmarks/bench_ray.py`` (needs the ``ray`` extra).

Data: every ASF/AMC take of ``../shared/data/hdm05_cut``, ``cmu/02`` and
``cmu/86`` (the CMU folders that ship their skeleton), copied ``--copies``
times into a temporary folder, each copy with a comment line of its own in
front so that its bytes (and sha256) differ — otherwise both paths would
store each take once. Both paths read the same files and do the same work:
read, features, postings, annotation with the default model (keyframe
preselection), the single-process path into a new DuckDB file (ingest with
its default two threads, then ``annotate``), the Ray path into Parquet.

Printed, wall time and CPU time (user + system of this process and all its
descendants — a local Ray's GCS, raylet and workers too — sampled from /proc
every 0.1 s, so Linux only; CPU time is the steadier figure on a shared
machine):

* throughput of both paths (source frames/s) and their ratio, on this
  machine's 2 CPUs, in a running Ray session and with the start of a local Ray;
* the Ray path's cost per run (starting the actors, loading the kernels) and
  per file — a line through runs over 1 and ``--copies`` copies — against
  the single-process path's, and the actor's own work without Ray;
* the Ray path on 1 and on 2 CPUs (``num_cpus``).

The paper has no distributed figure; its feature extraction ran at
2,128 frames/s (74 min of 120 Hz data in 250 s).
"""
import argparse
import logging
import os
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path


REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"
FOLDERS = ("hdm05_cut", "cmu/02", "cmu/86")


def make_copies(root: Path, copies: int) -> list[Path]:
    """``copies`` copies of the data folders under ``root`` (skeletons linked, takes
    rewritten with a distinguishing first line); returns the copy folders."""
    out = []
    for k in range(copies):
        base = root / f"copy{k:03d}"
        for folder in FOLDERS:
            for src in (DATA / folder).rglob("*"):
                if src.suffix.lower() not in (".asf", ".amc"):
                    continue
                dst = base / folder / src.relative_to(DATA / folder)
                dst.parent.mkdir(parents=True, exist_ok=True)
                if src.suffix.lower() == ".asf":
                    dst.symlink_to(src.resolve())
                else:
                    dst.write_bytes(f"# benchmark copy {k}\n".encode() + src.read_bytes())
        out.append(base)
    return out


def run_single(sources, tmp: Path):
    """ingest + annotate in one process, into a new DuckDB file: (report, segments)."""
    import mocapdb

    db = tmp / "single.duckdb"
    db.unlink(missing_ok=True)
    con = mocapdb.connect(db)
    try:
        report = mocapdb.ingest(con, sources)
        segments = mocapdb.annotate(con).num_rows
    finally:
        con.close()
    return report, segments


def run_ray(sources, tmp: Path, **kw):
    from mocapdb.distributed import ray_annotate

    return ray_annotate(sources, tmp / "archive", overwrite=True, **kw)


def run_worker_alone(sources, tmp: Path, batch_files: int):
    """The actor's work in this process, batch after batch, without Ray: one core's throughput.

    Returns (source frames, files, segments)."""
    from datetime import datetime

    import pyarrow as pa

    from mocapdb._numba import limit_threads
    from mocapdb.distributed import ERRORS_SCHEMA, MotionWorker, expand_sources
    from mocapdb.storage.model_store import DEFAULT_MODEL, load_model
    from mocapdb.storage.parquet import table_schemas
    from mocapdb.storage.schema import open_database

    con = open_database(":memory:")
    model = load_model(con, DEFAULT_MODEL)
    con.close()
    out = tmp / "alone"
    shutil.rmtree(out, ignore_errors=True)
    worker = MotionWorker(model=model, model_name=DEFAULT_MODEL, tau=None, keyframes=None, out=str(out),
                          schemas={**table_schemas(), "errors": ERRORS_SCHEMA}, stamp=datetime.now(),
                          bucket_motions=1000, threads=1)
    files = [str(f) for f in expand_sources(sources)]
    frames = segments = 0
    for k in range(0, len(files), batch_files):
        batch = pa.table({"motion_id": pa.array(range(k + 1, k + 1 + len(files[k:k + batch_files])), pa.int32()),
                          "path": files[k:k + batch_files]})
        summary = worker(batch)
        frames += sum(n or 0 for n in summary.column("n_source_frames").to_pylist())
        segments += sum(summary.column("n_segments").to_pylist())
    limit_threads(1 << 16)  # the worker set this thread's kernels to one thread: back to all
    return frames, len(files), segments


def _tree_ticks() -> dict:
    """pid -> CPU clock ticks (user + system) of this process and all its descendants."""
    procs = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                stat = Path(f"/proc/{d}/stat").read_text()
            except OSError:
                continue
            f = stat[stat.rindex(")") + 2:].split()
            procs[int(d)] = (int(f[1]), int(f[11]) + int(f[12]))
    mine, grew = {os.getpid()}, True
    while grew:
        more = {pid for pid, (ppid, _) in procs.items() if ppid in mine} - mine
        mine |= more
        grew = bool(more)
    return {pid: procs[pid][1] for pid in mine if pid in procs}


class CpuClock:
    """CPU seconds of this process tree — a local Ray's GCS, raylet and workers included —
    sampled every ``interval`` s from /proc (Linux), since Ray's workers exit unreaped (their
    time never reaches a parent): a process is counted up to its last sample."""

    def __init__(self, interval=0.1):
        self.interval = interval

    def __enter__(self):
        self.start, self.last, self.done = _tree_ticks(), {}, threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        return self

    def _run(self):
        t0 = time.thread_time()
        while not self.done.wait(self.interval):
            for pid, ticks in _tree_ticks().items():
                self.last[pid] = max(self.last.get(pid, 0), ticks)
        self.own = time.thread_time() - t0  # the sampling itself is not the measured work

    def __exit__(self, *exc):
        for pid, ticks in _tree_ticks().items():
            self.last[pid] = max(self.last.get(pid, 0), ticks)
        self.done.set()
        self.thread.join()
        ticks = sum(t - self.start.get(pid, 0) for pid, t in self.last.items())
        self.seconds = ticks / os.sysconf("SC_CLK_TCK") - self.own


def measure(fn, repeat):
    """Least wall and least CPU time (whole process tree) over ``repeat`` calls, and the last result."""
    walls, cpus, res = [], [], None
    for _ in range(max(1, repeat)):
        with CpuClock() as clock:
            t = time.perf_counter()
            res = fn()
            walls.append(time.perf_counter() - t)
        cpus.append(clock.seconds)
    return min(walls), min(cpus), res


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copies", type=int, default=8, help="copies of the data set (default 8)")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    logging.getLogger("ray").setLevel(logging.ERROR)

    from mocapdb.distributed import BATCH_FILES, ray_session, require_ray

    ray = require_ray()
    big = f"{args.copies} copies"
    rows = {}  # (path, data) -> (wall, cpu, source frames, files, segments)
    with tempfile.TemporaryDirectory(prefix="mocapdb-bench-ray-") as t:
        tmp = Path(t)
        copies = make_copies(tmp / "data", args.copies)
        data = {"1 copy": [copies[0]], big: copies}

        # single process (warm: the numba cache is filled by a first small run)
        run_single(data["1 copy"], tmp)
        for name, src in data.items():
            wall, cpu, (rep, segs) = measure(lambda: run_single(src, tmp), args.repeat)
            rows[("single process", name)] = (wall, cpu, rep.source_frames, len(rep.ingested), segs)

        # the actor's work alone, in this process (one core: kernels on one thread)
        run_worker_alone(data["1 copy"], tmp, BATCH_FILES)
        wall, cpu, res = measure(lambda: run_worker_alone(data[big], tmp, BATCH_FILES), args.repeat)
        rows[("actor's work, no Ray", big)] = (wall, cpu, *res)

        # Ray: a local Ray's start and shutdown, then runs inside one session
        t0 = time.perf_counter()
        with ray_session(ray, num_cpus=2):
            t_start = time.perf_counter() - t0
            run_ray(data["1 copy"], tmp)  # the first actors fill nothing: kernels come from the cache
            for name, src in data.items():
                wall, cpu, rep = measure(lambda: run_ray(src, tmp), args.repeat)
                rows[("Ray, 2 CPUs", name)] = (wall, cpu, rep.source_frames, len(rep.ingested), rep.segments)
            t0 = time.perf_counter()
        t_stop = time.perf_counter() - t0
        with ray_session(ray, num_cpus=1):
            run_ray(data["1 copy"], tmp)
            wall, cpu, rep = measure(lambda: run_ray(data[big], tmp), args.repeat)
            rows[("Ray, 1 CPU", big)] = (wall, cpu, rep.source_frames, len(rep.ingested), rep.segments)
        # the command as a user runs it: a local Ray started and stopped by the call
        wall, cpu, rep = measure(lambda: run_ray(data[big], tmp, num_cpus=2), 1)
        rows[("Ray, 2 CPUs, with start", big)] = (wall, cpu, rep.source_frames, len(rep.ingested), rep.segments)

    print(f"{'path':<26} {'data':<10} {'files':>6} {'src frames':>11} {'segments':>8} {'wall s':>7} "
          f"{'frames/s':>9} {'CPU s':>6} {'frames/CPU-s':>12}")
    for (path, name), (wall, cpu, frames, files, segs) in rows.items():
        print(f"{path:<26} {name:<10} {files:>6} {frames:>11,} {segs:>8} {wall:>7.2f} {frames / wall:>9,.0f} "
              f"{cpu:>6.2f} {frames / cpu:>12,.0f}")
    single, ray2 = rows[("single process", big)], rows[("Ray, 2 CPUs", big)]
    assert single[2:] == ray2[2:], "the two paths did different work"
    print(f"\nthroughput Ray (2 CPUs, running session) / single process: {single[0] / ray2[0]:.2f} (wall), "
          f"{single[1] / ray2[1]:.2f} (per CPU second)")
    with_start = rows[("Ray, 2 CPUs, with start", big)]
    print(f"the same with a local Ray started and stopped by the call:  {single[0] / with_start[0]:.2f} (wall)")
    print(f"local Ray: start {t_start:.2f} s, shutdown {t_stop:.2f} s")

    def line(path, k):  # (fixed, per file) of wall (k=0) or CPU (k=1): a line through 1 copy and all
        a, b = rows[(path, "1 copy")], rows[(path, big)]
        per_file = (b[k] - a[k]) / (b[3] - a[3])
        return a[k] - per_file * a[3], per_file

    (rf, rp), (sf, sp) = line("Ray, 2 CPUs", 1), line("single process", 1)
    alone = rows[("actor's work, no Ray", big)]
    print(f"CPU per run and per file: Ray {rf:.2f} s + {rp * 1e3:.2f} ms/file; single process {sf:.2f} s + "
          f"{sp * 1e3:.2f} ms/file; the actor's work alone {alone[1] / alone[3] * 1e3:.2f} ms/file "
          f"(mean file {single[2] / single[3]:,.0f} source frames)")
    print(f"overhead of the Ray path: {rf - sf:.2f} CPU-s per run, {(rp - sp) * 1e3:+.2f} CPU-ms per file")
    w_fixed, w_per = line("Ray, 2 CPUs", 0)
    print(f"wall per run and per file (Ray, 2 CPUs): {w_fixed:.2f} s + {w_per * 1e3:.2f} ms/file")
    print(f"Ray 1 -> 2 CPUs: {rows[('Ray, 1 CPU', big)][0] / ray2[0]:.2f}x (wall)")


if __name__ == "__main__":
    sys.exit(main())
