"""Retrain the default model shipped in ``mocapdb/models/default/`` (reproducible).

Run: ``python benchmarks/train_default_model.py [--out DIR]``. Templates for
the 11 classes of ``../shared/data/hdm05_cut`` from all four actors (clips in
file-name order, δ = 0.05, τ = 0.13), coarse labels from the shipped HDM05
mapping (``mocapdb/models/hdm05_labels.csv``) — identical to the authors'
toolbox templates (../shared/oracle/templates) — plus one keyframe query per
class learned by the genetic algorithm (paper Sect. 6) on the same clips with
a fixed seed. Writes the model's rows as Parquet files (the shipped-model
format, :func:`mocapdb.storage.models.export_model`), and the same templates
without keyframe queries as the shipped model ``toolbox`` (the reference mode).
"""
import argparse
import os
import tempfile
import time
from pathlib import Path

import dataclasses

import mocapdb
from mocapdb.annotation import Model
from mocapdb.api import learn_keyframes, train
from mocapdb.storage.models import export_model, save_model

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
CUT = SHARED / "data" / "hdm05_cut"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=REPO / "mocapdb" / "models" / "default")
    ap.add_argument("--toolbox-out", type=Path, default=REPO / "mocapdb" / "models" / "toolbox")
    ap.add_argument("--runs", type=int, default=20, help="GA runs per class (paper: 100-500)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-keyframes", action="store_true", help="templates only")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        con = mocapdb.connect(Path(tmp) / "train.duckdb")
        try:
            t = time.perf_counter()
            model = train(con, model="default", folder=CUT, replace=True,
                          description="11 HDM05 classes (hdm05_cut, actors bd bk dg mm), coarse labels of "
                                      "paper Table 1")
            print(f"templates: {len(model.classes)} classes in {time.perf_counter() - t:.1f} s")
            toolbox = Model("toolbox", tuple(dataclasses.replace(c, keyframe_query=None) for c in model.classes),
                            labels=model.labels)
            save_model(con, toolbox, replace=True,
                       description="The authors' toolbox model: the 11 HDM05 classes of hdm05_cut with the "
                                   "toolbox's templates, no keyframe queries (the reference mode)",
                       source="the default model's templates (identical to the toolbox's), without keyframe "
                              "queries")
            export_model(con, "toolbox", args.toolbox_out)
            if not args.no_keyframes:
                t = time.perf_counter()
                learn_keyframes(con, model="default", folder=CUT, runs=args.runs, seed=args.seed)
                print(f"keyframe queries (GA, {args.runs} runs per class, seed {args.seed}): "
                      f"{time.perf_counter() - t:.1f} s")
            for row in con.execute("SELECT c.class, c.label, count(t.col), any_value(q.n_keyframes), "
                                   "any_value(q.fitness) FROM classes c JOIN templates t USING (model, class) "
                                   "LEFT JOIN keyframe_queries q USING (model, class) WHERE c.model = 'default' "
                                   "GROUP BY ALL ORDER BY any_value(c.class_id)").fetchall():
                print("  {:32s} {:12s} K={:4d} keyframes={} fitness={}".format(*row))
            export_model(con, "default", args.out)
            print(f"written to {args.out} and {args.toolbox_out}")
        finally:
            con.close()


if __name__ == "__main__":
    main()
