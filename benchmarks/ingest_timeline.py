"""Where a core is idle during one ingest on worker processes: a timeline of the parent and its workers.

Run: ``nice python benchmarks/ingest_timeline.py --hours 2 --formats amc [--repo DIR] [--cold]`` (the archive of
:mod:`ingest_archive`, built if missing). One ``mocapdb.ingest`` of the archive runs in a fresh process with
the worker processes forced (as on a quiet machine); this process samples every process's CPU from /proc
every 50 ms, and the ingest process records (by wrapping the pool's and the store's functions, no change to
the code measured) when each worker starts, each task is sent and answered, and each batch is stored.

Printed: the phases (set-up before the workers start, the workers' start to their first answer, the steady
part, the end after the last answer) with the CPU each process used and the core-seconds left idle
(2 cores × wall − CPU), the workers' waits between an answer and their next task, and the batches' stores.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import ingest_archive   # benchmarks/ingest_archive.py
from bench_ingest import watch

REPO = Path(__file__).resolve().parents[1]
SUFFIX = {"amc": "amc", "bvh": "bvh"}

# the ingest, instrumented by wrapping; events go to argv[4] as JSON (times: time.monotonic, as /proc samples)
_RUN = r"""
import json, os, sys, tempfile, threading, time
from pathlib import Path
sys.path.insert(0, sys.argv[1])
import mocapdb
import mocapdb.storage.ingest_pool as pool
import mocapdb.storage.ingest as ing
pool._idle_cores = lambda: 2.0
folders = [Path(f) for f in json.loads(sys.argv[2])]
events, now = [], time.monotonic

def wrap(owner, name, kind, info=lambda *a, **k: {}):
    fn = getattr(owner, name)
    def wrapped(*a, **k):
        t0 = now()
        try:
            return fn(*a, **k)
        finally:
            events.append(dict(kind=kind, t0=t0, t1=now(), thread=threading.get_ident(), **info(*a, **k)))
    setattr(owner, name, wrapped)

init = pool._Worker.__init__
def worker_init(self):
    t0 = now()
    init(self)
    events.append(dict(kind="spawn", t0=t0, t1=now(), pid=self.proc.pid))
pool._Worker.__init__ = worker_init
# a task's round trip as the parent sees it: sent at t0, answer unpickled at t1 (the worker's pid)
wrap(pool._Worker, "call", "call", lambda self, fn, arg: dict(pid=self.proc.pid, fn=getattr(fn, "__name__", "?"),
                                                               n=len(arg[1]) if isinstance(arg, tuple) and len(arg) == 2 and isinstance(arg[1], list) else 1))
wrap(ing, "store_motions", "store", lambda con, preps, **k: dict(n=len(preps)))
wrap(ing, "motion_files", "walk")
wrap(ing, "_stored_keys", "stored_keys")
wrap(ing, "use_processes", "use_processes")
with tempfile.TemporaryDirectory() as tmp:
    if sys.argv[5] == "warm":   # as bench_ingest.py: one file first, numba's kernels loaded in this process
        con = mocapdb.connect(Path(tmp) / "warm.duckdb")
        mocapdb.ingest(con, [next(folders[0].rglob("*." + sys.argv[3]))])
        con.close()
    con = mocapdb.connect(Path(tmp) / "bench.duckdb")
    events.clear()
    print("START", now(), flush=True)
    t0 = now()
    r = mocapdb.ingest(con, folders)
    t1 = now()
    con.close()
    t2 = now()
events.append(dict(kind="ingest", t0=t0, t1=t1))
events.append(dict(kind="close", t0=t1, t1=t2))
Path(sys.argv[4]).write_text(json.dumps(events))
print("DONE", json.dumps({"frames": r.source_frames, "files": len(r.ingested), "failed": len(r.failed)}), flush=True)
"""

_TICK = os.sysconf("SC_CLK_TCK")


def _cpu_of(pid):
    """CPU seconds of a process (user + system) and its parent pid, from /proc; None once it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            f = fh.read().rsplit(")", 1)[1].split()
        return (int(f[11]) + int(f[12])) / _TICK, int(f[1])
    except (OSError, IndexError, ValueError):
        return None


def run(repo: Path, folders, suffix: str, cold: bool = False):
    """One instrumented ingest; returns (events, samples {pid: [(t, cpu)]}, result)."""
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as fh:
        ev_path = fh.name
    proc = subprocess.Popen([sys.executable, "-c", _RUN, str(repo), json.dumps([str(f) for f in folders]), suffix,
                             ev_path, "cold" if cold else "warm"], stdout=subprocess.PIPE, text=True, cwd="/tmp")
    samples = {}

    def sample():
        t = time.monotonic()
        for pid in [proc.pid] + [int(d) for d in os.listdir("/proc") if d.isdigit()]:
            got = _cpu_of(pid)
            if got is not None and (pid == proc.pid or got[1] == proc.pid):
                samples.setdefault(pid, []).append((t, got[0]))

    result = next((json.loads(line.split(" ", 1)[1]) for line in watch(proc, sample) if line.startswith("DONE")), None)
    if result is None:
        raise SystemExit("the ingest failed")
    events = json.loads(Path(ev_path).read_text())
    os.unlink(ev_path)
    return events, samples, proc.pid, result


