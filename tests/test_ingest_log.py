"""The log of every ingest and import: the table ingest_log and `ingest --report FILE` (issue 26 item 4).

On the recordings shipped with mocapdb (they run in a bare clone): every file gets a row with its
outcome, reason, the reader's notes and the motion stored; a zip member is named by its archive and
member; a re-ingest logs the skips; a failed ingest that leaves the database as it was still leaves
its rows (the row of a stored file commits with its motion: a batch rolled back takes its rows
along); `--report` writes the same rows as CSV; an older database gains the table when opened;
import-features logs every motion under its source file. The real folders ../shared/data/foreign
and foreign2 are in test_foreign2.py, a ray-annotate archive's import in test_ray.py.
"""
import csv
import json
import lzma
import zipfile

import duckdb
import ezc3d
import numpy as np
import pytest

import mocapdb
import mocapdb.storage.ingest as storage_ingest
from mocapdb.api import export_features, import_features
from mocapdb.errors import ParameterError

from conftest import SAMPLE, SAMPLE_86_09, SAMPLE_BVH, SAMPLE_C3D, run

COLUMNS = ["path", "member", "outcome", "reason", "notes", "motion_id", "logged_at", "run_id", "command"]


def log_rows(con, run_id=None):
    sql = "SELECT path, member, outcome, reason, notes, motion_id FROM ingest_log"
    if run_id is not None:
        return con.execute(sql + " WHERE run_id = ? ORDER BY path, member", [run_id]).fetchall()
    return con.execute(sql + " ORDER BY run_id, path, member").fetchall()


def state(con):
    """What an ingest may change, besides the log."""
    return [con.execute(f"SELECT count(*) FROM {t}").fetchall()[0][0]
            for t in ("motions", "features", "mocap_index.postings", "annotations")]


@pytest.mark.slow
def test_every_file_of_an_ingest_gets_its_row(tmp_path, open_db):
    con = open_db(tmp_path / "a.duckdb")
    report = mocapdb.ingest(con, [SAMPLE])
    stored = dict(con.execute("SELECT source_path, motion_id FROM motions").fetchall())
    rows = log_rows(con, report.run_id)
    assert {r[0]: r[2] for r in rows} == {str(SAMPLE / "86.asf"): "not a motion file",
                                          str(SAMPLE / "CREDITS.txt"): "not a motion file",
                                          str(SAMPLE_C3D): "ingested", str(SAMPLE_86_09): "ingested",
                                          str(SAMPLE_BVH): "ingested"} and len(rows) == 5
    for path, member, outcome, reason, notes, mid in rows:
        assert member is None
        if outcome == "ingested":
            assert mid == stored[path] and reason is None
        else:
            assert mid is None and reason.startswith(("an ASF skeleton", "unsupported file type '.txt'"))
    # the sample's readers had nothing to say but the BVH's unit (issue 33 item 1)
    assert {r[0]: r[4] for r in rows if r[4] is not None} == {
        str(SAMPLE_BVH): "unit inch: the only unit giving the legs an adult's length (0.82 m)"}
    # again: every motion file is skipped, with why
    again = mocapdb.ingest(con, [SAMPLE])
    assert again.run_id == report.run_id + 1
    skipped = [r for r in log_rows(con, again.run_id) if r[2] == "skipped"]
    assert [(r[0], r[3]) for r in skipped] == [
        (path, f"already ingested as motion {stored[path]} (replace=True, ingest --replace, reads it again)")
        for path in sorted((str(SAMPLE_C3D), str(SAMPLE_86_09), str(SAMPLE_BVH)))]
    # and with replace=True the row says which motion it replaced
    replaced = mocapdb.ingest(con, [SAMPLE_BVH], replace=True)
    (path, _, outcome, reason, _, mid), = log_rows(con, replaced.run_id)
    assert (outcome, reason) == ("ingested", f"replaces motion {stored[path]} (replace=True: read again)")
    assert mid == con.execute("SELECT motion_id FROM motions WHERE source_path = ?", [path]).fetchall()[0][0]


