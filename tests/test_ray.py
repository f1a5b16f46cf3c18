"""The pipeline on a local Ray (the `ray` extra, which CI installs: without Ray this
module fails, it does not skip): the Parquet archive equals ingest + annotate on
the same files, broken files become rows of `errors`, a worker killed mid-run
changes nothing, and the archive is usable from SQL."""
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import duckdb
import pyarrow as pa
import pyarrow.compute  # noqa: F401 - pa.compute
import pyarrow.parquet as pq
import pytest
import ray  # noqa: F401  (the extra must be installed: an ImportError here fails the module)
from click.testing import CliRunner

import mocapdb
from mocapdb import api
from mocapdb.cli import main
from mocapdb.distributed import (DATASETS, ERRORS_SCHEMA, MissingExtraError, MotionWorker, expand_sources,
                                 ray_annotate, ray_session, require_ray)
from mocapdb.errors import ParameterError, SchemaError
from mocapdb.storage.model_store import load_model
from mocapdb.storage.parquet import table_schemas

from conftest import DATA, REPO, SAMPLE_86_09, run

#: Ray Data's own DataContext warns about its deprecated fields whenever it copies itself
pytestmark = [pytest.mark.filterwarnings("ignore::DeprecationWarning:ray.data.context"), pytest.mark.slow]

SOURCES = [DATA / "hdm05_cut", DATA / "cmu" / "02"]
#: small batches and buckets, so that batches cross bucket borders (100 is not a multiple of 16)
RUN = {"batch_files": 16, "bucket_motions": 100}


@pytest.fixture(scope="module")
def local_ray(tmp_path_factory):
    """One local Ray with 2 CPUs for the whole module, started as ray_annotate starts one.

    Ray puts the driver's working directory first on its workers' sys.path; the
    tests run from the checkout, whose ``mocapdb`` would then shadow the installed
    package under test. So Ray starts from an empty folder."""
    here = os.getcwd()
    os.chdir(tmp_path_factory.mktemp("ray_cwd"))
    try:
        session = ray_session(require_ray(), num_cpus=2)
        cpus = session.__enter__()
    finally:
        os.chdir(here)
    try:
        assert cpus == 2
        yield
    finally:
        session.__exit__(None, None, None)


@pytest.fixture(scope="module")
def single(tmp_path_factory):
    """The single-machine path on the same files: ingest, then annotate (stored)."""
    con = mocapdb.connect(tmp_path_factory.mktemp("single") / "single.duckdb")
    report = mocapdb.ingest(con, SOURCES)
    assert not report.failed
    mocapdb.annotate(con)
    yield con
    con.close()


@pytest.fixture(scope="module")
def archive(local_ray, tmp_path_factory):
    out = tmp_path_factory.mktemp("ray") / "archive"
    return out, ray_annotate(SOURCES, out, **RUN)


def _views(con, out, prefix):
    """Views ``<prefix>_<dataset>`` over an archive's Parquet, as plain DuckDB reads it."""
    for name in DATASETS:
        glob = f"{out}/{name}/*/*.parquet" if name in ("features", "postings", "annotations") else \
            f"{out}/{name}/*.parquet"
        con.execute(f"CREATE OR REPLACE TEMP VIEW {prefix}_{name} AS "
                    f"SELECT * FROM read_parquet('{glob}', hive_partitioning = true)")


#: rows by source file (motion ids differ between databases), without the timestamps
QUERIES = {
    "motions": "SELECT * EXCLUDE (motion_id, ingested_at) FROM {motions}",
    "features": "SELECT m.source_path, f.frame, f.bits FROM {features} f JOIN {motions} m USING (motion_id)",
    "postings": "SELECT m.source_path, p.* EXCLUDE (motion_id) FROM {postings} p JOIN {motions} m USING (motion_id)",
    "annotations": "SELECT m.source_path, a.* EXCLUDE (motion_id, annotated_at) "
                   "FROM {annotations} a JOIN {motions} m USING (motion_id)",
}
DB_TABLES = {"motions": "motions", "features": "features", "postings": "mocap_index.postings",
             "annotations": "annotations"}


def _rows(con, dataset, tables):
    rel = con.sql(QUERIES[dataset].format(**tables))
    keep = [f'"{c}"' for c in rel.columns if c != "motion_bucket"]  # the hive partition column
    return sorted(rel.project(", ".join(keep)).fetchall(), key=repr)


def _archive_rows(con, out, prefix, dataset):
    _views(con, out, prefix)
    return _rows(con, dataset, {k: f"{prefix}_{k}" for k in DB_TABLES})


