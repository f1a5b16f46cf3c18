"""Query by example (``mocapdb similar``, issue 21): latency and memory on archives up to 100 h.

Run: ``python benchmarks/bench_similar.py [--hours 100] [--db FILE] [--quick]``.
Target (issue 21): a query over 100 h answers in ≤ 1 s warm with keyframe
preselection, and a query's memory does not grow with the archive.

The archive is built from real features: every ASF/AMC take of
../shared/data (hdm05_cut, hdm05_full, cmu; ``bench_annotate.ingest_all``)
is read once, their words are concatenated in order and cut into 60-second
takes (1,800 frames), repeated until the archive holds ``--hours`` hours;
the takes are stored with ``mocapdb.storage.ingest.store_words`` into a
fresh DuckDB file (features, postings: the index every database keeps),
which is kept (``--db``) and reused by later runs of the same size.

Queries: a clip of each of the 11 HDM05 classes (its first take of actor
bd, whole) and two stretches of CMU 86_09 (walking, clapping), looked up in
the archive by their words.

(a) **warm latency** of ``mocapdb.similar(con, motion, start_frame=…,
    end_frame=…)`` (API) and of ``SELECT * FROM similar_to(…)`` (SQL), after a
    first query on the connection (which loads the index); median and
    maximum over the queries; with the frames the preselection keeps;
(b) the same without preselection (``keyframes=False``), one query;
(c) **memory**: peak RSS of a fresh process that opens the archive, runs
    the queries and reports, per archive size (10 h and ``--hours``), the
    RSS after loading the index and the peak during the queries: a query's
    own memory (peak − after loading) must not grow with the archive.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_annotate import FRAMES_PER_HOUR, ingest_all, machine_header, peak_rss_mb  # noqa: E402

TAKE_FRAMES = 60 * 30
#: stored per store_words call (one transaction each)
STORE_BATCH = 100


def source_words(tmp):
    """(names, words per take) of every ASF/AMC take of ../shared/data, in motion-id order."""
    from mocapdb.storage.motions import motion_documents

    con, _ = ingest_all(Path(tmp) / "source.duckdb")
    docs = motion_documents(con)
    con.close()
    starts = np.concatenate(([0], np.cumsum(docs.lengths)))
    return docs.names, [docs.words[a:b] for a, b in zip(starts[:-1], starts[1:])]


def build_archive(path, hours, words):
    """A database of ``hours`` hours of 60-second takes cut from the concatenated real words."""
    import mocapdb
    from mocapdb.storage.ingest import store_words

    stream = np.concatenate(words)
    n_takes = int(hours * FRAMES_PER_HOUR) // TAKE_FRAMES
    con = mocapdb.connect(path)
    t = time.perf_counter()
    batch = {}
    for k in range(n_takes):
        a = (k * TAKE_FRAMES) % (len(stream) - TAKE_FRAMES)
        batch[f"take_{k:06d}"] = stream[a:a + TAKE_FRAMES]
        if len(batch) == STORE_BATCH or k == n_takes - 1:
            store_words(con, batch, source="bench_similar")
            batch = {}
    con.close()
    return time.perf_counter() - t


def archive(path, hours, words):
    """Reuse ``path`` if it holds exactly ``hours`` hours, else build it."""
    import mocapdb

    want = int(hours * FRAMES_PER_HOUR) // TAKE_FRAMES * TAKE_FRAMES
    if Path(path).exists():
        con = mocapdb.connect(path, read_only=True)
        have = con.execute("SELECT coalesce(sum(n_frames), 0) FROM motions").fetchall()[0][0]
        con.close()
        if have == want:
            return 0.0
        Path(path).unlink()
    return build_archive(path, hours, words)


def query_stretches(names, words):
    """(label, offset in the concatenated stream, length) of the query stretches: a bd clip per
    HDM05 class (whole), two stretches of 86_09 (walking, clapping)."""
    starts = np.concatenate(([0], np.cumsum([len(w) for w in words])))
    out, seen = [], set()
    for k, n in enumerate(names):
        parts = n.split("_")
        if n.startswith("HDM_bd_") and parts[2] not in seen:
            seen.add(parts[2])
            out.append((parts[2], int(starts[k]), len(words[k])))
    k = names.index("86_09")
    out += [("86_09 walk", int(starts[k]) + 30, 90), ("86_09 clap", int(starts[k]) + 600, 90)]
    return out


def locate(con, offset, n):
    """(motion id, first, last) (1-based frames) of the first take holding stream[offset:offset + n]."""
    k = offset // TAKE_FRAMES
    if offset + n > (k + 1) * TAKE_FRAMES:  # straddles two takes: move it into the next one
        offset = (k + 1) * TAKE_FRAMES
        k += 1
    mid = con.execute("SELECT motion_id FROM motions WHERE name = ?", [f"take_{k:06d}"]).fetchall()[0][0]
    first = offset - k * TAKE_FRAMES + 1
    return int(mid), first, first + n - 1


def child(path, queries_json):
    """In a fresh process: open the archive, run a first query (it reads the index's runs, batch
    by batch, into the connection's cache), then every query; print JSON."""
    import mocapdb

    queries = json.loads(queries_json)
    con = mocapdb.connect(path, read_only=True)
    t = time.perf_counter()
    mocapdb.similar(con, queries[0][0], start_frame=queries[0][1], end_frame=queries[0][2])
    load_s = time.perf_counter() - t
    load_peak = peak_rss_mb()
    with open("/proc/self/clear_refs", "w") as fh:  # reset the peak (VmHWM) to the current RSS
        fh.write("5")
    after_load = current_rss_mb()
    times = []
    for mid, a, b in queries:
        t = time.perf_counter()
        mocapdb.similar(con, mid, start_frame=a, end_frame=b)
        times.append(time.perf_counter() - t)
    print(json.dumps({"load_s": load_s, "load_peak_mb": load_peak, "after_load_mb": after_load,
                      "peak_mb": peak_rss_mb(),
                      "first_query_s": times[0], "median_s": statistics.median(times[1:] or times)}))


def current_rss_mb():
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def preselection_share(con, mid, a, b):
    """Frames the query's preselection keeps, as a fraction of the archive (batch by batch, as
    ``similar`` searches it)."""
    from mocapdb.storage.cache import connection_cache
    from mocapdb.storage.retrieval import query_stretch, search_archive

    stats = {}
    search_archive(connection_cache(con), [query_stretch(con, mid, a, b)], stats=stats)
    return stats["ranked_frames"] / stats["archive_frames"]


def measure(path, queries, label):
    import mocapdb

    con = mocapdb.connect(path, read_only=True)
    mid, a, b = queries[0][1]
    mocapdb.similar(con, mid, start_frame=a, end_frame=b)  # reads the index's runs into the cache
    print(f"\n## {label}: warm latency per query (API / SQL), preselected share of the archive")
    print("| query | frames | API s | SQL s | kept | results | best cost |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    api, sql = [], []
    for name, (mid, a, b) in queries:
        reps = []
        for _ in range(3):
            t = time.perf_counter()
            table = mocapdb.similar(con, mid, start_frame=a, end_frame=b)
            reps.append(time.perf_counter() - t)
        t = time.perf_counter()
        rows = con.execute("SELECT * FROM similar_to(?, ?, ?)", [mid, a, b]).fetchall()
        sql_s = time.perf_counter() - t
        assert [r[1:4] for r in rows] == list(zip(*(table.column(c).to_pylist() for c in
                                                    ("motion_id", "start_frame", "end_frame")))), name
        api.append(min(reps))
        sql.append(sql_s)
        kept = preselection_share(con, mid, a, b)
        best = table.column("cost")[0].as_py() if table.num_rows else float("nan")
        print(f"| {name} | {b - a + 1} | {min(reps):.3f} | {sql_s:.3f} | {kept:.1%} | {table.num_rows} | {best:.3f} |")
    print(f"| **median / max** | | **{statistics.median(api):.3f}** / {max(api):.3f} | "
          f"{statistics.median(sql):.3f} / {max(sql):.3f} | | | |")
    mid, a, b = queries[0][1]
    t = time.perf_counter()
    mocapdb.similar(con, mid, start_frame=a, end_frame=b, keyframes=False)
    print(f"\nwithout preselection ({queries[0][0]}): {time.perf_counter() - t:.3f} s")
    con.close()
    return statistics.median(api), max(api)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=100.0)
    ap.add_argument("--db", type=Path, help="archive file to build or reuse (default: in a temporary folder)")
    ap.add_argument("--quick", action="store_true", help="10 h instead of --hours, no memory comparison")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    hours = 10.0 if args.quick else args.hours
    machine_header(f"bench_similar: query by example, {hours:g} h")
    with tempfile.TemporaryDirectory() as tmp:
        names, words = source_words(tmp)
        stretches = query_stretches(names, words)
        sizes = [hours] if args.quick else sorted({10.0, hours})
        results = {}
        for h in sizes:
            path = args.db if (args.db and h == hours) else Path(tmp) / f"archive_{h:g}h.duckdb"
            built = archive(path, h, words)
            print(f"\narchive {h:g} h ({int(h * FRAMES_PER_HOUR) // TAKE_FRAMES} takes of 60 s): "
                  + (f"built in {built:.0f} s" if built else "reused"))
            import mocapdb

            con = mocapdb.connect(path, read_only=True)
            queries = [(n, locate(con, off, length)) for n, off, length in stretches]
            con.close()
            med, worst = measure(path, queries, f"{h:g} h")
            r = subprocess.run([sys.executable, "-P", __file__, "--child", str(path),
                                json.dumps([q for _, q in queries])], capture_output=True, text=True,
                               env={**os.environ}, check=True)
            results[h] = json.loads(r.stdout.strip().splitlines()[-1])
            results[h]["median_s"] = med
            print(f"\nfresh process: index load {results[h]['load_s']:.2f} s (peak {results[h]['load_peak_mb']:.0f} MB), "
                  f"RSS after load {results[h]['after_load_mb']:.0f} MB, peak during the queries "
                  f"{results[h]['peak_mb']:.0f} MB "
                  f"(a query's own: {results[h]['peak_mb'] - results[h]['after_load_mb']:.0f} MB); first query "
                  f"{results[h]['first_query_s']:.2f} s")
        top = results[hours]
        print(f"\ntarget: ≤ 1 s warm on {hours:g} h: median {top['median_s']:.3f} s — "
              f"{'met' if top['median_s'] <= 1.0 else 'NOT met'}")
        if len(results) > 1:
            small, big = results[min(results)], results[max(results)]
            print(f"a query's own memory: {small['peak_mb'] - small['after_load_mb']:.0f} MB at {min(results):g} h, "
                  f"{big['peak_mb'] - big['after_load_mb']:.0f} MB at {max(results):g} h")


if __name__ == "__main__":
    main()
