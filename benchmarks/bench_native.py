"""The native extension against the Python UDFs, side by side in one run (issue 31).

Run: ``python benchmarks/bench_native.py [--quick]``. Prints figures for benchmarks/RESULTS.md.

Archives: real documents of ../shared (the HDM05 documents, CMU subjects 02 and 86) repeated to
the paper's 74 minutes (133,019 frames, as bench_sql.py) and to 10 hours (1,080,000 frames), with
the keyframe index built. Queries: the shipped default model's keyframe queries, inline (``keyframe_search_words`` with the
stored masks, values and gap bounds), each run once per pass; and ``mt_distance`` of three classes
(short, middle, long templates) on every motion; ``similar_to`` of 1–4 s stretches (k = 10).
Every side runs in a process of its own (Python duckdb; the native side never imports mocapdb)
and reports the first pass (cold: the Python side parses nothing, but loads index batches),
the best of the next passes, the least CPU time (all threads) of those passes (a ratio that holds on a
shared machine), the rows (which must agree) and the process's peak RSS.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_annotate import DATA, PAPER_FRAMES, load_now, machine_header, repeat_documents, synthetic_db  # noqa: E402
from timing import stored_words  # noqa: E402

HOURS_10 = 30 * 3600 * 10

QUERIES = """
SELECT class, list(mask ORDER BY k), list(value ORDER BY k),
       list(d_min ORDER BY k) FILTER (WHERE d_min IS NOT NULL OR d_max IS NOT NULL OR k < n),
       list(d_max ORDER BY k) FILTER (WHERE d_min IS NOT NULL OR d_max IS NOT NULL OR k < n)
FROM (SELECT *, max(k) OVER (PARTITION BY class) AS n FROM keyframes WHERE model = 'default')
GROUP BY class ORDER BY class
"""

# one side of the comparison, in its own process: argv = side, database, extension, passes
SIDE = r"""
import hashlib, json, resource, sys, time
side, db, ext, passes = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
queries = json.load(sys.stdin)
def peak_mb():  # VmHWM, not ru_maxrss: that keeps the parent's peak across exec
    line = next(x for x in open("/proc/self/status") if x.startswith("VmHWM:"))
    return int(line.split()[1]) / 1024
if side == "python":
    import mocapdb
    con = mocapdb.connect(db, read_only=True)
else:
    import duckdb
    con = duckdb.connect(db, read_only=True, config={"allow_unsigned_extensions": "true"})
    con.execute(f"LOAD '{ext}'")
con.execute("SET enable_progress_bar = false")
def cpu_s():  # the process's CPU time, every thread's: what a pass costs whatever else the machine runs
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
times, cpus, rows = [], [], None
for _ in range(passes):
    t, c = time.perf_counter(), cpu_s()
    rows = [con.execute(q).fetchall() for q in queries]
    times.append(time.perf_counter() - t)
    cpus.append(cpu_s() - c)
print(json.dumps({"first": times[0], "best": min(times[1:] or times), "cpu": min(cpus[1:] or cpus),
                  "rows": sum(map(len, rows)), "digest": hashlib.md5(str(rows).encode()).hexdigest(),
                  "rss_mb": peak_mb()}))
"""


def words_sql(masks, vals, gap_min, gap_max):
    def lst(xs):
        return "[" + ", ".join("NULL" if x is None else str(x) for x in xs) + "]"

    return (f"SELECT * FROM keyframe_search_words({lst(masks)}::UBIGINT[], {lst(vals)}::UBIGINT[], "
            f"{lst(gap_min or [])}::BIGINT[], {lst(gap_max or [])}::BIGINT[]) ORDER BY ALL")


def annotate_sql(keyframes):
    """annotate() of every motion under the default model: the Python macro takes named arguments, a
    native scalar function positional ones."""
    kf = "true" if keyframes == "on" else "false"
    return {"python": [f"SELECT motion_id, annotate(motion_id, keyframes := {kf}) FROM motions ORDER BY motion_id"],
            "native": [f"SELECT motion_id, annotate(motion_id, 'default', NULL, {kf}) FROM motions "
                       "ORDER BY motion_id"]}


def side(name, db, ext, queries, passes):
    """One side's figures; ``queries`` is a list, or a dict of lists by side (SQL that differs)."""
    queries = queries[name] if isinstance(queries, dict) else queries
    # the Python side keeps mocapdb.connect from loading the extension: its UDFs answer
    env = dict(os.environ, MOCAPDB_NATIVE="0") if name == "python" else None
    run = subprocess.run([sys.executable, "-c", SIDE, name, str(db), str(ext), str(passes)],
                         input=json.dumps(queries), capture_output=True, text=True, check=True, env=env)
    return json.loads(run.stdout)