def test_the_notes_are_the_readers(tmp_path, open_db):
    """A C3D marker lost for 0.1 s: the reader's notes, one a line, as the report and the motion have them."""
    c = ezc3d.c3d(str(plain_sample(tmp_path)))
    labels = [lab.split(":")[-1] for lab in c["parameters"]["POINT"]["LABELS"]["value"]]
    pts = c["data"]["points"]
    pts[:3, labels.index("LELB"), 100:112] = np.nan
    c["data"]["points"] = pts
    c.write(str(tmp_path / "gap.c3d"))
    con = open_db()
    report = mocapdb.ingest(con, [tmp_path / "gap.c3d"])
    (_, _, outcome, _, notes, mid), = log_rows(con, report.run_id)
    stored = json.loads(con.execute("SELECT reader_options FROM motions WHERE motion_id = ?", [mid]).fetchall()[0][0])
    assert notes.split("\n") == [n for _, n in report.notes] == stored["notes"]
    assert notes.startswith("interpolated 12 missing marker samples")


def plain_sample(tmp_path):
    plain = tmp_path / "HDM_mm_01-02_03_120.c3d"
    plain.write_bytes(lzma.decompress(SAMPLE_C3D.read_bytes()))
    return plain


def test_a_zip_member_is_named_by_its_archive_and_member(tmp_path, open_db):
    archive = tmp_path / "takes.zip"
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr("walk/walk.bvh", lzma.decompress(SAMPLE_BVH.read_bytes()))
        z.writestr("walk/readme.txt", "not a take")
        z.writestr("../beside.bvh", "never read")   # names that would leave the archive: as they are
        z.writestr("/abs/olute.bvh", "never read")
    con = open_db()
    mocapdb.ingest(con, [archive])
    assert [r[:3] for r in log_rows(con)] == [(str(archive), "../beside.bvh", "failed"),
                                              (str(archive), "/abs/olute.bvh", "failed"),
                                              (str(archive), "walk/readme.txt", "not a motion file"),
                                              (str(archive), "walk/walk.bvh", "ingested")]
    # the motion's source path runs through the archive: path / member
    assert con.execute("SELECT m.source_path = l.path || '/' || l.member FROM ingest_log l JOIN motions m "
                       "USING (motion_id)").fetchall() == [(True,)]


@pytest.mark.slow
def test_a_failed_ingest_leaves_the_database_as_it_was_and_its_log(tmp_path, open_db, monkeypatch):
    """Every file fails: nothing but the log changes. A batch whose storing fails is rolled back with
    its rows (a motion and its row commit together), then retried file by file: the file that cannot
    be stored is logged as failed, the other one as ingested — never a row naming a motion that is
    not there."""
    con = open_db(tmp_path / "f.duckdb")
    mocapdb.ingest(con, [SAMPLE_86_09])
    before = state(con)
    broken = tmp_path / "broken.bvh"
    broken.write_text("HIERARCHY\nROOT Hips\n{\n")
    report = mocapdb.ingest(con, [broken])
    assert state(con) == before and report.failed
    (path, member, outcome, reason, notes, mid), = log_rows(con, report.run_id)
    assert (path, outcome, mid) == (str(broken), "failed", None) and reason == report.failed[0][1]
    # a path that is not there: the call fails, and says so in the log too
    with pytest.raises(ParameterError, match="does not exist"):
        mocapdb.ingest(con, [tmp_path / "nowhere.bvh"])
    assert log_rows(con)[-1][:3] == (str(tmp_path / "nowhere.bvh"), None, "failed")
    assert state(con) == before

    real = storage_ingest.insert_features

    def fails_for_the_c3d(con_, ids, words):
        real(con_, ids, words)
        if any(len(w) == 998 for w in words):   # the HDM05 document's 30 Hz frames
            raise duckdb.ConstraintException("no room for this one")
    monkeypatch.setattr(storage_ingest, "insert_features", fails_for_the_c3d)
    report = mocapdb.ingest(con, [SAMPLE_C3D, SAMPLE_BVH])
    rows = {r[0]: r for r in log_rows(con, report.run_id)}
    assert rows[str(SAMPLE_C3D)][2:4] == ("failed", f"{SAMPLE_C3D}: not stored (no room for this one)")
    assert rows[str(SAMPLE_BVH)][2] == "ingested" and rows[str(SAMPLE_BVH)][5] is not None
    assert con.execute("SELECT count(*) FROM ingest_log l WHERE motion_id IS NOT NULL AND NOT EXISTS "
                       "(SELECT 1 FROM motions m WHERE m.motion_id = l.motion_id)").fetchall() == [(0,)]
    assert state(con)[0] == before[0] + 1