@pytest.mark.shared
def test_the_archive_equals_ingest_and_annotate(single, archive):
    out, report = archive
    n = single.execute("SELECT count(*) FROM motions").fetchall()[0][0]
    assert len(report.ingested) == n == 241 and not report.failed and not report.skipped
    for dataset in DB_TABLES:
        want = _rows(single, dataset, DB_TABLES)
        got = _archive_rows(single, out, "r", dataset)
        assert len(got) == len(want) > 0, dataset
        assert got == want, f"{dataset}: the archive differs from ingest + annotate"
    # segment for segment: same motions, labels, frames and costs (default model, keyframes as stored)
    segs = single.execute("SELECT count(*), count(DISTINCT label) FROM annotations").fetchall()[0]
    assert report.segments == segs[0] > 200 and segs[1] > 5


@pytest.mark.shared
def test_motion_ids_follow_the_file_list_and_parts_their_buckets(archive):
    out, report = archive
    files = expand_sources(SOURCES)
    assert [(f, i) for f, i, _ in report.ingested] == [(str(f), k + 1) for k, f in enumerate(files)]
    schemas = {**table_schemas(), "errors": ERRORS_SCHEMA}
    for name in DATASETS:
        parts = sorted((out / name).rglob("*.parquet"))
        assert parts, name
        for part in parts:
            assert pq.read_schema(part).remove_metadata() == schemas[name], part
            if name in ("features", "postings", "annotations"):
                bucket = int(re.fullmatch(r"motion_bucket=(\d+)", part.parent.name).group(1))
                first, last = map(int, re.fullmatch(r"part-(\d+)-(\d+)\.parquet", part.name).groups())
                ids = pq.read_table(part).column("motion_id").to_pylist()
                assert all(bucket * 100 < i <= (bucket + 1) * 100 and first <= i <= last for i in ids), part
    assert sorted(p.name for p in (out / "features").iterdir()) == [f"motion_bucket={k}" for k in range(3)]
    assert not [p for p in out.rglob("*") if p.name.startswith(".")]  # no temporary files left


@pytest.mark.shared
def test_every_format_and_every_failure_as_ingest(local_ray, tmp_path, open_db):
    """Foreign recordings (BVH of other tools, an AMC of another lab): the same motions and
    rows as ingest + annotate, and the files ingest refuses are the errors, with its reasons."""
    sources = [DATA / "foreign"]
    con = open_db()
    report = mocapdb.ingest(con, sources)
    mocapdb.annotate(con)
    out = tmp_path / "archive"
    ray_report = ray_annotate(sources, out)
    assert len(ray_report.ingested) == len(report.ingested) > 0
    for dataset in DB_TABLES:
        assert _archive_rows(con, out, "f", dataset) == _rows(con, dataset, DB_TABLES), dataset
    errors = pq.read_table(out / "errors").to_pylist()
    assert sorted((e["file"], e["reason"]) for e in errors) == sorted(report.failed) == sorted(ray_report.failed)
    # its import logs what ingest logs: the motions under their files, with the readers' notes, and the
    # files ray-annotate could not read (issue 26 item 4)
    into = open_db()
    run_id = api.import_features(into, out).run_id
    log = "SELECT path, outcome, notes, reason FROM ingest_log WHERE run_id = ? AND outcome IN ('ingested', 'failed')"
    ingested = sorted(r[:3] for r in con.execute(log, [report.run_id]).fetchall())
    imported = into.execute(log, [run_id]).fetchall()
    assert sorted(r[:3] for r in imported) == ingested and len(ingested) == len(report.ingested) + len(report.failed)
    assert sorted(r[3] for r in imported if r[1] == "failed") == sorted(f"ray-annotate: {e['reason']}" for e in errors)


@pytest.mark.shared
def test_ingest_and_ray_annotate_read_a_c3d_with_marker_rules_alike(local_ray, tmp_path, open_db):
    """One ReaderOptions value from the CLI to the workers (issue 26 item 5): `--marker-rules
    anatomical` reaches ray-annotate's workers as it reaches ingest (it was lost on the way), so the
    HDM05 C3D reads alike — the same motions row, features and postings — and not as the toolbox reads
    it."""
    c3d = DATA / "hdm05_full" / "HDM_dg_06-03_03_120.c3d"
    db, out = tmp_path / "i.duckdb", tmp_path / "archive"
    run(db, "ingest", c3d, "--marker-rules", "anatomical", "--silent")
    r = CliRunner().invoke(main, ["ray-annotate", str(c3d), "--out", str(out), "--marker-rules", "anatomical"])
    assert r.exit_code == 0, r.output
    con = open_db(db, read_only=True)
    for dataset in ("motions", "features", "postings"):
        assert _archive_rows(con, out, "r", dataset) == _rows(con, dataset, DB_TABLES), dataset
    assert con.execute("SELECT reader_options FROM motions").fetchall()[0][0].startswith(
        '{"marker_rules": "anatomical"')
    toolbox = open_db()
    mocapdb.ingest(toolbox, [c3d])
    assert _rows(toolbox, "features", DB_TABLES) != _rows(con, "features", DB_TABLES)


