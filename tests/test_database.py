"""Storage: schema, ingest (idempotent, atomic per file), the feature view, Parquet round trip."""
import lzma
import math
import re
import shutil

import numpy as np
import pytest

import mocapdb
from mocapdb.features import FEATURE_NAMES, motion_features
from mocapdb import ingest
from mocapdb.readers import motion_files
from mocapdb.readers import read_motion

from conftest import DATA, SAMPLE_86_09, SAMPLE_86_ASF, SAMPLE_BVH, amc_frame_count, c3d_frame_count

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


@pytest.mark.slow
@pytest.mark.shared
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


@pytest.mark.shared
def test_stored_words_are_the_features_of_the_file(archive):
    con = archive[0]
    for name in ("86_09", "HDM_bd_kickLFront1Reps_001_120", "13_29", "85_02"):
        path, asf = con.execute("SELECT source_path, skeleton_path FROM motions WHERE name = ?", [name]).fetchall()[0]
        stored = con.execute("SELECT bits FROM features f JOIN motions m USING (motion_id) "
                             "WHERE m.name = ? ORDER BY frame", [name]).fetchnumpy()["bits"]
        np.testing.assert_array_equal(stored, motion_features(read_motion(path, asf=asf)))


@pytest.mark.shared
def test_reingest_is_a_noop(archive):
    con = archive[0]
    before = con.execute("SELECT count(*), sum(motion_id), (SELECT count(*) FROM features) FROM motions").fetchall()
    again = ingest(con, [DATA / "cmu" / "86", DATA / "hdm05_cut" / "squat1Reps"])
    assert not again.ingested and not again.failed
    assert len(again.skipped) == 41 and all("already ingested" in r for _, r in again.skipped)
    assert con.execute("SELECT count(*), sum(motion_id), (SELECT count(*) FROM features) FROM motions"
                       ).fetchall() == before


@pytest.mark.shared
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


@pytest.mark.shared
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
    with mocapdb.connect(tmp_path / "fresh.duckdb") as fresh:
        report = import_features(fresh, tmp_path / "export")
        assert len(report.imported) == n and not report.failed
        again = import_features(fresh, tmp_path / "export")  # idempotent
        assert again.imported == {} and len(again.skipped) == n
        a = con.execute("SELECT m.sha256, f.frame, f.bits FROM features f JOIN motions m USING (motion_id) "
                        "ORDER BY ALL").fetchall()
        b = fresh.execute("SELECT m.sha256, f.frame, f.bits FROM features f JOIN motions m USING (motion_id) "
                          "ORDER BY ALL").fetchall()
        assert a == b


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


@pytest.mark.shared
def test_failed_files_change_nothing_and_others_go_in(tmp_path, open_db):
    d, good = _broken_copies(tmp_path)
    con = open_db(tmp_path / "t.duckdb")
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


@pytest.mark.shared
def test_delete_removes_everything_of_a_motion(tmp_path, open_db):
    from mocapdb.storage.ingest import delete_motions

    con = open_db(tmp_path / "t.duckdb")
    ingest(con, [DATA / "hdm05_cut" / "rotateArmsBothBackward1Reps"])
    ids = [r[0] for r in con.execute("SELECT motion_id FROM motions ORDER BY motion_id").fetchall()]
    assert delete_motions(con, ids[:5]) == 5
    left = con.execute("SELECT DISTINCT motion_id FROM features ORDER BY 1").fetchall()
    assert [r[0] for r in left] == ids[5:]
    # deleted files can be ingested again
    assert len(ingest(con, [DATA / "hdm05_cut" / "rotateArmsBothBackward1Reps"]).ingested) == 5


@pytest.mark.shared
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


