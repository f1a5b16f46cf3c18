"""The native DuckDB extension (``mocapdb.duckdb_extension``, extension/src, docs/EXTENSION.md).

What holds it: the binary ``pip install .`` built (``mocapdb extension-path``) LOADs into the two
DuckDBs at hand — Python ``duckdb`` 2.0.x in a process that never imports mocapdb, and the DuckDB
CLI 1.5.x of PyPI's ``duckdb-cli`` — and its ``keyframe_search_words`` gives the same rows as the
Python UDF (the numba kernels) on real recordings, for seeded random queries built from the
archive's own words; bad arguments are DuckDB errors naming the problem, a missing table names the
table and ``mocapdb ingest``; and a build under ``-fsanitize=address,undefined`` survives thousands
of seeded random calls.
"""
from __future__ import annotations

import contextlib
import gc
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import duckdb
import numpy as np
import pytest

import mocapdb
from mocapdb.extension.connection import NATIVE_ENV
from mocapdb.storage.schema import connect_raw
from mocapdb.extension.native_build import BINARY_NAME, MISSING_NAME, build, build_or_explain
from conftest import DATA, REPO, run
from mocapdb.annotation.model import STEP_ORDER

# A client that never imported mocapdb: plain Python duckdb, the extension LOADed, the queries of a
# JSON list on stdin run one by one; each answer is its rows or its error's first line.
PLAIN_CLIENT = r"""
import json, sys
import duckdb
db, ext, queries, read_only = json.load(sys.stdin)
con = duckdb.connect(db, read_only=read_only, config={"allow_unsigned_extensions": "true"})
con.execute("SET enable_progress_bar = false")
con.execute(f"LOAD '{ext}'")
out = []
for q in queries:
    try:
        out.append({"rows": [list(r) for r in con.execute(q).fetchall()]})
    except duckdb.Error as e:
        out.append({"error": str(e).splitlines()[0]})
assert "mocapdb" not in sys.modules
print(json.dumps(out))
"""


def plain_client(db, ext, queries, env=None, read_only=True):
    """Answers of :data:`PLAIN_CLIENT` in a fresh process (the extension keeps the database open
    for the life of its process: docs/EXTENSION.md)."""
    run = subprocess.run([sys.executable, "-c", PLAIN_CLIENT],
                         input=json.dumps([str(db), str(ext), queries, read_only]),
                         capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout)


@contextlib.contextmanager
def python_udfs(path):
    """A read-only mocapdb.connect whose SQL functions are the Python UDFs (the numba kernels: the
    reference), as where the native extension is missing: MOCAPDB_NATIVE=0 skips the LOAD."""
    old = os.environ.get(NATIVE_ENV)
    os.environ[NATIVE_ENV] = "0"
    try:
        with mocapdb.connect(path, read_only=True) as con:
            assert python_functions(con) == 5
            yield con
    finally:
        if old is None:
            del os.environ[NATIVE_ENV]
        else:
            os.environ[NATIVE_ENV] = old


def python_functions(con):
    """How many of the SQL functions' Python UDFs the connection's database has."""
    return con.execute("SELECT count(DISTINCT function_name) FROM duckdb_functions() WHERE function_name IN "
                       "('mocap_annotate', 'mocap_mt_distance', 'mocap_keyframe_search', "
                       "'mocap_keyframe_search_words', 'mocap_similar')").fetchall()[0][0]


def words_query(masks, vals, gap_min, gap_max, left, right):
    def sql_list(xs):
        return "[" + ", ".join("NULL" if x is None else str(int(x)) for x in xs) + "]"

    return (f"SELECT * FROM keyframe_search_words({sql_list(masks)}::UBIGINT[], {sql_list(vals)}::UBIGINT[], "
            f"{sql_list(gap_min)}::BIGINT[], {sql_list(gap_max)}::BIGINT[], extend_left := {left}, "
            f"extend_right := {right}) ORDER BY ALL")


@pytest.fixture(scope="module")
def native():
    import mocapdb.api  # noqa: F401  (run alone, nothing else has imported it)

    return mocapdb.api.extension_path()


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    """The shipped sample recordings and, from ../shared, an HDM05 document and the 40 squat clips
    (many motions: the search goes motion by motion)."""
    path = tmp_path_factory.mktemp("native") / "archive.duckdb"
    with mocapdb.connect(path) as con:
        mocapdb.ingest(con, sample=True)
        if DATA.is_dir():
            mocapdb.ingest(con, [DATA / "hdm05_full" / "HDM_dg_06-03_03_120.amc", DATA / "hdm05_cut" / "squat1Reps"],
                           asf=DATA / "hdm05_full" / "HDM_dg.asf")
    return path


def random_queries(path, n, seed):
    """Seeded keyframe queries that hit: keyframes are a few bits of the words of real frames
    (chosen along one motion, so the chain exists), gap bounds around the frames' distances,
    sometimes unbounded; margins up to 2 s."""
    rng = np.random.default_rng(seed)
    with mocapdb.connect(path, read_only=True) as con:
        words = con.execute("SELECT motion_id, list(bits ORDER BY frame) FROM features GROUP BY ALL "
                            "ORDER BY motion_id").fetchall()
    queries = []
    for _ in range(n):
        _, w = words[rng.integers(len(words))]
        K = int(rng.integers(1, 5))
        frames = np.sort(rng.integers(0, len(w), K))
        masks, vals = [], []
        for f in frames:
            mask = 0
            for b in rng.choice(40, int(rng.integers(0, 7)), replace=False):
                mask |= 1 << int(b)
            masks.append(mask)
            vals.append(int(w[f]) & mask)
        gaps = np.diff(frames)
        gap_min = [int(max(0, g - rng.integers(0, 20))) for g in gaps]
        gap_max = [None if rng.random() < 0.2 else int(g + rng.integers(0, 40)) for g in gaps]
        queries.append(words_query(masks, vals, gap_min, gap_max, int(rng.integers(0, 61)),
                                   int(rng.integers(0, 61))))
    return queries


@pytest.mark.shared
def test_keyframe_search_words_equals_the_python_udf(archive, native):
    """Seeded random queries over real recordings: the native rows are the numba kernels' rows."""
    queries = random_queries(archive, 300, seed=31)
    with python_udfs(archive) as con:
        want = [[list(r) for r in con.execute(q).fetchall()] for q in queries]
    got = plain_client(archive, native, queries)
    assert [g.get("error") for g in got] == [None] * len(queries)
    assert [g["rows"] for g in got] == want
    assert sum(map(bool, want)) > 200  # most queries hit: the comparison is not over empty answers
    assert len({m for rows in want for m, _, _ in rows}) > 20  # across many motions


