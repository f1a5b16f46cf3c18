"""Storage: schema, ingest (idempotent, atomic per file), the feature view, Parquet round trip."""
import math
import re
import shutil

import numpy as np
import pytest

import mocapdb
from mocapdb.features import FEATURE_NAMES, motion_features
from mocapdb import ingest
from mocapdb.storage.ingest import motion_files
from mocapdb.readers import read_motion

from conftest import DATA, amc_frame_count, c3d_frame_count

CMU_ASF = DATA / "cmu" / "02" / "02.asf"
NO_ASF_DIRS = (DATA / "cmu" / "13", DATA / "cmu" / "14")
#: the labelled HDM05/CMU recordings; the other labs' files of foreign/ have tests of their own
ARCHIVE = [DATA / "cmu", DATA / "hdm05_cut", DATA / "hdm05_full"]


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    """The HDM05 and CMU data ingested into a database file (cmu/13, cmu/14 read with 02.asf)."""
    path = tmp_path_factory.mktemp("db") / "archive.duckdb"
    con = mocapdb.connect(path)
    first = ingest(con, ARCHIVE)
    second = ingest(con, list(NO_ASF_DIRS), asf=CMU_ASF)
    yield con, first, second
    con.close()


def test_whole_data_ingests_with_right_frame_counts(archive):
    con, first, second = archive
    amcs = [p for p in motion_files(ARCHIVE) if p.suffix == ".amc"]
    c3ds = [p for p in motion_files(ARCHIVE) if p.suffix == ".c3d"]  # HDM05 and CMU marker files
    # the only failures of the first pass are the takes without an ASF, with a reason naming the fix
    assert sorted(p for p, _ in first.failed) == sorted(str(p) for p in amcs if p.parent in NO_ASF_DIRS)
    assert all("--asf" in reason for _, reason in first.failed)
    assert not second.failed
    rows = dict(con.execute("SELECT source_path, n_source_frames FROM motions").fetchall())
    assert len(c3ds) == 5 and sorted(rows) == sorted(str(p) for p in amcs + c3ds)
    for path in amcs:
        assert rows[str(path)] == amc_frame_count(path), path
    for path in c3ds:
        assert rows[str(path)] == c3d_frame_count(path), path
    counts = con.execute("""
        SELECT m.source_path, m.n_source_frames, m.n_frames, count(f.frame), min(f.frame), max(f.frame)
        FROM motions m JOIN features f USING (motion_id) GROUP BY ALL""").fetchall()
    assert len(counts) == len(amcs) + len(c3ds)
    for path, native, n30, rows30, lo, hi in counts:
        assert n30 == rows30 == math.ceil(native / 4) == hi and lo == 1, path
    assert con.execute("SELECT sum(n_source_frames) FROM motions WHERE source_path LIKE '%hdm05_cut%'"
                       ).fetchall()[0][0] == 56733


def test_stored_words_are_the_features_of_the_file(archive):
    con = archive[0]
    for name in ("86_09", "HDM_bd_kickLFront1Reps_001_120", "13_29", "85_02"):
        path, asf = con.execute("SELECT source_path, skeleton_path FROM motions WHERE name = ?", [name]).fetchall()[0]
        stored = con.execute("SELECT bits FROM features f JOIN motions m USING (motion_id) "
                             "WHERE m.name = ? ORDER BY frame", [name]).fetchnumpy()["bits"]
        np.testing.assert_array_equal(stored, motion_features(read_motion(path, asf=asf)))


def test_reingest_is_a_noop(archive):
    con = archive[0]
    before = con.execute("SELECT count(*), sum(motion_id), (SELECT count(*) FROM features) FROM motions").fetchall()
    again = ingest(con, [DATA / "cmu" / "86", DATA / "hdm05_cut" / "squat1Reps"])
    assert not again.ingested and not again.failed
    assert len(again.skipped) == 41 and all("already ingested" in r for _, r in again.skipped)
    assert con.execute("SELECT count(*), sum(motion_id), (SELECT count(*) FROM features) FROM motions"
                       ).fetchall() == before


def test_feature_flags_view_names_every_bit(archive):
    con = archive[0]
    cols = [r[0] for r in con.execute("DESCRIBE feature_flags").fetchall()]
    assert cols == ["motion_id", "frame", *FEATURE_NAMES]
    # each named column is exactly its bit of the packed word
    checks = " AND ".join(f"{name} = ((bits >> {k}) & 1 = 1)" for k, name in enumerate(FEATURE_NAMES))
    bad = con.execute(f"SELECT count(*) FROM feature_flags JOIN features USING (motion_id, frame) "
                      f"WHERE NOT ({checks})").fetchall()[0][0]
    assert bad == 0
    # a real property through the view: squats bend both knees, walking mostly does not
    squat, walk = con.execute("""
        SELECT avg(CASE WHEN m.name LIKE '%squat%' THEN (knee_right_bent AND knee_left_bent)::INT END),
               avg(CASE WHEN m.name = '86_09' AND frame < 220 THEN (knee_right_bent AND knee_left_bent)::INT END)
        FROM feature_flags v JOIN motions m USING (motion_id)""").fetchall()[0]
    assert squat > 0.3 > walk