def similar_sql(ranges):
    """similar_to of query stretches (motion, first, last), k = 10: the Python UDF behind the macro and
    the native function, both returning the ranked list."""
    return {"python": [f"SELECT mocap_similar('{m}', 'INTEGER', {a}, {b}, 10, (SELECT version FROM mocap_index.state))"
                       for m, a, b in ranges],
            "native": [f"SELECT similar_to({m}, {a}, {b}, 10)" for m, a, b in ranges]}


def main():
    import mocapdb
    from mocapdb.api import create_index

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="74 minutes only, fewer passes")
    ap.add_argument("--only", choices=("keyframe_search_words", "mt_distance", "annotate", "similar_to"),
                    help="one function only")
    ap.add_argument("--hours", type=float, nargs="+", help="archives of these many hours instead of 74 min and 10 h "
                    "(e.g. --hours 100: memory flat in archive size)")
    args = ap.parse_args()
    machine_header("bench_native" + (" --quick" if args.quick else "") + (f" --hours {args.hours}" if args.hours else ""))
    ext = mocapdb.api.extension_path()
    passes = 3 if args.quick else 5
    with tempfile.TemporaryDirectory(prefix="bench_native_") as tmp:
        with mocapdb.connect(Path(tmp) / "real.duckdb") as con:
            mocapdb.ingest(con, [DATA / "hdm05_full", DATA / "cmu" / "86"])
            mocapdb.ingest(con, [DATA / "cmu" / "02"])
            words, lengths = stored_words(con)
            queries = [words_sql(*r[1:]) for r in con.execute(QUERIES).fetchall()]
        delta = [f"SELECT motion_id, mt_distance(motion_id, '{c}') FROM motions ORDER BY motion_id"
                 for c in ("squat1Reps", "kickLFront1Reps", "lieDownFloor")]
        print(f"{len(queries)} keyframe queries (the default model's, inline); mt_distance of {len(delta)} classes")
        print("| archive | function | side | first pass s | best pass s | best pass CPU s | rows | peak RSS MB |")
        print("|---|---|---|---|---|---|---|---|")
        sizes = (("74 min", PAPER_FRAMES), ("10 h", HOURS_10))[:1 if args.quick else 2]
        if args.hours:
            sizes = [(f"{h:g} h", int(30 * 3600 * h)) for h in args.hours]
        for label, n_frames in sizes:
            w, lens = repeat_documents(words, lengths, n_frames)
            path = Path(tmp) / f"{n_frames}.duckdb"
            con, _ = synthetic_db(path, w, lens)
            create_index(con)
            con.close()
            functions = [(f"keyframe_search_words ×{len(queries)}", queries),
                         (f"mt_distance ×{len(delta)} classes", delta)]
            functions += [(f"annotate, keyframes {k}", annotate_sql(k)) for k in ("on", "off")]
            # query stretches of 1, 2 and 4 s from the first motions (whose stretches recur in the repeats)
            ranges = [(m, 31 + 90 * m, 31 + 90 * m + 30 * s - 1) for m in range(1, 5) for s in (1, 2, 4)
                      if 31 + 90 * m + 30 * s - 1 <= lens[m - 1]]
            functions.append((f"similar_to ×{len(ranges)}", similar_sql(ranges)))
            for what, qs in functions:
                if args.only and not what.startswith(args.only):
                    continue
                got = {s: side(s, path, ext, qs, passes) for s in ("python", "native")}
                assert got["python"]["digest"] == got["native"]["digest"], got  # the same rows, Δ bit for bit
                for s, r in got.items():
                    print(f"| {label} ({len(lens):,} motions) | {what} | {s} | "
                          f"{r['first']:.3f} | {r['best']:.3f} | {r['cpu']:.3f} | {r['rows']:,} | {r['rss_mb']:.0f} |")
            print(f"<!-- {load_now()} -->")


if __name__ == "__main__":
    main()