@pytest.mark.shared
def test_keyframe_search_equals_the_python_udf(archive, native):
    """Every class of the shipped default model with a keyframe query, with and without the
    annotation margins, and the toolbox's classes, which have none (an error naming the class)."""
    with python_udfs(archive) as con:
        classes = [c for c, in con.execute("SELECT class FROM keyframe_queries WHERE model = 'default' "
                                           "ORDER BY class").fetchall()]
        queries = [f"SELECT * FROM keyframe_search('{c}', extend := {e}) ORDER BY ALL"
                   for c in classes for e in ("false", "true")]
        want = [[list(r) for r in con.execute(q).fetchall()] for q in queries]
    got = plain_client(archive, native, queries + [
        "SELECT * FROM keyframe_search('squat1Reps', model := 'toolbox')",
        "SELECT * FROM keyframe_search('nope')", "SELECT * FROM keyframe_search(NULL)",
        "SELECT * FROM keyframe_search('squat1Reps', model := NULL)",
        "SELECT count(*) FROM keyframe_search('squat1Reps', extend := NULL)"])
    assert len(classes) > 30 and [g.get("error") for g in got[:len(queries)]] == [None] * len(queries)
    assert [g["rows"] for g in got[:len(queries)]] == want
    assert sum(map(bool, want)) > 20  # most classes hit something
    assert "class 'squat1Reps' of model 'toolbox' has no keyframe query" in got[-5]["error"]
    assert "model 'default' has no class 'nope'" in got[-4]["error"]
    assert "class is NULL" in got[-3]["error"] and "model is NULL" in got[-2]["error"]
    assert got[-1]["rows"] == [[len(want[classes.index("squat1Reps") * 2])]]  # NULL extend: none


@pytest.mark.shared
def test_mt_distance_equals_the_python_udf_bit_for_bit(archive, native):
    """Δ of every class of both shipped models on every motion: the same doubles, bit for bit (the
    C kernel does numba's operations in numba's order, without fused multiply-add), inf included."""
    with python_udfs(archive) as con:
        classes = con.execute("SELECT model, class FROM classes WHERE model IN ('default', 'toolbox') "
                              "ORDER BY ALL").fetchall()
        queries = [f"SELECT motion_id, mt_distance(motion_id, '{c}', '{m}') FROM motions ORDER BY motion_id"
                   for m, c in classes]
        want = [[[mid, list(d)] for mid, d in con.execute(q).fetchall()] for q in queries]
    got = plain_client(archive, native, queries)
    assert len(classes) > 40 and [g.get("error") for g in got] == [None] * len(queries)
    for (m, c), w, g in zip(classes, want, got):
        a = np.array([x for _, d in w for x in d])
        b = np.array([x for _, d in g["rows"] for x in d])
        assert [r[0] for r in g["rows"]] == [r[0] for r in w] and a.shape == b.shape, (m, c)
        assert np.array_equal(a.view(np.int64), b.view(np.int64)), (m, c)
    assert np.isfinite(a).any() and np.isinf(a).any()  # both kinds of value were compared


def test_mt_distance_arguments(archive, native):
    """A NULL or unknown motion is NULL (as the Python UDF); a NULL or unknown class or model is an
    error naming it; the model is the third argument, 'default' without it."""
    got = plain_client(archive, native, [
        "SELECT mt_distance(NULL, 'squat1Reps'), mt_distance(1000000, 'squat1Reps'), mt_distance(-1, 'squat1Reps')",
        "SELECT len(mt_distance(1, 'squat1Reps')) = n_frames, mt_distance(1, 'squat1Reps') = mt_distance(1, "
        "'squat1Reps', 'default') FROM motions WHERE motion_id = 1",
        "SELECT mt_distance(1, 'nope')", "SELECT mt_distance(1, 'squat1Reps', 'nomodel')",
        "SELECT mt_distance(1, NULL)", "SELECT mt_distance(1, 'squat1Reps', NULL)",
        "SELECT mt_distance(1, 'standStill', 'toolbox')"])
    assert got[0]["rows"] == [[None, None, None]]
    assert got[1]["rows"] == [[True, True]]
    assert "model 'default' has no class 'nope'; its classes: " in got[2]["error"]
    assert "no model 'nomodel' in the database (stored models: default, toolbox" in got[3]["error"]
    assert "class is NULL" in got[4]["error"] and "model is NULL" in got[5]["error"]
    assert "model 'toolbox' has no class 'standStill'" in got[6]["error"]  # a class of the default model only


ANNOTATE_SETTINGS = [(model, tau, keyframes) for model in ("default", "toolbox") for tau in ("NULL", "0.1")
                     for keyframes in ("NULL", "true", "false")]


@pytest.mark.shared
@pytest.mark.slow  # another client annotates every motion twelve times
def test_annotate_equals_the_python_udf(archive, native):
    """Every motion (the sample, an HDM05 document, the squat clips) under both shipped models, with
    each class's τ and a given one, keyframe preselection by default, on and off: the native
    segments are the Python UDF's — labels, frames, and cost, seconds and confidence as the same
    doubles (the C chain does numba's comparisons and float operations in the same order)."""
    native_q = [f"SELECT motion_id, annotate(motion_id, '{m}', {t}, {k}) FROM motions ORDER BY motion_id"
                for m, t, k in ANNOTATE_SETTINGS]
    with python_udfs(archive) as con:
        want = [[[mid, segs] for mid, segs in con.execute(
            f"SELECT motion_id, annotate(motion_id, model := '{m}', tau := {t}, keyframes := {k}) FROM motions "
            "ORDER BY motion_id").fetchall()] for m, t, k in ANNOTATE_SETTINGS]
    got = plain_client(archive, native, native_q)
    assert [g.get("error") for g in got] == [None] * len(native_q)
    labels = set()
    for setting, w, g in zip(ANNOTATE_SETTINGS, want, got):
        assert g["rows"] == w, setting
        labels |= {(setting[0], s["label"]) for _, segs in w for s in segs}
    # real work was compared: several labels of both models, the concurrent `turn` among them
    assert len({lab for m, lab in labels if m == "default"}) >= 4, labels
    assert len({lab for m, lab in labels if m == "toolbox"}) >= 3, labels
    assert ("default", "turn") in labels and want[0] != want[2]  # preselection changes something
    # the default model's confidence is calibrated: every segment's is a value of its stored maps or at most a
    # hundredth of the way above one (STEP_ORDER: the raw score orders a step's segments)
    with mocapdb.connect(archive, read_only=True) as con:
        values = np.array(sorted({v for v, in con.execute(
            "SELECT value FROM confidence_maps WHERE model = 'default'").fetchall()}))
    conf = np.array([s["confidence"] for _, segs in want[0] for s in segs])
    below = values[np.searchsorted(values, conf, side="right") - 1]
    assert len(values) > 3 and (conf - below <= STEP_ORDER * (1 - below) + 1e-15).all()


def _amc_head(src, dst, frames):
    """The AMC file ``src`` cut after its first ``frames`` frames, written to ``dst``."""
    out = []
    for line in src.read_text(encoding="latin-1").splitlines(keepends=True):
        if line.strip().isdigit() and int(line) > frames:
            break
        out.append(line)
    dst.write_text("".join(out), encoding="latin-1")


