"""What bounds a request of ``mocapdb serve`` (issue 33): a time limit that interrupts the DuckDB work and lets go
of the file, a client that leaves, a cap on heavy requests, the query stretch of find-similar, a source
re-read only when its bytes are those ingested, and a server open to the network that says so and keeps
its Host check. The application is driven in this process through ASGI (what uvicorn calls) where a
bound is set smaller than the server's default, and as ``mocapdb serve`` otherwise."""
import shutil
import socket
import subprocess
import sys
import time

import anyio
import pytest

import mocapdb
from mocapdb.server.app import allowed_hosts, create_app
from mocapdb.server.archive import Archive, Overloaded, RequestCancelled

from conftest import SHARED, run
from serving import Served, sample_db  # noqa: F401 (fixture)

#: servers in processes of their own, writers beside them, the shipped sample annotated: seconds each
pytestmark = pytest.mark.slow

#: minutes of DuckDB work (a count over a generated range), for requests that must be stopped
SLOW = "SELECT count(*) FROM range(200000000000) t(x) WHERE x % 7 = 3"


def _writer_gets_in(db):
    """Whether another process opens ``db`` for writing at once (no lock wait)."""
    code = "import sys, mocapdb; mocapdb.connect(sys.argv[1], lock_wait=0).close()"
    return subprocess.run([sys.executable, "-c", code, str(db)], capture_output=True, text=True).returncode == 0


@pytest.fixture()
def db(sample_db, tmp_path):
    copy = tmp_path / "bounds.duckdb"
    shutil.copy(sample_db, copy)
    return copy


def test_a_request_out_of_time_is_interrupted_and_lets_go_of_the_file(db):
    archive = Archive(db, timeout=0.5)
    t0 = time.monotonic()
    with pytest.raises(RequestCancelled, match="longer than 0.5 s"):
        anyio.run(archive.run, lambda con: con.execute(SLOW).fetchall())
    assert time.monotonic() - t0 < 5  # the query was stopped, not waited for
    assert _writer_gets_in(db)
    # a request within its time is answered as ever
    assert anyio.run(archive.run, lambda con: con.execute("SELECT count(*) FROM motions").fetchall()) == [(3,)]


def test_a_client_that_leaves_stops_its_request(db):
    archive = Archive(db, timeout=60)
    start = time.monotonic()

    async def gone():
        return time.monotonic() - start > 0.3

    with pytest.raises(RequestCancelled, match="the client left"):
        anyio.run(lambda: archive.run(lambda con: con.execute(SLOW).fetchall(), disconnected=gone))
    assert time.monotonic() - start < 5
    assert _writer_gets_in(db)


def test_heavy_requests_are_capped(db):
    archive = Archive(db, timeout=2, heavy_requests=2)
    outcomes = []

    async def one(delay):
        await anyio.sleep(delay)
        try:
            await archive.run(lambda con: con.execute(SLOW).fetchall(), heavy=True)
        except (Overloaded, RequestCancelled) as exc:
            outcomes.append((delay, type(exc).__name__, time.monotonic()))

    async def main():
        async with anyio.create_task_group() as tg:
            for delay in (0, 0, 0.5):
                tg.start_soon(one, delay)

    t0 = time.monotonic()
    anyio.run(main)
    late = [o for o in outcomes if o[0] == 0.5]
    assert late and late[0][1] == "Overloaded" and late[0][2] - t0 < 1.5  # refused at once, not queued
    assert sorted(o[1] for o in outcomes if o[0] == 0) == ["RequestCancelled", "RequestCancelled"]
    # light requests are not counted: the archive's pages go on while heavy ones run
    assert anyio.run(archive.run, lambda con: con.execute("SELECT 1").fetchall()) == [(1,)]


async def _get(app, path, host="127.0.0.1"):
    """(status, body) of a GET through the ASGI application, as uvicorn calls it."""
    path, _, query = path.partition("?")
    scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1", "method": "GET", "scheme": "http",
             "path": path, "raw_path": path.encode(), "query_string": query.encode(), "root_path": "",
             "headers": [(b"host", host.encode())], "client": ("127.0.0.1", 40000), "server": ("127.0.0.1", 80)}
    sent, messages = False, []

    async def receive():
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": b"", "more_body": False}
        await anyio.sleep_forever()  # the client stays

    async def send(message):
        messages.append(message)

    await app(scope, receive, send)
    return messages[0]["status"], b"".join(m.get("body", b"") for m in messages[1:]).decode()


