"""Takes of any length, and one motion's failure never costs the others (issue 22 item 1).

A treadmill or gait-lab session is one long repetitive take: a real walk
(CMU 02_01, 2.9 s) looped to 10 and to 60 minutes has thousands of hits of
several classes, where the toolbox's limit of 2000 stopped the annotation of
every motion. Time and memory per take length are in benchmarks/RESULTS.md
(bench_long_take.py).
"""
import numpy as np
import pytest

import mocapdb
from mocapdb import api
from mocapdb.features import motion_features
from mocapdb.readers import read_motion
from mocapdb.errors import PartialAnnotationError
from mocapdb.storage.ingest import store_words

from conftest import DATA, run

pytestmark = pytest.mark.shared

CLIPS = sorted((DATA / "hdm05_cut" / "kickLFront1Reps").glob("HDM_bd_*.amc"))[:4]


def looped_walk(minutes):
    """The 30 Hz words of CMU 02_01 (a walk) repeated for ``minutes``."""
    w = motion_features(read_motion(DATA / "cmu" / "02" / "02_01.amc"))
    n = 30 * 60 * minutes
    return np.tile(w, -(-n // len(w)))[:n]


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    path = tmp_path_factory.mktemp("long") / "long.duckdb"
    con = mocapdb.connect(path)
    assert not mocapdb.ingest(con, CLIPS).failed
    store_words(con, {"walk_10min": looped_walk(10), "walk_60min": looped_walk(60)})
    con.close()
    return path


@pytest.mark.slow
@pytest.mark.parametrize("model", ["default", "toolbox"])
def test_an_hour_long_repetitive_take_annotates_with_the_others(db, model):
    with mocapdb.connect(db) as con:
        table = api.annotate(con, model=model)
        per_motion = dict(con.execute("SELECT m.name, count(a.label) FROM motions m LEFT JOIN annotations a "
                                      "ON a.motion_id = m.motion_id AND a.model = $model GROUP BY m.name",
                                      {"model": model}).fetchall())
        # the same through SQL
        sql = con.execute("SELECT m.name, s.label, s.start_frame, s.end_frame FROM motions m, "
                          "LATERAL (SELECT unnest(annotate(m.motion_id, model := $model), recursive := true)) s "
                          "ORDER BY ALL", {"model": model}).fetchall()
    assert all(per_motion[c.stem] > 0 for c in CLIPS)
    assert sorted(zip(*(table.column(c).to_pylist() for c in ("document", "label", "start_frame", "end_frame")))) \
        == sql
    for name, minutes in (("walk_10min", 10), ("walk_60min", 60)):
        rows = table.filter(np.array(table.column("document").to_pylist()) == name)
        move = sum(e - s + 1 for lab, s, e in zip(*(rows.column(c).to_pylist() for c in
                                                    ("label", "start_frame", "end_frame"))) if lab == "move")
        assert per_motion[name] > 0 and move >= 0.9 * 30 * 60 * minutes, (name, model)  # walking is `move`


def test_the_toolbox_limit_only_when_asked_and_named_by_what_exists():
    from mocapdb.annotation import MATCH_NUM_MAX, annotate
    from mocapdb.errors import ParameterError
    from mocapdb.storage.model_store import load_model

    with mocapdb.connect() as con:
        model = load_model(con, "toolbox")
    walk = looped_walk(10)
    with pytest.raises(ParameterError, match=r"match_num_max=2000 hits reached.*doc_lengths\[0\].*match_num_max=None"):
        annotate(walk, model, match_num_max=MATCH_NUM_MAX)
    assert len(annotate(walk, model, keep_hits=False).segments) > 0


def test_the_cli_annotates_a_long_take(db):
    r = run(db, "annotate", "walk_60min", "--model", "toolbox", "--format", "csv")
    assert "walk_60min,move," in r.output and "match_num_max" not in r.output


def _damage(path, name):
    """A motion whose features lost rows (as an import of a partial archive by an older mocapdb left them)."""
    with mocapdb.connect(path) as con:
        con.execute("DELETE FROM features WHERE motion_id = (SELECT motion_id FROM motions WHERE name = $n) "
                    "AND frame > 20", {"n": name})


def test_one_bad_motion_never_empties_a_batch(tmp_path):
    path = tmp_path / "bad.duckdb"
    con = mocapdb.connect(path)
    assert not mocapdb.ingest(con, CLIPS).failed
    con.close()
    victim = CLIPS[1].stem
    _damage(path, victim)
    with mocapdb.connect(path) as con:
        with pytest.raises(PartialAnnotationError, match=rf"1 of 4 motions not annotated.*{victim}.*20 feature rows") \
                as e:
            api.annotate(con)
        stored = dict(con.execute("SELECT m.name, count(*) FROM annotations a JOIN motions m USING (motion_id) "
                                  "GROUP BY m.name").fetchall())
        with pytest.raises(Exception, match=f"{victim}.*ingest or import it again to repair it"):
            con.execute("SELECT annotate(motion_id) FROM motions").fetchall()
    assert [f[1] for f in e.value.failed] == [victim]
    assert set(stored) == {c.stem for c in CLIPS} - {victim}
    assert e.value.table.num_rows == sum(stored.values())
    # the CLI prints the others, names the bad one and exits 1
    r = run(path, "annotate", "--format", "csv", code=1)
    assert all(f"{c.stem},kick," in r.output for c in CLIPS if c.stem != victim)
    assert f"{victim}" in r.output.splitlines()[-1] and "Error:" in r.output
    # ingesting the file again repairs it, and then everything annotates
    with mocapdb.connect(path) as con:
        report = mocapdb.ingest(con, [CLIPS[1]])
        assert [p for p, _ in report.repaired] == [str(CLIPS[1])] and len(report.ingested) == 1
        assert api.annotate(con).num_rows == sum(stored.values()) + 1