@pytest.mark.shared
def test_annotate_of_short_clips_equals_the_python_udf(native, tmp_path):
    """Clips of 0.7 and 1 s (HDM05 jogs and sneaks cut to their first 84 and 120 frames, files of their
    own): shorter than twice a label's minimum, where a segment over half the clip is kept
    (postprocess.document_minimum) — the native segments are the Python UDF's, and there are some."""
    clips = [p for c in ("jogLeftCircle4StepsRstart", "sneak2StepsLStart")
             for p in sorted((DATA / "hdm05_cut" / c).glob("*.amc"))[:3]]
    for p in clips:
        for frames in (84, 120):
            _amc_head(p, tmp_path / f"{p.stem}_{frames}.amc", frames)
    db = tmp_path / "short.duckdb"
    with mocapdb.connect(db) as con:
        for actor in {p.name.split("_")[1] for p in clips}:
            mocapdb.ingest(con, sorted(tmp_path.glob(f"HDM_{actor}_*.amc")), asf=DATA / "hdm05_cut" / f"HDM_{actor}.asf")
        assert con.execute("SELECT count(*), max(n_frames) FROM motions").fetchall()[0] == (12, 30)  # 30 Hz
    settings = ("NULL", "true", "false")
    with python_udfs(db) as con:
        want = [[list(r) for r in con.execute(f"SELECT motion_id, annotate(motion_id, keyframes := {k}) FROM motions "
                                              "ORDER BY motion_id").fetchall()] for k in settings]
        n_frames = dict(con.execute("SELECT motion_id, n_frames FROM motions").fetchall())
    got = plain_client(db, native, [f"SELECT motion_id, annotate(motion_id, 'default', NULL, {k}) FROM motions "
                                    "ORDER BY motion_id" for k in settings])
    assert [g.get("error") for g in got] == [None] * len(settings)
    for k, w, g in zip(settings, want, got):
        assert g["rows"] == w, k
    # segments of a label whose minimum is longer than half the clip, in clips of 0.7 s too
    assert len({mid for mid, segs in want[0] if n_frames[mid] == 21 for s in segs if s["label"] == "move"}) >= 2


@pytest.mark.shared
def test_the_bounded_delta_of_preselection_is_the_full_one(archive, native):
    """With keyframe preselection the native Δ computes only the cells a hit (Δ <= τ) can pass through
    (distance_dp.h, bounded). The toolbox model has no keyframe query, so with keyframes on every slice is
    the whole motion and only the bound differs from keyframes off: the segments must be the same to the
    last bit at every τ, 0 (only perfect matches) and τ far above every class's included."""
    taus = ("0", "0.02", "0.1", "0.3", "NULL")
    queries = [f"SELECT motion_id, annotate(motion_id, 'toolbox', {t}, {k}) FROM motions ORDER BY motion_id"
               for t in taus for k in ("true", "false")]
    got = plain_client(archive, native, queries + [
        "SELECT count(*) FROM keyframe_queries WHERE model = 'toolbox'"])
    assert [g.get("error") for g in got] == [None] * (len(queries) + 1)
    assert got[-1]["rows"] == [[0]]
    for t, on, off in zip(taus, got[0:-1:2], got[1:-1:2]):
        assert on["rows"] == off["rows"], t
    # real segments were compared, fewer at τ = 0 than at 0.3
    count = [sum(len(segs or []) for _, segs in g["rows"]) for g in got[0:-1:2]]
    assert 0 < count[0] < count[3], count


def test_the_step_order_is_the_python_one():
    """extension/src/annotation.c's MDB_STEP_ORDER is mocapdb.annotation.model.STEP_ORDER."""
    text = (REPO / "extension" / "src" / "annotation.c").read_text()
    assert float(re.search(r"#define MDB_STEP_ORDER (\S+)", text).group(1)) == STEP_ORDER


def test_a_damaged_or_missing_confidence_map(archive, native, tmp_path):
    """A confidence map whose values fall, whose length weight is NaN or whose steps disagree on it or on
    length_product is an error naming the model and the table; a database from before the length multiplied
    the match (no column length_product) gives the maps of the length added, one from before the length entered
    the score (no columns length_weight, full_length) the maps of the raw score alone, and one from before
    calibrated confidence (no table confidence_maps) the raw score, as the Python UDF gives them under such
    models."""
    import dataclasses

    from mocapdb.storage.model_store import load_model, save_model

    db = tmp_path / "maps.duckdb"
    shutil.copy(archive, db)
    with mocapdb.connect(db) as con:
        model = load_model(con, "default")
        assert model.confidence_maps and all(m.length_weight > 0 and m.length_product
                                             for m in model.confidence_maps)
        unweighted = tuple(dataclasses.replace(m, length_weight=0.0, length_product=False)
                           for m in model.confidence_maps)
        added = tuple(dataclasses.replace(m, length_product=False) for m in model.confidence_maps)
        for name, maps in (("raw", ()), ("unweighted", unweighted), ("added", added), ("nan", model.confidence_maps),
                           ("mixed", model.confidence_maps), ("flip", model.confidence_maps)):
            save_model(con, dataclasses.replace(model, name=name, confidence_maps=maps))
        want = {name: con.execute(f"SELECT motion_id, annotate(motion_id, model := '{name}') FROM motions "
                                  "ORDER BY motion_id").fetchall() for name in ("raw", "unweighted", "added",
                                                                                "default")}
    every = "SELECT motion_id, annotate(motion_id, 'default') FROM motions ORDER BY motion_id"
    got = plain_client(db, native, [
        "UPDATE confidence_maps SET value = 0 WHERE model = 'default' AND k = 2",
        "SELECT annotate(1, 'default')",
        "UPDATE confidence_maps SET length_weight = 'nan'::DOUBLE WHERE model = 'nan'",
        "SELECT annotate(1, 'nan')",
        "UPDATE confidence_maps SET length_weight = length_weight + 1 WHERE model = 'mixed' AND k = 2",
        "SELECT annotate(1, 'mixed')",
        "UPDATE confidence_maps SET length_product = NOT length_product WHERE model = 'flip' AND k = 2",
        "SELECT annotate(1, 'flip')",
        "DELETE FROM confidence_maps WHERE model = 'default'",
        "INSERT INTO confidence_maps SELECT * REPLACE ('default' AS model) FROM confidence_maps "
        "WHERE model = 'added'",
        "ALTER TABLE confidence_maps DROP COLUMN length_product",
        every,
        "DELETE FROM confidence_maps WHERE model = 'default'",
        "INSERT INTO confidence_maps SELECT * REPLACE ('default' AS model) FROM confidence_maps "
        "WHERE model = 'unweighted'",
        "ALTER TABLE confidence_maps DROP COLUMN length_weight",
        "ALTER TABLE confidence_maps DROP COLUMN full_length",
        every,
        "DROP TABLE confidence_maps",
        every], read_only=False)
    for k, name in ((1, "default"), (3, "nan"), (5, "mixed"), (7, "flip")):
        assert f"model '{name}': its confidence_maps rows are damaged" in got[k]["error"]
    assert got[11]["rows"] == [list(r) for r in want["added"]]
    assert got[16]["rows"] == [list(r) for r in want["unweighted"]]
    assert got[18]["rows"] == [list(r) for r in want["raw"]]
    # the four answers differ: the length counts, and how it counts; the maps count
    assert len({str(want[k]) for k in ("raw", "unweighted", "added", "default")}) == 4
    assert any(s["confidence"] not in (0.0, 1.0) for _, segs in want["raw"] for s in segs)


def test_annotate_arguments(archive, native):
    """A NULL or unknown motion is NULL; a NULL or unknown model, a negative or NaN tau an error naming
    it; NULL tau / keyframes are the model's; the model is the second argument, 'default' without it."""
    got = plain_client(archive, native, [
        "SELECT annotate(NULL), annotate(1000000), annotate(-1, 'toolbox', 0.2, true)",
        "SELECT annotate(1) = annotate(1, 'default') AND annotate(1) = annotate(1, 'default', NULL, NULL)",
        "SELECT annotate(1, 'nomodel')", "SELECT annotate(1, NULL)",
        "SELECT annotate(1, 'default', -0.5)", "SELECT annotate(1, 'default', 'nan'::DOUBLE)",
        "SELECT annotate(1, 'default', 0.0) IS NOT NULL"])
    assert got[0]["rows"] == [[None, None, None]]
    assert got[1]["rows"] == [[True]]
    assert "no model 'nomodel' in the database (stored models: default, toolbox" in got[2]["error"]
    assert "model is NULL" in got[3]["error"]
    assert "tau must be a non-negative number" in got[4]["error"] and "got -0.5" in got[4]["error"]
    assert "tau must be a non-negative number" in got[5]["error"] and "nan" in got[5]["error"]
    assert got[6]["rows"] == [[True]]


