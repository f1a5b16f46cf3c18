"""Ingest throughput: raw files to stored features, this checkout against another, side by side.

Run: ``nice python benchmarks/bench_ingest.py --hours 10 --base DIR`` where DIR
is a checkout of the version to compare with (e.g. ``git archive d3b3f07 | tar
-x -C DIR``; it runs with this environment's packages). The archive
(:mod:`ingest_archive`: real 120 Hz takes of ``../shared/data`` repeated with
distinct bytes, as ASF/AMC, BVH and AMASS ``.npz``; the real C3D recordings
once) is built in ``--archive`` and reused.

The archive is read once first, so that each version finds it in the page cache (the read's
rate is printed: the disk's, when the archive was not cached). For each format and version,
one ``mocapdb.ingest`` of the whole archive into
a new database file runs in a fresh process (a one-file ingest first, so
numba's compile is not timed): wall seconds, CPU seconds of the process and
its worker processes, peak memory (the RSS of the process and its workers
summed, sampled every 50 ms), and source frames per second. ``--stages``
first times each step of the path in one process on one copy, one core:
hashing, the skeleton lookup, parse, forward kinematics, features, store.
The paper: 74 min of 120 Hz data in 250 s of feature extraction ≈ 2,100
frames/s (Matlab + C, Athlon X2 5000+).
"""
import argparse
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import ingest_archive   # benchmarks/ingest_archive.py

REPO = Path(__file__).resolve().parents[1]
PAPER_FPS = 532_076 / 250
SUFFIX = {"amc": "amc", "bvh": "bvh", "amass": "npz", "c3d": "c3d"}

# one ingest in a fresh process; prints a JSON line (the repo to import comes first on sys.path)
_RUN = r"""
import json, resource, sys, tempfile, time
from pathlib import Path
sys.path.insert(0, sys.argv[1])
import mocapdb
folders = [Path(f) for f in json.loads(sys.argv[2])]
suffix = sys.argv[3]
if sys.argv[4] == "processes":   # the worker processes whatever the load (as on a quiet machine)
    try:
        import mocapdb.storage.ingest_pool as pool
        pool._idle_cores = lambda: 2.0
    except ImportError:   # a version before the pool (d3b3f07): threads only
        pass
with tempfile.TemporaryDirectory() as tmp:
    con = mocapdb.connect(Path(tmp) / "warm.duckdb")
    mocapdb.ingest(con, [next(folders[0].rglob("*." + suffix))])
    con.close()
    con = mocapdb.connect(Path(tmp) / "bench.duckdb")
    c0 = resource.getrusage(resource.RUSAGE_SELF)
    print("START", flush=True)
    t = time.perf_counter()
    r = mocapdb.ingest(con, folders)
    wall = time.perf_counter() - t
    c1 = resource.getrusage(resource.RUSAGE_SELF)
    con.close()
print(json.dumps({"wall": wall, "cpu": c1.ru_utime + c1.ru_stime - c0.ru_utime - c0.ru_stime,
                  "frames": r.source_frames, "files": len(r.ingested), "failed": len(r.failed),
                  "module": mocapdb.__file__}))
"""


def _tree_rss(pid: int) -> int:
    """RSS in bytes of a process and all its descendants (Linux /proc)."""
    children = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as fh:
                    ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
                children.setdefault(ppid, []).append(int(d))
            except (OSError, IndexError, ValueError):
                pass
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        todo += children.get(p, [])
        try:
            with open(f"/proc/{p}/status") as fh:
                for line in fh:
                    if line.startswith("VmRSS:"):
                        total += int(line.split()[1]) * 1024
        except OSError:
            pass
    return total