@pytest.mark.slow
def test_report_writes_the_same_rows_as_csv(tmp_path, open_db):
    db, out = tmp_path / "r.duckdb", tmp_path / "report.csv"
    r = run(db, "ingest", "--sample", SAMPLE / "CREDITS.txt", "--silent", "--report", out, code=1)
    assert r.output.splitlines()[-1] == f"every file's outcome, reason and notes: ingest_log run 1, and {out}"
    with out.open(newline="", encoding="utf-8") as fh:
        got = list(csv.reader(fh))
    assert got[0] == COLUMNS
    con = open_db(db, read_only=True)
    rows = con.execute("SELECT * EXCLUDE (run_id, command, logged_at), logged_at, run_id, command FROM ingest_log "
                       "ORDER BY path, member").fetchall()
    assert len(got) - 1 == len(rows) == 4
    for line, row in zip(got[1:], rows):
        assert line == ["" if v is None else v.isoformat(sep=" ") if hasattr(v, "isoformat") else str(v)
                        for v in (row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7], row[8])]


def test_an_older_database_gains_the_log_when_opened(tmp_path):
    db = tmp_path / "old.duckdb"
    with mocapdb.connect(db) as con:
        mocapdb.ingest(con, [SAMPLE_86_09])
        con.execute("DROP TABLE ingest_log")
        con.execute("DROP SEQUENCE ingest_run_seq")
    with mocapdb.connect(db) as con:   # a read-write open creates what is missing
        report = mocapdb.ingest(con, [SAMPLE_BVH])
        assert report.run_id == 1 and [r[2] for r in log_rows(con)] == ["ingested"]
        assert con.execute("SELECT comment FROM duckdb_tables() WHERE table_name = 'ingest_log'"
                           ).fetchall()[0][0].startswith("mocapdb: one row per file an ingest")


def test_import_features_logs_every_motion_under_its_source(tmp_path, open_db):
    con = open_db(tmp_path / "a.duckdb")
    mocapdb.ingest(con, [SAMPLE])
    export_features(con, tmp_path / "export")
    into = open_db(tmp_path / "b.duckdb")
    report = import_features(into, tmp_path / "export")
    source = {path: (outcome, notes) for path, _, outcome, _, notes, _ in log_rows(con, 1) if outcome == "ingested"}
    rows = log_rows(into, report.run_id)
    assert {path: (outcome, notes) for path, _, outcome, _, notes, _ in rows} == source
    stored = dict(into.execute("SELECT source_path, motion_id FROM motions").fetchall())
    assert {r[0]: r[5] for r in rows} == stored
    assert all(r[3].startswith("imported archive motion ") and str(tmp_path / "export") in r[3] for r in rows)
    again = import_features(into, tmp_path / "export")
    assert {r[2] for r in log_rows(into, again.run_id)} == {"skipped"}
    with pytest.raises(ParameterError):
        import_features(into, tmp_path)   # not an archive: refused whole, and logged under the folder
    assert log_rows(into)[-1][:3] == (str(tmp_path), None, "failed")