def test_bad_arguments_are_errors_that_name_them(archive, native):
    cases = {
        "keyframe_search_words([], [], [], [])": "a query has 1..32 keyframes, got 0",
        "keyframe_search_words(NULL, [1], [], [])": "masks and values must not be NULL",
        "keyframe_search_words([1, 2], [1], [0], [1])": "2 masks but 1 values",
        "keyframe_search_words([1], [2], [], [])": "keyframe 1 must be 40-bit words",
        "keyframe_search_words([1099511627776], [0], [], [])": "keyframe 1 must be 40-bit words",
        "keyframe_search_words([-1], [0], [], [])": "keyframe 1 must be 40-bit words",
        "keyframe_search_words([1, 2], [1, 0], [5], [3])": "gap 1 must have 0 <= d_min <= d_max <= 108000",
        "keyframe_search_words([1, 2], [1, 0], [NULL], [3])": "gap 1 must have",
        "keyframe_search_words([1, 2], [1, 0], [0], [108001])": "gap 1 must have",
        "keyframe_search_words([1, 2], [1, 0], [], [])": "a query of 2 keyframes needs 1 gap bounds",
        "keyframe_search_words([1], [1], [], [], extend_left := -1)": "extend_left must be in 0..108000 frames",
        "keyframe_search_words([1], [1], [], [], extend_right := NULL)": "extend_right must be in 0..108000",
        "keyframe_search_words('x', [0], [], [])": "masks must be a list of integers",
        "keyframe_search_words([1.5], [0], [], [])": "masks must be a list of integers",
        "keyframe_search_words(range(40), range(40), [], [])": "a query has 1..32 keyframes, got 40",
    }
    got = plain_client(archive, native, [f"SELECT * FROM {q}" for q in cases])
    for (q, message), answer in zip(cases.items(), got):
        assert message in answer.get("error", ""), (q, answer)
    # integer lists of any type bind (the Python macro casts; here the function reads them)
    ok = plain_client(archive, native, ["SELECT count(*) FROM keyframe_search_words([0], [0], [], [])",
                                        "SELECT count(*) FROM motions"])
    assert ok[0]["rows"] == ok[1]["rows"]  # an all-wildcard keyframe matches every motion once, whole


def test_a_changed_index_is_read_again(archive, native, tmp_path):
    """The extension keeps index batches between queries, keyed by mocap_index.state.version: a
    write that bumps it (as every ingest, delete and import does) is seen by the next query, and
    postings stored out of (motion, run) order give the same rows."""
    db = tmp_path / "changed.duckdb"
    shutil.copy(archive, db)
    q = "SELECT * FROM keyframe_search_words([3, 12], [1, 0], [0], [NULL], extend_left := 3) ORDER BY ALL"
    answers = plain_client(db, native, [
        q,
        "CREATE OR REPLACE TABLE mocap_index.postings AS SELECT * FROM mocap_index.postings ORDER BY random()",
        "UPDATE mocap_index.state SET version = version + 1",
        q,
        "DELETE FROM mocap_index.postings WHERE motion_id = 1",
        "UPDATE mocap_index.state SET version = version + 1",
        q], read_only=False)
    before, shuffled, deleted = answers[0]["rows"], answers[3]["rows"], answers[6]["rows"]
    assert before and shuffled == before
    assert deleted == [r for r in before if r[0] != 1] != before


def test_motions_stored_out_of_order_give_the_same_answers(archive, native, tmp_path):
    """The motions' lengths are read without ORDER BY (insertion order, sorted in C when it is not
    ascending): a motions table rewritten in another order gives the same answers."""
    db = tmp_path / "reordered.duckdb"
    shutil.copy(archive, db)
    qs = ["SELECT list({'m': motion_id, 's': annotate(motion_id)} ORDER BY motion_id)::VARCHAR FROM motions",
          "SELECT list(len(mt_distance(motion_id, 'squat1Reps')) ORDER BY motion_id) FROM motions",
          "SELECT count(*), sum(start_frame) FROM keyframe_search('squat1Reps')"]
    got = plain_client(db, native, qs + [
        "CREATE OR REPLACE TABLE motions AS SELECT * FROM motions ORDER BY motion_id DESC"] + qs, read_only=False)
    assert [g.get("error") for g in got] == [None] * len(got)
    assert [g["rows"] for g in got[:3]] == [g["rows"] for g in got[4:]]
    assert "'label'" in got[0]["rows"][0][0] and got[2]["rows"][0][0] > 0  # real answers compared


def test_a_damaged_motion_is_named(archive, native, tmp_path):
    """Features that are not a motion's frames 1 … n (what an older mocapdb could leave) are an
    error naming the motion, as the Python UDF's; the other motions are unaffected."""
    db = tmp_path / "damaged.duckdb"
    shutil.copy(archive, db)
    # motions 1-3 are the shipped sample's (a bare clone has no others)
    got = plain_client(db, native, ["DELETE FROM features WHERE motion_id = 2 AND frame = 5",
                                    "SELECT mt_distance(2, 'squat1Reps')",
                                    "SELECT len(mt_distance(1, 'squat1Reps')), len(mt_distance(3, 'squat1Reps')), "
                                    "len(annotate(3)) > 0",
                                    # the words are read unordered, each row into its frame's slot: a frame
                                    # twice (n rows all the same) and one past n_frames are caught too
                                    "UPDATE features SET frame = 4 WHERE motion_id = 1 AND frame = 5",
                                    "SELECT annotate(1)",
                                    "UPDATE features SET frame = frame + 1 WHERE motion_id = 3 AND frame = "
                                    "(SELECT n_frames FROM motions WHERE motion_id = 3)",
                                    "SELECT annotate(3, 'default', NULL, false)"],
                       read_only=False)
    assert re.search(r"motion 2 \(\S+\) has feature rows that are not its frames", got[1]["error"])
    assert got[2]["rows"] == [[1199, 266, True]]
    assert re.search(r"motion 1 \(86_09\) has feature rows that are not its frames", got[4]["error"])
    assert re.search(r"motion 3 \(\S+\) has feature rows that are not its frames", got[6]["error"])


def test_kept_statements_follow_the_catalog(archive, native, tmp_path):
    """The extension prepares each of its queries once per database and keeps it: a table dropped
    and created again, or its rows changed, under a kept statement gives what a fresh statement
    would (DuckDB binds a kept statement again when the catalog changed)."""
    db = tmp_path / "recreated.duckdb"
    shutil.copy(archive, db)
    got = plain_client(db, native, ["SELECT len(mt_distance(3, 'squat1Reps'))",
                                    "CREATE TABLE features_away AS SELECT * FROM features",
                                    "DROP TABLE features",
                                    "CREATE TABLE features AS SELECT * FROM features_away WHERE motion_id <> 3 "
                                    "OR frame <= 200",
                                    "SELECT len(mt_distance(3, 'squat1Reps'))",
                                    "INSERT INTO features SELECT * FROM features_away WHERE motion_id = 3 "
                                    "AND frame > 200",
                                    "SELECT len(mt_distance(3, 'squat1Reps'))"],
                       read_only=False)
    assert got[0]["rows"] == [[266]]
    assert re.search(r"motion 3 \(\S+\) has feature rows that are not its frames", got[4]["error"])
    assert got[6]["rows"] == [[266]]


