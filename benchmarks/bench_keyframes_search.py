"""Speed of the inverted file index and the keyframe-chain search.

Prints figures for benchmarks/RESULTS.md (DESIGN.md §7 target: one keyframe
query <= 0.5 ms on 74 min, <= 20 ms on 100 h; the GA needs searches on a
24-minute training index to cost microseconds).

Data: the toolbox oracle's 30 Hz feature files (../shared/oracle/features:
232 HDM05 clips + 5 CMU documents).  Archives:

* ``77 oracle docs``   -- the keyframe oracle's database (documents.csv);
* ``237 docs``         -- every oracle feature file, one document each;
* ``74 min``/``10 h``/``100 h`` -- the 237 files in a seeded random order,
  concatenated into documents of about 1,220 frames (the paper's evaluation
  set: 109 documents, 133,019 frames) and repeated up to the frame count;
* ``GA train 24 min``  -- the 232 HDM05 clips as separate documents, repeated
  to 43,000 frames (the paper's training set size).

Queries: the 5 hand-made toolbox queries (keyframe oracle; each keyframe within
one feature set) and 3 queries of 3 columns of oracle templates (40-bit
keyframes spanning all sets, as the GA makes them), all with annotation
margins; for the GA figures, queries of 2-4 template columns: independent
random ones and GA-like runs (offspring recombine their parents' keyframes).

Layouts: ``sets`` = the toolbox's three per-set indexes, ``full`` = one index
over the 40-bit word.

Usage: python benchmarks/bench_keyframes_search.py [--max-hours H] [--reps N]
"""
import argparse
import csv
import os
import platform
import time
from pathlib import Path

import numba
import numpy as np

from mocapdb.features import pack_words
from mocapdb.keyframes import build_index
from mocapdb.keyframes import (KeyframeQuery, annot_margins, keyframe_hit_documents,
                               keyframe_search)

SHARED = Path(os.environ.get("MOCAPDB_SHARED", Path(__file__).resolve().parents[2] / "shared"))
ORACLE = SHARED / "oracle"
KF = ORACLE / "keyframes"
QUERIES = ("squat1Reps", "kickLFront1Reps", "hopBothLegs1hops", "rotateArmsBothBackward1Reps",
           "elbowToKnee1RepsLelbowStart")


def load_words(stem):
    x = np.loadtxt(ORACLE / "features" / f"{stem}_feat30.csv", delimiter=",", skiprows=1, ndmin=2)
    return pack_words(x.astype(bool))


def load_query(name):
    with open(KF / "queries" / f"{name}_keyframes.csv") as f:
        rows = list(csv.DictReader(f))
    with open(KF / "queries" / f"{name}_gaps.csv") as f:
        gaps = list(csv.DictReader(f))
    vecs = [[float(r[f"v{i:02d}"]) for i in range(1, int(r["n_features"]) + 1)] for r in rows]
    return KeyframeQuery.from_toolbox(
        vecs, [int(r["set_index"]) for r in rows], [int(r["position"]) for r in rows],
        [float(g["stiffness"]) for g in gaps], template_length=int(rows[0]["templateLength"]))


def archive(docs, n_frames, doc_frames, seed=0):
    """Documents of about ``doc_frames`` frames made of ``docs`` in random order, repeated."""
    rng = np.random.default_rng(seed)
    out, cur, total = [], [], 0
    while total < n_frames:
        for i in rng.permutation(len(docs)):
            cur.append(docs[i])
            total += len(docs[i])
            if sum(map(len, cur)) >= doc_frames or total >= n_frames:
                out.append(np.concatenate(cur))
                cur = []
            if total >= n_frames:
                break
    return out


def timings(fn, reps):
    fn()
    ts = []
    for _ in range(reps):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    ts = np.array(ts) * 1e3
    return np.median(ts), np.percentile(ts, 95)


def bench_archive(name, docs, queries, reps, layouts=("sets", "full")):
    n_frames = sum(map(len, docs))
    print(f"\n## {name}: {len(docs)} documents, {n_frames:,} frames "
          f"({n_frames / 30 / 60:.1f} min)")
    indexes = {}
    for layout, parts in (("sets", ("upper", "lower", "mix")), ("full", ("full",))):
        if layout not in layouts:
            continue
        t = time.perf_counter()
        idx = build_index(docs, feature_sets=parts)
        dt = time.perf_counter() - t
        indexes[layout] = idx
        print(f"index {layout}: build {dt * 1e3:.0f} ms, {len(idx.seg_start):,} segments, "
              f"{len(idx.words):,} words, {idx.nbytes / 1e6:.1f} MB")
    print("query                          layout threads  median ms    p95 ms  segments")
    for qname, q in queries:
        el, er = annot_margins(q)
        for layout, idx in indexes.items():
            for nt in ((1, None) if idx.n_frames >= 1 << 19 else (1,)):
                med, p95 = timings(lambda: keyframe_search(idx, q, extend_left=el, extend_right=er,
                                                           n_threads=nt), reps)
                n = len(keyframe_search(idx, q, extend_left=el, extend_right=er))
                print(f"{qname:30s} {layout:6s} {str(nt or 'auto'):>7s} {med:10.3f} {p95:9.3f} "
                      f"{n:9d}")
    return indexes


def _column_query(mask, value, pos, rng):
    """40-bit keyframes = template columns ``pos``; gap bounds with a random tolerance."""
    pos = np.sort(np.asarray(pos))
    delta = np.diff(pos)
    u = rng.uniform(0.2, 1.0, size=len(pos) - 1)
    return KeyframeQuery(mask[pos], value[pos], pos, np.floor(delta * (1 - u)),
                         np.ceil(delta * (1 + u)), len(mask))