def test_amass_files_with_a_body_model_as_ingest(local_ray, tmp_path, open_db):
    """AMASS-format takes (written from the shipped 86_09) beside an AMASS shape file, read with a
    body model folder (`--body-model`, one ReaderOptions field): the same motions and rows as ingest +
    annotate, so the option reaches the workers; the shape file is no motion in either."""
    from amass_files import make_body_model
    from mocapdb.readers import generic_rest, read_amc, read_asf
    from lab.amass_write import write_amass

    folder = tmp_path / "AMASS" / "CMU" / "86"
    folder.mkdir(parents=True)
    skel = read_asf(SAMPLE_86_09.parent / "86.asf")
    amc = read_amc(SAMPLE_86_09, skel)
    write_amass(folder / "86_09_poses.npz", skel, amc, gender="female")
    write_amass(folder / "86_09_x_poses.npz", skel, amc, family="smplx", gender="male")
    (folder / "shape.npz").write_bytes((folder / "86_09_poses.npz").read_bytes())
    models = tmp_path / "models"
    for family, file in (("smplh", "smplh/female/model.npz"), ("smplx", "smplx/SMPLX_MALE.npz")):
        make_body_model(models / file, generic_rest(), family=family)
    con = open_db()
    report = mocapdb.ingest(con, [tmp_path / "AMASS"], body_model=models)
    mocapdb.annotate(con)
    assert len(report.ingested) == 2 and not report.failed
    assert [u[0] for u in report.unsupported] == [str(folder / "shape.npz")]
    out = tmp_path / "archive"
    r = CliRunner().invoke(main, ["ray-annotate", str(tmp_path / "AMASS"), "--out", str(out), "--body-model",
                                  str(models)])
    assert r.exit_code == 0, r.output
    assert "(0 skipped, 0 failed, 1 not motion files)" in r.output   # the shape file
    for dataset in DB_TABLES:
        assert _archive_rows(con, out, "a", dataset) == _rows(con, dataset, DB_TABLES), dataset


