"""Nothing lost, nothing let in silently: partial archives, killed exports, truncated parts,
overwritten exports (issue 22 items 2, 5 and 6).

An import checks every motion of an archive to be exactly its frames
1 … n_frames: a motion with missing, partial or unreadable features is
refused and named, the others go in, and importing the repaired archive adds
the rest. An export marks its end by writing motions.parquet last. The
killed ray-annotate and the in-place views are tested with Ray (test_ray.py).
"""
import os
import random
import shutil
import signal
import subprocess
import sys
import time

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import mocapdb
from mocapdb import api
from mocapdb.errors import ParameterError
from mocapdb.storage.ingest import store_words
from mocapdb.storage.parquet import export_features, features_sql, import_features

from conftest import DATA, REPO, run

pytestmark = pytest.mark.shared


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """The 232 clips of hdm05_cut in a database, and their export."""
    d = tmp_path_factory.mktemp("partial")
    con = mocapdb.connect(d / "source.duckdb")
    assert not mocapdb.ingest(con, [DATA / "hdm05_cut"]).failed
    export_features(con, d / "export")
    con.close()
    return d / "source.duckdb", d / "export"


@pytest.fixture
def db_copy(source, tmp_path):
    """A copy of the source database, to change."""
    copy = tmp_path / "copy.duckdb"
    shutil.copy(source[0], copy)
    return copy


def check_invariants(con):
    """Every motion is its frames 1 … n_frames and is in the keyframe index; nothing dangles."""
    bad = con.execute("""
        SELECT count(*) FROM motions m LEFT JOIN (
            SELECT motion_id, count(*) AS n, min(frame) AS lo, max(frame) AS hi, count(DISTINCT frame) AS d
            FROM features GROUP BY motion_id) f USING (motion_id)
        WHERE NOT (coalesce(f.n, 0) = m.n_frames AND f.d = f.n AND f.lo = 1 AND f.hi = m.n_frames)""").fetchall()
    assert bad == [(0,)]
    assert con.execute("SELECT count(*) FROM motions WHERE motion_id NOT IN "
                       "(SELECT motion_id FROM mocap_index.postings)").fetchall() == [(0,)]
    for table in ("features", "mocap_index.postings", "annotations"):
        assert con.execute(f"SELECT count(*) FROM {table} WHERE motion_id NOT IN "
                           "(SELECT motion_id FROM motions)").fetchall() == [(0,)], table


@pytest.mark.slow
def test_missing_feature_folders_are_refused_by_name_and_the_repair_goes_in(source, tmp_path, open_db):
    _, export = source
    partial = tmp_path / "partial"
    shutil.copytree(export, partial)
    folders = sorted((partial / "features").iterdir())
    gone = random.Random(22).sample(folders, 133)
    for f in gone:
        shutil.rmtree(f)
    names = {r["motion_id"]: r["name"] for r in
             pq.read_table(export / "motions.parquet", columns=["motion_id", "name"]).to_pylist()}
    gone_names = {names[int(f.name.split("=")[1])] for f in gone}
    db = tmp_path / "db.duckdb"
    r = run(db, "import-features", partial, code=1)
    assert "99 motion(s) imported, 0 already present, 133 refused" in r.output
    assert all(f"({n}) has 0 feature rows for its" in r.output for n in gone_names)
    con = open_db(db)
    check_invariants(con)
    assert {n for (n,) in con.execute("SELECT name FROM motions").fetchall()} == set(names.values()) - gone_names
    report = import_features(con, export)  # the whole export: the refused motions go in now
    assert len(report.imported) == 133 and len(report.skipped) == 99 and not report.failed
    check_invariants(con)
    assert con.execute("SELECT count(*) FROM motions").fetchall() == [(232,)]


def test_partly_imported_motions_of_an_older_mocapdb_are_repaired(source, db_copy, open_db):
    """A database holding motions without all their features (what importing a partial archive left
    before): importing the archive again, or ingesting the files again, replaces them."""
    export = source[1]
    con = open_db(db_copy)
    con.execute("DELETE FROM features WHERE motion_id IN (3, 4) AND frame > 10")
    con.execute("DELETE FROM features WHERE motion_id = 5")
    report = import_features(con, export)
    assert len(report.repaired) == 3 and len(report.imported) == 3 and len(report.skipped) == 229
    assert "has 10 feature rows" in report.repaired[0][1]
    check_invariants(con)
    assert con.execute("SELECT count(*) FROM motions").fetchall() == [(232,)]
    assert con.execute("SELECT count(*) FROM (SELECT unnest(annotate(motion_id)) FROM motions)").fetchall()[0][0]