def test_parquet_export_import_round_trip(archive, tmp_path):
    from mocapdb.storage.parquet import export_features, features_sql, import_features

    con = archive[0]
    n = export_features(con, tmp_path / "export")
    assert n == con.execute("SELECT count(*) FROM motions").fetchall()[0][0]
    assert len(list((tmp_path / "export" / "features").glob("motion_id=*"))) == n
    # queried in place: identical words
    diff = con.execute(f"""
        SELECT count(*) FROM ({features_sql(tmp_path / 'export')}) p
        FULL JOIN features f USING (motion_id, frame) WHERE p.bits IS DISTINCT FROM f.bits""").fetchall()[0][0]
    assert diff == 0
    # imported into a fresh database: same motions (by sha256) and identical words
    fresh = mocapdb.connect(tmp_path / "fresh.duckdb")
    try:
        report = import_features(fresh, tmp_path / "export")
        assert len(report.imported) == n and not report.failed
        again = import_features(fresh, tmp_path / "export")  # idempotent
        assert again.imported == {} and len(again.skipped) == n
        a = con.execute("SELECT m.sha256, f.frame, f.bits FROM features f JOIN motions m USING (motion_id) "
                        "ORDER BY ALL").fetchall()
        b = fresh.execute("SELECT m.sha256, f.frame, f.bits FROM features f JOIN motions m USING (motion_id) "
                          "ORDER BY ALL").fetchall()
        assert a == b
    finally:
        fresh.close()


def _broken_copies(tmp_path):
    """A folder with real files and broken copies of them."""
    src = DATA / "hdm05_cut"
    d = tmp_path / "mixed"
    (d / "kick").mkdir(parents=True)
    shutil.copy(src / "HDM_bd.asf", d)
    good = sorted((src / "kickLFront1Reps").glob("HDM_bd_*.amc"))[:3]
    for p in good:
        shutil.copy(p, d / "kick")
    lines = good[0].read_bytes().splitlines(keepends=True)
    (d / "kick" / "HDM_bd_truncated_120.amc").write_bytes(b"".join(lines[:-3]))
    text = good[1].read_bytes().replace(b"rtibia", b"rshin", 1)
    (d / "kick" / "HDM_bd_badbone_120.amc").write_bytes(text)
    return d, good


def test_failed_files_change_nothing_and_others_go_in(tmp_path):
    d, good = _broken_copies(tmp_path)
    con = mocapdb.connect(tmp_path / "t.duckdb")
    try:
        report = ingest(con, [d])
        failed = dict(report.failed)
        assert sorted(failed) == sorted(str(d / "kick" / f"HDM_bd_{x}_120.amc") for x in ("badbone", "truncated"))
        assert "rshin" in failed[str(d / "kick" / "HDM_bd_badbone_120.amc")]
        assert re.search(r"truncated_120\.amc:\d+", failed[str(d / "kick" / "HDM_bd_truncated_120.amc")])
        names = sorted(r[0] for r in con.execute("SELECT name FROM motions").fetchall())
        assert names == sorted(p.stem for p in good)
        before = con.execute("SELECT count(*) FROM features").fetchall()
        # failing alone: nothing changes
        again = ingest(con, [d / "kick" / "HDM_bd_truncated_120.amc"])
        assert len(again.failed) == 1 and not again.ingested
        assert con.execute("SELECT count(*) FROM features").fetchall() == before
    finally:
        con.close()


def test_delete_removes_everything_of_a_motion(tmp_path):
    from mocapdb.storage.ingest import delete_motions

    con = mocapdb.connect(tmp_path / "t.duckdb")
    try:
        ingest(con, [DATA / "hdm05_cut" / "rotateArmsBothBackward1Reps"])
        ids = [r[0] for r in con.execute("SELECT motion_id FROM motions ORDER BY motion_id").fetchall()]
        assert delete_motions(con, ids[:5]) == 5
        left = con.execute("SELECT DISTINCT motion_id FROM features ORDER BY 1").fetchall()
        assert [r[0] for r in left] == ids[5:]
        # deleted files can be ingested again
        assert len(ingest(con, [DATA / "hdm05_cut" / "rotateArmsBothBackward1Reps"]).ingested) == 5
    finally:
        con.close()


def test_a_take_in_two_formats_is_named_by_its_file(archive):
    """hdm05_full holds the dg excerpt as .amc and as .c3d: both are stored, the
    stem names two motions, and a label file names either by its file name."""
    from mocapdb.errors import SchemaError
    from mocapdb.storage.motions import documents_by_name

    con = archive[0]
    stem = "HDM_dg_06-03_03_120"
    assert con.execute("SELECT count(*) FROM motions WHERE name = ?", [stem]).fetchall()[0][0] == 2
    with pytest.raises(SchemaError, match=r"name several motions .*name the file instead"):
        documents_by_name(con, [stem])
    docs = documents_by_name(con, [f"{stem}.amc", f"{stem}.c3d", "86_09"])
    assert sorted(docs.names) == sorted([f"{stem}.amc", f"{stem}.c3d", "86_09"])
    fmt = dict(con.execute("SELECT motion_id, format FROM motions").fetchall())
    assert {n: fmt[int(m)] for n, m in zip(docs.names, docs.motion_ids)} == {
        f"{stem}.amc": "amc", f"{stem}.c3d": "c3d", "86_09": "amc"}
