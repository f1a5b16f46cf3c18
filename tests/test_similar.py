"""mocapdb similar (query by example) from the API, the CLI and SQL on a fresh database of real takes."""
import csv
import io
import json

import numpy as np
import pytest

import mocapdb
from mocapdb.errors import ParameterError, SchemaError
from mocapdb.storage.postings import drop_index

from conftest import DATA, run

pytestmark = pytest.mark.shared

CLASSES = ("kickLFront1Reps", "rotateArmsBothBackward1Reps", "hopBothLegs1hops")
COLUMNS = ["document", "motion_id", "start_frame", "end_frame", "start_s", "end_s", "cost"]
KICK = "HDM_bd_kickLFront1Reps_001_120"


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    path = tmp_path_factory.mktemp("similar") / "similar.duckdb"
    con = mocapdb.connect(path)
    files = [p for c in CLASSES for p in sorted((DATA / "hdm05_cut" / c).glob("*.amc"))
             if p.name.startswith(("HDM_bd_", "HDM_dg_"))]
    report = mocapdb.ingest(con, [*files, DATA / "cmu" / "86" / "86_09.amc"])
    assert not report.failed
    con.close()
    return path


@pytest.fixture()
def con(db):
    c = mocapdb.connect(db)
    yield c
    c.close()


def _rows(table):
    return list(zip(*(table.column(c).to_pylist() for c in COLUMNS)))


def test_a_kick_finds_kicks_ranked_distinct_and_never_itself(con):
    table = mocapdb.similar(con, KICK, limit=8)
    assert table.column_names == COLUMNS and table.num_rows == 8
    rows = table.to_pylist()
    assert [r["cost"] for r in rows] == sorted(r["cost"] for r in rows)
    assert all("kickLFront1Reps" in r["document"] for r in rows[:5])
    assert KICK not in {r["document"] for r in rows}  # the whole motion is the query
    for r in rows:
        assert r["start_s"] == pytest.approx((r["start_frame"] - 1) / 30) and r["end_s"] == pytest.approx(
            r["end_frame"] / 30)
    by_motion = {}
    for r in rows:
        by_motion.setdefault(r["motion_id"], []).append((r["start_frame"], r["end_frame"]))
    for spans in by_motion.values():
        spans.sort()
        assert all(b[0] > a[1] for a, b in zip(spans, spans[1:]))


def test_a_stretch_of_a_long_take_excludes_itself_only(con):
    """A stretch of 86_09 (walking) finds the other walking of the same take, never the stretch."""
    table = mocapdb.similar(con, "86_09", start_frame=40, end_frame=110, limit=6)
    rows = table.to_pylist()
    assert rows and rows[0]["document"] == "86_09"
    for r in rows:
        if r["document"] == "86_09":
            assert r["end_frame"] < 40 or r["start_frame"] > 110
    # seconds address the same frames: frame k spans [(k-1)/30, k/30)
    again = mocapdb.similar(con, "86_09", 39 / 30, 110 / 30, limit=6)
    assert _rows(again) == _rows(table)


def test_the_api_the_cli_and_sql_agree(db):
    with mocapdb.connect(db) as con:  # closed before the CLI opens the file
        mid = con.execute("SELECT motion_id FROM motions WHERE name = ?", [KICK]).fetchall()[0][0]
        api = mocapdb.similar(con, mid, start_frame=5, end_frame=40, limit=7)
        sql = con.execute("SELECT * FROM similar_to(?, 5, 40, k := 7)", [mid]).fetchall()
        whole = con.execute("SELECT count(*) FROM similar_to(?)", [mid]).fetchall()[0][0]
    assert [tuple(r) for r in sql] == [tuple(pytest.approx(v) if isinstance(v, float) else v for v in r)
                                       for r in _rows(api)]
    out = run(db, "similar", KICK, "--start-frame", 5, "--end-frame", 40, "--limit", 7, "--format", "csv").output
    cli = list(csv.reader(io.StringIO(out)))
    assert cli[0] == COLUMNS
    assert [(r[0], int(r[1]), int(r[2]), int(r[3])) for r in cli[1:]] == [r[:4] for r in _rows(api)]
    out = json.loads(run(db, "similar", mid, "--start", 4 / 30, "--end", 40 / 30, "--limit", 7,
                         "--format", "json").output)
    assert [(r["motion_id"], r["start_frame"], r["end_frame"]) for r in out] == [r[1:4] for r in _rows(api)]
    assert whole == 10


def test_feature_subsets_and_more_like_these(con):
    lower = mocapdb.similar(con, KICK, limit=5, features="lower")
    upper = mocapdb.similar(con, KICK, limit=5, features="upper")
    named = mocapdb.similar(con, KICK, limit=5, features="foot_left_raised_rel_y_body_min,knee_left_bent")
    assert _rows(lower) != _rows(upper) and named.num_rows == 5
    # "more like these": a template learned from three kicks (two actors) finds the other kicks first
    other = "HDM_dg_kickLFront1Reps_013_120"
    n = con.execute("SELECT n_frames FROM motions WHERE name = ?", [other]).fetchall()[0][0]
    examples = ["HDM_bd_kickLFront1Reps_002_120", (other, 1, n)]
    more = mocapdb.similar(con, KICK, examples=examples, limit=8).to_pylist()
    assert len(more) == 8 and all("kickLFront1Reps" in r["document"] for r in more)
    assert not {"HDM_bd_kickLFront1Reps_002_120", other} & {r["document"] for r in more}  # the examples
    assert {r["document"][4:6] for r in more} == {"bd", "dg"}  # both actors' kicks


