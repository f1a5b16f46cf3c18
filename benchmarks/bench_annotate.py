"""Annotation speed: Python API, SQL and core paths; 10 h, 15 classes, librosa, 100 h.

Run: ``python benchmarks/bench_annotate.py [--quick]``. Prints figures for
benchmarks/RESULTS.md (DESIGN.md §7 targets: ≥ 300,000 frames/s for a
15-class-sized model without keyframes; the Δ kernel ≥ 10× librosa including
the cost; a 100 h archive in ≤ 60 s with peak RSS ≤ 2 GB).

(a) Every ASF/AMC take of ../shared/data is ingested into a temporary DuckDB
    file (cmu/13 and cmu/14 with cmu/02/02.asf) and annotated with the
    shipped model ``toolbox`` (the toolbox's 11 HDM05 templates; the shipped
    ``default`` model has its own benchmark, bench_default_model.py), no keyframes, through
    ``annotate_motions(store=False)``, the SQL ``annotate(motion_id)`` macro
    and the in-memory core ``annotate_words``. Figures are warm (best
    of N); the first call in this process is reported separately, and so is
    the first call in a fresh process with an empty numba cache (compile).
(b) A synthetic 10 h archive (1.08 M frames at 30 Hz): the real documents'
    words repeated in order (document lengths as the real ones), through the
    core and, inserted into a DuckDB file via Arrow, through SQL.
(c) A 15-class-sized model: the 11 templates + 4 left/right mirrored ones
    (the classes with a side: depositFloorR, grabHighR, kickLFront1Reps,
    elbowToKnee1RepsLelbowStart). The paper: 133,019 frames, 15 classes,
    305 s (≈ 436 frames/s, Athlon X2 5000+, Matlab + C).
(d) The Δ kernel (textbook rule) against ``librosa.sequence.dtw(C=…,
    subseq=True)`` with the annotation steps, cost computation included in
    both, identical Δ checked.
(e) A 100 h archive (10.8 M frames) annotated through the core in a fresh
    process: wall time and peak RSS of that process.

Helpers used by bench_keyframes.py: :func:`machine_header`,
:func:`ingest_all`, :func:`repeat_documents`, :func:`synthetic_db`.
"""
import argparse
import datetime
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from timing import annotate_words, best_of, stored_words  # benchmarks/timing.py

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("MOCAPDB_SHARED", REPO.parent / "shared"))
DATA = SHARED / "data"
QUERIES_DIR = SHARED / "oracle" / "keyframes" / "queries"
FRAMES_PER_HOUR = 30 * 3600
PAPER_FRAMES, PAPER_SECONDS = 133_019, 305.0
TARGET_FPS = 300_000
#: classes with a side: their mirror image is a plausible extra class
MIRRORED = ("depositFloorR", "grabHighR", "kickLFront1Reps", "elbowToKnee1RepsLelbowStart")


# ---------------------------------------------------------------------------
# helpers shared with bench_keyframes.py


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_header(title):
    """Print what ran where: date, CPU, cores, threads, load, versions."""
    import duckdb
    import numba

    load = os.getloadavg()
    print(f"# {title}")
    print(f"date {datetime.datetime.now().isoformat(timespec='seconds')}; CPU {cpu_model()}, "
          f"os.cpu_count() = {os.cpu_count()}, numba threads {numba.get_num_threads()}; "
          f"load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1 / 5 / 15 min)")
    print(f"python {platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
          f"duckdb {duckdb.__version__}")


def load_now():
    return f"load {os.getloadavg()[0]:.2f}"


def ingest_all(path):
    """Ingest every ASF/AMC take of ../shared/data into a new database file.

    Returns (connection, seconds).
    """
    import mocapdb

    con = mocapdb.connect(path)
    t = time.perf_counter()
    r1 = mocapdb.ingest(con, [DATA / "hdm05_cut", DATA / "hdm05_full", DATA / "cmu" / "02",
                              DATA / "cmu" / "86"])
    r2 = mocapdb.ingest(con, [DATA / "cmu" / "13", DATA / "cmu" / "14"],
                        asf=DATA / "cmu" / "02" / "02.asf")
    dt = time.perf_counter() - t
    if r1.failed or r2.failed:
        raise RuntimeError(f"ingest failed: {r1.failed + r2.failed}")
    return con, dt


