"""The per-frame kernels of ingest, each alone: text → numbers → joints → features (issue 35).

Run: ``nice python benchmarks/bench_kernels.py [--copy DIR]`` (another checkout: ``PYTHONPATH=DIR``).
One copy of the ingest archive (:mod:`ingest_archive`, ``/tmp/mocapdb_ingest_archive/{amc,bvh}/copy000``:
the 247 ASF/AMC takes of ``hdm05_cut`` and ``cmu`` at 120 Hz, 91,859 frames, and the same takes as BVH)
is read into memory first, so no step times the disk; each step runs once to warm (numba's compile,
caches), then three times: the minimum of the process's CPU seconds is reported, per source frame
and, for parsing, per megabyte of text. One process, one thread.

Steps: ``parse AMC`` (:func:`parse_amc` of the bytes), ``FK ASF`` (:func:`asf_forward_kinematics`),
``parse BVH`` (:func:`parse_bvh` of the bytes: the hierarchy is cached per header, so this is the
motion lines), ``FK BVH`` (the FK kernel and the gather of the 24 joints, as the reader runs them),
``features AMC`` / ``features BVH`` (:func:`motion_features`: #1–41, hysteresis, resampling, packing).
"""
import argparse
import time
from pathlib import Path


def timed(fn, repeat=3):
    """Min over ``repeat`` runs of the CPU seconds of ``fn()`` (after one warm run) and its result."""
    res = fn()
    best = float("inf")
    for _ in range(repeat):
        t = time.process_time()
        res = fn()
        best = min(best, time.process_time() - t)
    return best, res


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--archive", type=Path, default=Path("/tmp/mocapdb_ingest_archive"))
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    import os
    import mocapdb
    from mocapdb.bodies.kinematics import asf_forward_kinematics
    from mocapdb.bodies.motion import Motion
    from mocapdb.features import motion_features
    from mocapdb.readers import find_skeleton, load_skeleton, read_motion
    from mocapdb.readers.amc import parse_amc
    from mocapdb.readers.bvh import _joints_and_rotation, parse_bvh
    from mocapdb.readers.bvh_mapping import plan

    print(f"kernels of {Path(mocapdb.__file__).parents[1]}; load (1/5/15 min): "
          + " ".join(f"{x:.1f}" for x in os.getloadavg()))
    rows = []

    def report(name, sec, frames, nbytes=None):
        rate = f"{nbytes / sec / 1e6:7.0f} MB/s" if nbytes else ""
        rows.append(name)
        print(f"{name:14s} {sec:7.3f} s  {sec / frames * 1e6:6.2f} µs/frame  {rate}", flush=True)

    amc_files = sorted((args.archive / "amc" / "copy000").rglob("*.amc"))
    if amc_files:
        data = [f.read_bytes() for f in amc_files]
        skels = [load_skeleton(find_skeleton(f)) for f in amc_files]
        nbytes = sum(len(d) for d in data)
        sec, motions = timed(lambda: [parse_amc(d, s, path=f) for d, s, f in zip(data, skels, amc_files)],
                             args.repeat)
        frames = sum(m.n_frames for m in motions)
        print(f"AMC: {len(amc_files)} takes, {frames:,} frames, {nbytes / 1e6:.1f} MB")
        report("parse AMC", sec, frames, nbytes)
        sec, _ = timed(lambda: [asf_forward_kinematics(s, m) for s, m in zip(skels, motions)], args.repeat)
        report("FK ASF", sec, frames)
        del motions
        whole = [read_motion(f, asf=s) for f, s in zip(amc_files, skels)]
        sec, _ = timed(lambda: [motion_features(m) for m in whole], args.repeat)
        report("features AMC", sec, frames)
        del whole

    bvh_files = sorted((args.archive / "bvh" / "copy000").rglob("*.bvh"))
    if bvh_files:
        data = [f.read_bytes() for f in bvh_files]
        nbytes = sum(len(d) for d in data)
        sec, parsed = timed(lambda: [parse_bvh(d, path=f) for d, f in zip(data, bvh_files)], args.repeat)
        frames = sum(p.values.shape[0] for p in parsed)
        print(f"BVH: {len(bvh_files)} takes, {frames:,} frames, {nbytes / 1e6:.1f} MB")
        report("parse BVH", sec, frames, nbytes)
        plans = [plan(p.hierarchy, None, p.path, None) for p in parsed]
        sec, _ = timed(lambda: [_joints_and_rotation(p, *pl) for p, pl in zip(parsed, plans)], args.repeat)
        report("FK BVH", sec, frames)
        del parsed
        whole = [read_motion(f) for f in bvh_files]
        assert all(isinstance(m, Motion) for m in whole)
        sec, _ = timed(lambda: [motion_features(m) for m in whole], args.repeat)
        report("features BVH", sec, sum(m.n_frames for m in whole))


if __name__ == "__main__":
    main()