def _children_cpu(pid: int, seen: dict) -> None:
    """Record the CPU seconds so far of the process's descendants (their last sample counts)."""
    for d in os.listdir("/proc"):
        if d.isdigit() and int(d) != pid:
            try:
                with open(f"/proc/{d}/stat") as fh:
                    head, rest = fh.read().rsplit(")", 1)
                f = rest.split()
                if int(f[1]) == pid:
                    seen[int(d)] = (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")
            except (OSError, IndexError, ValueError):
                pass


def watch(proc, sample) -> list:
    """The lines a measured process prints after its ``START`` line, with ``sample()`` called every 50 ms
    from then until it exits (what the caller samples of it: CPU, memory)."""
    started, lines = threading.Event(), []

    def loop():
        while proc.poll() is None:
            if started.is_set():
                sample()
            time.sleep(0.05)

    mon = threading.Thread(target=loop, daemon=True)
    mon.start()
    for line in proc.stdout:
        if started.is_set():
            lines.append(line)
        elif line.startswith("START"):
            started.set()
    proc.wait()
    mon.join()
    return lines


def run_ingest(repo: Path, folders, suffix: str, processes: bool = False) -> dict:
    """One measured ingest of ``folders`` by the checkout ``repo`` in a fresh process."""
    proc = subprocess.Popen([sys.executable, "-c", _RUN, str(repo), json.dumps([str(f) for f in folders]), suffix,
                             "processes" if processes else "auto"], stdout=subprocess.PIPE, text=True, cwd="/tmp")
    peak, workers_cpu = 0, {}

    def sample():
        nonlocal peak
        peak = max(peak, _tree_rss(proc.pid))
        _children_cpu(proc.pid, workers_cpu)

    out = next((json.loads(line) for line in watch(proc, sample) if line.startswith("{")), None)
    if out is None:
        raise SystemExit(f"the ingest of {repo} failed")
    out["peak"] = peak
    out["cpu"] += sum(workers_cpu.values())
    return out


def read_through(folders) -> tuple[int, float]:
    """Read every file of ``folders`` once: ``(bytes, seconds)``. Both versions then find the archive in the
    page cache; else the first ingest of an invocation reads it from the disk and the second does not."""
    t0, n = time.perf_counter(), 0
    for folder in folders:
        for path in sorted(Path(folder).rglob("*")):
            if path.is_file():
                with open(path, "rb", buffering=0) as fh:
                    while chunk := fh.read(1 << 24):
                        n += len(chunk)
    return n, time.perf_counter() - t0


def stages(folder: Path):
    """Seconds per step of the path on one copy, one process, one core (this checkout)."""
    import mocapdb
    from mocapdb.features import motion_features
    from mocapdb.readers import find_skeleton, load_skeleton, motion_files, read_motion
    from mocapdb.readers.amc import read_amc
    from mocapdb.bodies.kinematics import asf_forward_kinematics
    from mocapdb.readers.sources import sha256
    from mocapdb.storage.ingest import store_words

    files = motion_files([folder])
    amc = files[0].suffix == ".amc"
    out = {}

    def timed(name, fn):
        fn()   # warm (compile, page cache)
        t = time.perf_counter()
        res = fn()
        out[name] = time.perf_counter() - t
        return res

    timed("hash (sha256 of the bytes)", lambda: [sha256(f) for f in files])
    if amc:
        skels = timed("skeleton lookup (find_skeleton + load)", lambda: [load_skeleton(find_skeleton(f)) for f in files])
        vals = timed("parse (read_amc, incl. file read)", lambda: [read_amc(f, s) for f, s in zip(files, skels)])
        timed("forward kinematics", lambda: [asf_forward_kinematics(s, v) for s, v in zip(skels, vals)])
        del vals
        motions = [read_motion(f, asf=s) for f, s in zip(files, skels)]
    else:
        motions = timed("read_motion (parse + FK + mapping)", lambda: [read_motion(f) for f in files])
    words = timed("features (41 + hysteresis + pack)", lambda: [motion_features(m) for m in motions])
    n = sum(m.n_frames for m in motions)

    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        con = mocapdb.connect(Path(tmp) / "s.duckdb")
        named = {f"{f.stem}_{i}": w for i, (f, w) in enumerate(zip(files, words))}
        store_words(con, dict(list(named.items())[:1]))
        t = time.perf_counter()
        store_words(con, dict(list(named.items())[1:]))
        out["store (DuckDB file, one transaction)"] = time.perf_counter() - t
        con.close()
    return n, len(files), out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=0.5, help="archive size (whole copies of 12.8 min)")
    ap.add_argument("--archive", type=Path, default=Path("/tmp/mocapdb_ingest_archive"))
    ap.add_argument("--base", type=Path, help="a checkout to compare with (e.g. of d3b3f07)")
    ap.add_argument("--formats", default="amc,bvh,amass,c3d")
    ap.add_argument("--stages", action="store_true", help="time each step on one copy first")
    ap.add_argument("--stages-only", action="store_true",
                    help="only the steps (of the mocapdb first on sys.path: PYTHONPATH=DIR for another checkout)")
    ap.add_argument("--processes", action="store_true",
                    help="ingest on the worker processes whatever the machine's load (what a quiet machine gets)")
    args = ap.parse_args()

    formats = args.formats.split(",")
    for fmt in formats:
        ingest_archive.build(args.archive, args.hours, fmt)
    print(f"machine load (1/5/15 min): {' '.join(f'{x:.1f}' for x in os.getloadavg())}; {os.cpu_count()} cores")
    if args.stages or args.stages_only:
        import mocapdb
        print(f"steps of {Path(mocapdb.__file__).parents[1]}")
        for fmt in formats:
            n, nf, st = stages(ingest_archive.copy_folders(args.archive, 0, fmt)[0])
            print(f"\n{fmt}: {nf} files, {n:,} source frames, one process, one thread")
            print(f"{'step':44s} {'seconds':>8s} {'frames/s':>11s}")
            for name, t in st.items():
                print(f"{name:44s} {t:8.3f} {n / t:11,.0f}")
            tot = sum(st.values())
            print(f"{'sum':44s} {tot:8.3f} {n / tot:11,.0f}")
    if args.stages_only:
        return
    versions = [("this", REPO)] + ([("base", args.base.resolve())] if args.base else [])
    print(f"\n{'format':6s} {'version':7s} {'files':>6s} {'frames':>11s} {'hours':>6s} {'wall s':>8s} "
          f"{'CPU s':>8s} {'frames/s':>10s} {'peak GB':>8s}")
    for fmt in formats:
        folders = ingest_archive.copy_folders(args.archive, args.hours, fmt)
        nbytes, secs = read_through(folders)
        print(f"{fmt:6s} archive read once first: {nbytes / 1e9:.2f} GB in {secs:.1f} s "
              f"({nbytes / 1e6 / secs:,.0f} MB/s)", flush=True)
        rows = {}
        for name, repo in versions:
            r = rows[name] = run_ingest(repo, folders, SUFFIX[fmt], args.processes)
            print(f"{fmt:6s} {name:7s} {r['files']:6d} {r['frames']:11,d} {r['frames'] / 432000:6.2f} "
                  f"{r['wall']:8.2f} {r['cpu']:8.2f} {r['frames'] / r['wall']:10,.0f} {r['peak'] / 1e9:8.2f}"
                  + (f"  ({r['failed']} failed)" if r["failed"] else ""), flush=True)
        if "base" in rows:
            a, b = rows["this"], rows["base"]
            speed = (a["frames"] / a["wall"]) / (b["frames"] / b["wall"])
            print(f"{fmt:6s} speed-up {speed:.2f}x; 10,000 h at this rate: "
                  f"{10_000 * 432_000 / (a['frames'] / a['wall']) / 3600:.1f} h (base "
                  f"{10_000 * 432_000 / (b['frames'] / b['wall']) / 3600:.1f} h)", flush=True)
    print(f"paper (feature extraction): {PAPER_FPS:,.0f} frames/s")


if __name__ == "__main__":
    main()
