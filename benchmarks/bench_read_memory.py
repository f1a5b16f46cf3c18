"""Memory and time of reading large and odd files (issue 22 item 7).

Run: ``python benchmarks/bench_read_memory.py [--mb 250] [--siblings 100000]``. Prints:

(a) peak resident memory of ``read_motion`` (one child process per file, peak RSS above the
    interpreter's after imports and a warm-up read) against the file's size, for a BVH (the pymo walk
    repeated), the same BVH gzipped, and an AMC (CMU 86_09 repeated) of about ``--mb`` MB;
    previously 2.2–5.4× the file's size (a 245 MB BVH: 1.32 GB, issue 22);
(b) the streamed SHA-256 of the BVH: peak RSS above baseline;
(c) reading a BVH of ``--siblings`` sibling joints (refused: not a humanoid), time;
    previously 222 s for 100,000.

``--bombs [--repo DIR]`` instead: the ingest (the CLI, a fresh process) of compression bombs beside the
shipped sample (issue 27 item 2) — a ~2 MB ``.bvh.gz`` that expands to 2 GiB and one to 1 GiB (the
walk's header, then lines of zeros: valid frames), a zip member of 2 GiB and an ``.xz`` of 2 GiB —
wall seconds, peak RSS, and what the summary says; ``--repo`` runs another checkout's CLI (the
figures before a change), ``--timeout`` stops a run.
"""
import argparse
import gzip
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"

CHILD = r"""
import resource, sys
from mocapdb.readers import read_motion
from mocapdb.readers.sources import sha256
path, what, warm = sys.argv[1], sys.argv[2], sys.argv[3]
read_motion(warm, **({"asf": sys.argv[4]} if len(sys.argv) > 4 else {}))   # compile, import everything
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
if what == "read":
    m = read_motion(path, **({"asf": sys.argv[4]} if len(sys.argv) > 4 else {}))
    n = m.n_frames
else:
    sha256(path)
    n = 0
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(base * 1024, peak * 1024, n)
"""


def bvh_of(src: Path, mb: float, dst: Path) -> Path:
    head, _, body = src.read_bytes().partition(b"MOTION")
    lines = body.split(b"\n")
    frames = [ln for ln in lines[3:] if ln.strip()]
    reps = max(1, int(mb * 1e6 / sum(len(f) + 1 for f in frames)))
    with open(dst, "wb") as fh:
        fh.write(head + b"MOTION\nFrames: %d\n" % (len(frames) * reps) + lines[2] + b"\n")
        for _ in range(reps):
            fh.write(b"\n".join(frames) + b"\n")
    return dst


def amc_of(src: Path, mb: float, dst: Path) -> Path:
    lines = src.read_bytes().split(b"\n")
    start = next(i for i, ln in enumerate(lines) if ln.strip().isdigit())
    frames, cur = [], []
    for ln in lines[start:]:
        if ln.strip().isdigit():
            if cur:
                frames.append(cur)
            cur = []
        elif ln.strip():
            cur.append(ln)
    frames.append(cur)
    size = sum(sum(len(x) + 1 for x in f) + 6 for f in frames)
    reps = max(1, int(mb * 1e6 / size))
    with open(dst, "wb") as fh:
        fh.write(b"\n".join(lines[:start]) + b"\n")
        k = 0
        for _ in range(reps):
            for f in frames:
                k += 1
                fh.write(b"%d\n" % k + b"\n".join(f) + b"\n")
    return dst


def measure(path: Path, what: str, warm: Path, asf=None):
    args = [sys.executable, "-c", CHILD, str(path), what, str(warm)] + ([str(asf)] if asf else [])
    out = subprocess.run(args, capture_output=True, text=True, check=True).stdout.split()
    base, peak, n = map(int, out)
    return peak - base, n


def star(n: int) -> bytes:
    rows = ["HIERARCHY", "ROOT Hips", "{", " OFFSET 0 0 0",
            " CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation"]
    for k in range(n):
        rows += [f" JOINT J{k}", " {", f"  OFFSET {k % 7} 1 0", "  CHANNELS 3 Zrotation Yrotation Xrotation",
                 "  End Site", "  {", "   OFFSET 0 1 0", "  }", " }"]
    row = " ".join(["0"] * (6 + 3 * n))
    rows += ["}", "MOTION", "Frames: 2", "Frame Time: 0.0333333", row, row]
    return ("\n".join(rows) + "\n").encode()


