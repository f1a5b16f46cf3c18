"""Keyframe search latency, index build time and annotation speed-up from keyframe preselection.

Run: ``python benchmarks/bench_keyframes.py [--quick]``. Prints figures for
benchmarks/RESULTS.md (DESIGN.md §7 targets: one keyframe query ≤ 0.5 ms on
74 min and ≤ 20 ms on 100 h; annotation with keyframe preselection ≥ 5×
faster than without). The paper (Athlon X2 5000+, Matlab + C, 74 min =
133,019 frames): one keyframe query 4 ms, indexing 4 s, annotation 305 s
without and 20 s with keyframe preselection.

Queries: the "toolbox keyframes" of the default model
(:func:`mocapdb.learning.toolbox_queries.toolbox_keyframe_queries`): the authors'
hand-made queries for 5 classes (each keyframe within one feature set) and
the toolbox's heuristic choice (3 template columns, 40-bit keyframes,
stiffness 0.5) for the other 6; searched with the annotation margins.

Archives: all of ../shared/data ingested (bench_annotate.ingest_all), and
synthetic ones made of the real documents' words repeated in order (74 min =
the paper's evaluation-set size, 10 h, 100 h), inserted into DuckDB files via
Arrow.

(a) latency of single queries, median and p95: Python (``load_index`` once,
    then ``keyframe_search``) and SQL (``keyframe_search_words(masks, vals,
    d_min, d_max, extend_left, extend_right)`` on the database); both give
    the same segments (checked);
(b) index build: ``build_index`` in memory (the 3 toolbox per-set parts, and
    all 4 parts as stored) and ``create_index`` into DuckDB (all 4 parts),
    plus ``load_index``;
(c) ``annotate_words`` with and without keyframe preselection, same
    model (default templates + toolbox keyframes), and the frames each
    class's preselection keeps.
"""
import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_annotate import (FRAMES_PER_HOUR, QUERIES_DIR, PAPER_FRAMES, ingest_all,  # noqa: E402
                            load_now, machine_header, repeat_documents, synthetic_db, timed)
from timing import annotate_words, stored_words  # noqa: E402

PAPER_QUERY_MS, PAPER_INDEX_S = 4.0, 4.0
PAPER_ANNOT_S, PAPER_KF_ANNOT_S = 305.0, 20.0


def latency(fn, reps):
    """(median ms, p95 ms) of ``reps`` calls after one warm-up call."""
    fn()
    ts = np.empty(reps)
    for i in range(reps):
        t = time.perf_counter()
        fn()
        ts[i] = time.perf_counter() - t
    return np.median(ts) * 1e3, np.percentile(ts, 95) * 1e3


def sql_list(values, cast="BIGINT"):
    return "[" + ", ".join("NULL" if v is None else str(int(v)) for v in values) + f"]::{cast}[]"


def sql_query(q, el, er):
    """The SQL text of one keyframe search (inline query, annotation margins)."""
    from mocapdb.keyframes import UNBOUNDED

    d_max = [None if d >= UNBOUNDED else d for d in q.d_max]
    return (f"SELECT motion_id, start_frame, end_frame FROM keyframe_search_words("
            f"{sql_list(q.mask, 'UBIGINT')}, {sql_list(q.value, 'UBIGINT')}, {sql_list(q.d_min)}, "
            f"{sql_list(d_max)}, extend_left := {el}, extend_right := {er}) ORDER BY motion_id, start_frame")


