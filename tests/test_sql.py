"""The SQL surface on real data: annotate / mt_distance / keyframe_search against the oracle."""
import csv
from importlib import resources

import numpy as np
import pytest

import mocapdb
from mocapdb import ingest
from mocapdb.api import annotate as annotate_motions
from mocapdb.storage.model_store import load_model, save_model

from conftest import DATA, ORACLE
from template_oracle import DOCS, oracle_model, quantized_template

pytestmark = pytest.mark.shared

ANNOT = ORACLE / "annotation"


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    """The five oracle documents and a few HDM05 clips, with the toolbox's own templates as model 'oracle'."""
    con = mocapdb.connect(tmp_path_factory.mktemp("sql") / "t.duckdb")
    ingest(con, [DATA / "cmu" / "86", *(DATA / "cmu" / "02" / f"{d}.amc" for d in DOCS if d.startswith("02")),
                 DATA / "hdm05_cut" / "squat1Reps", DATA / "hdm05_cut" / "kickLFront1Reps"])
    save_model(con, oracle_model(), description="toolbox templates (oracle)")
    yield con
    con.close()


def oracle_segments(doc):
    with open(ANNOT / doc / "segments.csv") as fh:
        return sorted((r["label"], int(r["start_frame"]), int(r["end_frame"]), float(r["cost"]))
                      for r in csv.DictReader(fh))


def check_segments(got, want):
    assert [g[:3] for g in got] == [w[:3] for w in want]
    np.testing.assert_allclose([g[3] for g in got], [w[3] for w in want], rtol=0, atol=1e-9)


@pytest.mark.parametrize("doc", DOCS)
def test_sql_annotate_reproduces_the_toolbox(db, doc):
    got = db.execute("""SELECT label, start_frame, end_frame, cost FROM (
                          SELECT unnest(annotate(m.motion_id, model := 'oracle'), recursive := true)
                          FROM motions m WHERE m.name = ?) ORDER BY ALL""", [doc]).fetchall()
    check_segments(got, oracle_segments(doc))


def test_every_unnest_form_and_the_python_api_agree(db):
    select_list = db.execute("""SELECT * FROM (SELECT m.motion_id, unnest(annotate(m.motion_id, model := 'oracle'),
                                recursive := true) FROM motions m) ORDER BY ALL""").fetchall()
    lateral = db.execute("""SELECT m.motion_id, s.* FROM motions m,
                            LATERAL (SELECT unnest(annotate(m.motion_id, model := 'oracle'), recursive := true)) s
                            ORDER BY ALL""").fetchall()
    assert select_list == lateral and len(select_list) > 19
    table = annotate_motions(db, model="oracle")
    cols = ["motion_id", "label", "start_frame", "end_frame", "cost", "start_s", "end_s", "confidence"]
    assert sorted(zip(*(table.column(c).to_pylist() for c in cols))) == select_list
    stored = db.execute("SELECT motion_id, label, start_frame, end_frame, cost, start_s, end_s, confidence FROM annotations "
                        "WHERE model = 'oracle' ORDER BY ALL").fetchall()
    assert stored == select_list
    # re-annotating replaces, never duplicates
    annotate_motions(db, model="oracle")
    assert db.execute("SELECT count(*) FROM annotations WHERE model = 'oracle'").fetchall()[0][0] == len(stored)


def test_seconds_follow_the_frame_rate(db):
    rows = db.execute("""SELECT m.fps, s.start_frame, s.end_frame, s.start_s, s.end_s FROM motions m,
                         LATERAL (SELECT unnest(annotate(m.motion_id, model := 'oracle'), recursive := true)) s""").fetchall()
    for fps, a, b, sa, sb in rows:
        assert fps == 30.0 and sa == pytest.approx((a - 1) / 30) and sb == pytest.approx(b / 30)


def test_mt_distance_reproduces_the_toolbox(db):
    with open(ANNOT / "86_09" / "delta_fine.csv") as fh:
        header = fh.readline().strip().split(",")
    want = np.loadtxt(ANNOT / "86_09" / "delta_fine.csv", delimiter=",", skiprows=1)
    for k, cls in enumerate(header):
        got = db.execute("SELECT mt_distance(motion_id, ?, model := 'oracle') FROM motions WHERE name = '86_09'",
                         [cls]).fetchall()[0][0]
        got = np.array(got)
        assert np.array_equal(np.isinf(got), np.isinf(want[:, k])), cls
        np.testing.assert_allclose(got[np.isfinite(got)], want[np.isfinite(want[:, k]), k], rtol=0, atol=1e-9)


def test_toolbox_model_is_the_reference(db):
    """The shipped toolbox model's templates are the toolbox's; it is the reference mode."""
    model = load_model(db, "toolbox")
    for c in model.classes:
        q = quantized_template(ORACLE / "templates" / c.name)
        np.testing.assert_array_equal(c.quantized.mask, q.mask, err_msg=c.name)
        np.testing.assert_array_equal(c.quantized.value, q.value, err_msg=c.name)
        np.testing.assert_array_equal(c.quantized.weights, q.weights, err_msg=c.name)
    for doc in DOCS:
        got = db.execute("""SELECT label, start_frame, end_frame, cost FROM (
                              SELECT unnest(annotate(m.motion_id, model := 'toolbox'), recursive := true)
                              FROM motions m WHERE m.name = ?) ORDER BY ALL""", [doc]).fetchall()
        check_segments(got, oracle_segments(doc))


def test_unknown_model_class_and_motion(db):
    import duckdb

    with pytest.raises(duckdb.Error, match="no model 'nope'"):
        db.execute("SELECT annotate(motion_id, model := 'nope') FROM motions").fetchall()
    with pytest.raises(duckdb.Error, match="has no class 'dance'"):
        db.execute("SELECT mt_distance(motion_id, 'dance') FROM motions").fetchall()
    assert db.execute("SELECT annotate(123456), mt_distance(123456, 'squat1Reps')").fetchall() == [(None, None)]


def test_model_round_trip(db):
    original = oracle_model()
    stored = load_model(db, "oracle")
    assert stored.labels == original.labels and stored.class_names == original.class_names
    for a, b in zip(original.classes, stored.classes):
        assert (a.label, a.tau, a.delta) == (b.label, b.tau, b.delta)
        np.testing.assert_array_equal(a.quantized.mask, b.quantized.mask)
        np.testing.assert_array_equal(a.quantized.weights, b.quantized.weights)
    with pytest.raises(mocapdb.ParameterError, match="already exists"):
        save_model(db, original)


@pytest.mark.parametrize("name", sorted(p.name for p in resources.files("mocapdb.sql.queries").iterdir()
                                        if p.name.endswith(".sql")))
def test_example_queries_run(db, name):
    text = resources.files("mocapdb.sql.queries").joinpath(name).read_text(encoding="utf-8")
    rel = db.sql(text)
    rows = rel.fetchall()
    assert rel.columns
    if name == "long_kicks.sql":
        assert all(r[1] == "kick" and r[4] > 1.0 for r in rows)
    if name == "seconds_per_label.sql":
        assert {r[0] for r in rows} >= {"86_09"}
    if name == "kicks.sql":
        # the designed kick keyframe finds every (left) kick clip, and nothing in the squats, the
        # CMU walks, runs, jumps, swordplay and washing, or 86_09
        names = {r[0] for r in rows}
        assert names == {r[0] for r in db.execute("SELECT name FROM motions WHERE name LIKE '%kick%'").fetchall()}
        assert {r[1] for r in rows} == {"left"}
