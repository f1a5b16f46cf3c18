"""Annotation quality on the development evaluation: the reference mode, the previous and the new default.

Runs :func:`mocapdb.evaluation.development_evaluation` three times on the
same folds and documents, every setting scored over the paper's 15 labels
(Table 1; truth labels outside them are 'others', left unlabelled by a good
annotation):

* **reference** — the toolbox's way: a template per HDM05 class (11
  classes), τ = 0.13, no keyframes (the shipped model ``toolbox`` with
  ``--no-keyframes``, bit-identical to the authors' toolbox);
* **previous default** — the same 11 templates with GA keyframe queries
  learned on each fold's clips (the default model before issue 11);
* **new default** — :func:`mocapdb.learning.default_model.train_recipe`
  with :func:`mocapdb.learning.recipe.default_recipe` on each fold's
  clips: learned HDM05 and CMU-stretch classes, mirrored and reversed
  classes, the designed classes and keyframes of ``mocapdb/shipped_models/classes``
  (``--ga``: also robust GA keyframe queries), τ per class, minimum segment
  length — annotated in its default mode and with each addition switched off.

Folds: leave-one-actor-out on hdm05_cut (loao; its mirror image
loao_mirrored), and CMU 86_09 / mocap6, each CMU document annotated by a
model built without its own stretches (leave-one-document-out). The
preselection check compares, per label, the truth segments the default
mode's preselection removes with those the reference mode misses.

Usage: python benchmarks/eval_quality.py [--ga] [--runs 20] [--generations 100]
       [--inner-runs 5] [--inner-generations 50] [--seed 0] [--jobs 2]
       [--json benchmarks/eval_quality.json] [--quick]
"""
import argparse
import json
import os
import platform
import time
from pathlib import Path

import numba

from mocapdb.evaluation import SETTINGS, development_data, development_evaluation, evaluate_by_label
from mocapdb.learning import learn_keyframe_queries
from mocapdb.learning.default_model import train_recipe
from mocapdb.learning.recipe import PAPER_LABELS, default_recipe

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"

#: paper Table 2 (Müller, Baak & Seidel 2009): P1 R1 F1 P2 R2 F2
PAPER = {
    ("total", "without keyframes"): (0.48, 0.78, 0.60, 0.57, 0.91, 0.70),
    ("total", "with keyframes"): (0.69, 0.79, 0.74, 0.78, 0.88, 0.82),
    ("CMU", "with keyframes"): (0.66, 0.74, 0.70, 0.65, 0.91, 0.76),
}
#: the new default's modes: the default, and each addition switched off
NEW_MODES = {
    "new default": {},
    "  no keyframes": {"keyframes": False},
    "  tau 0.13 for all": {"tau": 0.13},
    "  no minimum length": {"min_length": False},
    "  no won-frames rule": {"min_won": False},
    "  margin 0.01": {"margin": 0.01},
}
MEASURES = ("p1", "r1", "f1", "p2", "r2", "f2")


def previous_default(runs, seed, generations, jobs):
    """The default model before issue 11: the toolbox's templates + GA queries of the fold's clips."""
    def attach(model, clips):
        learned = learn_keyframe_queries(clips, runs=runs, random_state=seed, n_jobs=jobs, generations=generations,
                                         templates={c.name: c.template for c in model.classes})
        return model.with_keyframe_queries({name: lq.query for name, lq in learned.items()})
    return attach


def new_default(args, report):
    cache = {}
    recipe = default_recipe()

    def build(clips, name):
        t = time.perf_counter()
        trained = train_recipe(clips, recipe, name=name, keyframes=args.ga, runs=args.runs,
                               generations=args.generations,
                               inner_runs=args.inner_runs, inner_generations=args.inner_generations, seed=args.seed,
                               n_jobs=args.jobs, cache=cache)
        kept = sum(1 for q in trained.queries.values() if q.query is not None)
        report[name] = {c: src for c, src in trained.query_source.items()}
        print(f"  built {name}: {len(trained.model.classes)} classes, {kept}/{len(trained.queries)} learned "
              f"queries kept, {time.perf_counter() - t:.0f} s", flush=True)
        return trained.model
    return build


def _row(name, sc):
    return f"{name:<26s}" + " ".join(f"{getattr(sc, m):5.2f}" for m in MEASURES)