def test_a_damaged_model_names_its_class(archive, native, tmp_path):
    """annotate reads a model's templates and keyframe queries in one query each, all classes at once:
    a damaged row is still an error naming its model and class (the single-class readers' messages),
    and another model is unaffected."""
    db = tmp_path / "damaged_model.duckdb"
    shutil.copy(archive, db)
    got = plain_client(db, native, [
        "DELETE FROM templates WHERE model = 'toolbox' AND class = 'grabHighR'",
        "SELECT annotate(1, 'toolbox')",
        "SELECT annotate(1) IS NOT NULL",
        "UPDATE templates SET mask = mask | (1::UBIGINT << 50) WHERE model = 'default' AND class = 'squat1Reps' "
        "AND col = 3",
        "SELECT annotate(1)",
        "UPDATE templates SET mask = mask & ~(1::UBIGINT << 50) WHERE model = 'default' AND class = 'squat1Reps'",
        "UPDATE keyframes SET d_min = 5, d_max = 2 WHERE model = 'default' AND class = 'tpose1000' AND k = 1",
        "SELECT annotate(1)"], read_only=False)
    assert "model 'toolbox' has no class 'grabHighR'" in got[1]["error"]
    assert got[2]["rows"] == [[True]]
    assert "model 'default', class 'squat1Reps': the stored template is damaged" in got[4]["error"]
    assert ("model 'default', class 'tpose1000': gap 1 of the stored keyframe query has d_max < d_min"
            in got[7]["error"])


# the model tables annotate reads (model_cache.c keys a kept model by their rows)
KEYED_TABLES = ("models", "classes", "templates", "keyframe_queries", "keyframes", "confidence_maps")


def copy_model_sql(name, to):
    """SQL that stores model `name`'s rows again as model `to`: a model the extension has not read."""
    return [f"INSERT INTO {t} SELECT * REPLACE ('{to}' AS model) FROM {t} WHERE model = '{name}'"
            for t in KEYED_TABLES]


def test_a_kept_model_follows_every_write_to_its_rows(archive, native, tmp_path):
    """annotate keeps a model between calls while one query finds its rows unchanged (model_cache.c):
    after each plain-SQL write to a model table the answer is the one of the same rows read afresh (a
    copy under another name, never read before), and differs from the answer before the write; an
    uncommitted write is not seen (the extension reads committed rows, as before), a committed one
    is; confidence values written as -0.0 instead of 0.0 (which DuckDB hashes alike) come out as
    -0.0 (a step's value stands as stored where the raw score adds nothing to it)."""
    db = tmp_path / "kept_model.duckdb"
    shutil.copy(archive, db)
    # one text of every motion's segments: doubles as their shortest round-trip text, -0.0 included
    q = ("SELECT list({{'m': motion_id, 's': annotate(motion_id, '{m}', NULL, {kf})}} ORDER BY motion_id)::VARCHAR "
         "FROM motions")
    writes = [
        "UPDATE classes SET tau = tau / 2 WHERE model = 'default'",
        "UPDATE templates SET weight = weight * 3 WHERE model = 'default' AND col % 3 = 1",
        "UPDATE keyframes SET mask = 0, value = 0 WHERE model = 'default' AND k = 1",
        "DELETE FROM keyframe_queries WHERE model = 'default' AND class >= 'm'",
        "UPDATE models SET margin = margin + 0.05 WHERE model = 'default'",
        "UPDATE confidence_maps SET length_weight = length_weight * 2 WHERE model = 'default'",
        "UPDATE confidence_maps SET length_product = NOT length_product WHERE model = 'default'",
        "UPDATE confidence_maps SET value = 0.0 WHERE model = 'default'",
        "UPDATE confidence_maps SET value = -(0.0::DOUBLE) WHERE model = 'default'",
    ]
    queries = [q.format(m="default", kf=kf) for kf in ("true", "false")]
    for i, w in enumerate(writes):
        queries += [w] + [q.format(m="default", kf=kf) for kf in ("true", "false")]
        queries += copy_model_sql("default", f"fresh{i}") + [q.format(m=f"fresh{i}", kf=kf) for kf in ("true", "false")]
    # in a transaction of the client's own: not seen until committed
    queries += ["BEGIN TRANSACTION", "UPDATE classes SET tau = tau * 4 WHERE model = 'default'",
                q.format(m="default", kf="true"), "COMMIT", q.format(m="default", kf="true")]
    got = plain_client(db, native, queries, read_only=False)
    assert [g.get("error") for g in got] == [None] * len(queries)
    before = [got[0]["rows"][0][0], got[1]["rows"][0][0]]
    step = len(KEYED_TABLES) + 5
    for i, w in enumerate(writes):
        kept = [got[2 + i * step + 1]["rows"], got[2 + i * step + 2]["rows"]]
        fresh = [got[2 + i * step + 3 + len(KEYED_TABLES)]["rows"], got[2 + i * step + 4 + len(KEYED_TABLES)]["rows"]]
        assert kept == fresh, w
        now = [k[0][0] for k in kept]
        assert now != before, w  # the write changed the answer (keyframes on, off or both)
        before = now
    # -0.0: the rows as text keep the sign; both answers had zero confidences
    assert "'confidence': 0.0}" in got[2 + 7 * step + 1]["rows"][0][0]
    assert "'confidence': -0.0}" in got[2 + 8 * step + 1]["rows"][0][0]
    uncommitted, committed = got[-3]["rows"], got[-1]["rows"]
    assert uncommitted == got[2 + 8 * step + 1]["rows"] != committed


def test_a_model_stored_again_through_mocapdb_is_seen(archive, native, tmp_path):
    """The same through mocapdb: save_model(replace=True) under a connection whose annotate has kept
    the model gives the new model's answer, the one of the same model stored under a new name."""
    import dataclasses

    from mocapdb.storage.model_store import load_model, save_model

    db = tmp_path / "restored.duckdb"
    shutil.copy(archive, db)
    q = "SELECT motion_id, annotate(motion_id, model := '{m}') FROM motions ORDER BY motion_id"
    with mocapdb.connect(db) as con:
        assert python_functions(con) == 0  # the native functions
        model = load_model(con, "default")
        first = con.execute(q.format(m="default")).fetchall()
        assert con.execute(q.format(m="default")).fetchall() == first  # kept, the same
        changed = dataclasses.replace(model, classes=tuple(dataclasses.replace(c, tau=c.tau * 0.5)
                                                           for c in model.classes))
        save_model(con, changed, replace=True)
        again = con.execute(q.format(m="default")).fetchall()
        save_model(con, dataclasses.replace(changed, name="fresh"))
        assert again == con.execute(q.format(m="fresh")).fetchall() != first
        save_model(con, model, replace=True)  # and back
        assert con.execute(q.format(m="default")).fetchall() == first


def test_a_missing_table_is_named_with_the_command_that_creates_it(archive, native, tmp_path):
    no_index = tmp_path / "no_index.duckdb"
    shutil.copy(archive, no_index)
    with mocapdb.connect(no_index) as con:
        mocapdb.api.drop_index(con)
    empty = tmp_path / "empty.duckdb"
    __import__("duckdb").connect(str(empty)).close()
    q = ["SELECT * FROM keyframe_search_words([1], [1], [], [])"]
    assert "table mocap_index.postings does not exist" in plain_client(no_index, native, q)[0]["error"]
    err = plain_client(empty, native, q)[0]["error"]
    assert "table motions does not exist" in err and "`mocapdb ingest` creates it" in err


