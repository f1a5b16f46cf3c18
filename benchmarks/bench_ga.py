"""Speed and quality of the genetic keyframe learning (paper Sect. 6-7).

Prints figures for benchmarks/RESULTS.md: GA seconds per class and run
(M = 50, r = 5, G = 100) and keyframe retrievals per second during the GA,
next to the paper (~10 s per class and run, 3 ms per retrieval on the 24-min
training set, Athlon X2 5000+, Matlab + C); serial vs worker processes vs
threads; the learned query per class (consensus of the runs) with its
fitness, precision and recall on the training set, the classes it confuses
and the classes the GA could not separate.

Data: all 232 clips of ../shared/data/hdm05_cut (11 classes, all four actors)
as training documents, T- of a class = the clips of the other 10 classes.

Options: ``--runs`` runs per class (default 20, the library default);
``--loao`` adds leave-one-actor-out (train on 3 actors, score the learned
query on the 4th actor's clips); ``--ties`` compares the survival tie rules
on leave-one-actor-out (the measurement behind ``ties='fewest_fixed'``).

Usage: python benchmarks/bench_ga.py [--runs N] [--loao] [--ties]
"""
import argparse
import os
import platform
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numba
import numpy as np

from mocapdb import ga
from mocapdb.keyframes import keyframe_hit_documents, keyframe_search
from mocapdb.templates import learn_template
from mocapdb.learning.class_templates import clip_actor, clips_from_folders

SHARED = Path(os.environ.get("MOCAPDB_SHARED", Path(__file__).resolve().parents[2] / "shared"))
CUT = SHARED / "data" / "hdm05_cut"

#: why two classes are hard to tell apart with 40 boolean relational features
SIMILAR = {
    frozenset({"jogLeftCircle4StepsRstart", "sneak2StepsLStart"}):
        "both are a few steps of locomotion: the same leg features alternate; they differ in "
        "speed and posture, which the boolean features encode only partly",
    frozenset({"grabHighR", "depositFloorR"}):
        "both move only the right arm with the feet still (the paper's 'grabDepR' case): few "
        "consistent features besides the right hand",
    frozenset({"squat1Reps", "elbowToKnee1RepsLelbowStart"}):
        "both are standing exercises bending the knees",
    frozenset({"hopBothLegs1hops", "jogLeftCircle4StepsRstart"}):
        "both have flight phases (feet off the ground, fast feet)",
}
#: a learned query "separates" its class if fitness and precision reach these
#: (on held-out actors, with 3-10 test clips per class and fold, lower ones)
SEPARATED = {"fitness": 0.95, "precision": 0.9}
SEPARATED_HELD_OUT = {"fitness": 0.8, "precision": 0.8}


def load():
    t = time.perf_counter()
    raw = clips_from_folders(CUT)
    dt = time.perf_counter() - t
    clips = {c: [w for _, w in v] for c, v in raw.items()}
    actors = {c: [clip_actor(n) for n, _ in v] for c, v in raw.items()}
    return clips, actors, dt


def confusions(query, index, labels, names, ci, documents=None):
    """Negative classes hit by ``query``: {class: clips hit}."""
    hit = keyframe_hit_documents(index, [query])[0]
    if documents is not None:
        hit &= documents
    out = {}
    for cj, name in enumerate(names):
        n = int((hit & (labels == cj)).sum())
        if cj != ci and n:
            out[name] = n
    return out


def hint(name, conf, precision=0.0, recall=1.0):
    if not conf or recall < precision:
        return (f"misses positives (recall {recall:.2f}): the keyframes learned from the "
                "training clips are too specific for the other clips' style")
    worst = max(conf, key=conf.get)
    why = SIMILAR.get(frozenset({name, worst}),
                      "its template columns do not fix the features that differ")
    return f"confused with {worst} ({conf[worst]} clips): {why}"


def repeat_to(docs, n_frames):
    out, n = [], 0
    while n < n_frames:
        out.append(docs[len(out) % len(docs)])
        n += len(out[-1])
    return out


def bench_retrieval(queries, docs):
    """Seconds of one keyframe_search per query, and of hit_documents per query (batches of 10)."""
    index = ga.training_index(docs)
    for q in queries[:5]:
        keyframe_search(index, q)
    t = time.perf_counter()
    for q in queries:
        keyframe_search(index, q)
    single = (time.perf_counter() - t) / len(queries)
    t = time.perf_counter()
    for i in range(0, len(queries), 10):
        keyframe_hit_documents(index, queries[i:i + 10])
    batch = (time.perf_counter() - t) / len(queries)
    return index, single, batch


def learn_all(clips, templates, runs, n_jobs, seed=0, **params):
    t = time.perf_counter()
    res = ga.learn_keyframe_queries(clips, runs=runs, templates=templates, random_state=seed,
                                    n_jobs=n_jobs, **params)
    return res, time.perf_counter() - t


def thread_runs(tasks, n_threads):
    t = time.perf_counter()
    with ThreadPoolExecutor(n_threads) as pool:
        list(pool.map(lambda f: f(), tasks))
    return time.perf_counter() - t