def test_a_second_connect_in_one_process_and_cursors_have_the_functions(tmp_path):
    """A notebook cell run twice opens the file again while the first connection lives; each
    connection and each cursor has the SQL functions, also after the first one is gone."""
    import gc

    path = tmp_path / "twice.duckdb"
    first = mocapdb.connect(path)
    ingest(first, [SAMPLE_86_09])
    want = first.sql("SELECT annotate(1)").fetchall()
    again = mocapdb.connect(path)
    assert again.sql("SELECT annotate(1)").fetchall() == want
    cur = first.cursor()
    assert cur.sql("SELECT annotate(1)").fetchall() == want
    assert cur.execute("SELECT count(*) FROM keyframe_search('kickLFront1Reps')").fetchall()[0][0] >= 0
    first.close()
    del first, cur
    gc.collect()  # DuckDB dropped the first connection's Python functions: ours live on
    assert again.sql("SELECT annotate(1)").fetchall() == want
    with again.cursor() as c2:
        assert c2.sql("SELECT len(mt_distance(1, 'squat1Reps'))").fetchall() == [(1199,)]
    again.close()
    # all closed: a new instance registers afresh, read-only too
    with mocapdb.connect(path, read_only=True) as ro:
        assert ro.sql("SELECT annotate(1)").fetchall() == want
        assert isinstance(ro.duckdb, __import__("duckdb").DuckDBPyConnection)


def test_plain_duckdb_is_told_how_to_get_the_functions(tmp_path):
    import duckdb

    path = tmp_path / "plain.duckdb"
    mocapdb.connect(path).close()
    with duckdb.connect(str(path)) as con:
        # annotate is native now (LOAD the extension): no persisted stand-in answers in its place
        with pytest.raises(duckdb.Error, match="annotate"):
            con.sql("SELECT annotate(1)").fetchall()
        comments = dict(con.execute("SELECT table_name, comment FROM duckdb_tables() "
                                    "WHERE schema_name = 'main'").fetchall())
        assert {"motions", "features", "annotations", "models"} <= set(comments)
        assert all("mocapdb" in c for c in comments.values())
        assert "mocapdb.connect()" in comments["motions"]
        macros = dict(con.execute("SELECT function_name, comment FROM duckdb_functions() "
                                  "WHERE database_name = 'plain' AND comment IS NOT NULL").fetchall())
        # annotate, mt_distance, keyframe_search and keyframe_search_words are native (LOAD the
        # extension: tests/test_native_extension.py); no stand-in hides them
        assert not set(macros) & {"annotate", "mt_distance", "keyframe_search", "keyframe_search_words"}


