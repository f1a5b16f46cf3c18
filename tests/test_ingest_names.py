"""What ingest says about the names it meets (issue 33, the security probe).

Hidden files and folders (`.hidden.bvh`, `.git/`, `__MACOSX/`, zip members starting with `.`) were passed
over without a row in `ingest_log`, real takes among them; a file named `...bvh` became motion `..`, which
`import-features` of its export then refused; a duplicate zip member whose earlier copy was refused made a
later file of the same bytes "fail" although the member was ingested; `--report` wrote names raw, so
`=HYPERLINK(…)` reached a spreadsheet as a formula. On real BVH takes (the PyMO walk shipped with mocapdb,
two Bandai clips).
"""
import csv
import gzip
import lzma
import zipfile

import pytest

import mocapdb

from conftest import DATA, SAMPLE_BVH, run

WALK = lzma.decompress(SAMPLE_BVH.read_bytes())


def _log(db):
    with mocapdb.connect(db, read_only=True) as con:
        return con.execute("SELECT path, member, outcome, reason FROM ingest_log ORDER BY path, member").fetchall()


@pytest.mark.filterwarnings("ignore:Duplicate name:UserWarning")
def test_hidden_files_and_folders_are_logged_as_skipped_with_the_reason(tmp_path):
    takes = tmp_path / "takes"
    for rel in ("walk.bvh", ".hidden.bvh", ".git/objects/walk.bvh", "__MACOSX/walk.bvh"):
        (takes / rel).parent.mkdir(parents=True, exist_ok=True)
        (takes / rel).write_bytes(WALK)
    with zipfile.ZipFile(takes / "more.zip", "w") as z:
        z.writestr("s/walk2.bvh", WALK + b"\n")
        z.writestr("s/.take.bvh", WALK)
        z.writestr("__MACOSX/s/._walk2.bvh", b"\x00\x05\x16\x07 resource fork")
        z.writestr(".cache/a/b.bvh", WALK)
    db = tmp_path / "h.duckdb"
    r = run(db, "ingest", takes, "--silent")
    assert "2 ingested, 6 skipped, 0 failed" in r.output
    skipped = {(p, m): why for p, m, outcome, why in _log(db) if outcome == "skipped"}
    hidden_file = "a hidden file (its name starts with '.'): not read; name it on the command line to read it"
    hidden_folder = hidden_file.replace("file", "folder", 1)
    macos = "macOS zip metadata (__MACOSX): not read; name it on the command line to read it"
    zipped = str(takes / "more.zip")
    assert skipped == {(str(takes / ".git"), None): hidden_folder, (str(takes / ".hidden.bvh"), None): hidden_file,
                       (str(takes / "__MACOSX"), None): macos, (zipped, ".cache"): hidden_folder,
                       (zipped, "__MACOSX"): macos, (zipped, "s/.take.bvh"): hidden_file}
    # named on the command line, a hidden take is read
    run(db, "ingest", takes / ".hidden.bvh", "--silent")


def test_a_name_of_dots_is_a_name_import_accepts(tmp_path):
    (tmp_path / "...bvh").write_bytes(WALK)
    db = tmp_path / "d.duckdb"
    run(db, "ingest", tmp_path / "...bvh", "--silent")
    assert run(db, "sql", "SELECT name FROM motions", "--format", "csv").output == "name\n__\n"
    run(db, "export-features", tmp_path / "export")
    r = run(tmp_path / "i.duckdb", "import-features", tmp_path / "export")
    assert "1 motion(s) imported" in r.output


@pytest.mark.shared
@pytest.mark.filterwarnings("ignore:Duplicate name:UserWarning")
def test_a_copy_of_a_member_named_twice_is_skipped_not_failed(tmp_path):
    """The earlier copy of `s/walk.bvh` is refused (only the last is read); `x_copy.bvh`, the same bytes as the
    last, is a skipped copy of an ingested file — it was "same bytes as …/s/walk.bvh, which failed"."""
    clip = gzip.decompress((DATA / "bandai2_dev" / "dataset-2_walk_normal_001.bvh.gz").read_bytes())
    archive = tmp_path / "twice.zip"
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr("s/walk.bvh", clip)
        z.writestr("s/walk.bvh", WALK)
        z.writestr("s/x_copy.bvh", WALK)   # read after s/walk.bvh
    db = tmp_path / "z.duckdb"
    r = run(db, "ingest", archive, "--silent", code=1)   # the refused earlier copy fails the ingest
    assert "1 ingested, 1 skipped, 1 failed" in r.output and "which failed" not in r.output
    log = {(m, outcome): why for _, m, outcome, why in _log(db)}
    assert log[("s/x_copy.bvh", "skipped")] == f"same bytes as {archive}/s/walk.bvh of this ingest"
    assert ("s/walk.bvh", "ingested") in log
    assert log[("s/walk.bvh", "failed")].endswith("the archive holds 2 members of this name; only the last is read "
                                                  "(a path names one member); a member must name a file inside its "
                                                  "archive") or "only the last is read" in log[("s/walk.bvh", "failed")]


def test_the_report_csv_keeps_formulas_out_of_spreadsheets(tmp_path, monkeypatch):
    names = ['=HYPERLINK("example.invalid","x").bvh', "+1+1.bvh", "-2.bvh", "@SUM(A1).bvh"]
    archive = tmp_path / "names.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for n in names:
            z.writestr(n, b"not a BVH")
    (tmp_path / names[0]).write_bytes(b"not a BVH either")
    monkeypatch.chdir(tmp_path)
    db = tmp_path / "r.duckdb"
    report = tmp_path / "report.csv"
    run(db, "ingest", "names.zip", names[0], "--silent", "--report", report, code=1)
    with report.open(newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 5
    for r in rows:
        for v in r.values():
            assert not v.startswith(("=", "+", "-", "@")), v
    assert sorted(r["member"] for r in rows if r["member"]) == sorted("'" + n for n in names)
    # the database keeps the names as they are
    assert sorted(m for _, m, _, _ in _log(db) if m) == sorted(names)
