"""The native ``similar_to`` (extension/src/similar*.c, docs/EXTENSION.md) against the Python UDF.

What holds it: on real recordings, seeded queries — motions by id and by name, whole and in ranges,
k from 1 to 40 — give the Python UDF's lists (ranks, motions, frames and costs, the doubles equal),
with the whole archive ranked and with the keyframe preselection (a small cell budget,
``MOCAPDB_CELL_BUDGET``, read by both); bad arguments are errors naming them; the DuckDB CLI runs it;
``mocapdb.connect`` connections answer with it through the table macros.
"""
from __future__ import annotations

import math
import os
import random
import shutil
import subprocess
import sys
from pathlib import Path

import duckdb
import numpy as np
import pytest

import mocapdb
import mocapdb.storage.retrieval as storage_retrieval
from mocapdb.retrieval import clip_template, feature_frequencies, information_weights
from mocapdb.retrieval.search import CELL_BUDGET_ENV
from mocapdb.storage.postings import drop_index
from conftest import DATA
from test_native_extension import plain_client, python_functions, python_udfs

pytestmark = pytest.mark.shared


@pytest.fixture(scope="module")
def native():
    return mocapdb.api.extension_path()


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    """The shipped sample, an HDM05 take and the 40 squat clips: many motions, short and long."""
    path = tmp_path_factory.mktemp("native_similar") / "archive.duckdb"
    with mocapdb.connect(path) as con:
        mocapdb.ingest(con, sample=True)
        mocapdb.ingest(con, [DATA / "hdm05_full" / "HDM_dg_06-03_03_120.amc", DATA / "hdm05_cut" / "squat1Reps"],
                       asf=DATA / "hdm05_full" / "HDM_dg.asf")
    return path


def seeded_cases(path, n, seed):
    """(motion as SQL, first, last, k): ids and names, whole motions and ranges of 15–400 frames."""
    rng = random.Random(seed)
    with python_udfs(path) as con:
        motions = con.execute("SELECT motion_id, name, n_frames FROM motions WHERE n_frames >= 15 "
                              "ORDER BY motion_id").fetchall()
    cases = []
    for _ in range(n):
        mid, name, frames = rng.choice(motions)
        first = last = None
        if rng.random() < 0.6:
            length = rng.randint(15, min(frames, 400))
            first = rng.randint(1, frames - length + 1)
            last = first + length - 1
        cases.append((str(mid) if rng.random() < 0.5 else f"'{name}'", first, last, rng.choice([1, 2, 5, 10, 40])))
    return cases


def sql(x):
    return "NULL" if x is None else str(x)


def python_lists(path, cases, monkeypatch, budget=None):
    """The Python UDF's lists (MOCAPDB_NATIVE=0), with another cell budget when given."""
    if budget is not None:
        monkeypatch.setattr(storage_retrieval, "CELL_BUDGET", budget)
    with python_udfs(path) as con:
        out = [con.execute(f"SELECT mocap_similar({m}::VARCHAR, typeof({m}), {sql(a)}::INTEGER, {sql(b)}::INTEGER, "
                           f"{k}, (SELECT version FROM mocap_index.state))").fetchall()[0][0] for m, a, b, k in cases]
    monkeypatch.undo()
    return [[[r["rank"], r["motion_id"], r["start_frame"], r["end_frame"], r["cost"]] for r in rows] for rows in out]


def native_lists(path, ext, cases, budget=None):
    """The native function's lists, from a client that never imported mocapdb."""
    env = None if budget is None else dict(os.environ, **{CELL_BUDGET_ENV: str(budget)})
    queries = [f"SELECT r.rank, r.motion_id, r.start_frame, r.end_frame, r.cost FROM "
               f"(SELECT unnest(similar_to({m}, {sql(a)}, {sql(b)}, {k})) AS r)" for m, a, b, k in cases]
    got = plain_client(path, ext, queries, env=env)
    assert [g.get("error") for g in got] == [None] * len(cases)
    return [g["rows"] for g in got]


