"""What the command line says where it used to say too little or too much (issue 33 items 4, 5, 6).

On the recordings shipped with mocapdb (and ../shared for the stats of a larger archive).
"""
import sys

import pytest

from conftest import run


@pytest.fixture(scope="module")
def sample_db(tmp_path_factory):
    db = tmp_path_factory.mktemp("messages") / "m.duckdb"
    run(db, "ingest", "--sample", "--silent")
    return db


@pytest.mark.parametrize("hidden", ["uvicorn", "starlette"])
def test_serve_without_the_extra_names_the_extra(sample_db, monkeypatch, hidden):
    """Without the [serve] extra, `serve` said "Error: No module named 'uvicorn'"."""
    monkeypatch.setitem(sys.modules, hidden, None)   # import of it fails, as where it is not installed
    r = run(sample_db, "serve", "--port", "0", code=1)
    assert r.output == (f"Error: mocapdb serve needs the serve extra, which is not installed ({hidden} is missing): "
                        "pip install \"mocapdb[serve]\" (Starlette and uvicorn)\n")


def test_duration_reads_as_the_summary_page_writes_it():
    from mocapdb.cli.output import duration

    assert [duration(s) for s in (8.94, 59.96, 189.0, 3599.4, 12.4 * 3600)] == [
        "8.9 s", "1 min 00 s", "3 min 09 s", "59 min 59 s", "12 h 24 min"]


@pytest.mark.shared
def test_stats_prints_durations_within_the_terminal(sample_db, tmp_path, monkeypatch):
    """`stats` printed hours as 0.000314815 and padded its refused-files table to ~560 characters."""
    from conftest import DATA

    deep = tmp_path / ("a_session_folder_with_a_long_name_" * 4) / "takes"
    deep.mkdir(parents=True)
    (deep / "sinusoidal.bvh").write_bytes((DATA / "foreign" / "bvh" / "fairmotion_sinusoidal.bvh").read_bytes())
    db = tmp_path / "s.duckdb"
    import shutil
    shutil.copy(sample_db, db)
    run(db, "ingest", deep, "--silent", code=1)
    for columns in (80, 132):
        monkeypatch.setenv("COLUMNS", str(columns))
        lines = run(db, "stats").output.splitlines()
        assert lines[0] == "3 motion(s), 1 min 22 s in all (0.02281 hours)"
        assert max(map(len, lines)) < columns, max(lines, key=len)
        formats = lines[lines.index("hours and motions per source format and rate:") + 1:]
        assert formats[0].split() == ["format", "source_fps", "motions", "duration"]
        assert formats[2].split() == ["amc", "120", "1", "40.0", "s"]
        (refused,) = [ln for ln in lines if "failed" in ln]
        assert "…" in refused and refused.split()[0].endswith("al.bvh")   # the path cut in the middle: its end kept
    # machine-readable outputs keep the hours
    assert run(db, "stats", "--table", "formats", "--format", "csv").output.startswith(
        "format,source_fps,motions,hours\n")


@pytest.mark.parametrize("kind", ["csv", "json", "parquet"])
def test_a_db_that_is_not_a_duckdb_file_is_refused_before_anything_is_read(sample_db, tmp_path, kind):
    """DuckDB opened `--db archive.csv` as a throw-away database with the file as a view: an ingest into
    it reported success and was gone when the process exited."""
    if kind == "parquet":   # the export's own motions.parquet
        run(sample_db, "export-features", tmp_path / "export")
        db = tmp_path / "export" / "motions.parquet"
    else:
        db = tmp_path / f"archive.{kind}"
        db.write_text("name,n_frames\n86_09,4794\n" if kind == "csv" else '[{"name": "86_09"}]\n')
    before = db.read_bytes()
    from conftest import SAMPLE_86_09
    for args in (["ingest", SAMPLE_86_09.parent, "--silent"], ["sql", "SELECT 1"], ["stats"],
                 ["annotate", "--silent"], ["serve", "--port", "0"]):
        r = run(db, *args, code=1)
        assert r.output.startswith(f"Error: {db} is not a DuckDB database file (") and r.output.count("\n") == 1
        assert "give a .duckdb file, or a new path" in r.output
    assert db.read_bytes() == before
    # a new path with any suffix is a new database, which keeps what is written into it
    fresh = tmp_path / "new.csv"
    run(fresh, "ingest", "--sample", "--silent")
    assert run(fresh, "sql", "SELECT count(*) AS n FROM motions", "--format", "csv").output == "n\n3\n"


def test_what_was_an_internal_error_is_one_line(sample_db, tmp_path, monkeypatch):
    """The probe's `internal error (…)` cases: each a one-line error saying what is wrong, or an answer."""
    import gzip

    from conftest import SAMPLE_BVH
    import lzma

    take = tmp_path / "walk.bvh.gz"
    take.write_bytes(gzip.compress(lzma.decompress(SAMPLE_BVH.read_bytes())))
    db = tmp_path / "e.duckdb"
    r = run(db, "ingest", take, "--max-decompressed", "1e400", code=1)
    assert r.output == "Error: max_decompressed: '1e400' is not a positive finite size in bytes (e.g. 512MiB)\n"
    monkeypatch.setenv("MOCAPDB_MAX_DECOMPRESSED", "1e400")
    r = run(db, "ingest", take, "--silent", code=1)
    assert "MOCAPDB_MAX_DECOMPRESSED: '1e400' is not a positive finite size" in r.output
    assert "internal error" not in r.output
    monkeypatch.delenv("MOCAPDB_MAX_DECOMPRESSED")
    # a limit beyond int64: the command's bound says so (the library's check_limit clamps, the kernels count
    # in int64)
    r = run(sample_db, "similar", "86_09", "--start-frame", "40", "--end-frame", "110",
            "--limit", "99999999999999999999", "--format", "csv", code=1)
    assert r.output == "Error: limit must be an integer from 1 to 500, got 99999999999999999999\n"
    from mocapdb.retrieval.hits import check_limit
    assert check_limit(10 ** 20) == 1 << 62
    binary = tmp_path / "query.sql"
    binary.write_bytes(b"SELECT 1; \xd0\x00\xff\xfe binary")
    r = run(sample_db, "sql", "--file", binary, code=2)
    assert r.output.splitlines()[-1] == (f"Error: {binary} is not UTF-8 text (byte 0xd0 at offset 10): the query "
                                         "must be SQL text")
    # a Ray archive whose manifest is a JSON list
    archive = tmp_path / "archive"
    (archive / "motions").mkdir(parents=True)
    for text in ("[1, 2]", '{"motions": 3, "parts": ["motions/part-0.parquet"]}', '"x"'):
        (archive / "manifest.json").write_text(text)
        for args in (["import-features", archive], ["attach", archive]):
            r = run(tmp_path / "i.duckdb", *args, code=1)
            assert r.output.startswith(f"Error: {archive / 'manifest.json'}: not a manifest of ray-annotate ("), \
                r.output
            assert r.output.count("\n") == 1
