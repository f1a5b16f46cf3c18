"""BVH from other tools: read speed, the foreign folder's outcomes, fuzzing (issue 9).

Run: ``python benchmarks/bench_bvh.py [--repeat 5] [--fuzz 10000]``. Prints:

(a) BVH read speed (parse + FK + mapping, warm, one core) on all 232 HDM05 cut
    clips written as BVH: with cmuconvert names and 6 decimals (how most
    exporters write) and with the writer's 12 significant digits. Target
    >= 300,000 frames/s; previous 89,000 (issue 9's measurement) — 115,000 on
    this machine before issue 9 (RESULTS.md "Ingest").
(b) ``mocapdb ingest ../shared/data/foreign/bvh``: outcome per file, time.
(c) seeded fuzzing of real AMC/ASF/BVH through ``read_motion`` (tests/fuzzing.py):
    cases, refused, accepted, escaped exceptions (must be 0), time.
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
sys.path.insert(0, str(REPO / "tests"))
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"

import mocapdb  # noqa: E402
from mocapdb.errors import MocapdbError  # noqa: E402
from mocapdb.readers import read_amc, read_asf, read_bvh, read_motion  # noqa: E402
from mocapdb.writers import write_bvh


def fixed_decimals(path: Path, digits=6) -> Path:
    """The same file with every motion value as ``%.6f`` (MotionBuilder, Blender, Mixamo style)."""
    head, body = path.read_text().split("MOTION\n")
    lines = body.split("\n")
    rows = [" ".join(f"{float(v):.{digits}f}" for v in ln.split()) for ln in lines[2:] if ln.strip()]
    out = path.with_name(path.stem + "_f6.bvh")
    out.write_text(head + "MOTION\n" + "\n".join(lines[:2]) + "\n" + "\n".join(rows) + "\n")
    return out


def read_speed(repeat):
    cut = DATA / "hdm05_cut"
    files = sorted(cut.glob("*/*.amc"))
    skels = {a: read_asf(cut / f"HDM_{a}.asf") for a in ("bd", "bk", "dg", "mm")}
    n = 0
    with tempfile.TemporaryDirectory() as tmp:
        six, twelve = [], []
        for f in files:
            s = skels[f.name.split("_")[1]]
            m = read_amc(f, s)
            n += m.n_frames
            p = write_bvh(Path(tmp) / (f.stem + ".bvh"), s, m, layout="cmu")
            twelve.append(p)
            six.append(fixed_decimals(p))
        mb6 = sum(p.stat().st_size for p in six) / 1e6
        for name, paths, mb in (("cmuconvert names, %.6f values", six, mb6),
                                ("cmuconvert names, 12 significant digits", twelve,
                                 sum(p.stat().st_size for p in twelve) / 1e6)):
            [read_bvh(p) for p in paths[:5]]  # compile / cache
            t = best_seconds(lambda: [read_bvh(p) for p in paths], repeat)
            print(f"BVH read ({name}): {n / t:,.0f} frames/s ({t:.3f} s for {len(paths)} files, "
                  f"{n:,} frames, {mb:.1f} MB; target >= 300,000; previous 89,000)")


def foreign_ingest():
    folder = DATA / "foreign" / "bvh"
    with tempfile.TemporaryDirectory() as tmp:
        con = mocapdb.connect(Path(tmp) / "f.duckdb")
        t = time.perf_counter()
        report = mocapdb.ingest(con, [folder])
        elapsed = time.perf_counter() - t
        rows = {r[0]: r[1:] for r in con.execute(
            "SELECT source_path, source_fps, n_source_frames, n_frames, skeleton FROM motions").fetchall()}
        con.close()
    print(f"\ningest {folder}: {report.summary()} in {elapsed:.2f} s")
    print("| file | outcome | source rate | source frames | 30 Hz frames |")
    print("|---|---|---|---|---|")
    for p, *_ in report.ingested:
        fps, n, n30, skel = rows[str(Path(p).resolve())]
        print(f"| {Path(p).name} | ingested ({skel}) | {fps:g} Hz | {n} | {n30} |")
    for p, reason in report.failed:
        print(f"| {Path(p).name} | refused: {reason.split(': ', 1)[1][:90]}… | | | |")


def fuzz(cases):
    from fuzzing import mutate

    amc = DATA / "hdm05_cut/kickLFront1Reps/HDM_bd_kickLFront1Reps_001_120.amc"
    asf = DATA / "hdm05_cut/HDM_bd.asf"
    lines, out, seen = amc.read_bytes().split(b"\n"), [], 0
    for ln in lines:
        seen += ln.strip().isdigit()
        if seen > 40:
            break
        out.append(ln)
    short = b"\n".join(out) + b"\n"
    srcs = [("amc", short)] * 3 + [("asf", asf.read_bytes())] * 2 + \
        [("bvh", p.read_bytes()) for p in sorted((DATA / "foreign/bvh").glob("*.bvh"))]
    rng = np.random.default_rng(1)
    refused = accepted = escaped = 0
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        t = time.perf_counter()
        for _ in range(cases):
            kind, data = srcs[int(rng.integers(0, len(srcs)))]
            bad = mutate(data, rng)
            if kind == "asf":
                (tmp / "m.asf").write_bytes(bad)
                (tmp / "a.amc").write_bytes(short)
                path, kw = tmp / "a.amc", {"asf": tmp / "m.asf"}
            else:
                path, kw = tmp / f"t.{kind}", ({"asf": asf} if kind == "amc" else {})
                path.write_bytes(bad)
            try:
                m = read_motion(path, **kw)
                mocapdb.features.motion_features(m)
                accepted += 1
            except MocapdbError:
                refused += 1
            except Exception:  # noqa: BLE001 - counted, must be 0
                escaped += 1
        elapsed = time.perf_counter() - t
    print(f"\nfuzz: {cases:,} mutated real files in {elapsed:.1f} s: {refused:,} refused with a MocapdbError, "
          f"{accepted:,} accepted (finite, features computed), {escaped} escaped exceptions (must be 0)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--fuzz", type=int, default=10_000)
    args = ap.parse_args()
    print(f"# bench_bvh; os.cpu_count() = {os.cpu_count()}; load {os.getloadavg()[0]:.2f}")
    read_speed(args.repeat)
    foreign_ingest()
    fuzz(args.fuzz)


if __name__ == "__main__":
    main()