def test_similar_to_equals_the_python_udf(archive, native, monkeypatch):
    """80 seeded queries over real recordings: the same ranks, motions, frames and costs (the doubles
    equal: the weights, τ, the byte tables and Δ are computed with the same operations in the same
    order), ranking the whole archive."""
    cases = seeded_cases(archive, 80, seed=31)
    want = python_lists(archive, cases, monkeypatch)
    got = native_lists(archive, native, cases)
    assert got == want
    assert sum(map(len, want)) > 400 and sum(len(w) > 1 for w in want) > 40  # real answers were compared
    costs = np.array([r[4] for rows in got for r in rows])
    assert np.array_equal(costs.view(np.int64), np.array([r[4] for rows in want for r in rows]).view(np.int64))


@pytest.mark.slow  # two clients rank 80 queries twice
def test_similar_to_preselects_as_the_python_udf(archive, native, monkeypatch):
    """With a cell budget the archive exceeds, both take keyframes from the query and rank only the
    preselected segments, each batch within its share: the same lists again, for several budgets
    (the strictest levels and the most lenient), and fewer hits than ranking everything."""
    cases = seeded_cases(archive, 60, seed=32)
    whole = python_lists(archive, cases, monkeypatch)
    for budget in (2_000, 30_000, 1_000_000):
        want = python_lists(archive, cases, monkeypatch, budget=budget)
        assert native_lists(archive, native, cases, budget=budget) == want, budget
        if budget == 30_000:
            assert want != whole and sum(map(len, want)) < sum(map(len, whole))  # the preselection ran
            assert sum(map(len, want)) > 100


def test_the_weights_are_the_c_librarys_log2(archive):
    """The information weights are −log2 of the C library (math.log2, what the native function
    computes), not np.log2, whose AVX-512 code differs from it in the last bit of ~0.2 % of values:
    the Python reference is then the same on every CPU."""
    with python_udfs(archive) as con:
        sample = np.asarray(con.execute("SELECT bits FROM features WHERE frame % 3 = 0").fetchnumpy()["bits"],
                            np.uint64)
        words = np.asarray(con.execute("SELECT bits FROM features WHERE motion_id = 2 ORDER BY frame")
                           .fetchnumpy()["bits"], np.uint64)
    p = feature_frequencies(sample)
    w = information_weights(clip_template(words), p)
    on = (words[:, None] >> np.arange(40, dtype=np.uint64)) & np.uint64(1)
    want = np.array([[-math.log2(p[f] if on[i, f] else 1.0 - p[f]) for f in range(40)] for i in range(len(words))])
    assert w.shape == (len(words), 40) and np.array_equal(w.view(np.int64), want.view(np.int64))