# Another process writes the file: it can only if this one closed it.
WRITER = r"""
import sys, duckdb
con = duckdb.connect(sys.argv[1])
con.execute("CREATE OR REPLACE TABLE closed_check AS SELECT 1 AS x")
con.close()
"""


def another_process_writes(db):
    run = subprocess.run([sys.executable, "-c", WRITER, str(db)], capture_output=True, text=True, timeout=120)
    return run.returncode == 0 or run.stderr[-500:]


def test_mocapdb_connect_answers_with_the_native_functions(archive, native):
    """A mocapdb.connect connection (and its cursors) has the native functions: no Python UDF of
    theirs is registered, the macros keep the named arguments and give the
    Python UDFs' answers (MOCAPDB_NATIVE=0: the fallback where the extension is missing)."""
    queries = ["SELECT motion_id, annotate(motion_id, model := 'toolbox', keyframes := false), "
               "annotate(motion_id, tau := 0.1) FROM motions ORDER BY motion_id",
               "SELECT motion_id, mt_distance(motion_id, 'squat1Reps', model := 'default') FROM motions "
               "ORDER BY motion_id",
               "SELECT * FROM keyframe_search('squat1Reps', extend := true) ORDER BY ALL",
               "SELECT * FROM keyframe_search_words([3, 12], [1, 0], [0], [NULL], extend_left := 3) ORDER BY ALL"]
    with python_udfs(archive) as con:
        want = [con.execute(q).fetchall() for q in queries]
    with mocapdb.connect(archive, read_only=True) as con:
        cur = con.cursor()
        assert python_functions(con) == 0  # similar_to is native too (tests/test_native_similar.py)
        assert con.execute("SELECT count(*) FROM duckdb_functions() WHERE function_name = 'mocapdb_release'"
                           ).fetchall() == [(1,)]
        assert [con.execute(q).fetchall() for q in queries] == want
        assert [cur.execute(q).fetchall() for q in queries] == want
        with pytest.raises(duckdb.Error, match="model 'default' has no class 'nope'"):
            con.execute("SELECT mt_distance(1, 'nope')").fetchall()
    assert want[0] and any(w[1] for w in want[1]) and want[2] and want[3]  # real answers were compared


def test_the_last_connection_closed_closes_the_file(archive, native, tmp_path):
    """The extension's own connection no longer keeps the file open: when the last mocapdb
    connection of it is closed (its cursors with it) or garbage-collected, the keeper releases the
    extension and the file opens read-only in this process and for writing in another."""
    db = tmp_path / "closing.duckdb"
    shutil.copy(archive, db)
    con = mocapdb.connect(db)
    cur = con.cursor()
    want = cur.execute("SELECT annotate(1)").fetchall()
    con.close()  # closes cur too
    with mocapdb.connect(db, read_only=True) as ro:  # a config DuckDB refuses while the file is open
        assert ro.execute("SELECT annotate(1)").fetchall() == want
    assert another_process_writes(db) is True

    def forgotten():
        c = mocapdb.connect(db)
        c.execute("SELECT len(annotate(1)), len(mt_distance(1, 'squat1Reps'))").fetchall()

    forgotten()
    gc.collect()
    assert another_process_writes(db) is True


def test_an_instance_kept_open_after_the_release_falls_back_to_the_python_udfs(archive, native, tmp_path):
    """A plain DuckDB connection keeps the instance after the last mocapdb connection closed (the
    extension released): calling the native functions there is a clear error, and the next
    mocapdb.connect gets the Python UDFs, with the same answers."""
    db = tmp_path / "kept.duckdb"
    shutil.copy(archive, db)
    plain = connect_raw(db)
    with mocapdb.connect(db) as con:
        want = con.execute("SELECT annotate(2, model := 'toolbox')").fetchall()
    with pytest.raises(duckdb.Error, match="the extension was released on this database"):
        plain.execute("SELECT annotate(2)").fetchall()
    with mocapdb.connect(db) as con:
        assert python_functions(con) == 5
        assert con.execute("SELECT annotate(2, model := 'toolbox')").fetchall() == want
    plain.close()
    assert another_process_writes(db) is True


def test_older_stand_ins_go_and_a_loaded_instance_opens_again(archive, native, tmp_path):
    """The persisted stand-in macros an older mocapdb wrote would hide the native functions: a
    read-write open drops them, and a second open of the loaded instance (where the bare names are
    the native functions, which DuckDB refuses to drop) works."""
    db = tmp_path / "stand_ins.duckdb"
    shutil.copy(archive, db)
    raw = connect_raw(db)
    raw.execute("CREATE MACRO annotate(m) AS 'stand-in'")
    raw.execute("CREATE MACRO keyframe_search(c) AS TABLE SELECT 'stand-in' AS x")
    raw.close()
    with mocapdb.connect(db) as first, mocapdb.connect(db) as second:
        for con in (first, second):
            assert con.execute("SELECT typeof(annotate(1))").fetchall()[0][0].startswith("STRUCT")
        assert second.execute("SELECT count(*) FROM duckdb_functions() WHERE database_name = current_database() "
                              "AND function_type IN ('macro', 'table_macro')").fetchall() == [(0,)]
        assert second.execute("SELECT count(*) FROM keyframe_search('squat1Reps')").fetchall()[0][0] > 0


@pytest.fixture(scope="module")
def archive_v15(archive):
    """The archive as mocapdb wrote it: in DuckDB 1.5's storage format (mocapdb.storage.schema.STORAGE_VERSION),
    which the DuckDB 1.5 clients (the CLI, Node's @duckdb/node-api) read as it is — no copy."""
    return archive


#: what the Node test runs: keyframe hits, Δ's length and its finite sum (in millionths), a class's hits
CLIENT_QUERIES = [
    "SELECT * FROM keyframe_search_words([3, 12], [1, 0], [0], [NULL], extend_right := 5) ORDER BY ALL",
    "SELECT motion_id, len(d), list_sum(list_filter(d, lambda x: isfinite(x))) * 1e6 // 1 "
    "FROM (SELECT motion_id, mt_distance(motion_id, 'squat1Reps') AS d FROM motions) ORDER BY ALL",
    "SELECT * FROM keyframe_search('squat1Reps', extend := true) ORDER BY ALL"]


@pytest.mark.slow  # subprocesses: another client, a sanitizer build
def test_the_duckdb_cli_loads_it(archive, archive_v15, native):
    """PyPI's duckdb-cli (1.5.x): LOAD with -unsigned, the same rows as in Python duckdb 2.0; without
    -unsigned DuckDB refuses the unsigned binary cleanly."""
    beside = Path(sys.executable).with_name("duckdb")  # the venv's, when it is not on PATH
    cli = shutil.which("duckdb") or (str(beside) if beside.is_file() else None)
    assert cli, "the [test] extra installs duckdb-cli (a `duckdb` executable)"
    old = archive_v15
    for query, want in zip(CLIENT_QUERIES, plain_client(archive, native, CLIENT_QUERIES)):
        run = subprocess.run([cli, "-unsigned", "-csv", "-noheader", str(old), "-c", f"LOAD '{native}'; {query}"],
                             capture_output=True, text=True, timeout=300)
        assert run.returncode == 0, run.stderr
        got = [[int(float(x)) for x in line.split(",")] for line in run.stdout.split()]
        assert got and got == [[int(x) for x in row] for row in want["rows"]]
    refused = subprocess.run([cli, str(old), "-c", f"LOAD '{native}'"], capture_output=True, text=True, timeout=300)
    assert refused.returncode != 0 and "unsigned" in refused.stderr + refused.stdout