def _cpu_between(series, a, b):
    """CPU seconds a sampled process used between times a and b (linear between samples)."""
    if not series:
        return 0.0

    def at(t):
        if t <= series[0][0]:
            return series[0][1]
        for (t0, c0), (t1, c1) in zip(series, series[1:]):
            if t0 <= t <= t1:
                return c0 + (c1 - c0) * (t - t0) / (t1 - t0) if t1 > t0 else c1
        return series[-1][1]
    return max(0.0, at(b) - at(a))


def report(events, samples, parent, result, cores=2):
    first = lambda k: [e for e in events if e["kind"] == k]
    ing = first("ingest")[0]
    t0, t_end = ing["t0"], first("close")[0]["t1"]
    spawns = first("spawn")
    calls = sorted(first("call"), key=lambda e: e["t0"])
    reads = [c for c in calls if c["fn"] == "apply_all"]
    stores = first("store")
    workers = [s["pid"] for s in spawns]
    for s in spawns:   # a worker used no CPU before it was started (its first sample may come up to 50 ms later)
        samples.setdefault(s["pid"], []).insert(0, (s["t0"], 0.0))
    t_spawn = min(s["t0"] for s in spawns)
    t_first = min(c["t1"] for c in reads)
    t_last = max(c["t1"] for c in reads)
    phases = [("set-up (walk, stored keys) before the workers start", t0, t_spawn),
              ("workers start, until the first answer", t_spawn, t_first),
              ("steady: first answer to last answer", t_first, t_last),
              ("end: last answer to the ingest's return", t_last, ing["t1"]),
              ("closing the database", ing["t1"], t_end)]
    print(f"{result['files']} files, {result['frames']:,} frames, wall {t_end - t0:.2f} s "
          f"(ingest {ing['t1'] - t0:.2f} s + close {t_end - ing['t1']:.2f} s); load {os.getloadavg()[0]:.1f}")
    print(f"{'phase':55s} {'wall s':>7s} {'parent':>7s} {'workers':>8s} {'idle core-s':>11s}")
    tot_idle = 0.0
    for name, a, b in phases:
        p = _cpu_between(samples.get(parent, []), a, b)
        w = sum(_cpu_between(samples.get(pid, []), a, b) for pid in workers)
        idle = max(0.0, cores * (b - a) - p - w)
        tot_idle += idle
        print(f"{name:55s} {b - a:7.2f} {p:7.2f} {w:8.2f} {idle:11.2f}")
    p = _cpu_between(samples.get(parent, []), t0, t_end)
    w = sum(_cpu_between(samples.get(pid, []), t0, t_end) for pid in workers)
    print(f"{'all':55s} {t_end - t0:7.2f} {p:7.2f} {w:8.2f} {tot_idle:11.2f}")
    # per worker: busy from its answers' view: time between an answer and the next task sent to it
    for pid in workers:
        mine = [c for c in calls if c["pid"] == pid]
        gaps = [b["t0"] - a["t1"] for a, b in zip(mine, mine[1:])]
        cpu = _cpu_between(samples.get(pid, []), t0, t_end)
        print(f"worker {pid}: {len(mine)} tasks, CPU {cpu:.2f} s; between an answer and the next task: "
              f"sum {sum(gaps):.3f} s, max {max(gaps, default=0):.3f} s, gaps > 10 ms: "
              f"{sum(g > 0.01 for g in gaps)}; round trip median {sorted(c['t1'] - c['t0'] for c in mine)[len(mine) // 2]:.3f} s; "
              f"done at +{mine[-1]['t1'] - t0:.2f} s" if mine else f"worker {pid}: no tasks")
    print(f"stores: {len(stores)}, " + ", ".join(f"{s['n']} files at +{s['t0'] - t0:.2f} s for {s['t1'] - s['t0']:.3f} s"
                                                for s in stores))
    print("walk %.3f s, stored keys %.3f s, use_processes %.3f s" % tuple(
        sum(e["t1"] - e["t0"] for e in first(k)) for k in ("walk", "stored_keys", "use_processes")))
    # the CPU of each process over the run, by 0.5 s bins (a picture of the idle)
    print("per 0.5 s: parent / workers CPU (core-s)")
    line, t = [], t0
    while t < t_end:
        p = _cpu_between(samples.get(parent, []), t, t + 0.5)
        w = sum(_cpu_between(samples.get(pid, []), t, t + 0.5) for pid in workers)
        line.append(f"{p:.2f}/{w:.2f}")
        t += 0.5
    for i in range(0, len(line), 10):
        print(f"  +{i * 0.5:5.1f} s  " + "  ".join(line[i:i + 10]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=2)
    ap.add_argument("--archive", type=Path, default=Path("/tmp/mocapdb_ingest_archive"))
    ap.add_argument("--formats", default="amc")
    ap.add_argument("--repo", type=Path, default=REPO, help="the checkout to measure (default: this one)")
    ap.add_argument("--cold", action="store_true",
                    help="no one-file ingest first: the process loads numba's cached kernels during the ingest, "
                         "as a CLI run does")
    args = ap.parse_args()
    for fmt in args.formats.split(","):
        ingest_archive.build(args.archive, args.hours, fmt)
        folders = ingest_archive.copy_folders(args.archive, args.hours, fmt)
        print(f"\n{fmt}, {args.repo}")
        report(*run(args.repo.resolve(), folders, SUFFIX[fmt], args.cold))


if __name__ == "__main__":
    main()
