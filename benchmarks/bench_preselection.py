"""Keyframe preselection with the shipped default model: what it keeps, and what it saves through SQL (issue 20).

Run: ``python benchmarks/bench_preselection.py [--hours 100] [--previous REV …] [--model-dir DIR …] [--repeat 5]
[--threads N] [--per-class]``.

The archive: every ASF/AMC take of ../shared/data, ingested, its real words
repeated in order up to the paper's evaluation-set size (74 min, 133,019
frames at 30 Hz, 1,448 motions; ``--hours H``: H hours instead), stored in a
DuckDB file with its keyframe index (as bench_sql.py and
bench_default_model.py build it).

For each model (the shipped default; the default as committed at a git
revision with ``--previous``; models exported as Parquet files with
``--model-dir``):

(a) the share of (frame × class) cells that survive the preselection, per
    class and in all, each class weighted by its template length (Δ costs
    one cell per template column and frame): the keyframe search of every
    class's query over the stored index, its segments widened by the
    annotation margins (``keyframe_preselection``);
(b) ``SELECT annotate(motion_id, keyframes := false / true) FROM motions``,
    warm, best of ``--repeat``: wall seconds, and CPU seconds of this
    process (steadier on a shared machine). Target: ≥ 5× faster with
    keyframes.

Quality with and without keyframes is benchmarks/eval_quality.py's.
"""
import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_annotate import (FRAMES_PER_HOUR, PAPER_FRAMES, ingest_all, load_now, machine_header,  # noqa: E402
                            repeat_documents, synthetic_db)
from timing import model_at, model_dir, stored_words  # noqa: E402

SQL = "SELECT m.motion_id, annotate(m.motion_id, model := '{model}', keyframes := {kf}) AS s FROM motions m"


def cell_shares(index, model):
    """Per class: (template columns, share of the archive's frames its Δ runs on) with keyframes."""
    from mocapdb.annotation import keyframe_preselection

    found = keyframe_preselection(index, model)
    n = int(index.doc_lengths.sum())
    out = []
    for c, segs in zip(model.classes, found):
        frames = n if segs is None else int((segs.end - segs.start + 1).sum())
        out.append((c.name, len(c.quantized.expand()), frames / n))
    return out


def timed(con, sql, repeat):
    con.sql(sql).to_arrow_table()                      # warm: compile, caches, the index search
    best = (np.inf, np.inf)
    for _ in range(repeat):
        cpu, wall = time.process_time(), time.perf_counter()
        con.sql(sql).to_arrow_table()
        best = min(best, (time.perf_counter() - wall, time.process_time() - cpu))
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=None, help="archive size (default: the paper's 74 min)")
    ap.add_argument("--model-dir", type=Path, action="append", default=[],
                    help="also a model exported as Parquet files (repeatable)")
    ap.add_argument("--previous", metavar="REV", action="append", default=[],
                    help="also the default model as committed at this git revision (repeatable)")
    ap.add_argument("--repeat", type=int, default=5, help="warm repetitions (best of)")
    ap.add_argument("--threads", type=int, default=None, help="DuckDB threads (default: DuckDB's)")
    ap.add_argument("--per-class", action="store_true", help="print every class's share")
    args = ap.parse_args()

    import mocapdb
    from mocapdb.storage.model_store import load_model, save_model
    from mocapdb.storage.postings import create_index, load_index

    machine_header("keyframe preselection with the shipped default model")
    n_frames = PAPER_FRAMES if args.hours is None else int(args.hours * FRAMES_PER_HOUR)
    with tempfile.TemporaryDirectory(prefix="bench_preselection_") as tmp:
        con, _ = ingest_all(Path(tmp) / "real.duckdb")
        words, lengths = stored_words(con)
        con.close()
        words, lengths = repeat_documents(words, lengths, n_frames)
        con, _ = synthetic_db(Path(tmp) / "archive.duckdb", words, lengths)
        t = time.perf_counter()
        create_index(con)
        print(f"archive: {len(lengths):,} motions, {n_frames:,} frames ({n_frames / FRAMES_PER_HOUR:.2f} h); "
              f"index built in {time.perf_counter() - t:.1f} s; {load_now()}")
        if args.threads:
            con.execute(f"SET threads = {int(args.threads)}")
        try:
            models = {"default": load_model(con, "default")}
            others = [(f"default at {rev}", model_at(rev, f"previous{k}")) for k, rev in enumerate(args.previous)]
            others += [(str(d), model_dir(d, f"other{k}")) for k, d in enumerate(args.model_dir)]
            for _, m in others:
                save_model(con, m, replace=True)
                models[m.name] = m
            what_is = {m.name: what for what, m in others}
            index, _ = load_index(con)
            for name, model in models.items():
                what = what_is.get(name, "the shipped default")
                shares = cell_shares(index, model)
                total = sum(k * s for _, k, s in shares) / sum(k for _, k, _ in shares)
                queried = sum(c.keyframe_query is not None for c in model.classes)
                print(f"\n## {what}: {len(model.classes)} classes, {queried} with a keyframe query")
                print(f"(frame x class) cells kept by the preselection, weighted by template length: {total:.1%}")
                rows = sorted(shares, key=lambda r: -r[1] * r[2])
                for cname, k, s in (rows if args.per_class else rows[:10]):
                    print(f"  {cname:32s} K={k:4d}  {s:6.1%} of the frames  ({k * s / sum(x for _, x, _ in shares):5.2%} "
                          "of all cells)")
                res = {kf: timed(con, SQL.format(model=name, kf=kf), args.repeat) for kf in ("false", "true")}
                (w0, c0), (w1, c1) = res["false"], res["true"]
                print(f"SQL annotate(): keyframes := false {w0:.3f} s ({n_frames / w0:,.0f} frames/s, CPU {c0:.3f} s), "
                      f"true {w1:.3f} s ({n_frames / w1:,.0f} frames/s, CPU {c1:.3f} s): "
                      f"{w0 / w1:.1f}x faster (CPU {c0 / c1:.1f}x); target >= 5x; {load_now()}")
        finally:
            con.close()


if __name__ == "__main__":
    main()