@pytest.mark.slow  # another client annotates every motion
def test_the_duckdb_cli_annotates_as_mocapdb_annotate(archive, archive_v15, native):
    """Issue 31's "done when": `duckdb -unsigned archive -c "LOAD …; SELECT m.name, unnest(annotate(
    m.motion_id), recursive := true) FROM motions m"` prints the segments of `mocapdb annotate`
    (mocapdb.api.annotate): the same names, labels and frames, the doubles to the CLI's printing."""
    import csv
    import io

    import mocapdb.api

    beside = Path(sys.executable).with_name("duckdb")
    cli = shutil.which("duckdb") or (str(beside) if beside.is_file() else None)
    assert cli, "the [test] extra installs duckdb-cli (a `duckdb` executable)"
    query = "SELECT m.name, unnest(annotate(m.motion_id), recursive := true) FROM motions m"
    run = subprocess.run([cli, "-unsigned", "-csv", str(archive_v15), "-c", f"LOAD '{native}'; {query}"],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    rows = list(csv.DictReader(io.StringIO(run.stdout)))
    with python_udfs(archive) as con:
        want = mocapdb.api.annotate(con, store=False).to_pylist()
    got = sorted((r["name"], r["label"], int(r["start_frame"]), int(r["end_frame"]), r) for r in rows)
    want = sorted((w["document"], w["label"], w["start_frame"], w["end_frame"], w) for w in want)
    assert len(got) > 20 and [g[:4] for g in got] == [w[:4] for w in want]
    for (*_, g), (*_, w) in zip(got, want):
        for col in ("cost", "start_s", "end_s", "confidence"):
            assert float(g[col]) == pytest.approx(w[col], rel=1e-12, abs=1e-15), (w, col)


#: Node's DuckDB client (DuckDB 1.5.6 inside), installed from the npm registry into the test's folder
NODE_API = "@duckdb/node-api@1.5.6-r.1"
NODE_CLIENT = r"""
import { DuckDBInstance } from '@duckdb/node-api';
const [db, ext, queries] = [process.argv[2], process.argv[3], JSON.parse(process.argv[4])];
const instance = await DuckDBInstance.create(db, { allow_unsigned_extensions: 'true', access_mode: 'READ_ONLY' });
const con = await instance.connect();
await con.run(`LOAD '${ext}'`);
const out = [];
for (const q of queries) out.push((await con.runAndReadAll(q)).getRowsJson());
console.log(JSON.stringify(out));
"""


@pytest.mark.slow  # subprocesses: another client, a sanitizer build
def test_node_loads_it(archive, archive_v15, native, tmp_path):
    """@duckdb/node-api (a third client, JavaScript): LOAD, the same rows as Python duckdb 2.0."""
    node, npm = shutil.which("node"), shutil.which("npm")
    assert node and npm, "the Node client test needs node and npm (Debian: nodejs, npm)"
    subprocess.run([npm, "install", "--silent", "--no-audit", "--no-fund", "--prefix", str(tmp_path), NODE_API],
                   check=True, timeout=600, capture_output=True)
    script = tmp_path / "client.mjs"
    script.write_text(NODE_CLIENT)
    run = subprocess.run([node, str(script), str(archive_v15), str(native), json.dumps(CLIENT_QUERIES)],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    got = json.loads(run.stdout)
    want = plain_client(archive, native, CLIENT_QUERIES)
    assert [[[int(float(x)) for x in row] for row in rows] for rows in got] == \
        [[[int(x) for x in row] for row in w["rows"]] for w in want]
    assert all(got)


def test_mocapdb_extension_path_names_the_binary(native, tmp_path):
    # the last line: a first run on a cold numba cache may say so before it
    out = run(tmp_path / "unused.duckdb", "extension-path").output.strip().splitlines()[-1]
    assert Path(out) == native and native.is_absolute() and native.name == "mocapdb.duckdb_extension"
    # DuckDB's footer: C API v1.2.0, the C_STRUCT ABI, unsigned (a zero signature)
    tail = native.read_bytes()[-534:]
    assert tail[:22] == b"\x00\x93\x04\x10duckdb_signature\x80\x04"
    fields = [tail[22 + 32 * i:54 + 32 * i].rstrip(b"\0").decode() for i in range(8)][::-1]
    assert fields[0] == "4" and fields[1] == "linux_amd64" and fields[2] == "v1.2.0" and fields[4] == "C_STRUCT"
    assert tail[-256:] == bytes(256)


def test_a_machine_without_a_c_compiler_still_installs(tmp_path, monkeypatch):
    """The build step leaves the reason where the binary would be (extension-path reports it), and
    no stale binary."""
    (tmp_path / BINARY_NAME).write_bytes(b"old")
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    status = build_or_explain(tmp_path)
    assert status.startswith("native extension NOT built") and not (tmp_path / BINARY_NAME).exists()
    assert "install gcc and reinstall mocapdb" in (tmp_path / MISSING_NAME).read_text()


# Thousands of seeded random calls, valid and not: every one must end in rows or a DuckDB error.
FUZZ_CLIENT = r"""
import json, os, random, sys
import duckdb
db, db2, ext, seed, n = json.load(sys.stdin)
rng = random.Random(seed)
def open_loaded(path):
    c = duckdb.connect(path, read_only=True, config={"allow_unsigned_extensions": "true"})
    c.execute("SET enable_progress_bar = false")
    c.execute(f"LOAD '{ext}'")
    return c
# two databases in one process, each with the extension's state of its own; the second is released
# now and then (its calls are then errors saying so), closed and opened again (a fresh LOAD)
con = open_loaded(db)
cons = [con, open_loaded(db2)]
released = False
n_released = 0
SCALARS = ["NULL", "0", "1", "-1", "3", "1023", "1099511627775", "1099511627776", "9223372036854775807",
           "-9223372036854775808", "18446744073709551615", "108000", "108001", "2.5", "'x'", "true", "[]", "[[1]]"]
def value():
    return rng.choice(SCALARS) if rng.random() < 0.7 else str(rng.randrange(-5, 1 << 41))
def a_list():
    r = rng.random()
    if r < 0.05:
        return "NULL"
    if r < 0.1:
        return rng.choice(["'text'", "42", "[1.5, 2]", "{'a': 1}", "range(100)", "[NULL]::UBIGINT[]"])
    n = rng.choice([0, 1, 2, 3, 4, 5, 31, 32, 33, 200])
    items = [value() for _ in range(n)]
    cast = rng.choice(["", "::UBIGINT[]", "::BIGINT[]", "::INTEGER[]", "::VARCHAR[]"])
    return "[" + ", ".join(items) + "]" + cast
n_rows = n_errors = n_similar = 0
for i in range(n):
    k = rng.choice([1, 2, 3, 4, 32])
    if rng.random() < 0.5:  # a well-formed query with random words and bounds
        masks = [rng.randrange(0, 1 << 40) & rng.choice([0, 1, 15, 1023, (1 << 40) - 1]) for _ in range(k)]
        vals = [m & rng.randrange(0, 1 << 40) for m in masks]
        lo = [rng.choice([0, 1, 10, 108000]) for _ in range(k - 1)]
        hi = [rng.choice(["NULL", str(x + rng.choice([0, 5, 1000])), "108000"]) for x in lo]
        args = [str(masks), str(vals), str(lo), "[" + ", ".join(hi) + "]::BIGINT[]"]
    else:
        args = [a_list() for _ in range(4)]
    named = []
    for name in ("extend_left", "extend_right"):
        if rng.random() < 0.5:
            named.append(f"{name} := {rng.choice(['NULL', '0', '5', '108000', '108001', '-3', str(1 << 40)])}")
    q = f"SELECT count(*), min(start_frame), max(end_frame) FROM keyframe_search_words({', '.join(args + named)})"
    if rng.random() < 0.3:  # mt_distance: motions, classes and models good and bad, NULLs, a column of rows
        motion = rng.choice(["NULL", "1", "3", "0", "-1", "2147483647", "2147483648", "motion_id", "'1'"])
        cls = rng.choice(["'squat1Reps'", "'kickLFront1Reps'", "NULL", "''", "'x' || motion_id", "'squat1Reps'"])
        model = rng.choice([[], ["'default'"], ["'toolbox'"], ["NULL"], ["'nomodel'"], ["''"]])
        q = (f"SELECT count(*), sum(len(d)) FROM (SELECT mt_distance({', '.join([motion, cls] + model)}) AS d "
             "FROM (SELECT motion_id FROM motions ORDER BY n_frames LIMIT 4))")
        if rng.random() < 0.3:  # keyframe_search: a class's stored query, or none
            named = [f"{k} := {rng.choice(v)}" for k, v in (("model", ["'default'", "'toolbox'", "NULL", "'x'"]),
                                                             ("extend", ["true", "false", "NULL"]))
                     if rng.random() < 0.5]
            q = f"SELECT count(*) FROM keyframe_search({', '.join([cls.replace(' || motion_id', '')] + named)})"
    if rng.random() < 0.02:  # annotate: motions, models, taus and keyframe settings good and bad
        args = [rng.choice(["NULL", "1", "0", "-1", "2147483648", "motion_id", "'1'"])]
        for choices in (["'default'", "'toolbox'", "NULL", "'nomodel'", "''", "'extreme'"],
                        ["NULL", "0", "0.13", "1e308", "-1", "'nan'::DOUBLE", "'inf'::DOUBLE", "'x'"],
                        ["NULL", "true", "false", "3"]):
            if rng.random() < 0.7:
                args.append(rng.choice(choices))
            else:
                break
        q = (f"SELECT count(*), sum(len(s)) FROM (SELECT annotate({', '.join(args)}) AS s "
             "FROM (SELECT motion_id FROM motions ORDER BY n_frames LIMIT 4))")
    similar = rng.random() < 0.08
    if similar:  # similar_to: motions by id, name and other types, ranges good and bad, k, cell budgets
        motion = rng.choice(["1", "'86_09'", "motion_id", "name", "'5'", "5::UTINYINT"] * 2
                            + ["NULL", "0", "-1", "2147483648", "18446744073709551615::UBIGINT", "''", "'nope'",
                               "3.7", "true"])
        first, last = rng.choice([("NULL", "NULL")] * 3 + [("1", "15"), ("1", "NULL"), ("NULL", "20"), ("30", "10"),
                                                            ("0", "20"), ("-5", "NULL"), ("1", "2147483647"),
                                                            ("5", "6")])
        k = rng.choice(["1", "3", "10", "2147483647"] * 2 + ["NULL", "0", "-1"])
        # the native function reads the budget at each call: small ones preselect with keyframes
        os.environ["MOCAPDB_CELL_BUDGET"] = rng.choice(["", "1", "5000", "300000", "200000000", "x", "-3"])
        q = (f"SELECT count(*), sum(len(s)) FROM (SELECT similar_to({motion}, {first}, {last}, {k}) AS s "
             "FROM (SELECT motion_id, name FROM motions WHERE n_frames >= 15 ORDER BY n_frames LIMIT 3))")
    r = rng.random()
    if r < 0.01 and not released:
        assert cons[1].execute("SELECT mocapdb_release()").fetchall() == [(True,)]
        released = True
    elif r < 0.03 and released:
        cons[1].close()  # the file closes: nothing else holds it
        cons[1] = open_loaded(db2)
        released = False
    c = rng.choice(cons)
    try:
        c.execute(q).fetchall()
        n_rows += 1
        n_similar += similar
        assert not (released and c is cons[1]), "a call answered after mocapdb_release(): " + q
    except duckdb.Error as e:
        n_errors += 1
        n_released += released and c is cons[1] and "was released on this database" in str(e)
print(json.dumps([n_rows, n_errors, n_released, n_similar]))
"""


@pytest.mark.slow  # subprocesses: another client, a sanitizer build
def test_thousands_of_random_calls_under_the_sanitizers(archive, tmp_path):
    """A build with -fsanitize=address,undefined (UBSan aborting on the first finding) LOADed into
    Python duckdb with libasan preloaded, in two databases of one process (the second also holding a model
    whose confidence maps weigh the length the most they may, counted in full from one frame): 3,000 seeded
    random calls, none may crash; after mocapdb_release() every call on that database is refused, and it opens
    and loads again once closed."""
    cc = os.environ.get("CC") or shutil.which("gcc")
    assert cc, "the sanitizer test needs gcc"
    asan = subprocess.run([cc, "-print-file-name=libasan.so"], capture_output=True, text=True).stdout.strip()
    ubsan = subprocess.run([cc, "-print-file-name=libubsan.so"], capture_output=True, text=True).stdout.strip()
    assert Path(asan).is_file() and Path(ubsan).is_file(), "gcc's libasan/libubsan (Debian: libgcc-12-dev)"
    ext = build(tmp_path / "mocapdb.duckdb_extension", sanitize=True)
    # leaks: CPython and DuckDB keep memory at exit by design; the extension's own are bounded by LOAD
    env = dict(os.environ, LD_PRELOAD=f"{asan} {ubsan}", ASAN_OPTIONS="detect_leaks=0:abort_on_error=1",
               UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1")
    second = shutil.copyfile(archive, tmp_path / "second.duckdb")
    import dataclasses

    from mocapdb.learning.confidence_maps import MAX_LENGTH_WEIGHT
    from mocapdb.storage.model_store import load_model, save_model

    with mocapdb.connect(second) as con:   # the second database also holds maps at the extremes of their score
        model = load_model(con, "default")
        maps = tuple(dataclasses.replace(m, length_weight=MAX_LENGTH_WEIGHT, full_length=1)
                     for m in model.confidence_maps)
        save_model(con, dataclasses.replace(model, name="extreme", confidence_maps=maps))
    run = subprocess.run([sys.executable, "-c", FUZZ_CLIENT],
                         input=json.dumps([str(archive), str(second), str(ext), 31, 3000]),
                         capture_output=True, text=True, env=env, timeout=1200)
    assert run.returncode == 0, run.stderr[-4000:]
    assert len(run.stdout.splitlines()) == 1, run.stdout[:3000]
    n_rows, n_errors, n_released, n_similar = json.loads(run.stdout)
    assert n_rows + n_errors == 3000 and n_rows > 500 and n_errors > 500  # both paths were exercised
    assert n_similar > 25  # similar_to answered, not only refused
    assert n_released > 50  # calls after mocapdb_release() were made, and refused