def _broken_folder(tmp_path):
    """Real HDM05 files, a truncated copy of one (cut inside a frame) and a byte-identical copy."""
    d = tmp_path / "mixed"
    (d / "kick").mkdir(parents=True)
    shutil.copy(DATA / "hdm05_cut" / "HDM_bd.asf", d)
    good = sorted((DATA / "hdm05_cut" / "kickLFront1Reps").glob("HDM_bd_*.amc"))[:3]
    for p in good:
        shutil.copy(p, d / "kick")
    text = good[0].read_bytes()
    (d / "kick" / "HDM_bd_truncated_120.amc").write_bytes(text[: len(text) // 2 - 7])
    shutil.copy(good[1], d / "kick" / "HDM_bd_zcopy_120.amc")
    return d, good


@pytest.mark.shared
def test_broken_files_become_rows_of_errors_and_the_rest_goes_on(local_ray, tmp_path):
    d, good = _broken_folder(tmp_path)
    out = tmp_path / "archive"
    report = ray_annotate([d], out, batch_files=2)
    broken = str(d / "kick" / "HDM_bd_truncated_120.amc")
    errors = pq.read_table(out / "errors").to_pylist()
    assert [e["file"] for e in errors] == [broken] == [f for f, _ in report.failed]
    assert re.match(rf"{re.escape(broken)}:\d+", errors[0]["reason"]), errors[0]["reason"]
    # the good files are in, the byte-identical copy once (skipped, as ingest does)
    names = sorted(pq.read_table(out / "motions").column("name").to_pylist())
    assert names == sorted(p.stem for p in good)
    assert report.skipped == [(str(d / "kick" / "HDM_bd_zcopy_120.amc"),
                               f"same bytes as {d / 'kick' / good[1].name} of this run")]
    with duckdb.connect() as con:
        _views(con, out, "a")
        ids = con.execute("SELECT DISTINCT motion_id FROM a_features ORDER BY 1").fetchall()
        assert ids == con.execute("SELECT motion_id FROM a_motions ORDER BY 1").fetchall()
        assert len(ids) == 3
    # the same through the CLI: one line per failed file, the summary, exit 0 (some files went in)
    r = CliRunner().invoke(main, ["ray-annotate", str(d), "--out", str(out), "--overwrite", "--batch-files", "2"])
    assert r.exit_code == 0, r.output
    assert f"failed  {broken}:" in r.output and "3 motions" in r.output and "1 skipped, 1 failed" in r.output


@pytest.mark.shared
@pytest.mark.filterwarnings("ignore:Duplicate name:UserWarning")  # the member named twice, on purpose
def test_zip_members_ingest_refuses_are_failed_rows_and_hidden_ones_skipped(local_ray, tmp_path):
    """Issue 33: ray-annotate dropped the zip members ingest refuses (names leaving the archive, an earlier
    copy of a member named twice) and hidden files without a trace; they are now rows of the errors dataset
    (so import-features logs them in ingest_log) and skipped files, as ingest reports them."""
    import zipfile

    walk = (DATA / "foreign" / "bvh").glob("*.bvh")
    bvh = next(p for p in sorted(walk)).read_bytes()
    z = tmp_path / "takes.zip"
    with zipfile.ZipFile(z, "w") as zf:
        zf.writestr("good/walk.bvh", bvh)
        zf.writestr("../evil.bvh", bvh)
        zf.writestr("twice/a.bvh", b"HIERARCHY broken first copy")
        zf.writestr("twice/a.bvh", bvh)
        zf.writestr(".hidden.bvh", bvh)
    ingested = mocapdb.connect(tmp_path / "i.duckdb")
    want = mocapdb.ingest(ingested, [z])
    out = tmp_path / "archive"
    report = ray_annotate([z], out)
    refused = sorted(f for f, _ in want.failed)
    assert refused and sorted(f for f, _ in report.failed) == refused
    assert sorted(pq.read_table(out / "errors").column("file").to_pylist()) == refused
    # the hidden member, and the later copy of the member named twice (the same bytes as good/walk.bvh)
    assert sorted(f for f, _ in report.skipped) == sorted(f for f, _ in want.skipped)
    assert any(f.endswith("/.hidden.bvh") for f, _ in report.skipped)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["failed"] == len(refused)
    # imported, the archive's refusals are in ingest_log as ingest's own are: under the zip, by member
    db = tmp_path / "imported.duckdb"
    run(db, "import-features", out, code=None)
    query = "SELECT path, member FROM ingest_log WHERE outcome = 'failed' ORDER BY ALL"
    with mocapdb.connect(db, read_only=True) as con:
        logged = con.execute(query).fetchall()
    assert logged and logged == ingested.execute(query).fetchall()


def _dies_once(victim: str, marker: Path):
    """A MotionWorker that kills its own process once, after writing the features and
    postings parts of the batch holding ``victim`` (the marker file says it did)."""

    class DiesOnce(MotionWorker):
        def __call__(self, batch):
            self.paths = batch.column("path").to_pylist()
            return super().__call__(batch)

        def write_part(self, relative, table):
            super().write_part(relative, table)
            if relative.startswith("postings/") and victim in self.paths and not marker.exists():
                marker.write_text(str(os.getpid()))
                os._exit(1)

    return DiesOnce


@pytest.mark.shared
def test_a_worker_killed_mid_run_changes_nothing(local_ray, archive, single, tmp_path):
    out, clean = archive
    files = expand_sources(SOURCES)
    victim = str(files[len(files) // 2])
    marker = tmp_path / "died"
    killed = tmp_path / "archive"
    report = ray_annotate(SOURCES, killed, worker=_dies_once(victim, marker), **RUN)
    assert marker.exists()  # a worker did die, after writing part of its batch
    assert report.ingested == clean.ingested and report.segments == clean.segments
    for dataset in DB_TABLES:
        assert _archive_rows(single, killed, "k", dataset) == _archive_rows(single, out, "c", dataset), dataset
    # no duplicates: one row per motion and per (motion, frame); every part once
    assert single.execute("SELECT count(*) = count(DISTINCT motion_id) FROM k_motions").fetchall()[0][0]
    assert single.execute("SELECT count(*) = count(DISTINCT (motion_id, frame)) FROM k_features").fetchall()[0][0]
    assert sorted(p.relative_to(killed) for p in killed.rglob("*") if p.is_file()) == \
        sorted(p.relative_to(out) for p in out.rglob("*") if p.is_file())


@pytest.mark.shared
def test_the_archive_imports_into_a_database_that_answers_sql(archive, single, tmp_path):
    out, report = archive
    with api.connect(tmp_path / "imported.duckdb") as con:
        assert len(api.import_features(con, out).imported) == len(report.ingested)
        by_file = ("SELECT m.source_path, s.label, s.start_frame, s.end_frame, s.cost FROM motions m, "
                   "LATERAL (SELECT unnest(annotate(m.motion_id), recursive := true)) s")
        sql = sorted(con.execute(by_file).fetchall())
        assert sql == sorted(single.execute(by_file).fetchall()) and len(sql) == report.segments
        # the Ray annotations came along into the annotations table
        assert _rows(con, "annotations", DB_TABLES) == _rows(single, "annotations", DB_TABLES)
        for c in (c.name for c in load_model(con).classes if c.keyframe_query is not None):
            q = (f"SELECT m.source_path, k.start_frame, k.end_frame FROM keyframe_search('{c}') k "
                 "JOIN motions m USING (motion_id)")
            assert sorted(con.execute(q).fetchall()) == sorted(single.execute(q).fetchall()), c
        assert api.import_features(con, out).imported == {}  # the same motions again: nothing new


@pytest.mark.shared
def test_the_archive_is_queryable_in_place(archive, single, tmp_path):
    """`mocapdb attach DIR`: motions, features, annotations and the index are views of the archive's
    Parquet; the SQL functions answer as in a database that holds the same motions (issue 20 item 3)."""
    out, report = archive
    db = tmp_path / "views.duckdb"
    r = run(db, "attach", out)
    assert f"{len(report.ingested)} motion(s)" in r.output, r.output
    with api.connect(db) as con:
        assert con.execute("SELECT table_type FROM information_schema.tables WHERE table_name = 'features'"
                           ).fetchall() == [("VIEW",)]
        for dataset in DB_TABLES:
            assert _rows(con, dataset, DB_TABLES) == _rows(single, dataset, DB_TABLES), dataset
        by_file = ("SELECT m.source_path, s.label, s.start_frame, s.end_frame, s.cost FROM motions m, "
                   "LATERAL (SELECT unnest(annotate(m.motion_id{}), recursive := true)) s")
        for options in ("", ", keyframes := false", ", model := 'toolbox'"):
            q = by_file.format(options)
            assert sorted(con.execute(q).fetchall()) == sorted(single.execute(q).fetchall()), options
        for c in ("kickLFront1Reps", "throwBasketball", "lieDownFloor"):
            q = (f"SELECT m.source_path, k.start_frame, k.end_frame FROM keyframe_search('{c}') k "
                 "JOIN motions m USING (motion_id)")
            assert sorted(con.execute(q).fetchall()) == sorted(single.execute(q).fetchall()) != [], c
        q = ("SELECT m.source_path, mt_distance(m.motion_id, 'squat1Reps') FROM motions m "
             "WHERE m.name LIKE '%squat%' ORDER BY 1")
        assert con.execute(q).fetchall() == single.execute(q).fetchall()
        # reading commands work; writing ones say why not
        assert api.annotate(con, store=False).num_rows == report.segments
        with pytest.raises(SchemaError, match="attached to the archive .* read-only views"):
            api.ingest(con, [DATA / "cmu" / "86" / "86_09.amc"])
        with pytest.raises(SchemaError, match="attached to the archive"):
            api.annotate(con)
    r = run(db, "annotate", "--no-store", "--format", "csv")
    assert len(r.output.splitlines()) == report.segments + 1
    # a database with motions of its own is not attached
    with pytest.raises(ParameterError, match="holds .* rows of its own"):
        api.attach(single, out)


def _tampered(out, tmp_path, name):
    """A copy of the archive to tamper with, its parts by dataset."""
    copy = tmp_path / name
    shutil.copytree(out, copy)
    parts = {ds: sorted(p for p in (copy / ds).rglob("*.parquet")) for ds in DATASETS}
    return copy, parts


def _refusals(archive, db):
    """What attach and import-features say of an archive (each must refuse), through the CLI."""
    said = []
    for args in (["attach", archive], ["import-features", archive]):
        r = run(db, *args, code=1)
        assert len(r.output.strip().splitlines()) == 1 and "internal error" not in r.output, r.output
        said.append(r.output.strip())
    return said


@pytest.mark.shared
def test_a_tampered_archive_is_refused_naming_what_is_missing_or_extra(archive, tmp_path):
    """Issue 27 item 4: every part is checked against the manifest (which lists them with their rows)."""
    out, report = archive
    manifest = json.loads((out / "manifest.json").read_text())
    assert sum(n for rel, n in manifest["parts"].items() if rel.startswith("annotations/")) == report.segments
    db = tmp_path / "t.duckdb"
    # motions/ emptied: was "internal error (ArrowInvalid …)"
    a, parts = _tampered(out, tmp_path, "no_motions")
    for f in parts["motions"]:
        f.unlink()
    for said in _refusals(a, db):
        assert "does not match its manifest.json: motions/part-" in said and ") is missing" in said, said
    # an annotations part deleted, or copied: answers silently changed, import exited 0
    a, parts = _tampered(out, tmp_path, "deleted")
    gone = parts["annotations"][0]
    gone.unlink()
    for said in _refusals(a, db):
        assert f"{gone.relative_to(a).as_posix()} (" in said and "rows) is missing" in said, said
    a, parts = _tampered(out, tmp_path, "copied")
    twin = parts["annotations"][0].with_name("part-copy.parquet")
    shutil.copy(parts["annotations"][0], twin)
    for said in _refusals(a, db):
        assert f"{twin.relative_to(a).as_posix()} is not one of its parts" in said, said
    # a part rewritten with fewer rows, under its own name
    a, parts = _tampered(out, tmp_path, "rewritten")
    t = pq.read_table(parts["features"][0])
    pq.write_table(t.slice(0, t.num_rows - 5), parts["features"][0])
    for said in _refusals(a, db):
        assert f"holds {t.num_rows - 5} rows, manifest.json says {t.num_rows}" in said, said
    # an archive of an older mocapdb (no parts nor digests in its manifest): its totals, and each motion's frames
    a, parts = _tampered(out, tmp_path, "older")
    old = {k: v for k, v in manifest.items() if k not in ("parts", "digests")}
    (a / "manifest.json").write_text(json.dumps(old))
    parts["annotations"][0].unlink()
    for said in _refusals(a, db):
        assert "annotations/ holds" in said and f"manifest.json says {report.segments}" in said, said
    a, parts = _tampered(out, tmp_path, "older_moved")
    (a / "manifest.json").write_text(json.dumps(old))
    t = pq.read_table(parts["features"][0]).sort_by("motion_id")
    first = t.column("motion_id")[0].as_py()
    mine = pa.compute.equal(t.column("motion_id"), first)
    moved = t.filter(mine).set_column(t.schema.get_field_index("motion_id"), "motion_id",
                                      pa.array([first + 1] * int(pa.compute.sum(mine).as_py()), pa.int32()))
    pq.write_table(pa.concat_tables([t.filter(pa.compute.invert(mine)), moved.cast(t.schema)]), parts["features"][0])
    r = run(db, "attach", a, code=1)
    assert f"motion {first} (" in r.output and "has 0 feature rows" in r.output, r.output
    assert not db.exists() or api.connect(db).execute("SELECT count(*) FROM motions").fetchall() == [(0,)]


@pytest.mark.shared
def test_rows_rewritten_in_place_are_refused_by_their_digest(archive, tmp_path):
    """Issue 33: an archive whose annotation labels were rewritten (the same rows) was attached and imported
    silently; the manifest now holds each part's SHA-256 beside its rows."""
    out, _ = archive
    manifest = json.loads((out / "manifest.json").read_text())
    assert sorted(manifest["digests"]) == sorted(manifest["parts"]) and all(
        len(v) == 64 for v in manifest["digests"].values())
    a, parts = _tampered(out, tmp_path, "relabelled")
    part = next(p for p in parts["annotations"] if pq.read_metadata(p).num_rows)
    t = pq.read_table(part)
    k = t.schema.get_field_index("label")
    pq.write_table(t.set_column(k, "label", pa.array(["jump"] * t.num_rows, t.schema.field("label").type)), part)
    for said in _refusals(a, tmp_path / "t.duckdb"):
        assert (f"does not match its manifest.json: {part.relative_to(a).as_posix()} is not the file written (its "
                "bytes differ from the SHA-256 in manifest.json: changed since)") in said, said


@pytest.mark.shared
def test_a_truncated_annotations_part_is_named_as_annotations(archive, tmp_path):
    """Issue 33: a truncated annotations part of an archive without digests (written before them) was
    reported as "features unreadable"; the message names the dataset whose part could not be read."""
    out, _ = archive
    a, parts = _tampered(out, tmp_path, "truncated")
    manifest = json.loads((a / "manifest.json").read_text())
    del manifest["digests"]  # an archive of an earlier mocapdb: its parts are checked by rows only
    (a / "manifest.json").write_text(json.dumps(manifest))
    part = next(p for p in parts["annotations"] if pq.read_metadata(p).num_rows)
    part.write_bytes(part.read_bytes()[: part.stat().st_size // 2])
    r = run(tmp_path / "t.duckdb", "import-features", a, code=1)
    failed = [line for line in r.output.splitlines() if "unreadable" in line]
    assert failed and all("annotations unreadable: " in line and part.name in line for line in failed), r.output
    assert "features unreadable" not in r.output


@pytest.mark.shared
def test_similar_ranks_no_motion_without_its_feature_rows(archive, tmp_path):
    """A features part deleted after attach: its motions keep their index runs, but are no answer."""
    out, _ = archive
    a, parts = _tampered(out, tmp_path, "after")
    db = tmp_path / "v.duckdb"
    run(db, "attach", a)
    with api.connect(db) as con:
        ids = set(pq.read_table(parts["features"][-1]).column("motion_id").to_pylist())
        query = con.execute("SELECT name FROM motions WHERE motion_id NOT IN (SELECT unnest($ids)) AND n_frames > 60 "
                            "ORDER BY motion_id LIMIT 1", {"ids": sorted(ids)}).fetchall()[0][0]
        before = set(api.similar(con, query, start_frame=1, end_frame=40, limit=200).column("motion_id").to_pylist())
        assert before & ids
        parts["features"][-1].unlink()
        after = set(api.similar(con, query, start_frame=1, end_frame=40, limit=200).column("motion_id").to_pylist())
        assert after and not after & ids


@pytest.mark.shared
def test_a_killed_ray_annotate_is_refused_until_run_again(local_ray, tmp_path):
    """SIGKILL of a running `mocapdb ray-annotate` (its whole process group, Ray included): the batches
    written so far have no manifest beside them, so import, attach and a new run without --overwrite
    refuse the archive; running it again with --overwrite finishes it (issue 22 item 2)."""
    out = tmp_path / "archive"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    p = subprocess.Popen([sys.executable, "-P", "-m", "mocapdb.cli", "ray-annotate", str(DATA / "hdm05_cut"),
                          "--out", str(out), "--num-cpus", "1", "--batch-files", "4"], env=env, cwd=tmp_path,
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        while not list((out / "motions").glob("part-*.parquet")) and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
    assert p.returncode == -signal.SIGKILL  # killed while running
    written = len(list((out / "motions").glob("part-*.parquet")))
    assert 0 < written < 58 and not (out / "manifest.json").exists()
    with api.connect(tmp_path / "db.duckdb") as con:
        with pytest.raises(ParameterError, match="unfinished ray-annotate archive .* run ray-annotate again"):
            api.import_features(con, out)
        with pytest.raises(ParameterError, match="unfinished ray-annotate archive"):
            api.attach(con, out)
        assert con.execute("SELECT count(*) FROM motions").fetchall() == [(0,)]
        with pytest.raises(ParameterError, match="holds an unfinished archive.*--overwrite"):
            ray_annotate([DATA / "hdm05_cut"], out, batch_files=4)
        report = ray_annotate([DATA / "hdm05_cut"], out, batch_files=4, overwrite=True)
        assert len(report.ingested) == 232 and (out / "manifest.json").exists()
        assert len(api.import_features(con, out).imported) == 232


@pytest.mark.shared
def test_a_cluster_with_token_authentication(tmp_path):
    """`ray-annotate --address` on a cluster started with `ray start` and RAY_AUTH_MODE=token (Ray ≥ 2.52):
    the client needs the same mode and the token (here RAY_AUTH_TOKEN_PATH); without them one clear line."""
    import secrets

    from ray_cluster import LocalCluster

    token = tmp_path / "token"
    token.write_text(secrets.token_hex(16))
    auth = {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN_PATH": str(token)}
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_AUTH")}
    env.update(PYTHONPATH=str(REPO), RAY_USAGE_STATS_ENABLED="0")
    cmd = [sys.executable, "-P", "-m", "mocapdb.cli", "ray-annotate", str(DATA / "cmu" / "02")]
    with LocalCluster(nodes=1, cpus=1, port=6397, env={**auth, "PYTHONPATH": str(REPO)}) as cluster:
        p = subprocess.run([*cmd, "--out", str(tmp_path / "a"), "--address", cluster.address], env=env,
                           capture_output=True, text=True, cwd=tmp_path, timeout=300)
        assert p.returncode == 1
        last = p.stderr.strip().splitlines()[-1]
        assert last.startswith(f"Error: cannot connect to the Ray cluster at {cluster.address}")
        assert "RAY_AUTH_MODE=token" in last and "RAY_AUTH_TOKEN_PATH" in last
        p = subprocess.run([*cmd, "--out", str(tmp_path / "b"), "--address", cluster.address], env={**env, **auth},
                           capture_output=True, text=True, cwd=tmp_path, timeout=600)
        assert p.returncode == 0, p.stderr[-2000:]
        assert p.stdout.startswith("9 motions") and (tmp_path / "b" / "manifest.json").exists()


@pytest.mark.shared
def test_a_trained_model_from_the_database_with_tau_and_no_keyframes(local_ray, tmp_path):
    """`mocapdb --db DB ray-annotate --model NAME --tau … --no-keyframes`: the model comes from the
    database; the segments equal `annotate` with the same options in that database."""
    root = tmp_path / "cut"
    root.mkdir()
    for asf in (DATA / "hdm05_cut").glob("HDM_*.asf"):
        (root / asf.name).symlink_to(asf)
    for c in ("squat1Reps", "kickLFront1Reps"):
        (root / c).symlink_to(DATA / "hdm05_cut" / c, target_is_directory=True)
    db = tmp_path / "trained.duckdb"
    with api.connect(db) as con:
        api.train(con, model="two", folder=root)
        api.ingest(con, [DATA / "cmu" / "02", root])
        want = api.annotate(con, model="two", tau=0.2, keyframes=False, store=True)
        single = _rows(con, "annotations", DB_TABLES)
    out = tmp_path / "archive"
    r = run(db, "ray-annotate", DATA / "cmu" / "02", root, "--out", out, "--model", "two", "--tau", "0.2",
            "--no-keyframes")
    assert f"{want.num_rows} segments written to {out}" in r.output
    with duckdb.connect() as con:
        _views(con, out, "t")
        assert _rows(con, "annotations", {k: f"t_{k}" for k in DB_TABLES}) == single
        assert con.execute("SELECT DISTINCT model, tau, keyframes FROM t_annotations").fetchall() == [("two", 0.2, False)]


@pytest.mark.shared
def test_the_readme_example_queries_the_parquet_in_place(archive, tmp_path, monkeypatch):
    """docs/CLUSTER.md's Python block, run where `archive` is the archive."""
    out, report = archive
    section = (REPO / "docs" / "CLUSTER.md").read_text(encoding="utf-8")
    code = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert len(code) == 1
    assert re.search(r"mocapdb ray-annotate .* --out archive", section)
    assert "mocapdb --db archive.duckdb import-features archive" in section
    (tmp_path / "archive").symlink_to(out, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    scope = {}
    exec(code[0], scope)
    rows = scope["seconds"].fetchall()
    assert sum(n for _, n, _ in rows) == report.segments and all(s > 0 for _, _, s in rows)


@pytest.mark.shared
def test_sources_expand_like_ingest_and_globs(tmp_path):
    cmu = DATA / "cmu" / "02"
    assert expand_sources([cmu]) == expand_sources([f"{cmu}/*.amc"]) == sorted(cmu.glob("*.amc"))
    assert expand_sources([f"{DATA}/hdm05_cut/**/*.amc"]) == sorted(expand_sources([DATA / "hdm05_cut"]))
    assert expand_sources([cmu, cmu / "02_01.amc"]) == expand_sources([cmu])  # listed twice: once
    with pytest.raises(ParameterError, match="matches no motion file"):
        expand_sources([f"{cmu}/*.nothing"])
    with pytest.raises(ParameterError, match="does not exist"):
        expand_sources([tmp_path / "nowhere"])


@pytest.mark.shared
def test_parameters_are_checked_before_any_work(tmp_path):
    with pytest.raises(SchemaError, match="no model 'nope'"):
        ray_annotate(SOURCES, tmp_path / "a", model="nope")
    with pytest.raises(ParameterError, match="database: .* does not exist"):
        ray_annotate(SOURCES, tmp_path / "a", database=tmp_path / "none.duckdb")
    with pytest.raises(ParameterError, match="batch_files must be a positive integer"):
        ray_annotate(SOURCES, tmp_path / "a", batch_files=0)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    r = CliRunner().invoke(main, ["ray-annotate", str(DATA / "cmu" / "02"), "--out", str(tmp_path / "full")])
    assert r.exit_code == 1
    assert r.output.strip() == f"Error: out: {str(tmp_path / 'full')!r} is not empty; pass overwrite=True " \
                               "(--overwrite) to replace the archive in it"


def test_without_ray_one_clear_error(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "ray", None)  # what `import ray` sees without the extra
    with pytest.raises(MissingExtraError, match=re.escape("pip install 'mocapdb[ray]'")):
        require_ray()
    r = CliRunner().invoke(main, ["ray-annotate", str(SAMPLE_86_09), "--out", str(tmp_path / "a")])
    assert r.exit_code == 1
    assert r.output == "Error: ray_annotate needs Ray, which is not installed: pip install 'mocapdb[ray]'\n"


def test_the_base_package_does_not_import_ray():
    code = ("import sys, mocapdb, mocapdb.api, mocapdb.cli, mocapdb.distributed; "
            "loaded = [m for m in sys.modules if m == 'ray' or m.startswith('ray.')]; "
            "assert not loaded, loaded")
    subprocess.run([sys.executable, "-P", "-c", code], check=True)