def test_results_are_deterministic_and_the_same_from_the_index_or_the_features(db, tmp_path):
    import shutil

    with mocapdb.connect(db) as con:
        a = _rows(mocapdb.similar(con, KICK, limit=10, keyframes=False))
        b = _rows(mocapdb.similar(con, KICK, limit=10, keyframes=False))
        forced = mocapdb.similar(con, KICK, limit=10, keyframes=True).to_pylist()
    assert a == b
    assert forced and all(r["cost"] >= a[0][6] for r in forced)  # a preselection cannot find better
    copy = tmp_path / "copy.duckdb"
    shutil.copy(db, copy)
    with mocapdb.connect(copy) as con:
        drop_index(con)  # then the words come from the features table, batch by batch
        assert _rows(mocapdb.similar(con, KICK, limit=10)) == a
        with pytest.raises(SchemaError, match="no keyframe index"):
            mocapdb.similar(con, KICK, keyframes=True)


def test_bad_input_is_a_clear_error(con):
    mid = con.execute("SELECT motion_id FROM motions WHERE name = ?", [KICK]).fetchall()[0][0]
    n = con.execute("SELECT n_frames FROM motions WHERE motion_id = ?", [mid]).fetchall()[0][0]
    with pytest.raises(SchemaError, match="no motion 'no_such_take'"):
        mocapdb.similar(con, "no_such_take")
    with pytest.raises(ParameterError, match="is empty"):
        mocapdb.similar(con, KICK, start_frame=30, end_frame=20)
    with pytest.raises(ParameterError, match=rf"outside motion \d+ \('{KICK}'\)"):
        mocapdb.similar(con, KICK, start_frame=1, end_frame=n + 1)
    with pytest.raises(ParameterError, match="outside"):
        mocapdb.similar(con, KICK, start_frame=0, end_frame=5)
    with pytest.raises(ParameterError, match="holds no frame"):
        mocapdb.similar(con, KICK, 0.5, 0.5)
    with pytest.raises(ParameterError, match="not both"):
        mocapdb.similar(con, KICK, 0.1, 0.5, start_frame=3)
    with pytest.raises(ParameterError, match="limit"):
        mocapdb.similar(con, KICK, limit=0)
    with pytest.raises(ParameterError, match="unknown feature 'toes'"):
        mocapdb.similar(con, KICK, features="toes")
    with pytest.raises(ParameterError, match="format and out"):
        mocapdb.similar(con, KICK, format="html")
    with pytest.raises(ParameterError, match=r"examples\[0\] must be a motion"):
        mocapdb.similar(con, KICK, examples=[(KICK, 3)])
    for query, message in ((f"SELECT * FROM similar_to({mid}, 9, 3)", "is empty"),
                           (f"SELECT * FROM similar_to({mid}, 1, {n + 1})", "outside motion"),
                           ("SELECT * FROM similar_to(99999)", "no motion with id 99999"),
                           (f"SELECT * FROM similar_to({mid}, k := 0)", "k must be a positive integer")):
        with pytest.raises(Exception, match=message):
            con.execute(query).fetchall()


def test_bad_input_on_the_command_line(db):
    r = run(db, "similar", "no_such_take", code=1)
    assert r.output.startswith("Error: no motion 'no_such_take'")
    r = run(db, "similar", KICK, "--start-frame", 9, "--end-frame", 3, code=1)
    assert r.output.startswith("Error: the range 9–3") and "is empty" in r.output
    r = run(db, "similar", KICK, "--example", "no_such_take:1-5", code=1)
    assert r.output.startswith("Error: no motion 'no_such_take'")
    r = run(db, "similar", KICK, "--format", "html", code=2)
    assert "--out DIR" in r.output


@pytest.mark.slow
def test_results_page_links_each_hit(db, tmp_path):
    out = tmp_path / "hits"
    r = run(db, "similar", "86_09", "--start-frame", 40, "--end-frame", 110, "--limit", 4, "--format", "html",
            "--out", out, "--silent")
    assert "4 result(s) written" in r.output
    from browser import Elements

    page = Elements((out / "index.html").read_text(encoding="utf-8"))
    rows = [e for e in page.elements if e[0] == "tr" and "hit" in e[1].get("class", "")]
    links = [e[1]["href"] for e in page.elements if e[0] == "a"]
    assert len(rows) == 4
    for row in rows:
        name = next(e for e in page.elements if e[0] == "a" and e[1]["href"].endswith(
            f"#frame={row[1]['data-start']}-{row[1]['data-end']}"))
        assert (out / name[1]["href"].split("#")[0]).is_file()
    assert "86_09.html#frame=40-110" in links  # the query itself
    np.testing.assert_equal(sorted(p.name for p in out.glob("*.html"))[0], "86_09.html")
    # a link opens its motion's page at the hit, the hit selected (in a real browser)
    from browser import console_errors, dump_dom

    first = rows[0][1]
    href = next(x for x in links if x.endswith(f"#frame={first['data-start']}-{first['data-end']}"))
    path, fragment = href.split("#")
    dom, log = dump_dom(out / path, "#" + fragment)
    assert console_errors(log) == []
    shown = Elements(dom)
    body = next(e for e in shown.elements if e[0] == "body")
    assert body[1]["data-opened-at"] == first["data-start"]
    assert shown.by_id("similar")[1]["data-last"] == first["data-end"]
