"""``mocapdb serve`` and ``mocapdb stats`` on the shipped sample: the JSON API against the database, the
summary against SQL, a server that never writes and lives beside a real writing process."""
import json
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import urlencode

import pytest

import mocapdb
import mocapdb.server
from mocapdb.storage.browse import STRIP_BINS

from conftest import run
from serving import Served, digest as _digest, sample_db, server  # noqa: F401 (fixtures)


def _sql(db, query, params=()):
    with mocapdb.connect(db, read_only=True) as con:
        return con.execute(query, list(params)).fetchall()


def _names(server, **params):
    status, page = server.json("/api/motions?" + urlencode(params))
    assert status == 200, page
    return [r["name"] for r in page["rows"]], page


@pytest.mark.slow
def test_the_archive_lists_every_motion_with_its_facts(server, sample_db):
    names, page = _names(server)
    want = _sql(sample_db, "SELECT motion_id, name, format, source_fps, n_frames / fps FROM motions ORDER BY motion_id")
    assert page["total"] == 3 and len(want) == 3
    assert [(r["motion_id"], r["name"], r["format"], r["source_fps"], r["seconds"]) for r in page["rows"]] == \
        [tuple(w) for w in want]
    assert {r["format"] for r in page["rows"]} == {"amc", "bvh", "c3d"}


def test_filters_keep_what_sql_keeps(server, sample_db):
    for (label,) in _sql(sample_db, "SELECT DISTINCT label FROM annotations WHERE model = 'default'"):
        want = [n for (n,) in _sql(sample_db, "SELECT name FROM motions WHERE motion_id IN (SELECT motion_id FROM "
                                              "annotations WHERE label = ?) ORDER BY motion_id", [label])]
        assert _names(server, label=label)[0] == want, label
    assert _names(server, source_format="bvh")[0] == ["pymo_AV_8Walk_Meredith_HVHA_Rep1"]
    assert _names(server, q="PyMo")[0] == ["pymo_AV_8Walk_Meredith_HVHA_Rep1"]  # a substring, any case
    assert _names(server, q="_0")[0] == ["86_09", "HDM_mm_01-02_03_120"]
    assert _names(server, min_s=30)[0] == ["86_09", "HDM_mm_01-02_03_120"]  # 40.0 s and 33.3 s; the walk 8.9 s
    assert _names(server, max_s=35, min_s=10)[0] == ["HDM_mm_01-02_03_120"]
    assert _names(server, label="move", source_format="amc", q="86")[0] == ["86_09"]
    assert _names(server, source_format="c3d")[0] == ["HDM_mm_01-02_03_120"] and _names(server, source_format="fbx")[0] == []


def test_q_matches_the_source_path_and_rows_name_their_folder(server, sample_db):
    """Two takes of one name are told apart by their folder; ``q`` filters a folder (issue 33)."""
    rows = _sql(sample_db, "SELECT name, source_path FROM motions ORDER BY motion_id")
    _, page = _names(server)
    for (name, path), row in zip(rows, page["rows"]):
        assert row["name"] == name and row["source_path"] == path
        assert row["folder"] == str(Path(path).parent)
    folder = Path(rows[0][1]).parent.name + "/"  # the sample's folder: in every path, in no name
    assert not any(folder.lower() in n.lower() for n, _ in rows)
    assert _names(server, q=folder.upper())[0] == [n for n, _ in rows]
    assert _names(server, q=".bvh.xz")[0] == [rows[2][0]]  # the file's suffix, in its path only
    assert _names(server, q="nowhere/")[0] == []


def test_an_unknown_label_is_refused_with_the_labels(server, sample_db):
    labels = [r[0] for r in _sql(sample_db, "SELECT label FROM classes WHERE model = 'default' GROUP BY label "
                                            "ORDER BY min(label_id), label")]
    for path in ("/api/motions?label=walk", "/api/segments?label=walk"):
        status, body = server.json(path)
        assert status == 400 and "'walk' is not a label of model 'default'" in body["message"], body
        assert body["message"].endswith(", ".join(labels))