@pytest.mark.shared
def test_an_archive_with_names_no_ingest_gives_is_refused(archive, tmp_path):
    """import-features checks motion names: ../x, absolute paths, control characters are refused, naming them."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from mocapdb.errors import SchemaError
    from mocapdb.storage.parquet import export_features, import_features

    con = archive[0]
    export_features(con, tmp_path / "export")
    table = pq.read_table(tmp_path / "export" / "motions.parquet")
    names = table.column("name").to_pylist()
    names[0], names[1], names[2] = "../../ESCAPED", "/tmp/ABSOLUTE", "a\nb"
    pq.write_table(table.set_column(table.schema.get_field_index("name"), "name", pa.array(names)),
                   tmp_path / "export" / "motions.parquet")
    # the names checked on their own: without digests.json (an older export), which would refuse the change
    # itself (tests/test_digests.py)
    (tmp_path / "export" / "digests.json").unlink()
    with mocapdb.connect(tmp_path / "fresh.duckdb") as fresh:
        with pytest.raises(SchemaError, match=r"3 motion name\(s\).*'\.\./\.\./ESCAPED': holds a path separator"
                                              r".*'a\\nb': holds control characters"):
            import_features(fresh, tmp_path / "export")
        assert fresh.execute("SELECT count(*) FROM motions").fetchall() == [(0,)]


@pytest.mark.shared
def test_delete_asks_which_when_a_name_names_several(archive, tmp_path, open_db):
    """hdm05_full holds one take as .amc and .c3d: delete NAME names both, so it needs an id or --all-named."""
    from mocapdb.errors import ParameterError

    con = open_db(tmp_path / "d.duckdb")
    ingest(con, [DATA / "hdm05_full" / "HDM_dg_06-03_03_120.amc", DATA / "hdm05_full" / "HDM_dg_06-03_03_120.c3d",
                 DATA / "hdm05_full" / "HDM_dg.asf"])
    with pytest.raises(ParameterError, match=r"names 2 motions: 1 \(amc, .*\); 2 \(c3d, .*all_named=True"):
        mocapdb.delete(con, ["HDM_dg_06-03_03_120"])
    assert con.execute("SELECT count(*) FROM motions").fetchall() == [(2,)]
    report = mocapdb.delete(con, ["2"])
    assert [r[:3] for r in report.deleted] == [(2, "HDM_dg_06-03_03_120", "c3d")] and report.absent == []
    assert mocapdb.delete(con, ["2"]).absent == ["2"]  # again: nothing there, no error
    ingest(con, [DATA / "hdm05_full" / "HDM_dg_06-03_03_120.c3d"])
    report = mocapdb.delete(con, ["HDM_dg_06-03_03_120"], all_named=True)
    assert sorted(r[2] for r in report.deleted) == ["amc", "c3d"]


def test_replace_reads_a_stored_file_again(tmp_path, open_db):
    """A file re-ingested with replace=True (a corrected joint map) replaces its motion; without, it is skipped."""
    from mocapdb.api import joint_map_template

    bvh = SAMPLE_BVH
    joint_map = tmp_path / "map.toml"
    joint_map.write_text(joint_map_template(bvh), encoding="utf-8")
    con = open_db(tmp_path / "r.duckdb")
    first = ingest(con, [bvh])
    assert len(first.ingested) == 1, first.failed
    old = first.ingested[0][1]
    mocapdb.annotate(con)
    skipped = ingest(con, [bvh], joint_map=joint_map)
    assert skipped.skipped and "replace" in skipped.skipped[0][1]
    again = ingest(con, [bvh], joint_map=joint_map, replace=True)
    assert again.replaced == [(str(bvh), old)] and len(again.ingested) == 1
    assert "joint_map" in con.execute("SELECT reader_options FROM motions").fetchall()[0][0]
    rows = con.execute("SELECT motion_id FROM motions").fetchall()
    assert rows == [(again.ingested[0][1],)] and rows[0][0] != old
    assert con.execute("SELECT count(*) FROM annotations WHERE motion_id = ?", [old]).fetchall() == [(0,)]
    n = con.execute("SELECT n_frames FROM motions").fetchall()[0][0]
    assert con.execute("SELECT count(*), min(frame), max(frame) FROM features").fetchall() == [(n, 1, n)]


def test_paths_are_stored_as_given_and_relocate_repoints_them(tmp_path, open_db):
    """Source paths are stored absolute but not symlink-resolved; after the files move,
    relocate repoints the motions whose bytes are at the new place, and view works again."""
    real = tmp_path / "real"
    real.mkdir()
    shutil.copy(SAMPLE_86_ASF, real / "86.asf")
    (real / "86_09.amc").write_bytes(lzma.decompress(SAMPLE_86_09.read_bytes()))
    link = tmp_path / "link"
    link.symlink_to(real, target_is_directory=True)
    con = open_db(tmp_path / "m.duckdb")
    ingest(con, [link / "86_09.amc"])
    src, skel = con.execute("SELECT source_path, skeleton_path FROM motions").fetchall()[0]
    assert (src, skel) == (str(link / "86_09.amc"), str(link / "86.asf"))
    moved = tmp_path / "moved"
    real.rename(moved)
    with pytest.raises(mocapdb.SchemaError, match=r"is gone.*mocapdb relocate"):
        mocapdb.view(con, "86_09", out=tmp_path / "p.html")
    wrong = tmp_path / "wrong"
    wrong.mkdir()
    (wrong / "86_09.amc").write_bytes(b"not the take")
    shutil.copy(moved / "86.asf", wrong / "86.asf")
    done, refused = mocapdb.api.relocate(con, link, wrong)
    assert done == [] and refused and "other bytes" in refused[0][2]
    done, refused = mocapdb.api.relocate(con, str(link) + "/", moved)
    assert refused == [] and done == [(1, str(link / "86_09.amc"), str(moved / "86_09.amc"))]
    assert con.execute("SELECT skeleton_path FROM motions").fetchall() == [(str(moved / "86.asf"),)]
    mocapdb.view(con, "86_09", out=tmp_path / "p.html")
    assert (tmp_path / "p.html").stat().st_size > 10_000