def test_the_query_stretch_of_find_similar_is_bounded(db):
    app = create_app(Archive(db, max_query_s=10))
    status, body = anyio.run(_get, app, "/api/similar?motion=86_09&start_frame=1&end_frame=600")
    assert status == 400 and "is 20.0 s; mocapdb serve answers stretches of at most 10 s" in body
    status, body = anyio.run(_get, app, "/api/similar?motion=86_09&start_frame=1&end_frame=300&limit=3")
    assert status == 200 and '"rows":[{' in body
    # while as many heavy requests run as allowed, another answers "busy" at once, and says why
    archive = Archive(db, heavy_requests=1)
    archive._heavy.acquire()  # the one heavy request running
    status, body = anyio.run(_get, create_app(archive), "/api/similar?motion=86_09&start_frame=1&end_frame=300")
    assert status == 503 and "1 heavy request(s) (find similar, a motion's page) are running" in body
    assert anyio.run(_get, create_app(archive), "/api/motions")[0] == 200  # the archive's pages go on
    archive._heavy.release()
    assert anyio.run(_get, create_app(archive), "/api/similar?motion=86_09&start_frame=1&end_frame=300")[0] == 200


@pytest.mark.shared
def test_a_source_is_read_again_only_when_its_bytes_are_those_ingested(db):
    """A source path changed (an imported archive tampered with, a file replaced) is refused, naming relocate:
    the server and ``view`` never show another file of the machine."""
    other = SHARED / "data" / "accad_dev" / "Male1_A13_Skipping.bvh.gz"  # a real take, not the one ingested
    assert other.is_file()
    with mocapdb.connect(db) as con:
        con.execute("UPDATE motions SET source_path = ? WHERE motion_id = 3", [str(other)])
    status, body = anyio.run(_get, create_app(Archive(db)), "/motion/3")
    assert status == 422 and "has other bytes than the file ingested" in body and "relocate" in body
    assert anyio.run(_get, create_app(Archive(db)), "/motion/1")[0] == 200
    r = run(db, "view", "3", "--out", str(db.parent / "p.html"), code=1)
    assert "has other bytes than the file ingested" in r.output and "mocapdb relocate" in r.output
    assert len(r.output.strip().splitlines()) == 1 and not (db.parent / "p.html").exists()


def test_a_server_open_to_the_network_says_so_and_keeps_its_host_check(sample_db):
    server = Served(sample_db, "--host", "0.0.0.0")
    try:
        port = server.url.rsplit(":", 1)[1].strip("/")
        assert server.get("/api/stats", headers={"Host": f"127.0.0.1:{port}"})[0] == 200
        assert server.get("/api/stats", headers={"Host": f"archive.example.com:{port}"})[0] == 400
    finally:
        server.stop()
    assert "open to every machine that reaches this one" in server.err and "--host 127.0.0.1" in server.err
    assert socket.gethostname() in allowed_hosts("0.0.0.0") and "0.0.0.0" not in allowed_hosts("0.0.0.0")
    assert allowed_hosts("127.0.0.1") == sorted(["127.0.0.1", "localhost", "::1", "[::1]"])


def test_query_by_example_stops_between_two_batches_once_cancelled(db, monkeypatch):
    """DuckDB's interrupt cannot reach a numba kernel: a cancelled request's find-similar stops at the next batch
    of the archive instead of ranking the rest (the time limit fires during the first batch here, and the
    index batches are in the server's cache already, so no DuckDB call comes between)."""
    import mocapdb.storage.retrieval as retrieval
    from mocapdb.api.reading import Request, SharedReader
    from mocapdb.storage.cache import connection_cache

    reader, calls, words = SharedReader(db), [], retrieval.index_words
    monkeypatch.setattr(retrieval, "index_words", lambda *a: calls.append(a[1:]) or words(*a))
    with reader.reading() as con:  # uncancelled, the query ranks every batch (and the cache keeps them)
        connection_cache(con).batch_frames = 1300  # 86_09 (1,200 frames), then the others: two batches
        assert mocapdb.api.similar(con, "86_09", start_frame=1, end_frame=300, keyframes=False).num_rows > 0
    assert len(calls) >= 2
    calls.clear()
    request = Request()

    def first_batch_then_cancelled(*args):
        calls.append(args[1:])
        request.cancel("the request took longer than its limit")  # as the watcher does, from another thread
        return words(*args)

    monkeypatch.setattr(retrieval, "index_words", first_batch_then_cancelled)
    with reader.reading(request) as con:
        connection_cache(con).batch_frames = 1300
        with pytest.raises(RequestCancelled, match="longer than its limit"):
            mocapdb.api.similar(con, "86_09", start_frame=1, end_frame=300, keyframes=False)
    assert len(calls) == 1