def test_sorts_and_pages(server):
    by_length = _names(server, sort="-seconds")[0]
    assert by_length == ["86_09", "HDM_mm_01-02_03_120", "pymo_AV_8Walk_Meredith_HVHA_Rep1"]
    assert _names(server, sort="seconds")[0] == by_length[::-1]
    assert _names(server, sort="name")[0] == sorted(by_length)
    pages = [_names(server, sort="-seconds", limit=2, offset=k) for k in (0, 2, 4)]
    assert [p[0] for p in pages] == [by_length[:2], by_length[2:], []]
    assert [p[1]["total"] for p in pages] == [3, 3, 3]  # an empty page past the end still counts them


def test_label_strips_are_the_stored_segments(server, sample_db):
    """Each strip cell holds exactly the labels whose stored segments cover part of it."""
    _, page = _names(server)
    for row in page["rows"]:
        n = row["n_frames"]
        want = {}
        for label, a, b in _sql(sample_db, "SELECT label, start_frame, end_frame FROM annotations WHERE motion_id = ? "
                                           "AND model = 'default'", [row["motion_id"]]):
            cells = range((a - 1) * STRIP_BINS // n, (b - 1) * STRIP_BINS // n + 1)
            want.setdefault(label, set()).update(cells)
        got, rows = {}, {}
        for label, first, last, k in row["strip"]:
            assert 0 <= first <= last < STRIP_BINS and 0 <= k < row["strip_rows"]
            assert not got.get(label, set()) & set(range(first, last + 1)), "runs of a label overlap"
            got.setdefault(label, set()).update(range(first, last + 1))
            # concurrent labels on rows of their own: no cell of a row holds two labels
            cells = set(range(first, last + 1))
            assert not rows.get(k, set()) & cells, f"{label} shares a strip row with another label"
            rows.setdefault(k, set()).update(cells)
        assert got == want and want, row["name"]
        assert set(row["labels"]) == set(want)
        assert all(label in page["colors"] for label in row["labels"])


def test_one_motion_and_its_segments(server, sample_db):
    status, body = server.json("/api/motions/1")
    assert status == 200 and body["motion"]["name"] == "86_09"
    want = _sql(sample_db, "SELECT label, start_frame, end_frame, confidence FROM annotations WHERE motion_id = 1 "
                           "ORDER BY start_frame, label")
    got = [(s["label"], s["start_frame"], s["end_frame"], s["confidence"]) for s in body["segments"]]
    assert got == [tuple(w) for w in want] and all(0 <= w[3] <= 1 for w in want)
    assert server.json("/api/motions/86_09")[1] == body  # a name, as the CLI takes
    for missing in ("99", "nosuch", "9223372036854775808"):
        status, body = server.json(f"/api/motions/{missing}")
        assert status == 404 and f"no motion '{missing}'" in body["message"]


def test_the_server_and_the_command_line_give_the_same_rows(server, sample_db):
    """/api/motions is ``mocapdb motions --format json``, filters and fields alike (issue 34)."""
    for params, args in [({}, []), ({"label": "move", "sort": "-seconds"}, ["--label", "move", "--sort", "-seconds"]),
                         ({"q": "hdm", "source_format": "c3d"}, ["--q", "hdm", "--source-format", "c3d"]),
                         ({"limit": 1, "offset": 1}, ["--limit", "1", "--offset", "1"])]:
        _, page = _names(server, **params)
        cli = json.loads(run(sample_db, "motions", "--format", "json", *args).output)
        assert cli["rows"] == page["rows"] and cli["total"] == page["total"], params
    table = run(sample_db, "motions", "--label", "move").output
    assert "folder" in table.splitlines()[0] and "86_09" in table
    assert "is not a label of model" in run(sample_db, "motions", "--label", "walk", code=1).output


def test_label_segments_across_the_archive(server, sample_db):
    status, body = server.json("/api/segments?label=move&limit=2")
    want = _sql(sample_db, "SELECT motion_id, start_frame, end_frame, confidence FROM annotations WHERE label = 'move' "
                           "ORDER BY end_s - start_s DESC, motion_id, start_frame")
    assert status == 200 and body["total"] == len(want) >= 3
    assert [(r["motion_id"], r["start_frame"], r["end_frame"], r["confidence"]) for r in body["rows"]] == \
        [tuple(w) for w in want[:2]]
    _, rest = server.json("/api/segments?label=move&limit=50&offset=2")
    assert [(r["motion_id"], r["start_frame"], r["end_frame"]) for r in rest["rows"]] == [tuple(w[:3]) for w in want[2:]]


@pytest.mark.slow
def test_find_similar_is_mocapdb_similar(server, sample_db):
    status, body = server.json("/api/similar?motion=1&start_frame=550&end_frame=700&limit=5")
    assert status == 200, body
    with mocapdb.connect(sample_db, read_only=True) as con:
        want = mocapdb.similar(con, 1, start_frame=550, end_frame=700, limit=5).to_pylist()
    assert body["rows"] == want and len(want) >= 3
    assert body["query"] == {"motion_id": 1, "name": "86_09", "start_frame": 550, "end_frame": 700}
    status, body = server.json("/api/similar?motion=3&features=lower&limit=3")  # the whole walk, the legs
    with mocapdb.connect(sample_db, read_only=True) as con:
        want = mocapdb.similar(con, 3, features="lower", limit=3).to_pylist()
    assert status == 200 and body["rows"] == want
    status, by_name = server.json("/api/similar?motion=86_09&start_frame=550&end_frame=700&limit=5")  # as the CLI
    assert status == 200 and by_name["query"]["motion_id"] == 1 and len(by_name["rows"]) >= 3


@pytest.mark.parametrize("path, status, text", [
    ("/api/motions?sort=length", 400, "sort must be one of"),
    ("/api/motions?limit=0", 400, "limit must be an integer from 1 to 500"),
    ("/api/motions?min_s=long", 400, "min_s must be a number of seconds"),
    ("/api/motions?offset=x", 400, "offset must be an integer"),
    ("/api/motions?offset=9223372036854775808", 400, "offset must be an integer from 0 to 2147483647"),
    ("/api/segments?label=move&offset=-1", 400, "offset must be an integer from 0"),
    ("/api/similar", 400, "motion must be a motion id or name"),
    ("/api/similar?motion=1&start_frame=5&end_frame=5000", 400, "lies outside motion 1"),
    ("/api/similar?motion=42", 404, "no motion '42'"),
    ("/api/similar?motion=1&limit=100000", 400, "limit must be an integer from 1 to 500"),
    ("/api/segments", 400, "label must be a label name"),
])
def test_bad_requests_say_what_is_wrong(server, path, status, text):
    got, body = server.json(path)
    assert got == status and text in body["message"], body


def test_pages_are_self_contained(server):
    for path in ("/", "/stats", "/motion/1"):
        status, body, headers = server.get(path)
        page = body.decode()
        assert status == 200 and headers["Content-Type"].startswith("text/html")
        # no resource from elsewhere: no src/href to another host, no stylesheet or script file
        assert "http://" not in page and "https://" not in page and "<link" not in page
        assert "<script src" not in page
    status, body, _ = server.get("/motion/99")
    assert status == 404 and b"no motion &#x27;99&#x27;" in body
    assert server.get("/motion/86_09")[0] == 200  # a name, as the CLI takes
    status, body, headers = server.get("/favicon.ico")
    assert status == 200 and headers["Content-Type"] == "image/svg+xml" and body.startswith(b"<svg")


def test_a_foreign_host_name_is_refused(server):
    """Bound to 127.0.0.1, the server answers requests for this machine only (DNS rebinding)."""
    status, _, _ = server.get("/api/stats", headers={"Host": "archive.example.com"})
    assert status == 400
    assert server.get("/api/stats", headers={"Host": "localhost"})[0] == 200


def test_the_summary_is_what_sql_says(server, sample_db):
    status, s = server.json("/api/stats")
    assert status == 200
    (hours,) = _sql(sample_db, "SELECT sum(n_frames / fps) / 3600 FROM motions")[0]
    assert s["motions"] == 3 and s["hours"] == pytest.approx(hours)
    assert sorted((r["format"], r["source_fps"], r["motions"]) for r in s["formats"]) == \
        [("amc", 120.0, 1), ("bvh", 120.0, 1), ("c3d", 120.0, 1)]
    want = dict(_sql(sample_db, "SELECT label, sum(end_s - start_s) / 3600 FROM annotations GROUP BY label"))
    assert {r["label"]: r["hours"] for r in s["labels"]} == pytest.approx(want)

def test_refused_files_come_from_the_ingest_log(server, sample_db):
    with mocapdb.connect(sample_db, read_only=True) as con:
        s = mocapdb.api.stats(con)
    refused = s.refused.to_pylist()
    # the latest word on each file counts: fixed.bvh failed once and went in later
    assert [(r["path"], r["member"], r["outcome"]) for r in refused] == [
        ("/d/broken.bvh", None, "failed"), ("/d/cmu.zip", "x/13_29.amc", "failed"),
        ("/d/notes.txt", None, "not a motion file")]
    assert refused[0]["reason"].startswith("broken.bvh:12:")
    status, body = server.json("/api/stats")
    assert status == 200 and [r["path"] for r in body["refused"]] == [r["path"] for r in refused]
    r = run(sample_db, "stats", "--table", "refused", "--format", "csv")
    assert r.output.splitlines()[0] == "path,member,outcome,reason,logged_at" and len(r.output.splitlines()) == 4


def test_without_an_ingest_log_nothing_is_said_about_refused_files(sample_db, tmp_path):
    db = tmp_path / "unlogged.duckdb"
    shutil.copy(sample_db, db)
    with mocapdb.connect(db) as con:
        con.execute("DROP TABLE ingest_log")
        s = mocapdb.api.stats(con)
    assert s.refused is None and set(s.tables()) == {"formats", "labels"}
    r = run(db, "stats")
    assert "refused" not in r.output and "hours and motions per source format and rate:" in r.output
    assert "no ingest log" in run(db, "stats", "--table", "refused", code=2).output


def test_stats_command(sample_db):
    r = run(sample_db, "stats")
    lines = r.output.splitlines()
    assert lines[0] == "3 motion(s), 1 min 22 s in all (0.02281 hours)"   # as the summary page (issue 33 item 7)
    assert "hours and motions per source format and rate:" in lines and "files refused at their latest ingest:" in lines
    assert any(ln.split()[:3] == ["bvh", "120", "1"] for ln in lines)
    data = json.loads(run(sample_db, "stats", "--format", "json").output)
    assert data["motions"] == 3 and set(data) == {"model", "motions", "hours", "formats", "labels", "refused"}
    assert run(sample_db, "stats", "--table", "labels", "--format", "csv").output.startswith(
        "label,segments,motions,hours\nmove,")
    r = run(sample_db, "stats", "--format", "csv", code=2)
    assert "--format csv prints one table" in r.output
    r = run(sample_db, "stats", "--model", "toolbox")
    assert "none stored (mocapdb annotate stores them; models with annotations: default)" in r.output


def test_serving_never_writes(server, sample_db):
    """After every kind of request (and those of the tests before), the file is as it was, and no
    write-ahead log or temporary file appeared beside it."""
    for path in ("/", "/stats", "/api/motions?label=move", "/api/motions/2", "/api/stats",
                 "/api/similar?motion=2&start_frame=100&end_frame=200", "/motion/2", "/api/segments?label=turn"):
        assert server.get(path)[0] == 200, path
    assert _digest(sample_db) == server.digest
    assert sorted(p.name for p in sample_db.parent.iterdir()) == ["sample.duckdb"]


_WRITER = """
import sys, numpy, mocapdb
from mocapdb.storage.ingest import store_words
con = mocapdb.connect(sys.argv[1])
words = numpy.asarray(con.execute("SELECT bits FROM features WHERE motion_id = 1 ORDER BY frame").fetchnumpy()["bits"])
print(len(store_words(con, {"copied_words": words[:300]}, source="test")), flush=True)
sys.stdin.read()  # hold the file (as a long ingest would) until the test closes stdin
con.close()
"""


@pytest.mark.slow
def test_the_server_lives_beside_a_writing_process(sample_db, tmp_path):
    """A second process writes: it gets in although the server answered requests before (the server
    holds nothing between requests); while it holds the file the server answers busy (503, naming
    it) and its static pages still load; once it is done the server shows what it wrote."""
    db = tmp_path / "live.duckdb"
    shutil.copy(sample_db, db)
    served = Served(db)
    try:
        assert served.json("/api/motions")[1]["total"] == 3
        writer = subprocess.Popen([sys.executable, "-P", "-c", _WRITER, str(db)],
                                  stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            assert writer.stdout.readline().strip() == "1", writer.stderr.read()
            status, body = served.json("/api/motions")
            assert status == 503 and body["error"] == "busy"
            assert f"(PID {writer.pid}" in body["message"] and "reads it again once the writer is done" in body["message"]
            status, page, headers = served.get("/motion/1")
            assert status == 503 and b'http-equiv="refresh"' in page
            assert served.get("/")[0] == 200  # the archive page itself needs no database: it says busy, asks again
        finally:
            writer.stdin.close()
            assert writer.wait(60) == 0, writer.stderr.read()
            writer.stdout.close()
            writer.stderr.close()
        names, page = _names(served)
        assert page["total"] == 4 and names[-1] == "copied_words"
        # stored from words, it has no source file to re-read: its page says so, with its stored facts
        status, body, _ = served.get(f"/motion/{page['rows'][-1]['motion_id']}")
        assert status == 422 and b"no viewer for this motion" in body and b"test:copied_words" in body
    finally:
        served.stop()


_READER = """
import sys, time, duckdb
con = duckdb.connect(sys.argv[1], read_only=True)
print("holding", flush=True)
time.sleep(float(sys.argv[2]))
con.close()
"""


@pytest.mark.slow
def test_a_writer_waits_for_a_reader_to_finish_its_request(sample_db, tmp_path):
    """A writer that starts while a reader (a server's request) holds the file waits for it
    (``lock_wait``) instead of failing; without the wait it fails naming the reader."""
    db = tmp_path / "wait.duckdb"
    shutil.copy(sample_db, db)
    reader = subprocess.Popen([sys.executable, "-c", _READER, str(db), "1.5"], stdout=subprocess.PIPE, text=True)
    try:
        assert reader.stdout.readline().strip() == "holding"
        with pytest.raises(mocapdb.storage.schema.DatabaseLockedError, match=f"PID {reader.pid}"):
            mocapdb.connect(db, lock_wait=0)
        t = time.monotonic()
        with mocapdb.connect(db, lock_wait=30) as con:
            waited = time.monotonic() - t
            assert con.execute("SELECT count(*) FROM motions").fetchone()[0] == 3
        assert 0.3 < waited < 30
    finally:
        reader.wait(30)
        reader.stdout.close()


def test_serve_refuses_what_it_cannot_do(tmp_path, sample_db):
    r = run(tmp_path / "missing.duckdb", "serve", code=1)
    assert "no such database file" in r.output
    with pytest.raises(mocapdb.ParameterError, match="port must be an integer from 0 to 65535"):
        mocapdb.server.serve(sample_db, port=70000)
    with pytest.raises(mocapdb.ParameterError, match="timeout must be a number of seconds > 0"):
        mocapdb.server.serve(sample_db, timeout=0)
    with pytest.raises(mocapdb.ParameterError, match="lock_wait"):
        mocapdb.connect(sample_db, lock_wait="soon")
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        r = run(sample_db, "serve", "--port", port, code=1)
    assert f"cannot listen on 127.0.0.1:{port}" in r.output and "choose another with --port" in r.output
