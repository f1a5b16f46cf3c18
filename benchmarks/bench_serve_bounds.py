"""What bounds a request of ``mocapdb serve`` (issue 33): the query stretch, the time limit, a client that hangs up,
the cap on heavy requests, and a writer beside the server.

Run: ``python benchmarks/bench_serve_bounds.py [--hours 20] [--db FILE]``.

The archive is ``bench_serve``'s (built, or reused, at ``--hours``). ``mocapdb serve`` runs in a process of its own
with ``--timeout``; from the client:

* find-similar with the longest stretch a request may ask (60 s: the bench's takes are 60 s long, so a longer
  stretch is refused as outside the take; ``tests/test_serve_bounds.py`` holds the refusal itself);
* find-similar over the whole archive with the time limit set low (``--timeout 2``): when its answer comes;
* a client that hangs up after 1 s of a heavy request: when a writer in another process gets the file
  (``mocapdb.connect(lock_wait=…)``), and the server's CPU time spent after the hang-up;
* four heavy requests at once: what each answers, and when.
"""
import argparse
import concurrent.futures
import http.client
import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_annotate import machine_header  # noqa: E402
import bench_serve  # noqa: E402

HERE = Path(__file__).resolve().parent


class Server(bench_serve.Server):
    """``bench_serve``'s server, asked with a connection that may hang up, and its CPU time."""

    def get(self, path, *, hang_up=None):
        """(seconds, status) of a GET; ``hang_up``: close the connection after that many seconds instead."""
        t = time.perf_counter()
        port = int(self.url.rsplit(":", 1)[1])
        con = http.client.HTTPConnection("127.0.0.1", port, timeout=hang_up or 600)
        con.request("GET", path)
        try:
            r = con.getresponse()
            r.read()
            return time.perf_counter() - t, r.status
        except TimeoutError:
            return time.perf_counter() - t, None
        finally:
            con.close()

    def cpu(self):
        """The server process's CPU seconds so far (user + system)."""
        fields = Path(f"/proc/{self.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _writer_waits(db):
    """Seconds until another process opens ``db`` read-write (waiting up to 600 s for the lock)."""
    code = ("import sys, time, mocapdb; t = time.perf_counter(); "
            "mocapdb.connect(sys.argv[1], lock_wait=600).close(); print(time.perf_counter() - t)")
    return float(subprocess.run([sys.executable, "-c", code, str(db)], capture_output=True, text=True,
                                check=True).stdout)


def measure(db):
    import mocapdb

    with mocapdb.connect(db, read_only=True) as con:
        mid, n = con.execute("SELECT motion_id, n_frames FROM motions ORDER BY n_frames DESC LIMIT 1").fetchall()[0]
        frames = con.execute("SELECT sum(n_frames) FROM motions").fetchall()[0][0]
    print(f"archive: {frames:,} frames ({frames / 30 / 3600:.1f} h); query motion {mid} ({n} frames)")
    rows = []
    server = Server(db)
    try:
        server.get(f"/api/similar?motion={mid}&start_frame=1&end_frame=90")  # the index read once (warm)
        t, status = server.get(f"/api/similar?motion={mid}&start_frame=1&end_frame=1800")
        rows.append(("find-similar, a 60 s stretch (the bound)", t, status))
        # a client that hangs up after 1 s: when does a writer get in, and what does the server spend after?
        cpu0 = server.cpu()
        t0 = time.perf_counter()
        with concurrent.futures.ThreadPoolExecutor(1) as pool:
            hung = pool.submit(server.get, f"/api/similar?motion={mid}&start_frame=1&end_frame=1800", hang_up=1.0)
            time.sleep(0.5)
            waited = _writer_waits(db)
            hung.result()
        rows.append(("a writer beside a heavy request whose client hung up after 1 s: writer in after", waited, None))
        time.sleep(2)
        rows.append(("server CPU seconds from the hang-up request's start, 2 s after", server.cpu() - cpu0, None))
        rows.append(("(wall seconds of that span)", time.perf_counter() - t0, None))
        # four heavy requests at once
        t0 = time.perf_counter()
        with concurrent.futures.ThreadPoolExecutor(4) as pool:
            got = list(pool.map(lambda k: server.get(f"/api/similar?motion={mid}&start_frame={1 + 300 * k}"
                                                     f"&end_frame={900 + 300 * k}"), range(4)))
        for k, (t, status) in enumerate(sorted(got)):
            rows.append((f"four heavy requests at once: answer {k + 1}", t, status))
    finally:
        server.stop()
    server = Server(db, "--timeout", "2")
    try:
        server.get(f"/api/similar?motion={mid}&start_frame=1&end_frame=90")
        t, status = server.get(f"/api/similar?motion={mid}&start_frame=1&end_frame=1800")
        rows.append(("find-similar, a 60 s stretch, --timeout 2", t, status))
    finally:
        server.stop()
    for what, t, status in rows:
        print(f"| {what} | {t:.2f} | {'' if status is None else status} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=20.0)
    ap.add_argument("--db", type=Path, help="archive file to build or reuse")
    args = ap.parse_args()
    db = args.db or HERE / "out" / f"serve_{args.hours:g}h.duckdb"
    db.parent.mkdir(parents=True, exist_ok=True)
    built = bench_serve.serve_archive(db, args.hours)
    machine_header("mocapdb serve: the bounds of a request")
    if built:
        print(f"archive built in {built:.0f} s")
    measure(db)


if __name__ == "__main__":
    main()