def repeat_documents(words, lengths, n_frames):
    """The documents repeated in order up to exactly ``n_frames`` frames (last one cut)."""
    lengths = np.asarray(lengths, dtype=np.int64)
    reps = -(-n_frames // int(lengths.sum()))
    w = np.tile(words, reps)[:n_frames]
    lens = np.tile(lengths, reps)
    cum = np.cumsum(lens)
    k = int(np.searchsorted(cum, n_frames))
    lens = lens[:k + 1].copy()
    lens[-1] -= int(cum[k]) - n_frames
    return w, lens[lens > 0]


def synthetic_db(path, words, lengths, *, fps=30.0):
    """A mocapdb database whose motions are the given word sequences (inserted via Arrow).

    The keyframe index is left empty (call ``mocapdb.storage.postings.create_index``).
    Returns (connection, seconds to insert).
    """
    import pyarrow as pa

    import mocapdb

    con = mocapdb.connect(path)
    t = time.perf_counter()
    lengths = np.asarray(lengths, dtype=np.int64)
    n = len(lengths)
    ids = np.arange(1, n + 1, dtype=np.int32)
    motions = pa.table({
        "motion_id": pa.array(ids), "name": pa.array([f"synthetic_{i}" for i in ids]),
        "source_path": pa.array(["synthetic"] * n), "format": pa.array(["amc"] * n),
        "sha256": pa.array([f"synthetic-{i}" for i in ids]),
        "source_fps": pa.array(np.full(n, 4 * fps)), "fps": pa.array(np.full(n, fps)),
        "n_source_frames": pa.array((4 * lengths).astype(np.int32)),
        "n_frames": pa.array(lengths.astype(np.int32))})
    starts = np.repeat(np.cumsum(lengths) - lengths, lengths)
    features = pa.table({
        "motion_id": pa.array(np.repeat(ids, lengths)),
        "frame": pa.array((np.arange(len(words)) - starts + 1).astype(np.int32)),
        "bits": pa.array(np.asarray(words, dtype=np.uint64), pa.uint64())})
    con.register("_bench_motions", motions)
    con.register("_bench_features", features)
    con.execute("INSERT INTO motions (motion_id, name, source_path, format, sha256, source_fps, fps, "
                "n_source_frames, n_frames) SELECT * FROM _bench_motions")
    con.execute("INSERT INTO features SELECT * FROM _bench_features")
    con.unregister("_bench_motions")
    con.unregister("_bench_features")
    return con, time.perf_counter() - t


def timed(fn, repeat):
    """(first call seconds, best of ``repeat`` further calls, result of the last call)."""
    first, _ = best_of(fn, 1)
    best, res = best_of(fn, repeat)
    return first, best, res


def mirrored_model(model, classes=MIRRORED, name="mirror15"):
    """``model`` plus left/right mirrored templates of ``classes`` (same labels)."""
    import dataclasses

    from mocapdb.features import mirror_words
    from mocapdb.annotation.model import ClassModel, Model
    from mocapdb.templates import QuantizedTemplate

    extra = []
    for c in model.classes:
        if c.name in classes:
            q = c.quantized
            extra.append(ClassModel(f"{c.name}_mirrored", c.label,
                                    quantized=QuantizedTemplate(mirror_words(q.mask), mirror_words(q.value),
                                                                q.weights),
                                    delta=c.delta, tau=c.tau))
    base = [dataclasses.replace(c, keyframe_query=None) for c in model.classes]
    return Model(name, tuple(base + extra), labels=model.labels)


# ---------------------------------------------------------------------------
# the benchmark


SQL_ANNOTATE = ("SELECT m.motion_id, unnest(annotate(m.motion_id, model := '{model}', keyframes := false), "
                "recursive := true) FROM motions m")


def row(what, frames, first, best, n_segments, target=None):
    fps = frames / best
    mark = "" if target is None else ("  met" if fps >= target else "  NOT met")
    print(f"{what:44s} {frames:>11,} {first:9.3f} {best:9.3f} {fps:>13,.0f} {n_segments:>9,}{mark}")


def header():
    print(f"{'path':44s} {'frames':>11s} {'first s':>9s} {'warm s':>9s} {'frames/s':>13s} "
          f"{'segments':>9s}")


def sql_annotate(con, model="toolbox"):
    return con.sql(SQL_ANNOTATE.format(model=model)).to_arrow_table()


def cold_compile(npz):
    """First ``annotate_words`` call in a fresh process: empty numba cache, then warm cache."""
    code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
            "import time, numpy as np, mocapdb; from timing import annotate_words; "
            "from mocapdb.storage.model_store import load_model; m = load_model(mocapdb.connect(), 'toolbox'); "
            f"z = np.load(r'{npz}'); t = time.perf_counter(); "
            "annotate_words(z['words'], z['lengths'], m, keyframes=False); "
            "print(time.perf_counter() - t)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        out = [float(subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                                    check=True).stdout) for _ in range(2)]
    return out


def peak_rss_mb():
    """This process's own peak RSS (VmHWM). ru_maxrss is no good in a child: on Linux it
    starts from the parent's peak at fork, so it reports the benchmark's own memory."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def scale_child(npz, n_frames, n_classes):
    """Run in a fresh process: annotate ``n_frames`` repeated real frames, print JSON."""
    t0 = time.perf_counter()
    import mocapdb
    from mocapdb.storage.model_store import load_model

    con = mocapdb.connect()
    model = load_model(con, "toolbox")
    if n_classes == 15:
        model = mirrored_model(model)
    z = np.load(npz)
    annotate_words(z["words"], z["lengths"], model, keyframes=False)  # load the kernels
    t1 = time.perf_counter()
    words, lengths = repeat_documents(z["words"], z["lengths"], n_frames)
    t2 = time.perf_counter()
    segs = annotate_words(words, lengths, model, keyframes=False)
    t3 = time.perf_counter()
    print(json.dumps({"setup_s": t1 - t0, "build_s": t2 - t1, "annotate_s": t3 - t2, "wall_s": t3 - t0,
                      "maxrss_mb": peak_rss_mb(),
                      "n_docs": int(len(lengths)), "n_segments": int(len(segs))}))


def librosa_compare(words, templates, n_threads_list):
    """Δ (textbook rule) of ours vs librosa on the same words and templates, cost included."""
    import librosa
    import numba

    from mocapdb.templates import ANNOTATION_STEPS, cost_table, mt_distance

    sigma = np.array([[s[0], s[1]] for s in ANNOTATION_STEPS])
    wmul = np.array([s[2] for s in ANNOTATION_STEPS])
    qs = [q.expand() for q in templates]

    def run_librosa(w):
        out = []
        for q in qs:
            pc = np.bitwise_count((q.value[:, None] ^ w[None, :]) & q.mask[:, None])
            C = cost_table(q)[np.arange(len(q))[:, None], pc]
            D = librosa.sequence.dtw(C=C, subseq=True, step_sizes_sigma=sigma, weights_mul=wmul,
                                     backtrack=False)
            out.append(D[-1])
        return np.array(out)

    run_librosa(words[:2000])  # librosa's numba compile
    t = time.perf_counter()
    ref = run_librosa(words)
    t_lib = time.perf_counter() - t
    cells = sum(len(q) for q in qs) * len(words)
    print(f"{len(words):,} frames x {len(qs)} templates (ΣK = {sum(len(q) for q in qs)}, "
          f"{cells / 1e6:.0f} M cells): librosa {t_lib:.3f} s ({cells / t_lib / 1e6:.1f} M cells/s)")
    default_threads = numba.get_num_threads()
    for nt in n_threads_list:
        numba.set_num_threads(nt)
        mt_distance(words[:2000], qs, rule="textbook", expand=False)
        _, t_ours, ours = timed(lambda: mt_distance(words, qs, rule="textbook", expand=False), 2)
        same = np.array_equal(ours, ref)
        ratio = t_lib / t_ours
        print(f"ours, {nt} thread(s): {t_ours:.3f} s ({cells / t_ours / 1e6:.0f} M cells/s) -> "
              f"{ratio:.1f}x librosa; Δ identical: {same}; target >= 10x: {'met' if ratio >= 10 else 'NOT met'}")
        if not same:
            raise AssertionError("textbook Δ differs from librosa")
    numba.set_num_threads(default_threads)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: 1 h instead of 10 h, 10 h instead of 100 h, fewer repeats")
    ap.add_argument("--repeat", type=int, default=None, help="warm repetitions (best of)")
    ap.add_argument("--no-cold", action="store_true", help="skip the fresh-process compile measurement")
    ap.add_argument("--scale-child", nargs=3, metavar=("NPZ", "FRAMES", "CLASSES"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.scale_child:
        scale_child(args.scale_child[0], int(args.scale_child[1]), int(args.scale_child[2]))
        return
    import numba

    import mocapdb  # noqa: F401
    from mocapdb.api import annotate as annotate_motions
    from mocapdb.storage.model_store import load_model, save_model

    hours = 1 if args.quick else 10
    scale_hours = 10 if args.quick else 100
    rep_small = args.repeat or (2 if args.quick else 5)
    rep_big = args.repeat or (1 if args.quick else 2)
    lib_frames = 20_000 if args.quick else 100_000

    machine_header("bench_annotate" + (" --quick" if args.quick else ""))
    tmp = tempfile.TemporaryDirectory(prefix="bench_annotate_")
    tmpdir = Path(tmp.name)

    # ---- (a) all ingested data -------------------------------------------------
    con, t_ingest = ingest_all(tmpdir / "all.duckdb")
    words, lengths = stored_words(con)
    n_all = len(words)
    model = load_model(con, "toolbox")
    print(f"\n## (a) all of ../shared/data ingested: {len(lengths)} motions, {n_all:,} frames at 30 Hz "
          f"({n_all / 1800:.1f} min) in {t_ingest:.1f} s; toolbox model, {len(model.classes)} classes "
          f"(ΣK = {sum(len(c.quantized) for c in model.classes)}), no keyframes; warm = best of {rep_small}; "
          f"{load_now()}")
    header()
    first, best, tab = timed(lambda: annotate_motions(con, model="toolbox", store=False, keyframes=False), rep_small)
    row("Python annotate_motions(store=False)", n_all, first, best, tab.num_rows)
    first, best, sql = timed(lambda: sql_annotate(con), rep_small)
    row("SQL unnest(annotate(motion_id))", n_all, first, best, sql.num_rows)
    first, best, segs = timed(lambda: annotate_words(words, lengths, model, keyframes=False), rep_small)
    row("core annotate_words", n_all, first, best, len(segs))
    assert tab.num_rows == sql.num_rows == len(segs), "the three paths disagree"
    npz = tmpdir / "words.npz"
    np.savez(npz, words=words, lengths=lengths)
    if not args.no_cold:
        cold, warm = cold_compile(npz)
        print(f"first core call in a fresh process: {cold:.1f} s with an empty numba cache (compile), "
              f"{warm:.2f} s with the cache")
    model15 = mirrored_model(model)
    save_model(con, model15, description="benchmark: default + 4 mirrored templates")
    first, best, segs15 = timed(lambda: annotate_words(words, lengths, model15, keyframes=False),
                                rep_small)
    row("core, 15-class model", n_all, first, best, len(segs15), TARGET_FPS)
    first, best, sql15 = timed(lambda: sql_annotate(con, "mirror15"), rep_small)
    row("SQL, 15-class model", n_all, first, best, sql15.num_rows, TARGET_FPS)
    con.close()

    # ---- (b, c) synthetic archive -----------------------------------------------
    n_syn = hours * FRAMES_PER_HOUR
    w_syn, l_syn = repeat_documents(words, lengths, n_syn)
    con, t_insert = synthetic_db(tmpdir / f"synthetic_{hours}h.duckdb", w_syn, l_syn)
    save_model(con, model15)
    load_model(con, "toolbox")  # stores the shipped toolbox model in the new database
    print(f"\n## (b, c) synthetic {hours} h: the real documents repeated, {len(l_syn):,} documents, "
          f"{n_syn:,} frames (inserted via Arrow in {t_insert:.1f} s); warm = best of {rep_big}; {load_now()}")
    header()
    first, best, segs = timed(lambda: annotate_words(w_syn, l_syn, model, keyframes=False), rep_big)
    row("core, toolbox model (11 classes)", n_syn, first, best, len(segs))
    first, best, sql = timed(lambda: sql_annotate(con), rep_big)
    row("SQL, toolbox model (11 classes)", n_syn, first, best, sql.num_rows)
    first, best, segs15 = timed(lambda: annotate_words(w_syn, l_syn, model15, keyframes=False),
                                rep_big)
    row("core, 15-class model", n_syn, first, best, len(segs15), TARGET_FPS)
    fps15 = n_syn / best
    first, best, sql15 = timed(lambda: sql_annotate(con, "mirror15"), rep_big)
    row("SQL, 15-class model", n_syn, first, best, sql15.num_rows, TARGET_FPS)
    con.close()
    print(f"paper: {PAPER_FRAMES:,} frames, 15 classes, {PAPER_SECONDS:.0f} s = "
          f"{PAPER_FRAMES / PAPER_SECONDS:,.0f} frames/s; ours (core, 15 classes, {hours} h) "
          f"{fps15 / (PAPER_FRAMES / PAPER_SECONDS):,.0f}x that; 74 min would take "
          f"{PAPER_FRAMES / fps15:.2f} s (target < 0.5 s)")

    # ---- (d) librosa ------------------------------------------------------------
    print(f"\n## (d) Δ kernel vs librosa.sequence.dtw(C=…, subseq=True, steps [[1,1],[1,2],[2,1]], "
          f"weights_mul [1,1,2]), textbook rule, cost included in both; {load_now()}")
    try:
        librosa_compare(w_syn[:lib_frames], [c.quantized for c in model.classes],
                        sorted({1, numba.config.NUMBA_NUM_THREADS}))
    except ImportError:
        print("librosa not importable: skipped")

    # ---- (e) scale ------------------------------------------------------------
    n_scale = scale_hours * FRAMES_PER_HOUR
    print(f"\n## (e) scale: {scale_hours} h = {n_scale:,} frames (real documents repeated), core path, "
          f"fresh process; {load_now()}")
    print(f"{'model':14s} {'annotate s':>10s} {'frames/s':>11s} {'process s':>10s} {'peak RSS MB':>11s} "
          f"{'segments':>10s}")
    for n_cls in (11,) if args.quick else (11, 15):
        out = subprocess.run([sys.executable, __file__, "--scale-child", str(npz), str(n_scale), str(n_cls)],
                             capture_output=True, text=True, check=True).stdout
        r = json.loads(out.strip().splitlines()[-1])
        ok = r["annotate_s"] <= 60 * scale_hours / 100 and r["maxrss_mb"] <= 2048
        print(f"{n_cls:>2d} classes     {r['annotate_s']:10.1f} {n_scale / r['annotate_s']:11,.0f} "
              f"{r['wall_s']:10.1f} {r['maxrss_mb']:11,.0f} {r['n_segments']:10,}"
              f"  target ({60 * scale_hours / 100:.0f} s, 2048 MB): {'met' if ok else 'NOT met'}")
    tmp.cleanup()


if __name__ == "__main__":
    main()