def bench_archive(name, con, queries, reps, sql_reps, words, lengths, note=""):
    """(b) index build and (a) latency on one database; returns the slowest query's median ms."""
    from mocapdb.keyframes import INDEX_PARTS, SET_PARTS, build_index
    from mocapdb.keyframes import PARALLEL_MIN_FRAMES, keyframe_search
    from mocapdb.storage.postings import create_index, load_index

    n = int(lengths.sum())
    print(f"\n## {name}: {len(lengths):,} documents, {n:,} frames ({n / 1800:.1f} min){note}; {load_now()}")
    t = time.perf_counter()
    build_index(words, doc_lengths=lengths, feature_sets=SET_PARTS)
    t_sets = time.perf_counter() - t
    t = time.perf_counter()
    idx_mem = build_index(words, doc_lengths=lengths, feature_sets=INDEX_PARTS)
    t_all = time.perf_counter() - t
    t = time.perf_counter()
    n_rows = create_index(con)
    t_db = time.perf_counter() - t
    t = time.perf_counter()
    index, ids = load_index(con)
    t_load = time.perf_counter() - t
    assert index.n_frames == n and idx_mem.n_frames == n
    print(f"index build: in memory {t_sets:.3f} s (3 per-set parts), {t_all:.3f} s (4 parts, "
          f"{idx_mem.nbytes / 1e6:.0f} MB); create_index into DuckDB {t_db:.2f} s ({n_rows:,} postings rows); "
          f"load_index {t_load:.2f} s; paper: {PAPER_INDEX_S:.0f} s for 74 min")
    print(f"latency ms (median / p95): Python over {reps} calls (keyframe_search, threads auto: 2 from "
          f"{PARALLEL_MIN_FRAMES:,} frames), SQL over {sql_reps} calls (keyframe_search_words, rows fetched)")
    print(f"{'class':30s} {'kind':9s} {'K':>2s} {'segments':>9s} {'frames':>10s}   {'Python med':>10s} "
          f"{'p95':>7s}   {'SQL med':>8s} {'p95':>8s}")
    ids = np.asarray(ids)
    py_med, sql_med = [], []
    for cname, kind, q, el, er in queries:
        med, p95 = latency(lambda: keyframe_search(index, q, extend_left=el, extend_right=er), reps)
        segs = keyframe_search(index, q, extend_left=el, extend_right=er)
        py_med.append(med)
        sql_txt = sql_query(q, el, er)
        s_med = s_p95 = float("nan")
        if sql_reps:
            s_med, s_p95 = latency(lambda: con.execute(sql_txt).fetchnumpy(), sql_reps)
            got = con.execute(sql_txt).fetchnumpy()
            mine = np.stack([ids[segs.doc], segs.start + 1, segs.end + 1], 1).reshape(-1, 3)
            theirs = np.stack([got["motion_id"], got["start_frame"], got["end_frame"]], 1).reshape(-1, 3)
            assert np.array_equal(mine, theirs), f"{cname}: SQL and Python searches differ"
            sql_med.append(s_med)
        print(f"{cname:30s} {kind:9s} {q.n_keyframes:2d} {len(segs):9,} {segs.n_frames:10,}   {med:10.3f} "
              f"{p95:7.3f}   {s_med:8.2f} {s_p95:8.2f}")
    print(f"{'all 11 queries':30s} {'':9s} {'':2s} {'':9s} {'':10s}   {np.median(py_med):10.3f} "
          f"{'(med)':>7s}   {(np.median(sql_med) if sql_med else float('nan')):8.2f} {'(med)':>8s}"
          f"   max Python median {max(py_med):.3f} ms")
    return max(py_med)


