"""The command line: real files in, exact messages and exit codes out."""
import csv
import io
import json
import shutil

import pytest
from click.testing import CliRunner

from mocapdb.cli import main

from conftest import DATA, REPO, amc_frame_count


@pytest.fixture
def run(tmp_path):
    db = tmp_path / "cli.duckdb"
    runner = CliRunner()

    def invoke(*args):
        return runner.invoke(main, ["--db", str(db), *map(str, args)], catch_exceptions=False)

    return invoke


def test_ingest_and_query(run):
    r = run("ingest", DATA / "cmu" / "86", DATA / "hdm05_cut" / "hopBothLegs1hops", "--silent")
    assert r.exit_code == 0, r.output
    assert "34 ingested, 0 skipped, 0 failed" in r.output
    r = run("sql", "SELECT name, n_frames FROM motions WHERE name = '86_09'", "--format", "csv")
    assert list(csv.reader(io.StringIO(r.output))) == [["name", "n_frames"], ["86_09", "1199"]]
    r = run("sql", "SELECT count(*) AS n FROM features", "--format", "json")
    hops = sorted((DATA / "hdm05_cut" / "hopBothLegs1hops").glob("*.amc"))
    assert json.loads(r.output) == [{"n": 1199 + sum(-(-amc_frame_count(p) // 4) for p in hops)}]
    r = run("sql", "SELECT name FROM motions ORDER BY name LIMIT 2")
    assert r.output.splitlines()[0].strip() == "name" and "HDM_bd_hopBothLegs1hops_001_120" in r.output
    # again: nothing new
    r = run("ingest", DATA / "cmu" / "86", "--silent")
    assert "0 ingested, 1 skipped, 0 failed" in r.output


def test_failed_file_reports_file_and_line_and_exits_nonzero(run, tmp_path):
    bad = tmp_path / "86_09.amc"
    lines = (DATA / "cmu" / "86" / "86_09.amc").read_bytes().splitlines(keepends=True)
    bad.write_bytes(b"".join(lines[:1000]) + b"lfemur abc 1 2\r\n" + b"".join(lines[1001:2000]))
    shutil.copy(DATA / "cmu" / "86" / "86.asf", tmp_path)
    r = run("ingest", bad, "--silent")
    assert r.exit_code == 1
    assert f"{bad}:1001" in r.output
    assert "0 ingested, 0 skipped, 1 failed" in r.output
    assert run("sql", "SELECT count(*) FROM motions", "--format", "csv").output.splitlines()[1] == "0"


def test_sql_error_is_a_clean_message(run):
    r = run("sql", "SELECT * FROM no_such_table")
    assert r.exit_code == 1 and r.output.startswith("Error: ") and "no_such_table" in r.output


def test_delete_by_name(run):
    run("ingest", DATA / "hdm05_cut" / "rotateArmsBothBackward1Reps", "--silent")
    r = run("delete", "HDM_bd_rotateArmsBothBackward1Reps_001_120", "HDM_bd_rotateArmsBothBackward1Reps_002_120")
    assert r.exit_code == 0 and "2 motion(s) deleted" in r.output
    assert run("sql", "SELECT count(*) FROM motions", "--format", "csv").output.splitlines()[1] == "11"
    r = run("delete", "no_such_motion")
    assert r.exit_code == 1 and "no motion 'no_such_motion'" in r.output


def test_every_command_has_help_and_a_readme_entry():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    runner = CliRunner()
    for name, cmd in main.commands.items():
        assert cmd.help, f"command {name} has no help text"
        r = runner.invoke(main, [name, "--help"])
        assert r.exit_code == 0 and "Usage:" in r.output
        assert f"`{name}" in readme, f"README.md does not document the command {name!r}"
