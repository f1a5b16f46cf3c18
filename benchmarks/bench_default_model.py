"""Annotation speed of the shipped default model (issue 11): all its classes, keyframes on, 74 minutes.

Run: ``python benchmarks/bench_default_model.py [--repeat 5]``. Target: with
the larger model (every subclass template, keyframe preselection on) the
annotation stays at ≥ 300,000 frames/s on an archive the size of the paper's
evaluation set (74 min, 133,019 frames at 30 Hz; the paper: 305 s without
keyframes, 20 s with, Matlab + C on an Athlon X2).

The archive: the real documents of ../shared/data (every ASF/AMC take,
ingested) repeated in order up to 133,019 frames, stored in a DuckDB file
with its keyframe index. Timed (warm, best of ``--repeat``): the SQL macro
``annotate(motion_id)`` over every motion, the Python API
``mocapdb.annotate(store=False)`` (the stored index's preselection, cached
per connection as in SQL), and the in-memory core (an index of the words,
then the chain) — each with and without keyframes; the ``toolbox`` model
(11 templates, no keyframes) beside them.
"""
import argparse
import os
import tempfile
import time
from pathlib import Path

from bench_annotate import ingest_all, load_now, machine_header, repeat_documents, synthetic_db
from timing import annotate_words, best_of, stored_words

PAPER_FRAMES, PAPER_SECONDS, PAPER_KEYFRAME_SECONDS = 133_019, 305.0, 20.0
TARGET_FPS = 300_000


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="warm repetitions (best of)")
    args = ap.parse_args()

    import mocapdb
    from mocapdb.storage.model_store import load_model
    from mocapdb.storage.postings import create_index

    machine_header("annotation speed of the shipped default model")
    with tempfile.TemporaryDirectory() as tmp:
        con, _ = ingest_all(Path(tmp) / "real.duckdb")
        words, lengths = stored_words(con)
        con.close()
        words, lengths = repeat_documents(words, lengths, PAPER_FRAMES)
        con, _ = synthetic_db(Path(tmp) / "archive.duckdb", words, lengths)
        create_index(con)
        try:
            default, toolbox = load_model(con, "default"), load_model(con, "toolbox")
            with_query = sum(c.keyframe_query is not None for c in default.classes)
            print(f"archive: {len(lengths)} motions, {int(lengths.sum())} frames (74 min at 30 Hz); default "
                  f"model: {len(default.classes)} classes, {len(default.labels)} labels, {with_query} keyframe "
                  f"queries; toolbox: {len(toolbox.classes)} classes\n")
            sql = ("SELECT count(*) FROM (SELECT unnest(annotate(m.motion_id, model := $model, "
                   "keyframes := $kf), recursive := true) FROM motions m)")
            rows = []
            for name, model, kf in (("default", default, True), ("default", default, False),
                                    ("toolbox", toolbox, False)):
                what = f"{name}, keyframes {'on' if kf else 'off'}"
                con.execute(sql, {"model": name, "kf": kf}).fetchall()        # warm: compile, caches
                t_sql, n = best_of(lambda: con.execute(sql, {"model": name, "kf": kf}).fetchall()[0][0],
                                   args.repeat)
                mocapdb.annotate(con, model=name, keyframes=kf, store=False)
                t_api, _ = best_of(lambda: mocapdb.annotate(con, model=name, keyframes=kf, store=False),
                                   args.repeat)
                t_core, _ = best_of(lambda: annotate_words(words, lengths, model, keyframes=kf), args.repeat)
                rows.append((what, n, t_sql, t_api, t_core))
            print(f"{'model and mode':<28s} {'segments':>9s} {'SQL s':>8s} {'frames/s':>11s} {'API s':>8s} "
                  f"{'frames/s':>11s} {'core s':>8s} {'frames/s':>11s}")
            for what, n, *ts in rows:
                print(f"{what:<28s} {n:9d} " + " ".join(f"{t:8.3f} {PAPER_FRAMES / t:11,.0f}" for t in ts))
            print(f"paper (15 classes, Matlab + C, Athlon X2): {PAPER_SECONDS:.0f} s without keyframes "
                  f"({PAPER_FRAMES / PAPER_SECONDS:,.0f} frames/s), {PAPER_KEYFRAME_SECONDS:.0f} s with "
                  f"({PAPER_FRAMES / PAPER_KEYFRAME_SECONDS:,.0f} frames/s)")
            slowest = min(PAPER_FRAMES / t for _, _, *ts in rows[:1] for t in ts)
            print(f"\ntarget >= {TARGET_FPS:,} frames/s with the default model, keyframes on (slowest path): "
                  f"{slowest:,.0f} — {'met' if slowest >= TARGET_FPS else 'NOT met'}; {load_now()}")
        finally:
            con.close()


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    main()