def test_similar_to_arguments(archive, native, tmp_path):
    """NULLs, unknown motions and names, a name of digits (an id), bad k, ranges outside, empty or
    shorter than 0.5 s, a type neither integer nor text: DuckDB errors that name the problem; a NULL
    range is the whole motion; an integer of any type is an id."""
    queries = ["SELECT similar_to(NULL, NULL, NULL, 5)", "SELECT similar_to(424242, NULL, NULL, 5)",
               "SELECT similar_to('no such take', NULL, NULL, 5)", "SELECT similar_to(1, NULL, NULL, 0)",
               "SELECT similar_to(1, NULL, NULL, NULL)", "SELECT similar_to(1, 30, 10, 5)",
               "SELECT similar_to(1, 1, 100000, 5)", "SELECT similar_to(1, 0, 20, 5)", "SELECT similar_to(1, 5, 6, 5)",
               "SELECT similar_to(3.7, NULL, NULL, 5)", "SELECT similar_to(-1, NULL, NULL, 5)",
               "SELECT similar_to(18446744073709551615::UBIGINT, NULL, NULL, 5)",
               "SELECT similar_to(99999999999999999999, NULL, NULL, 5)",
               "SELECT similar_to(2, NULL, NULL, 3) = similar_to('2', NULL, NULL, 3)",
               "SELECT similar_to(2::TINYINT, NULL, NULL, 3) = similar_to(2::UHUGEINT, 1, NULL, 3)",
               "SELECT len(similar_to(name, NULL, NULL, 2)) FROM motions WHERE motion_id IN (3, 5) ORDER BY motion_id",
               "SELECT len(similar_to(motion_id, NULL, NULL, 1000000000)) FROM motions WHERE motion_id = 5"]
    got = plain_client(archive, native, queries)
    errors = [g.get("error") or "" for g in got]
    assert "no motion with id NULL" in errors[0]
    assert "no motion with id 424242" in errors[1]
    assert "no motion 'no such take' in the database" in errors[2]
    assert "k must be a positive integer, got 0" in errors[3] and "got NULL" in errors[4]
    assert "is empty" in errors[5] and "lies outside motion 1" in errors[6] and "lies outside" in errors[7]
    assert "a query needs at least 0.5 s (15 frames at 30 Hz)" in errors[8]
    assert "motion must be a motion id (an integer) or a name, got DECIMAL" in errors[9]
    assert "no motion with id -1" in errors[10] and "no motion has that id (ids are 32-bit" in errors[11]
    assert "no motion has that id" in errors[12]
    assert got[13]["rows"] == [[True]] and got[14].get("rows") == [[True]]
    assert got[15]["rows"] == [[2], [2]] and got[16]["rows"][0][0] > 10  # a huge k: every hit
    bare = tmp_path / "no_index.duckdb"
    shutil.copy(archive, bare)
    with mocapdb.connect(bare) as con:
        drop_index(con)
    got = plain_client(bare, native, ["SELECT similar_to(1, NULL, NULL, 5)"])
    assert "no keyframe index" in got[0]["error"] and "mocapdb create-index" in got[0]["error"]


def test_mocapdb_connect_answers_with_the_native_similar_to(archive, native):
    """A mocapdb.connect connection has no Python UDF (the native similar_to answers), and its table
    macros give the Python macros' rows: names, seconds, named k, the type check naming the value."""
    queries = ["SELECT * FROM similar_to(5, k := 7)", "SELECT * FROM similar_to('86_09', 100, 300)",
               "SELECT * FROM similar_to(3, NULL, NULL, k := 1)"]
    with python_udfs(archive) as con:
        want = [con.execute(q).fetchall() for q in queries]
    with mocapdb.connect(archive, read_only=True) as con:
        assert python_functions(con) == 0
        assert [con.execute(q).fetchall() for q in queries] == want
        with pytest.raises(duckdb.Error, match=r"got 3.7 \(DECIMAL\(2,1\)\)"):
            con.execute("SELECT * FROM similar_to(3.7)").fetchall()
        with pytest.raises(duckdb.Error, match="k must be a positive integer, got 0"):
            con.execute("SELECT * FROM similar_to(2, k := 0)").fetchall()
    assert all(want) and len(want[0]) == 7


@pytest.mark.slow  # a subprocess: another client
def test_the_duckdb_cli_runs_similar_to(archive, native):
    """PyPI's duckdb-cli (1.5.x) LOADs the binary and gives Python duckdb's list."""
    beside = Path(sys.executable).with_name("duckdb")
    cli = shutil.which("duckdb") or (str(beside) if beside.is_file() else None)
    assert cli, "the [test] extra installs duckdb-cli (a `duckdb` executable)"
    query = ("SELECT r.rank, r.motion_id, r.start_frame, r.end_frame, r.cost FROM "
             "(SELECT unnest(similar_to('86_09', 200, 350, 6)) AS r)")
    want = plain_client(archive, native, [query])[0]["rows"]
    run = subprocess.run([cli, "-unsigned", "-csv", "-noheader", str(archive), "-c",
                          f"LOAD '{native}'; SET enable_progress_bar = false; {query}"],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    got = [[int(x) for x in line.split(",")[:4]] + [float(line.split(",")[4])] for line in run.stdout.split()]
    assert len(want) == 6 and got == want