def loao(clips, actors, runs, seed=0, **params):
    """Leave-one-actor-out: per class held-out P/R/F (mean over folds) and confusions."""
    names = list(clips)
    words = [w for c in names for w in clips[c]]
    labels = np.array([i for i, c in enumerate(names) for _ in clips[c]])
    act = np.array([a for c in names for a in actors[c]])
    index = ga.training_index(words)
    rows = {c: [] for c in names}
    conf = {c: {} for c in names}
    for a in sorted(set(act)):
        test = act == a
        sub = {c: [w for w, x in zip(clips[c], actors[c]) if x != a] for c in names}
        res = ga.learn_keyframe_queries(sub, runs=runs, random_state=seed, **params)
        for ci, c in enumerate(names):
            hit = keyframe_hit_documents(index, [res[c].query])[0]
            P, R, F = ga.fitness_from_hits(hit[None, test], (labels == ci)[test])
            rows[c].append((res[c].fitness, F[0], P[0], R[0], res[c].query.n_keyframes))
            for k, n in confusions(res[c].query, index, labels, names, ci, test).items():
                conf[c][k] = conf[c].get(k, 0) + n
    return rows, conf


def print_loao(rows, conf, title):
    print(f"\n## {title}")
    print("class                          train F  test F  test P  test R     K  confused with "
          "(held-out clips hit, all folds)")
    allv = []
    for c, v in rows.items():
        m = np.mean(v, axis=0)
        allv.append(m)
        cf = ", ".join(f"{k} {n}" for k, n in sorted(conf[c].items(), key=lambda x: -x[1]))
        print(f"{c:30s} {m[0]:7.3f} {m[1]:7.3f} {m[2]:7.3f} {m[3]:7.3f} {m[4]:5.1f}  {cf}")
    m = np.mean(allv, axis=0)
    print(f"{'mean':30s} {m[0]:7.3f} {m[1]:7.3f} {m[2]:7.3f} {m[3]:7.3f} {m[4]:5.1f}")
    return m


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="GA runs per class (default 20)")
    ap.add_argument("--scale-runs", type=int, default=4,
                    help="runs per class for the threads-vs-processes comparison")
    ap.add_argument("--loao", action="store_true", help="leave-one-actor-out held-out scores")
    ap.add_argument("--ties", action="store_true", help="compare survival tie rules (LOAO)")
    args = ap.parse_args()
    ncpu = os.cpu_count() or 1
    print(f"# bench_ga: {platform.processor() or platform.machine()}, {ncpu} cores, "
          f"numpy {np.__version__}, numba {numba.__version__}")

    clips, actors, t_load = load()
    names = list(clips)
    words = [w for c in names for w in clips[c]]
    labels = np.array([i for i, c in enumerate(names) for _ in clips[c]])
    n_frames = sum(map(len, words))
    t = time.perf_counter()
    index = ga.training_index(words)
    t_index = time.perf_counter() - t
    t = time.perf_counter()
    templates = {c: learn_template(v) for c, v in clips.items()}
    t_tmpl = time.perf_counter() - t
    print(f"\ntraining set: {len(names)} classes, {len(words)} clips, {n_frames:,} frames at "
          f"30 Hz ({n_frames / 1800:.1f} min); read + features {t_load:.2f} s, 40-bit index "
          f"{t_index * 1e3:.1f} ms, 11 templates {t_tmpl:.2f} s")
    print("GA: M = 50, r = 5 (10 offspring), G = 100, beta = 2 -> 1,050 retrievals per run")

    ga.learn_keyframe_queries(clips, classes=names[:1], runs=1, templates=templates,
                              n_jobs=1, generations=2)  # load the kernels
    serial, t_serial = learn_all(clips, templates, args.runs, 1)

    # ---- (a) seconds per class and run, retrievals per second ------------
    print(f"\n## (a) one process, {args.runs} runs per class")
    print("class                          s/run (mean)  s/run (min)  retrievals/s  "
          "best F (mean of runs)  K")
    all_s, all_ev = [], []
    for c in names:
        rs = serial[c].runs
        s = np.array([r.seconds for r in rs])
        ev = np.array([r.n_evaluations for r in rs])
        all_s += s.tolist()
        all_ev += ev.tolist()
        print(f"{c:30s} {s.mean():12.3f} {s.min():12.3f} {ev.sum() / s.sum():13,.0f}  "
              f"{np.mean([r.fitness for r in rs]):21.3f}  "
              f"{np.mean([r.query.n_keyframes for r in rs]):.1f}")
    print(f"{'all classes':30s} {np.mean(all_s):12.3f} {np.min(all_s):12.3f} "
          f"{np.sum(all_ev) / np.sum(all_s):13,.0f}")
    print(f"paper: ~10 s per class and run -> {10 / np.mean(all_s):.0f}x faster; target "
          "<= 0.5 s: " + ("met" if np.mean(all_s) <= 0.5 else "NOT met"))

    # ---- retrieval time on the training set and on a 24-min set ----------
    queries = [q for c in names for r in serial[c].runs[:2] for q in r.population]
    _, single, batch = bench_retrieval(queries, words)
    big = repeat_to(words, 43_000)
    _, single24, batch24 = bench_retrieval(queries, big)
    print(f"\nretrieval of one GA query ({len(queries)} queries of the final populations): "
          f"keyframe_search {single * 1e3:.3f} ms, keyframe_hit_documents "
          f"{batch * 1e6:.1f} us/query on the {n_frames / 1800:.1f}-min training set; "
          f"{single24 * 1e3:.3f} ms / {batch24 * 1e6:.1f} us on the clips repeated to 24 min "
          f"({len(big)} docs, 43,000 frames); paper: 3 ms on 24 min")

    # ---- (b) parallel runs ------------------------------------------------
    par, t_par = learn_all(clips, templates, args.runs, None)
    same = all(np.array_equal(serial[c].query.mask, par[c].query.mask)
               and serial[c].best_run == par[c].best_run for c in names)
    n_tasks = len(names) * args.runs
    print(f"\n## (b) all {len(names)} classes x {args.runs} runs: one process "
          f"{t_serial:.1f} s ({t_serial / n_tasks:.3f} s per class and run), {ncpu} worker "
          f"processes {t_par:.1f} s ({t_par / n_tasks:.3f} s; speed-up "
          f"{t_serial / t_par:.2f}x incl. ~1 s worker start); same results: {same}")
    tasks = []
    for ci, c in enumerate(names):
        pos, neg = np.flatnonzero(labels == ci), np.flatnonzero(labels != ci)
        for s in range(args.scale_runs):
            tasks.append(lambda pos=pos, neg=neg, c=c, s=s: ga.evolve_keyframes(
                pos, neg, template=templates[c], index=index, random_state=s))
    t1 = thread_runs(tasks, 1)
    tn = thread_runs(tasks, ncpu)
    print(f"threads ({len(tasks)} runs): 1 thread {t1:.1f} s, {ncpu} threads {tn:.1f} s "
          f"(speed-up {t1 / tn:.2f}x): most of a run is Python holding the GIL (operators, "
          "query validation, search planning), hence worker processes")

    # ---- (c) learned queries ----------------------------------------------
    print(f"\n## (c) learned query per class (consensus of {args.runs} runs), on the training "
          "set")
    print("class                          fitness  precision  recall   K  fixed  run  "
          "consensus  negatives hit")
    bad = []
    for ci, c in enumerate(names):
        lq = serial[c]
        conf = confusions(lq.query, index, labels, names, ci)
        cf = ", ".join(f"{k} {n}" for k, n in sorted(conf.items(), key=lambda x: -x[1]))
        print(f"{c:30s} {lq.fitness:7.3f} {lq.precision:10.3f} {lq.recall:7.3f} "
              f"{lq.query.n_keyframes:3d} {ga.fixed_entries(lq.query):6d} {lq.best_run:4d} "
              f"{lq.consensus[lq.best_run]:10.2f}  {cf}")
        if lq.fitness < SEPARATED["fitness"] or lq.precision < SEPARATED["precision"]:
            bad.append((c, hint(c, conf, lq.precision, lq.recall)))
    print(f"\nclasses not separated on the training set (fitness < {SEPARATED['fitness']} or "
          f"precision < {SEPARATED['precision']}): " + ("none" if not bad else ""))
    for c, h in bad:
        print(f"  {c}: {h}")

    # ---- Fig. 5 -------------------------------------------------------------
    st = ga.average_statistics(serial.values())
    print("\n## paper Fig. 5: population averages over all classes and runs")
    print("generation  precision  recall  fitness  best fitness  keyframes")
    for g in (0, 1, 5, 10, 20, 50, 100):
        if g <= st.generations:
            print(f"{g:10d} {st.mean_precision[g]:10.3f} {st.mean_recall[g]:7.3f} "
                  f"{st.mean_fitness[g]:8.3f} {st.best_fitness[g]:13.3f} "
                  f"{st.mean_keyframes[g]:10.2f}")

    if args.loao:
        rows, conf = loao(clips, actors, args.runs)
        print_loao(rows, conf, f"leave-one-actor-out ({args.runs} runs per class, consensus)")
        held = {c: np.mean(v, axis=0) for c, v in rows.items()}
        bad = [c for c, m in held.items()
               if m[1] < SEPARATED_HELD_OUT["fitness"] or m[2] < SEPARATED_HELD_OUT["precision"]]
        print(f"not separated on held-out actors (test fitness < "
              f"{SEPARATED_HELD_OUT['fitness']} or precision < "
              f"{SEPARATED_HELD_OUT['precision']}): " + (", ".join(bad) if bad else "none"))
        for c in bad:
            print(f"  {c}: {hint(c, conf[c], held[c][2], held[c][3])}")
    if args.ties:
        for ties in ("fewest_fixed", "offspring"):
            rows, conf = loao(clips, actors, 3, ties=ties)
            m = print_loao(rows, conf, f"ties={ties!r}: leave-one-actor-out, 3 runs per class")
            print(f"ties={ties!r}: held-out F {m[1]:.3f} P {m[2]:.3f} R {m[3]:.3f}, "
                  f"{m[4]:.1f} keyframes")


if __name__ == "__main__":
    main()
