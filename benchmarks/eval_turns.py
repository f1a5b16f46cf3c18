"""Turns while walking: does the default model label a walker who turns round with `turn`, and only them?

Run: ``python benchmarks/eval_turns.py [--previous REV …] [--model-dir DIR …] [--json benchmarks/eval_turns.json]``.

Walks of three walkers from two labs, made to turn (:mod:`lab.turns`:
the body's own motion kept, the path and heading turned):

* CMU 02_01 and 02_02 (subject 2, ASF/AMC, straight walks of 2.5–2.9 s);
* CMU 86_09's two walks (subject 86, a slow walker walking in circles),
  straightened: 7.3 s and 9.1 s;
* the PyMO BVH walk (another lab's figure-of-eight walk, 120 Hz), straightened: 8.9 s.

Each walk turns round — by 180° either way or by 135°, over 1, 1.5, 2 or 2.5 s,
evenly or step by step (the heading turning while a foot swings, as people
turn) — or bends slightly (±30°, ±45°, ±60° over 1 or 2 s), or stays straight.
A 90° corner is reported on its own (neither a turn round nor a slight bend).
Real recordings beside them: the Mixamo clip (a walker who turns round),
86_09 as recorded (walking in circles; its ground truth says walk), the PyMO
walk as recorded (a figure of eight: two U-turns and bends).

Figures per model: recall on turning walks (share of the turning frames
labelled turn, and turns with at least one such frame), false turns on
straight and bending walks (walks with a turn frame, turn frames). The
development documents' false turns are in benchmarks/eval_quality.json
(per label, `turn`).
"""
import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[1]))  # lab/, the development harness beside benchmarks/ (not installed)

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"

TURNS = ((180, (1.0, 1.5, 2.0, 2.5)), (-180, (1.0, 1.5, 2.0, 2.5)), (135, (1.0, 1.5, 2.0, 2.5)))
BENDS = ((30, (1.0, 2.0)), (-30, (1.0, 2.0)), (45, (1.0, 2.0)), (-45, (1.0, 2.0)), (60, (1.0, 2.0)),
         (-60, (1.0, 2.0)))
CORNERS = ((90, (1.0, 2.0)), (-90, (1.0, 2.0)))
STYLES = ("steps", "bursts", "smooth")


def walks():
    """The straight walks: name → Motion."""
    from lab.turns import straightened_walk
    from mocapdb.readers import read_motion

    walk86 = read_motion(DATA / "cmu" / "86" / "86_09.amc")
    return {"cmu02_01": read_motion(DATA / "cmu" / "02" / "02_01.amc"),
            "cmu02_02": read_motion(DATA / "cmu" / "02" / "02_02.amc"),
            # 86_09's walk segments (labels/cmu86_segmentation, 120 Hz frames 1-880 and 3700-4794)
            "cmu86_09 walk 1": straightened_walk(walk86, start=0, stop=880),
            "cmu86_09 walk 2": straightened_walk(walk86, start=3699, stop=4794)}


def variants(walk, table):
    """(name, turned walk, degrees, start, seconds) for every angle, time and style that fits the walk."""
    from lab.turns import turning_walk

    span = walk.n_frames / walk.fps
    for degrees, times in table:
        for seconds in times:
            # the turn in the middle of the walk, at least 0.5 s of walking before and after
            start = round(max(0.5, (span - seconds) / 2), 2)
            if start + seconds > span - 0.5:
                continue
            for style in STYLES:
                yield f"{style} {degrees:+d}° in {seconds:g} s", turning_walk(walk, start, seconds, degrees,
                                                                              style=style), start, seconds


def turn_frames(model, motion):
    """(n,) bool: 30 Hz frames labelled turn, and the segments."""
    from mocapdb.annotation import annotate, preselection_for
    from mocapdb.features import motion_features

    w = motion_features(motion)
    segs = annotate(w, model, preselection=preselection_for(w, [len(w)], model)).segments
    out = np.zeros(len(w), bool)
    for s in segs[segs["label"] == "turn"]:
        out[s["start"]:s["end"] + 1] = True
    return out, segs


def heading_turn_frames(motion, rate=60.0):
    """30 Hz frames where the hip axis turns faster than ``rate`` °/s (over 1/3 s): a real take's turning."""
    from lab.turns import hip_heading

    step = max(1, int(round(motion.fps / 30)))
    h = np.degrees(hip_heading(motion))[::step]
    k = 5
    d = np.zeros_like(h)
    d[k:-k] = (h[2 * k:] - h[:-2 * k]) / (2 * k / 30.0)
    return np.abs(d) > rate


