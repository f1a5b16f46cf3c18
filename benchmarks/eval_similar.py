"""Retrieval quality of ``mocapdb similar`` (issue 21): R-precision and precision at 1, 5, 10 per class.

Run: ``python benchmarks/eval_similar.py``. Prints the tables of
benchmarks/RESULTS.md ("Query by example").

**Leave one actor out** (``lab.retrieval.loao_retrieval``):
the leave-one-actor-out documents of the four hdm05_cut actors
(``loao_documents``, seed 0, the 11 classes as labels); every clip of an
actor is a query over the other three actors' documents, which it never saw.
R-precision with n = the class's clips among those actors; a result counts
when the truth clip it overlaps most has the query's class, covers at least
half of it and was not found before. Variants:

* ``clip`` — the clip's words, features weighted by their information in
  the archive (the method ``similar`` uses); the archive (≈ 6 min per fold)
  is small enough to rank without preselection;
* ``clip, 100 h preselection`` — the same with the keyframe preselection as
  strict as on a 100 h archive: the cell budget scaled by the fold's share
  of 100 h, so the query keeps the share of the archive it would keep there;
* ``unweighted`` — every feature counting the same (the paper's c^Q);
* ``mirror`` — a template learned from the clip and its mirror image;
* ``keyframes`` — fuzzy keyframes only (three, from the clip), no Δ.

**Threshold**: the share of relevant results per bin of cost / chance level
(``clip``), which places τ.

**Another lab**: the CMU exercise routines with mocap6 labels (13_29–31 of
subject 13, 14_14 and 14_20 of subject 14): every labelled stretch (its
middle 3 s) queries the other subject's takes.
"""
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_annotate import DATA, FRAMES_PER_HOUR, machine_header  # noqa: E402

sys.path.append(str(Path(__file__).resolve().parents[1]))  # lab/, the development harness beside benchmarks/ (not installed)

#: the classes the issue's aim is about (kick, jump, rotate arms, throw, lie down)
DISTINCTIVE = ("kickLFront1Reps", "hopBothLegs1hops", "rotateArmsBothBackward1Reps", "throwBasketball",
               "lieDownFloor")
ACTORS = ("bd", "bk", "dg", "mm")


def table(title, scores, classes=None):
    from lab.retrieval import PRECISION_AT

    print(f"\n### {title}\n")
    print("| class | queries | n | R-precision | " + " | ".join(f"P@{k}" for k in PRECISION_AT) + " |")
    print("|---|---:|---:|---:|" + "---:|" * len(PRECISION_AT))
    shown = [c for c in scores if c.n_relevant > 0 and (classes is None or c.label in classes)]
    for c in sorted(shown, key=lambda c: c.label):
        mark = " *" if c.label in DISTINCTIVE else ""
        print(f"| {c.label}{mark} | {c.n_queries} | {c.n_relevant:.1f} | {c.r_precision:.3f} | "
              + " | ".join(f"{c.precision_at[k]:.3f}" for k in PRECISION_AT) + " |")
    dist = [c.r_precision for c in shown if c.label in DISTINCTIVE]
    if dist:
        print(f"| **mean, distinctive (\\*)** | | | **{np.mean(dist):.3f}** | | | |")
    print(f"| mean, all | | | {np.mean([c.r_precision for c in shown]):.3f} | "
          + " | ".join(f"{np.mean([c.precision_at[k] for c in shown]):.3f}" for k in PRECISION_AT) + " |")
    return np.mean(dist) if dist else float("nan"), np.mean([c.r_precision for c in shown])


def main():
    from lab.documents import DocumentSet, loao_documents, mocap6_documents
    from lab.retrieval import class_scores, loao_retrieval
    from mocapdb.retrieval import CELL_BUDGET

    machine_header("eval_similar: query by example on held-out actors")
    t = time.perf_counter()
    docs = DocumentSet.concat(loao_documents(DATA / "hdm05_cut", a, class_labels={}) for a in ACTORS)
    print(f"\nleave-one-actor-out documents: {len(docs.names)} documents, {int(docs.doc_lengths.sum())} frames, "
          f"{len(docs.truth)} clips ({time.perf_counter() - t:.1f} s to read)")
    fold = int(docs.doc_lengths.sum()) * 3 // 4  # a fold's archive: three of four actors
    at_100h = int(CELL_BUDGET * fold / (100 * FRAMES_PER_HOUR))
    summary = []
    for title, kwargs in (("clip (the method of `similar`)", dict(variant="clip")),
                          ("clip, preselection as strict as on 100 h", dict(variant="clip", budget=at_100h)),
                          ("unweighted (every feature the same, the paper's c^Q)", dict(variant="unweighted")),
                          ("mirror (template learned from the clip and its mirror image)", dict(variant="mirror")),
                          ("keyframes only (three fuzzy keyframes from the clip, no Δ)", dict(variant="keyframes"))):
        t = time.perf_counter()
        results = loao_retrieval(docs, **kwargs)
        dist, everything = table(f"{title} — {time.perf_counter() - t:.0f} s", class_scores(results))
        summary.append((title, dist, everything))
        if kwargs == dict(variant="clip"):
            per_actor = {g: np.mean([r.relevant[:r.n_relevant].count(True) / r.n_relevant for r in results
                                     if r.group == g]) for g in ACTORS}
            print("\nmean R-precision by the query's actor: "
                  + ", ".join(f"{g} {v:.3f}" for g, v in per_actor.items()))
            ratio = np.array([c for r in results for c in r.cost_by_chance])
            rel = np.array([x for r in results for x in r.relevant])
            print("\nrelevant share of the results by cost / chance level:\n")
            print("| cost / chance | results | relevant |")
            print("|---|---:|---:|")
            for lo, hi in ((0, 0.3), (0.3, 0.4), (0.4, 0.5), (0.5, 0.6), (0.6, 0.7), (0.7, 0.75)):
                m = (ratio >= lo) & (ratio < hi)
                print(f"| {lo:.2f}–{hi:.2f} | {m.sum()} | {rel[m].mean() if m.any() else float('nan'):.3f} |")
            first = np.array([c for r in results for c in r.cost_by_chance[:r.n_relevant]])
            print(f"\nlargest cost / chance among each query's first n results: {first.max():.3f}")
    print("\n### summary: mean R-precision\n")
    print("| variant | distinctive classes | all classes |")
    print("|---|---:|---:|")
    for title, dist, everything in summary:
        print(f"| {title} | {dist:.3f} | {everything:.3f} |")
    m6 = mocap6_documents(DATA, class_labels={})
    results = loao_retrieval(m6, groups=lambda name: name.split("_")[0], query_frames=90)
    table("CMU mocap6, the middle 3 s of each labelled stretch against the other subject's takes",
          class_scores(results))


if __name__ == "__main__":
    main()