def ga_queries(templates, rng, n):
    """Random GA-like queries: 2-4 template columns as 40-bit keyframes."""
    out = []
    for _ in range(n):
        mask, value = templates[rng.integers(len(templates))]
        k = int(rng.integers(2, 5))
        out.append(_column_query(mask, value, rng.choice(len(mask), size=k, replace=False), rng))
    return out


def ga_generations(template, rng, n_gens, *, population=50, offspring=10):
    """Offspring of a GA-like run on one class.

    Each offspring takes keyframes of two parents, plus one added or removed column.
    """
    mask, value = template
    pop = [np.sort(rng.choice(len(mask), size=int(rng.integers(2, 5)), replace=False))
           for _ in range(population)]
    gens = []
    for _ in range(n_gens):
        kids = []
        for _ in range(offspring):
            a, b = (pop[i] for i in rng.choice(len(pop), 2, replace=False))
            cols = np.union1d(rng.choice(a, rng.integers(1, len(a) + 1), replace=False),
                              rng.choice(b, rng.integers(1, len(b) + 1), replace=False))
            if rng.random() < 0.5 or len(cols) < 2:  # mutation: add a column
                cols = np.union1d(cols, rng.integers(len(mask), size=1))
            elif len(cols) > 2:  # or remove one
                cols = np.delete(cols, rng.integers(len(cols)))
            kids.append(cols)
        pop = pop[offspring:] + kids
        gens.append([_column_query(mask, value, c, rng) for c in kids])
    return gens


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-hours", type=float, default=100.0,
                    help="largest synthetic archive (10 and 100 h by default)")
    ap.add_argument("--reps", type=int, default=200, help="repetitions per small-index query")
    args = ap.parse_args()
    print(f"# bench_keyframes_search: {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, numpy {np.__version__}, numba {numba.__version__}")

    with open(KF / "index" / "documents.csv") as f:
        oracle_stems = [Path(r["file"]).stem for r in csv.DictReader(f)]
    with open(ORACLE / "features" / "manifest.csv") as f:
        manifest = list(csv.DictReader(f))
    words = {r["stem"]: load_words(r["stem"]) for r in manifest}
    all_docs = [words[r["stem"]] for r in manifest]
    clips = [words[r["stem"]] for r in manifest if r["kind"] == "clip"]
    queries = [(q, load_query(q)) for q in QUERIES]
    templates = []
    for d in sorted((ORACLE / "templates").iterdir()):
        q = np.loadtxt(d / "template_quantized_0.05.csv", delimiter=",", ndmin=2).T
        templates.append((d.name, pack_words(q != 0.5), pack_words(q == 1.0)))
    rng = np.random.default_rng(0)
    for name, mask, value in templates[::4]:  # 3 classes: 40-bit keyframes across sets
        pos = np.linspace(0.2 * len(mask), 0.8 * len(mask), 3).astype(int)
        queries.append((f"40-bit columns {name}", _column_query(mask, value, pos, rng)))

    build_index(all_docs[:3], feature_sets=("upper", "lower", "mix", "full"))  # load the kernels
    keyframe_search(build_index(all_docs[:3]), queries[0][1])
    bench_archive("77 oracle docs", [words[s] for s in oracle_stems], queries, args.reps)
    bench_archive("237 docs", all_docs, queries, args.reps)
    bench_archive("74 min", archive(all_docs, 133_019, 1220), queries, args.reps)
    for hours in (10, 100):
        if hours <= args.max_hours:
            reps = max(5, args.reps // (4 * hours))
            bench_archive(f"{hours} h", archive(all_docs, int(hours * 108_000), 1220), queries,
                          reps)

    # ---- GA: many queries on a small training index ------------------------
    train, n = [], 0
    while n < 43_000:
        train.append(clips[len(train) % len(clips)])
        n += len(train[-1])
    rng = np.random.default_rng(1)
    gens = [ga_queries([t[1:] for t in templates], rng, 10) for _ in range(50)]
    runs = [g for t in templates for g in ga_generations(t[1:], rng, 10)]
    print(f"\n## GA train 24 min: {len(train)} documents, {sum(map(len, train)):,} frames")
    print("(a) independent generations of 10 random template-column queries; "
          "(b) GA-like runs: 10 offspring per generation, keyframes recombined from parents, "
          "11 classes x 10 generations")
    print("layout  (a) hit_documents ms/gen  us/query  single search us  | (b) no cache us/query  "
          "with cache us/query")
    for layout, parts in (("sets", ("upper", "lower", "mix")), ("full", ("full",))):
        idx = build_index(train, feature_sets=parts)
        keyframe_hit_documents(idx, gens[0])
        t = time.perf_counter()
        for g in gens:
            keyframe_hit_documents(idx, g)
        per_gen = (time.perf_counter() - t) / len(gens)
        singles = [q for g in gens[:10] for q in g]
        t = time.perf_counter()
        for q in singles:
            keyframe_search(idx, q)
        per_single = (time.perf_counter() - t) / len(singles)
        t = time.perf_counter()
        for g in runs:
            keyframe_hit_documents(idx, g)
        no_cache = (time.perf_counter() - t) / (10 * len(runs))
        cache = {}
        t = time.perf_counter()
        for g in runs:
            keyframe_hit_documents(idx, g, cache=cache)
        with_cache = (time.perf_counter() - t) / (10 * len(runs))
        print(f"{layout:6s}  {per_gen * 1e3:24.3f}  {per_gen / 10 * 1e6:8.1f}  "
              f"{per_single * 1e6:16.1f}"
              f"  | {no_cache * 1e6:21.1f}  {with_cache * 1e6:19.1f}")


if __name__ == "__main__":
    main()