@pytest.mark.slow
def test_a_killed_export_is_refused_never_imported_in_part(source, tmp_path):
    """SIGKILL of `mocapdb export-features` at random points: the folder is either a finished export
    (imports whole) or refused as unfinished; never a silent partial import."""
    db, _ = source
    rng = random.Random(5)
    outcomes = []
    for trial in range(8):
        out = tmp_path / f"killed{trial}"
        env = dict(os.environ, PYTHONPATH=str(REPO))
        p = subprocess.Popen([sys.executable, "-P", "-m", "mocapdb.cli", "--db", str(db), "export-features", str(out)],
                             env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 120
            while not (out / "features").exists() and p.poll() is None and time.monotonic() < deadline:
                time.sleep(0.002)
            time.sleep(rng.uniform(0, 0.15))
        finally:
            p.send_signal(signal.SIGKILL)
            p.wait()
        with mocapdb.connect(tmp_path / f"import{trial}.duckdb") as fresh:
            if (out / "motions.parquet").exists():
                report = import_features(fresh, out)
                assert len(report.imported) == 232 and not report.failed
                outcomes.append("finished")
            else:
                with pytest.raises(ParameterError, match="the export did not finish"):
                    import_features(fresh, out)
                assert fresh.execute("SELECT count(*) FROM motions").fetchall() == [(0,)]
                outcomes.append("refused")
            check_invariants(fresh)
        if "refused" in outcomes and trial >= 2:
            break
    assert "refused" in outcomes, outcomes  # a kill did land inside an export


@pytest.mark.slow
def test_a_killed_import_leaves_whole_motions_and_importing_again_finishes(source, tmp_path):
    """SIGKILL of `mocapdb import-features` at random points: the database holds whole motions (features,
    postings) or none of an unfinished batch, and importing again adds exactly the rest."""
    _, export = source
    rng = random.Random(7)
    for trial in range(3):
        db = tmp_path / f"killed{trial}.duckdb"
        mocapdb.connect(db).close()  # the schema first: the kill lands in the import itself
        env = dict(os.environ, PYTHONPATH=str(REPO))
        p = subprocess.Popen([sys.executable, "-P", "-m", "mocapdb.cli", "--db", str(db), "import-features",
                              str(export)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            time.sleep(rng.uniform(1.0, 6.0))
        finally:
            p.send_signal(signal.SIGKILL)
            p.wait()
        with mocapdb.connect(db) as con:
            check_invariants(con)
            before = con.execute("SELECT count(*) FROM motions").fetchall()[0][0]
            report = import_features(con, export)
            assert len(report.imported) == 232 - before and len(report.skipped) == before and not report.failed
            check_invariants(con)


def test_a_truncated_part_names_its_cause_and_costs_only_its_motion(source, tmp_path):
    _, export = source
    broken = tmp_path / "broken"
    shutil.copytree(export, broken)
    victim = sorted((broken / "features").glob("motion_id=7/*.parquet"))[0]
    victim.write_bytes(victim.read_bytes()[:100])
    db = tmp_path / "db.duckdb"
    r = run(db, "import-features", broken, code=1)
    assert "No magic bytes found" in r.output and str(victim) in r.output
    assert "TransactionContext" not in r.output and "transaction is aborted" not in r.output
    assert "231 motion(s) imported, 0 already present, 1 refused" in r.output


def test_a_failed_write_reports_its_own_error_not_the_aborted_transaction(source, tmp_path, open_db):
    """registered() inside a transaction that the failure aborted: the real cause comes out, and the
    database and the connection are as before."""
    import duckdb

    from mocapdb.storage.transaction import registered, transaction

    _, export = source
    truncated = tmp_path / "part.parquet"
    truncated.write_bytes(sorted((export / "features").glob("motion_id=1/*.parquet"))[0].read_bytes()[:100])
    con = open_db(tmp_path / "w.duckdb")
    with pytest.raises(duckdb.Error, match="No magic bytes found") as e:
        with transaction(con):
            with registered(con, mocap_new_rows=pa.table({"a": [1]})):
                con.execute("INSERT INTO features SELECT 1, frame, bits FROM read_parquet($f)", {"f": str(truncated)})
    assert "aborted" not in str(e.value)
    # a write path of the library: a motion without a name breaks a NOT NULL constraint
    words = pa.array([1, 2, 3], pa.uint64()).to_numpy()
    with pytest.raises(duckdb.Error, match="NOT NULL constraint failed: motions.*name") as e:
        store_words(con, {None: words})
    assert "aborted" not in str(e.value)
    assert con.execute("SELECT count(*) FROM motions").fetchall() == [(0,)]
    store_words(con, {"a": words})  # the connection is usable again
    assert con.execute("SELECT count(*) FROM features").fetchall() == [(3,)]


@pytest.mark.slow
def test_export_overwrite_leaves_no_stale_partition(db_copy, tmp_path, open_db):
    out = tmp_path / "export"
    con = open_db(db_copy)
    assert export_features(con, out) == 232
    (out / "notes.txt").write_text("mine")
    api.delete(con, list(range(1, 101)))
    assert export_features(con, out, overwrite=True) == 132
    ids = {int(f.name.split("=")[1]) for f in (out / "features").iterdir()}
    in_place = con.execute(f"SELECT count(DISTINCT motion_id), count(*) FROM ({features_sql(out)})").fetchall()
    assert ids == {i for (i,) in con.execute("SELECT motion_id FROM motions").fetchall()}
    assert in_place == con.execute("SELECT count(DISTINCT motion_id), count(*) FROM features").fetchall()
    assert (out / "notes.txt").read_text() == "mine"  # nothing else in the folder is touched