def evaluate(model, verbose=False):
    from mocapdb.readers import read_motion

    out = {"turning": [], "bending": [], "straight": [], "corner": [], "real": {}}
    for wname, walk in walks().items():
        got, _ = turn_frames(model, walk)
        out["straight"].append({"walk": wname, "turn_frames": int(got.sum()), "frames": int(got.size)})
        for kind, table in (("turning", TURNS), ("bending", BENDS), ("corner", CORNERS)):
            for name, turned, start, seconds in variants(walk, table):
                got, segs = turn_frames(model, turned)
                truth = np.zeros(got.size, bool)
                truth[int(round(start * 30)):int(round((start + seconds) * 30))] = True
                row = {"walk": wname, "what": name, "turn_frames": int(got.sum()), "frames": int(got.size),
                       "truth_frames": int(truth.sum()), "found": int((got & truth).sum())}
                out[kind].append(row)
                if verbose:
                    print(f"  {kind:8s} {wname:16s} {name:22s} turn {row['found']:3d}/{row['truth_frames']:3d} of the "
                          f"turn, {row['turn_frames']:3d} frames: " + ", ".join(
                              f"{s['label']} {s['start']}-{s['end']}" for s in segs))
    for name, path in (("mixamo (turns round)", DATA / "foreign" / "bvh" / "mixamo_freebvh.bvh"),
                       ("HDM_mm_01-02_03 (C3D; turns round at its end)",
                        DATA / "hdm05_full" / "HDM_mm_01-02_03_120.c3d"),
                       ("pymo figure of eight", DATA / "foreign" / "bvh" / "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh"),
                       ("cmu86_09 (walks in circles)", DATA / "cmu" / "86" / "86_09.amc")):
        m = read_motion(path)
        got, segs = turn_frames(model, m)
        turning = heading_turn_frames(m)[:got.size]
        out["real"][name] = {"turn_frames": int(got.sum()), "frames": int(got.size),
                             "turning_frames": int(turning.sum()), "turn_on_turning": int((got & turning).sum()),
                             "segments": [(str(s["label"]), int(s["start"]), int(s["end"])) for s in segs]}
    return out


def summary(res):
    t = res["turning"]
    s = {"turn_recall_frames": sum(r["found"] for r in t) / max(1, sum(r["truth_frames"] for r in t)),
         "turns_found": sum(r["found"] > 0 for r in t), "turns": len(t)}
    for kind in ("bending", "straight", "corner"):
        s[f"{kind}_with_turn"] = sum(r["turn_frames"] > 0 for r in res[kind])
        s[f"{kind}_walks"] = len(res[kind])
        s[f"{kind}_turn_frames"] = sum(r["turn_frames"] for r in res[kind])
        s[f"{kind}_frames"] = sum(r["frames"] for r in res[kind])
    for style in STYLES:
        rows = [r for r in t if r["what"].startswith(style)]
        s[f"turns_found_{style}"] = sum(r["found"] > 0 for r in rows)
        s[f"turns_{style}"] = len(rows)
    return s


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model-dir", type=Path, action="append", default=[],
                    help="a model exported as Parquet files (train_default_model.py's format); repeatable; "
                         "default: the shipped default model")
    ap.add_argument("--previous", metavar="REV", action="append", default=[],
                    help="also the default model as committed at this git revision (repeatable)")
    ap.add_argument("--json", type=Path, default=None, help="write the figures here")
    ap.add_argument("--verbose", action="store_true", help="every walk's segments")
    args = ap.parse_args()
    from mocapdb.storage.model_store import model_from_tables, shipped_model_tables
    from timing import model_at, model_dir

    models = {f"default at {rev}": model_at(rev) for rev in args.previous}
    models.update({str(d): model_dir(d) for d in args.model_dir} or {
        "shipped default": model_from_tables(shipped_model_tables("default"))})
    report = {}
    for name, model in models.items():
        print(f"## {name}")
        res = evaluate(model, verbose=args.verbose)
        s = summary(res)
        report[name] = {"summary": s, "walks": res}
        print(f"turning walks (turned round, 135-180°): turn on {s['turn_recall_frames']:.1%} of the turning "
              f"frames; {s['turns_found']}/{s['turns']} turns found (step by step {s['turns_found_steps']}/"
              f"{s['turns_steps']}, in bursts {s['turns_found_bursts']}/{s['turns_bursts']}, evenly "
              f"{s['turns_found_smooth']}/{s['turns_smooth']})")
        print(f"bending walks (30-60°): {s['bending_with_turn']}/{s['bending_walks']} with a turn, "
              f"{s['bending_turn_frames']} of {s['bending_frames']} frames; straight walks: "
              f"{s['straight_with_turn']}/{s['straight_walks']}, {s['straight_turn_frames']} frames; "
              f"90° corners: {s['corner_with_turn']}/{s['corner_walks']} with a turn")
        for rname, r in res["real"].items():
            print(f"{rname}: turn on {r['turn_frames']} of {r['frames']} frames ({r['turn_on_turning']} of the "
                  f"{r['turning_frames']} frames turning faster than 60°/s); " +
                  ", ".join(f"{lab} {a}-{b}" for lab, a, b in r["segments"]))
        print()
    if args.json:
        args.json.write_text(json.dumps(report, indent=1, sort_keys=True) + "\n")
        print(f"figures written to {args.json}")


if __name__ == "__main__":
    main()
