"""Retrain the models shipped in ``mocapdb/shipped_models/default`` and ``mocapdb/shipped_models/toolbox`` (reproducible).

Run: ``python benchmarks/train_default_model.py [--runs 20] [--seed 0] [--jobs N]``.

* ``default`` — the paper's 15 labels (Table 1) from everything in
  ``../shared/data`` (:func:`mocapdb.evaluation.development_data`): the 11
  HDM05 classes of ``hdm05_cut`` (all four actors) and the classes cut out
  of labelled CMU stretches (walks, jogs, the mocap6 exercise sets, one
  repetition each), their mirror images and reversals, and the designed
  classes of ``mocapdb/shipped_models/classes/*.toml``
  (:func:`lab.recipe.default_recipe`); designed keyframe
  queries (``--ga``: also robust GA queries), τ per class and minimum
  segment lengths
  (:func:`lab.default_model.train_recipe`), and its calibrated confidence:
  per label a map from the raw score to the share of right segments, fitted
  on a leave-one-lab-out evaluation of the recipe
  (:func:`lab.calibration.recipe_confidence_maps`). Every random step
  is seeded: the same seed gives the same Parquet files, whatever ``--jobs``.
* ``toolbox`` — the 11 HDM05 templates, identical to the authors' toolbox
  templates (../shared/oracle/templates), τ = 0.13, no keyframe queries: the
  reference mode.

Writes each model's rows as Parquet files (the shipped-model format,
:func:`mocapdb.storage.model_store.export_model`).
"""
import argparse
import dataclasses
import os
import tempfile
import time
import sys
from pathlib import Path

import mocapdb
from mocapdb.api import train
from mocapdb.storage.model_store import export_model, save_model

sys.path.append(str(Path(__file__).resolve().parents[1]))  # lab/, the development harness beside benchmarks/ (not installed)
from lab.calibration import recipe_confidence_maps
from lab.development import development_data
from lab.default_model import train_recipe
from lab.recipe import PAPER_LABELS, default_recipe

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=REPO / "mocapdb" / "shipped_models" / "default")
    ap.add_argument("--toolbox-out", type=Path, default=REPO / "mocapdb" / "shipped_models" / "toolbox")
    ap.add_argument("--runs", type=int, default=20, help="GA runs per class (paper: 100-500)")
    ap.add_argument("--generations", type=int, default=100)
    ap.add_argument("--inner-runs", type=int, default=3, help="GA runs per class and held-out group")
    ap.add_argument("--inner-generations", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=None, help="GA worker processes (default: all cores)")
    ap.add_argument("--ga", action="store_true",
                    help="also learn GA keyframe queries for learned classes (off in the shipped model)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        con = mocapdb.connect(Path(tmp) / "train.duckdb")
        try:
            t = time.perf_counter()
            toolbox = train(con, model="toolbox", folder=DATA / "hdm05_cut", replace=True,
                            description="The authors' toolbox model: the 11 HDM05 classes of hdm05_cut with the "
                                        "toolbox's templates, no keyframe queries (the reference mode)")
            export_model(con, "toolbox", args.toolbox_out)
            print(f"toolbox: {len(toolbox.classes)} templates in {time.perf_counter() - t:.1f} s")

            t = time.perf_counter()
            data = development_data(DATA)
            clips = data.clips()
            trained = train_recipe(clips, default_recipe(), name="default", keyframes=args.ga,
                                   runs=args.runs, generations=args.generations, inner_runs=args.inner_runs,
                                   inner_generations=args.inner_generations, seed=args.seed, n_jobs=args.jobs,
                                   progress=lambda what: print(f"  {what} ({time.perf_counter() - t:.0f} s)",
                                                               flush=True))
            model = trained.model
            maps = recipe_confidence_maps(DATA, data, default_recipe(), model.labels, vocabulary=PAPER_LABELS,
                                          seed=args.seed)
            model = dataclasses.replace(model, confidence_maps=maps)
            print(f"  confidence maps from leave-one-lab-out segments ({time.perf_counter() - t:.0f} s)", flush=True)
            stats = {}
            for c in model.classes:
                if c.keyframe_query is None:
                    continue
                r = trained.queries.get(c.name)
                stats[c.name] = {"source": trained.query_source[c.name]}
                if r is not None:
                    stats[c.name].update(fitness=r.fitness, precision=r.precision, recall=r.recall)
            n_clips = sum(len(v) for v in clips.values())
            ga = [(name, run, g, st.mean_precision[g], st.mean_recall[g], st.mean_fitness[g], st.best_fitness[g],
                   st.mean_keyframes[g])
                  for name, r in trained.queries.items() for run, st in enumerate(r.statistics)
                  for g in range(st.generations + 1)]
            save_model(con, model, replace=True, keyframe_stats=stats, ga_statistics=ga,
                       description="The paper's 15 labels (Table 1): HDM05 and CMU classes learned from "
                                   "../shared/data, mirrored, reversed and designed classes, designed keyframe "
                                   "queries, tau per class, minimum segment lengths, confidence calibrated on "
                                   "leave-one-lab-out segments",
                       source=f"benchmarks/train_default_model.py: {n_clips} clips (hdm05_cut, CMU stretches), "
                              f"class and keyframe definitions mocapdb/shipped_models/classes"
                              + (f", GA {args.runs} runs x {args.generations} generations (inner "
                                 f"{args.inner_runs} x {args.inner_generations}), seed {args.seed}" if args.ga else ""))
            print(f"default: {len(model.classes)} classes, {len(model.labels)} labels in "
                  f"{time.perf_counter() - t:.0f} s")
            missing = sorted(set(PAPER_LABELS) - set(model.labels))
            if missing:
                print(f"  labels without a class: {missing}")
            for c in model.classes:
                q = c.keyframe_query
                print(f"  {c.name:32s} {c.label:11s} K={len(c.quantized):4d} tau={c.tau:.2f} "
                      f"min={c.min_frames:3d} keyframes={q.n_keyframes if q else 0}  "
                      f"{trained.query_source[c.name]}")
            export_model(con, "default", args.out)
            print(f"written to {args.out} and {args.toolbox_out}")
        finally:
            con.close()


if __name__ == "__main__":
    main()
