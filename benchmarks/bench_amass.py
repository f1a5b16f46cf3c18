"""AMASS .npz: read speed and agreement with the ASF/AMC reading; export-joints round trip (issue 26).

Run: ``python benchmarks/bench_amass.py [--repeat 3] [--amass-sample FILE]``. Prints:

(a) read speed (np.load + forward kinematics + Motion, warm, one core) of AMASS-format files
    written from the 232 HDM05 cut clips (SMPL-H layout) and of one long take (86_09 repeated
    to 1 M frames), frames/s;
(b) agreement of the feature bits of each take read as AMASS (generic rest skeleton) with the
    same take read as ASF/AMC: 86_09 in the SMPL-H, SMPL-X and SMPL layouts (the generic
    skeleton is 86's own), and the 232 HDM05 clips of four other actors (their rotations on
    86's proportions): all bits, the worst clip;
(c) export-joints: the sample's ASF, BVH and C3D takes written as BVH and read back, feature
    bits equal;
(d) with ``--amass-sample FILE``, a real AMASS file that carries its markers (``markers`` or
    ``marker_data`` with ``labels``/``marker_labels``, e.g. human_body_prior's
    ``support_data/dowloads/amass_sample.npz``; AMASS's licence keeps it out of the
    repository): its generic reading against the C3D reading of its own markers.
"""
import argparse
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from timing import best_seconds  # benchmarks/timing.py

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"
SAMPLE = REPO / "mocapdb" / "sample"

from mocapdb.features import N_BITS, motion_features, unpack_words  # noqa: E402
from mocapdb.readers import read_amc, read_asf, read_motion  # noqa: E402
from mocapdb.writers.joints_write import write_joints  # noqa: E402

sys.path.append(str(Path(__file__).resolve().parents[1]))  # lab/, the development harness beside benchmarks/ (not installed)
from lab.amass_write import write_amass  # noqa: E402


def bits(m):
    return unpack_words(motion_features(m), N_BITS)


def agreement(a, b):
    x, y = bits(a), bits(b)
    return int((x == y).sum()), x.size


def hdm05_files(tmp):
    cut = DATA / "hdm05_cut"
    skels = {a: read_asf(cut / f"HDM_{a}.asf") for a in ("bd", "bk", "dg", "mm")}
    out = []
    for f in sorted(cut.glob("*/*.amc")):
        actor = f.name.split("_")[1]
        p = write_amass(Path(tmp) / (f.stem + ".npz"), skels[actor], read_amc(f, skels[actor]))
        out.append((f, cut / f"HDM_{actor}.asf", p))
    return out


def _cpu_seconds(fn, repeat):
    """Best process (CPU) time of ``repeat`` calls: the machine is shared, wall time counts the others' jobs."""
    best = float("inf")
    for _ in range(max(1, repeat)):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def read_speed(files, long_path, long_frames, repeat):
    paths = [p for *_, p in files]
    frames = sum(read_motion(p).n_frames for p in paths)
    for name, n, fn in ((f"{len(paths)} HDM05 clips as AMASS SMPL-H", frames, lambda: [read_motion(p) for p in paths]),
                        (f"one long take ({long_path.stat().st_size / 1e6:.0f} MB)", long_frames,
                         lambda: read_motion(long_path))):
        wall, cpu = best_seconds(fn, repeat), _cpu_seconds(fn, repeat)
        print(f"(a) read {name}: {n:,} frames; wall {wall:.2f} s = {n / wall:,.0f} frames/s; "
              f"CPU {cpu:.2f} s = {n / cpu:,.0f} frames/s")


def agreement_figures(tmp, files):
    skel = read_asf(SAMPLE / "86.asf")
    amc = read_amc(SAMPLE / "86_09.amc.xz", skel)
    ref = read_motion(SAMPLE / "86_09.amc.xz", asf=SAMPLE / "86.asf")
    for family in ("smplh", "smplx", "smpl"):
        p = write_amass(Path(tmp) / f"86_09_{family}.npz", skel, amc, family=family)
        same, total = agreement(read_motion(p), ref)
        print(f"(b) 86_09 as {family}: {same / total:.4%} of {total:,} feature bits equal")
    same = total = 0
    worst = (1.0, "")
    for amc_path, asf, p in files:
        s, t = agreement(read_motion(p), read_motion(amc_path, asf=asf))
        same, total = same + s, total + t
        worst = min(worst, (s / t, amc_path.stem))
    print(f"    {len(files)} HDM05 clips (4 actors) on the generic skeleton: {same / total:.4%} of {total:,} bits "
          f"equal; worst clip {worst[1]} {worst[0]:.2%}")


def export_round_trip(tmp):
    takes = [(SAMPLE / "86_09.amc.xz", {"asf": SAMPLE / "86.asf"}),
             (SAMPLE / "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh.xz", {}), (SAMPLE / "HDM_mm_01-02_03_120.c3d.xz", {})]
    for path, kw in takes:
        m = read_motion(path, **kw)
        out = Path(tmp) / "take.bvh"
        write_joints(out, m, format="bvh")
        same, total = agreement(m, read_motion(out))
        print(f"(c) export-joints --format bvh, read back: {path.name}: {same / total:.4%} of {total:,} bits equal")


def markers_trial(path, tmp):
    import ezc3d

    z = np.load(path)
    key = "markers" if "markers" in z.files else "marker_data"
    labels = [x.decode() if isinstance(x, bytes) else str(x) for x in z["labels" if "labels" in z.files
                                                                            else "marker_labels"]]
    xyz = np.nan_to_num(z[key] * 1000.0)   # metres → mm; a missing marker is (0, 0, 0) in C3D
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(z["mocap_framerate"])]
    c["parameters"]["POINT"]["LABELS"]["value"] = labels
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, len(labels), len(xyz)))
    pts[:3] = np.transpose(xyz, (2, 1, 0))
    c["data"]["points"] = pts
    c3d = str(Path(tmp) / "markers.c3d")
    c.write(c3d)
    same, total = agreement(read_motion(path), read_motion(c3d))
    print(f"(d) {Path(path).name} (generic skeleton) against the C3D reading of its own {len(labels)} markers: "
          f"{same / total:.2%} of {total:,} bits equal")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--amass-sample", type=Path)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        files = hdm05_files(tmp)
        skel = read_asf(SAMPLE / "86.asf")
        amc = read_amc(SAMPLE / "86_09.amc.xz", skel)
        reps = -(-1_000_000 // amc.n_frames)
        long_amc = replace(amc, values=np.tile(amc.values, (reps, 1)))
        long_path = write_amass(Path(tmp) / "long.npz", skel, long_amc)
        read_motion(files[0][2])   # compile
        read_speed(files, long_path, long_amc.n_frames, args.repeat)
        agreement_figures(tmp, files)
        export_round_trip(tmp)
        if args.amass_sample:
            markers_trial(args.amass_sample, tmp)
    print(f"machine: {os.cpu_count()} cores; {time.strftime('%Y-%m-%d')}")


if __name__ == "__main__":
    sys.exit(main())