def cli_run(bench_scale, args, timeout) -> dict:
    """``mocapdb ARGS`` in a fresh process as bench_scale.run_cli, but a failed ingest is a result too and
    a run past ``timeout`` seconds is killed (its peak RSS polled until then)."""
    with tempfile.NamedTemporaryFile(suffix=".rss") as rss:
        env = dict(os.environ, PYTHONPATH=str(bench_scale.REPO), BENCH_RSS_FILE=rss.name)
        t = time.perf_counter()
        p = subprocess.Popen([sys.executable, "-P", "-c", bench_scale.CLI_CHILD, *map(str, args)], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        polled = 0
        while p.poll() is None and time.perf_counter() - t < timeout:
            try:
                status = Path(f"/proc/{p.pid}/status").read_text()
                polled = max(polled, int(status.split("VmHWM:")[1].split()[0]))
            except (OSError, IndexError, ValueError):
                pass
            time.sleep(0.5)
        killed = p.poll() is None
        if killed:
            p.kill()
        out, err = p.communicate()
        dt = time.perf_counter() - t
        kb = int(Path(rss.name).read_text() or 0) or polled
    return {"s": dt, "gb": kb / 2**20, "stdout": out, "stderr": err, "killed": killed}


def bombs(a):
    """--bombs: each bomb ingested with the sample, in a fresh process."""
    sys.path.insert(0, str(REPO / "benchmarks"))
    sys.path.insert(0, str(REPO / "tests"))
    import bench_scale
    from bench_annotate import machine_header
    from fuzzing import bomb, zip_bomb

    if a.repo is not None:
        bench_scale.REPO = a.repo.resolve()
    machine_header(f"bench_read_memory --bombs: compression bombs beside the sample, checkout {bench_scale.REPO}")
    walk = (DATA / "foreign" / "bvh" / "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh").read_bytes()
    head, _, body = walk.partition(b"MOTION")
    zeros = b" ".join([b"0"] * len(body.split(b"\n")[3].split())) + b"\n"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        sample = REPO / "mocapdb" / "sample"
        bench_scale.run_cli(["--db", tmp / "warm.duckdb", "ingest", "--silent", "--sample"])   # compile once
        cases = []
        for gib in (2, 1):
            path = tmp / f"walk_{gib}gib.bvh.gz"
            frames = (gib << 30) // len(zeros)
            path.write_bytes(bomb("gz", gib << 30, head=head + b"MOTION\nFrames: %d\nFrame Time: 0.0083333\n" % frames,
                                  line=zeros))
            cases.append((f"{path.stat().st_size / 1e6:.1f} MB .bvh.gz → {gib} GiB of frames", path))
        cases.append(("zip member → 2 GiB", zip_bomb(tmp / "bomb.zip", "takes/bomb.bvh", 2 << 30) / "takes/bomb.bvh"))
        xz = tmp / "bomb.c3d.xz"
        xz.write_bytes(bomb("xz", 2 << 30))
        cases.append((f"{xz.stat().st_size / 1e6:.1f} MB .c3d.xz → 2 GiB", xz))
        rows = []
        for what, path in [("none (the sample alone)", None), *cases]:
            db = tmp / "b.duckdb"
            for f in tmp.glob("b.duckdb*"):
                f.unlink()
            args = ["--db", db, "ingest", *([path] if path else []), *sorted(sample.glob("*.xz"))]
            r = cli_run(bench_scale, args, a.timeout)
            failed = [ln for ln in r["stderr"].splitlines() if ln.startswith("failed")]
            said = ("killed after the timeout" if r["killed"] else
                    (r["stdout"].strip().splitlines() or ["(no summary)"])[-1]
                    + (f"; {failed[0].replace(str(tmp) + '/', '')[:110]}…" if failed else ""))
            print(f"  {what}: {r['s']:.1f} s, peak {r['gb']:.2f} GB; {said}", flush=True)
            rows.append((what, r, said))
    print("\n| bomb | s | peak GB | summary |\n|---|---:|---:|---|")
    for what, r, said in rows:
        print(f"| {what} | {r['s']:.1f} | {r['gb']:.2f} | {said} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mb", type=float, default=250.0)
    ap.add_argument("--siblings", type=int, default=100_000)
    ap.add_argument("--bombs", action="store_true", help="ingest compression bombs beside the sample instead")
    ap.add_argument("--repo", type=Path, help="with --bombs: the checkout whose CLI runs (default: this one)")
    ap.add_argument("--timeout", type=float, default=900.0, help="with --bombs: seconds before a run is stopped")
    a = ap.parse_args()
    if a.bombs:
        return bombs(a)
    walk = DATA / "foreign" / "bvh" / "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh"
    amc, asf = DATA / "cmu" / "86" / "86_09.amc", DATA / "cmu" / "86" / "86.asf"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        big = bvh_of(walk, a.mb, tmp / "big.bvh")
        gz = tmp / "big.bvh.gz"
        with open(big, "rb") as src, gzip.open(gz, "wb", compresslevel=1) as dst:
            while chunk := src.read(1 << 24):
                dst.write(chunk)
        big_amc = amc_of(amc, a.mb, tmp / "big.amc")
        print(f"(a) peak RSS of read_motion above baseline (measured under load), file of ~{a.mb:g} MB")
        for label, path, warm, skel in (("BVH", big, walk, None), ("BVH .gz", gz, walk, None),
                                        ("AMC", big_amc, amc, asf)):
            size = (big if label == "BVH .gz" else path).stat().st_size
            t = time.perf_counter()
            rss, n = measure(path, "read", warm, skel)
            print(f"    {label:8s} {size / 1e6:7.1f} MB ({n} frames): {rss / 1e6:7.1f} MB = {rss / size:.2f}x "
                  f"the {'decompressed ' if label == 'BVH .gz' else ''}size, {time.perf_counter() - t:.1f} s")
        rss, _ = measure(big, "hash", walk)
        print(f"(b) streamed sha256 of the BVH: {rss / 1e6:.1f} MB above baseline")
        star_path = tmp / "star.bvh"
        star_path.write_bytes(star(a.siblings))
        t = time.perf_counter()
        subprocess.run([sys.executable, "-c", "import sys\nfrom mocapdb.readers import read_motion\n"
                        "try:\n    read_motion(sys.argv[1])\nexcept Exception as e:\n    print(str(e)[:90])",
                        str(star_path)], check=True)
        print(f"(c) {a.siblings} sibling joints: {time.perf_counter() - t:.1f} s (a fresh process, imports "
              "included)")


if __name__ == "__main__":
    main()