def _missed_by_preselection(res, setting):
    """Per label: share of truth segments without a preselected frame of the label."""
    by = evaluate_by_label(res.truth[setting], res.preselected[setting], labels=PAPER_LABELS)
    return {lab: 1.0 - sc.r2 for lab, sc in by.items() if sc.truth_segments}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--runs", type=int, default=20, help="GA runs per class (paper: 100-500)")
    ap.add_argument("--generations", type=int, default=100)
    ap.add_argument("--inner-runs", type=int, default=3, help="GA runs per class and held-out group")
    ap.add_argument("--inner-generations", type=int, default=50)
    ap.add_argument("--jobs", type=int, default=None, help="GA worker processes (default: all cores)")
    ap.add_argument("--json", type=Path, default=REPO / "benchmarks" / "eval_quality.json",
                    help="write the figures here (the tests read them)")
    ap.add_argument("--quick", action="store_true", help="5 GA runs of 50 generations, 3 inner runs (a look)")
    ap.add_argument("--ga", action="store_true",
                    help="the new default with GA keyframe queries for its learned classes (off in the shipped one)")
    args = ap.parse_args()
    if args.quick:
        args.runs, args.generations, args.inner_runs = 5, 50, 3
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cpus, numba threads "
          f"{numba.config.NUMBA_NUM_THREADS}; data {DATA}")
    print(f"GA: {args.runs} runs x {args.generations} generations, inner {args.inner_runs} x "
          f"{args.inner_generations}, seed {args.seed}\n")
    t0 = time.perf_counter()
    data = development_data(DATA)
    common = dict(data=data, vocabulary=PAPER_LABELS, mirrored=True, seed=args.seed)
    results, timings = {}, {}
    t = time.perf_counter()
    results["reference"] = development_evaluation(DATA, cmu_training=False, tau=0.13, **common)
    timings["reference"] = time.perf_counter() - t
    t = time.perf_counter()
    results["previous default"] = development_evaluation(
        DATA, cmu_training=False, tau=0.13,
        keyframes=previous_default(args.runs, args.seed, args.generations, args.jobs), **common)
    timings["previous default"] = time.perf_counter() - t
    t = time.perf_counter()
    sources = {}
    results.update(development_evaluation(DATA, build=new_default(args, sources), modes=NEW_MODES, **common))
    timings["new default"] = time.perf_counter() - t

    print(f"\nDevelopment evaluation over the paper's 15 labels (seed {args.seed})\n")
    print(f"{'':<26s}   P1    R1    F1    P2    R2    F2")
    for s in SETTINGS:
        docs = results["reference"].documents.get(s)
        size = f" ({len(docs.names)} documents, {int(docs.doc_lengths.sum())} frames)" if docs is not None else ""
        print(f"{s}{size}")
        for mode, res in results.items():
            if s in res.scores:
                print(_row("  " + mode, res.scores[s]))
    print()
    for (part, kf), v in PAPER.items():
        print(f"{'paper ' + part + ', ' + kf:<40s}" + " ".join(f"{x:5.2f}" for x in v))
    dropped = results["reference"].scores["all"].dropped_truth
    print("\n'others' in the truth (dropped from scoring): " + ", ".join(f"{k} x{v}" for k, v in sorted(dropped.items())))

    per_label = {}
    for s in ("loao", "loao_mirrored", "cmu"):
        print(f"\nper label, {s}: F1 / F2 (truth segments)")
        print(f"{'':<14s}" + "".join(f"{m[:18]:>20s}" for m in results))
        table = {m: evaluate_by_label(r.truth[s], r.auto[s], labels=PAPER_LABELS) for m, r in results.items()}
        per_label[s] = {m: {lab: {k: getattr(sc, k) for k in MEASURES + ("truth_segments", "auto_segments")}
                            for lab, sc in t.items()} for m, t in table.items()}
        for lab in PAPER_LABELS:
            ref = table["reference"][lab]
            if not (ref.truth_segments or any(t[lab].auto_segments for t in table.values())):
                continue
            print(f"{lab:<14s}" + "".join(f"{t[lab].f1:>12.2f} / {t[lab].f2:4.2f}" for t in table.values())
                  + f"   ({ref.truth_segments})")

    print("\npreselection check: truth segments the default mode's preselection removes vs those the reference "
          "mode misses")
    for s in ("loao", "cmu"):
        cut = _missed_by_preselection(results["new default"], s)
        ref = {lab: 1.0 - sc.r2 for lab, sc in evaluate_by_label(results["reference"].truth[s],
                                                                  results["reference"].auto[s],
                                                                  labels=PAPER_LABELS).items() if sc.truth_segments}
        print(f"  {s}: " + ", ".join(f"{lab} {cut[lab]:.2f}/{ref.get(lab, 0):.2f}" for lab in cut))

    print("\nkeyframe queries of the model built on all folds' data ('all'):")
    for c, src in sources.get("all", {}).items():
        print(f"  {c:32s} {src}")
    total = time.perf_counter() - t0
    print("\ntimings: " + ", ".join(f"{k} {v:.0f} s" for k, v in timings.items()) + f"; total {total:.0f} s")
    if args.json:
        out = {"settings": {m: {s: {k: getattr(sc, k) for k in MEASURES} for s, sc in r.scores.items()}
                            for m, r in results.items()},
               "per_label": per_label, "queries": sources.get("all", {}),
               "parameters": {k: getattr(args, k) for k in ("seed", "runs", "generations", "inner_runs", "ga",
                                                            "inner_generations")},
               "seconds": total}
        args.json.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
        print(f"figures written to {args.json}")


if __name__ == "__main__":
    main()