def bench_preselection(name, words, lengths, model, repeat, *, queries="toolbox"):
    """(c) annotation with and without keyframe preselection on the same data and model.

    ``queries``: "toolbox" (hand-made + heuristic) or "ga" (the shipped default model's)."""
    from mocapdb.annotation import preselection_for

    n = int(lengths.sum())
    what = "toolbox keyframes" if queries == "toolbox" else "its GA keyframe queries (shipped)"
    print(f"\n## (c) {name}: {len(lengths):,} documents, {n:,} frames; model = default templates + {what}; "
          f"best of {repeat}; {load_now()}")
    _, t_off, segs_off = timed(lambda: annotate_words(words, lengths, model, keyframes=False), repeat)
    _, t_on, segs_on = timed(lambda: annotate_words(words, lengths, model, keyframes=True), repeat)
    _, t_pre, pre = timed(lambda: preselection_for(words, lengths, model, True), repeat)
    speedup = t_off / t_on
    print(f"without keyframes {t_off:.3f} s ({n / t_off:,.0f} frames/s, {len(segs_off):,} segments); "
          f"with keyframe preselection {t_on:.3f} s ({n / t_on:,.0f} frames/s, {len(segs_on):,} segments), "
          f"of which the preselection {t_pre:.3f} s")
    print(f"speed-up {speedup:.1f}x (target >= 5x: {'met' if speedup >= 5 else 'NOT met'}); paper "
          f"{PAPER_ANNOT_S:.0f} s -> {PAPER_KF_ANNOT_S:.0f} s = {PAPER_ANNOT_S / PAPER_KF_ANNOT_S:.1f}x")
    print(f"{'class':30s} {'query':9s} {'kept frames':>12s} {'% of all':>9s} {'slices':>8s}")
    total = cells = 0
    for c, sl in zip(model.classes, pre):
        kept = int((sl[:, 1] - sl[:, 0] + 1).sum()) if sl is not None else n
        total += kept
        cells += kept * len(c.quantized)
        kind = ("ga" if queries == "ga" else
                "hand-made" if c.keyframe_query.feature_sets[0] is not None else "heuristic")
        print(f"{c.name:30s} {kind:9s} {kept:12,} {100 * kept / n:8.1f}% {len(sl) if sl is not None else 0:8,}")
    sum_k = sum(len(c.quantized) for c in model.classes)
    print(f"all classes: {100 * total / (n * len(model.classes)):.1f}% of (frames x classes), "
          f"{100 * cells / (n * sum_k):.1f}% of the Δ cells (frames x template columns)")
    return speedup


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: archives up to 1 h instead of 100 h, fewer repetitions")
    args = ap.parse_args()

    import mocapdb  # noqa: F401
    from mocapdb.keyframes import annot_margins
    from mocapdb.storage.model_store import load_model
    from mocapdb.learning.toolbox_queries import has_toolbox_query, toolbox_keyframe_queries

    machine_header("bench_keyframes" + (" --quick" if args.quick else ""))
    tmp = tempfile.TemporaryDirectory(prefix="bench_keyframes_")
    tmpdir = Path(tmp.name)
    con, t_ingest = ingest_all(tmpdir / "all.duckdb")
    words, lengths = stored_words(con)
    model = toolbox_keyframe_queries(load_model(con, "toolbox"), queries_dir=QUERIES_DIR)
    queries = [(c.name, "hand-made" if has_toolbox_query(QUERIES_DIR, c.name) else "heuristic",
                c.keyframe_query, *annot_margins(c.keyframe_query)) for c in model.classes]

    q = 4 if args.quick else 1
    # (name, frames or None for the ingested data, Python reps, SQL reps)
    archives = [("all ingested data", None, 400 // q, 50 // q),
                ("74 min (paper's evaluation-set size)", PAPER_FRAMES, 400 // q, 30 // q)]
    if args.quick:
        archives.append(("1 h", FRAMES_PER_HOUR, 50, 5))
    else:
        archives += [("10 h", 10 * FRAMES_PER_HOUR, 100, 10), ("100 h", 100 * FRAMES_PER_HOUR, 20, 3)]

    worst = {}
    for name, n_frames, reps, sql_reps in archives:
        if n_frames is None:
            worst[name] = bench_archive(name, con, queries, reps, sql_reps, words, lengths)
            continue
        w, lens = repeat_documents(words, lengths, n_frames)
        c2, t_ins = synthetic_db(tmpdir / f"syn_{n_frames}.duckdb", w, lens)
        worst[name] = bench_archive(name, c2, queries, reps, sql_reps, w, lens,
                                    note=f", synthetic: the real documents repeated, inserted via Arrow "
                                         f"in {t_ins:.1f} s")
        c2.close()
        Path(tmpdir / f"syn_{n_frames}.duckdb").unlink()
    print("\nsummary, slowest query's median (Python): " + "; ".join(f"{k} {v:.3f} ms" for k, v in worst.items())
          + f". Targets: <= 0.5 ms on 74 min ({'met' if worst[archives[1][0]] <= 0.5 else 'NOT met'})"
          + (f", <= 20 ms on 100 h ({'met' if worst['100 h'] <= 20 else 'NOT met'})" if '100 h' in worst else "")
          + f"; paper {PAPER_QUERY_MS:.0f} ms on 74 min")

    hours = 1 if args.quick else 10
    w, lens = repeat_documents(words, lengths, hours * FRAMES_PER_HOUR)
    for queries, m in (("toolbox", model), ("ga", load_model(con, "default"))):
        bench_preselection("all ingested data", words, lengths, m, 3 if args.quick else 10, queries=queries)
        bench_preselection(f"synthetic {hours} h", w, lens, m, 1 if args.quick else 2, queries=queries)
    con.close()
    tmp.cleanup()


if __name__ == "__main__":
    main()
