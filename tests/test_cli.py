"""The command line: real files in, exact messages and exit codes out."""
import csv
import functools
import io
import json
import lzma
import os
import re
import shutil
from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner

import mocapdb
from mocapdb.cli import main
from lab.recipe import PAPER_LABELS

from conftest import DATA, REPO, SAMPLE_86_09, SAMPLE_86_ASF, amc_frame_count, eval_scores, run, user_docs_text, write_truth_86_09


@pytest.fixture
def cli(tmp_path):
    """``cli(*args)``: a command on a fresh database of this test; the test checks the exit status."""
    db = tmp_path / "cli.duckdb"
    mocapdb.connect(db).close()  # commands that only read refuse a missing file (test_a_mistyped_db_…)
    return functools.partial(run, db, code=None)


@pytest.mark.shared
def test_ingest_and_query(cli):
    r = cli("ingest", DATA / "cmu" / "86", DATA / "hdm05_cut" / "hopBothLegs1hops", "--silent")
    assert r.exit_code == 0, r.output
    assert "34 ingested, 0 skipped, 0 failed" in r.output
    r = cli("sql", "SELECT name, n_frames FROM motions WHERE name = '86_09'", "--format", "csv")
    assert list(csv.reader(io.StringIO(r.output))) == [["name", "n_frames"], ["86_09", "1199"]]
    r = cli("sql", "SELECT count(*) AS n FROM features", "--format", "json")
    hops = sorted((DATA / "hdm05_cut" / "hopBothLegs1hops").glob("*.amc"))
    assert json.loads(r.output) == [{"n": 1199 + sum(-(-amc_frame_count(p) // 4) for p in hops)}]
    r = cli("sql", "SELECT name FROM motions ORDER BY name LIMIT 2")
    assert r.output.splitlines()[0].strip() == "name" and "HDM_bd_hopBothLegs1hops_001_120" in r.output
    # again: nothing new
    r = cli("ingest", DATA / "cmu" / "86", "--silent")
    assert "0 ingested, 1 skipped, 0 failed" in r.output


def test_failed_file_reports_file_and_line_and_exits_nonzero(cli, tmp_path):
    bad = tmp_path / "86_09.amc"
    lines = lzma.decompress(SAMPLE_86_09.read_bytes()).splitlines(keepends=True)
    bad.write_bytes(b"".join(lines[:1000]) + b"lfemur abc 1 2\r\n" + b"".join(lines[1001:2000]))
    shutil.copy(SAMPLE_86_ASF, tmp_path)
    r = cli("ingest", bad, "--silent")
    assert r.exit_code == 1
    assert f"{bad}:1001" in r.output
    assert "0 ingested, 0 skipped, 1 failed" in r.output
    assert cli("sql", "SELECT count(*) FROM motions", "--format", "csv").output.splitlines()[1] == "0"


def test_sql_error_is_a_clean_message(cli):
    r = cli("sql", "SELECT * FROM no_such_table")
    assert r.exit_code == 1 and r.output.startswith("Error: ") and "no_such_table" in r.output


@pytest.mark.shared
def test_delete_by_name(cli):
    cli("ingest", DATA / "hdm05_cut" / "rotateArmsBothBackward1Reps", "--silent")
    r = cli("delete", "HDM_bd_rotateArmsBothBackward1Reps_001_120", "HDM_bd_rotateArmsBothBackward1Reps_002_120")
    assert r.exit_code == 0 and "2 motion(s) deleted" in r.output
    assert "deleted motion 1 HDM_bd_rotateArmsBothBackward1Reps_001_120 (amc, " in r.output
    assert cli("sql", "SELECT count(*) FROM motions", "--format", "csv").output.splitlines()[1] == "11"
    # what is gone is not an error: a delete re-run after it committed (killed before it could say so)
    r = cli("delete", "no_such_motion", "1")
    assert r.exit_code == 0 and "no motion 'no_such_motion' (nothing to delete)" in r.output
    assert "no motion '1' (nothing to delete)" in r.output and "0 motion(s) deleted" in r.output


def test_every_command_has_help_and_a_readme_entry():
    readme = (REPO / "docs" / "USER_GUIDE.md").read_text(encoding="utf-8")  # its command table
    runner = CliRunner()
    for name, cmd in main.commands.items():
        assert cmd.help, f"command {name} has no help text"
        r = runner.invoke(main, [name, "--help"])
        assert r.exit_code == 0 and "Usage:" in r.output
        assert f"`{name}" in readme, f"docs/USER_GUIDE.md does not document the command {name!r}"


#: CLI parameters that only shape the output or the terminal, with no API counterpart
PRESENTATION = {"silent", "fmt", "out", "read_only", "query", "sql_file", "table"}
#: options spelled otherwise than their keyword: `class` is a Python keyword; a repeatable
#: option names one of its values (--example A --example B is examples=[A, B])
RENAMED = {"class_name": "--class", "examples": "--example"}


def test_the_cli_mirrors_the_api():
    """Every command calls the mocapdb.api function of the same name (serve: mocapdb.server.serve, the web
    server above the API), and every option is one of its parameters (sqlite-utils style)."""
    import inspect

    from mocapdb import api
    from mocapdb import server

    for name, cmd in main.commands.items():
        if name == "sql":  # mocapdb.connect(...).sql(query)
            continue
        fn = server.serve if name == "serve" else getattr(api, name.replace("-", "_"), None)
        assert fn is not None, f"command {name!r} has no mocapdb.api.{name.replace('-', '_')}"
        params = set(inspect.signature(fn).parameters) - {"con"}
        options = {p.name for p in cmd.params} - PRESENTATION
        assert options <= params, f"{name}: options {sorted(options - params)} are not parameters of api.{fn.__name__}"
        for p in cmd.params:  # the option is the keyword with dashes (--label-map is label_map=)
            if isinstance(p, click.Option) and p.name not in PRESENTATION:
                assert p.opts[0] == RENAMED.get(p.name, "--" + p.name.replace("_", "-")), (name, p.opts, p.name)


def _class_folder(tmp_path, classes):
    """An HDM05-cut-layout folder with some real classes (symlinked, not copied)."""
    root = tmp_path / "cut"
    root.mkdir()
    for asf in (DATA / "hdm05_cut").glob("HDM_*.asf"):
        (root / asf.name).symlink_to(asf)
    for c in classes:
        (root / c).symlink_to(DATA / "hdm05_cut" / c, target_is_directory=True)
    return root


@pytest.mark.slow
@pytest.mark.shared
def test_train_then_annotate(cli, tmp_path):
    root = _class_folder(tmp_path, ["squat1Reps", "kickLFront1Reps"])
    r = cli("train", "--model", "two", "--folder", root, "--silent")
    assert r.exit_code == 0, r.output
    assert "kickLFront1Reps" in r.output and "-> kick" in r.output and "-> exercise" in r.output
    assert "model 'two': 2 classes, 2 labels" in r.output
    r = cli("train", "--model", "two", "--folder", root, "--silent")
    assert r.exit_code == 1 and "already exists" in r.output
    cli("ingest", DATA / "cmu" / "86", DATA / "hdm05_cut" / "squat1Reps" / "HDM_bd_squat1Reps_001_120.amc", "--silent")
    out = tmp_path / "seg.csv"
    r = cli("annotate", "--model", "two", "--format", "csv", "--out", out)
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0]) == ["document", "label", "start_frame", "end_frame", "fps", "start_s", "end_s", "cost",
                             "confidence"]
    assert {r["fps"] for r in rows} == {"30"}
    # the training clip itself is found as exercise, with a near-zero cost, over most of its frames
    squat = [r for r in rows if r["document"] == "HDM_bd_squat1Reps_001_120" and r["label"] == "exercise"]
    assert squat and min(float(r["cost"]) for r in squat) < 0.05
    assert sum(int(r["end_frame"]) - int(r["start_frame"]) + 1 for r in squat) >= 0.8 * 35
    stored = cli("sql", "SELECT count(*) FROM annotations WHERE model = 'two'", "--format", "csv")
    assert int(stored.output.splitlines()[1]) == len(rows)
    r = cli("annotate", "86_09", "--model", "two", "--tau", "0.05", "--format", "json")
    assert all(s["cost"] <= 0.05 and s["document"] == "86_09" for s in json.loads(r.output))


def test_annotate_unknown_model(cli):
    cli("ingest", SAMPLE_86_09, "--silent")
    r = cli("annotate", "--model", "nope")
    assert r.exit_code == 1 and "no model 'nope'" in r.output
    r = cli("sql", "SELECT annotate(motion_id, model := 'nope') FROM motions")
    assert r.exit_code == 1 and r.output.startswith("Error: no model 'nope' in the database")
    assert len(r.output.strip().splitlines()) == 1


@pytest.mark.slow
def test_a_locked_database_is_one_line_naming_the_process(tmp_path):
    """Another process writing the file: `Error: … in use by another process (PID …)`, exit 1."""
    import subprocess
    import sys

    db = tmp_path / "locked.duckdb"
    holder = subprocess.Popen([sys.executable, "-c", f"import duckdb, sys, time; c = duckdb.connect({str(db)!r}); "
                               "print('ready', flush=True); time.sleep(60)"], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "ready"
        # a writer waits for the lock a moment (a reader's request) before it says so: half a second here
        r = subprocess.run([sys.executable, "-P", "-m", "mocapdb.cli", "--db", str(db), "sql", "SELECT 1"],
                           capture_output=True, text=True, env={**os.environ, "MOCAPDB_LOCK_WAIT": "0.5"})
        assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert r.stderr.startswith(f"Error: {db} is in use by another process (PID {holder.pid}, "), r.stderr
    finally:
        holder.kill()
        holder.wait()


@pytest.mark.shared
def test_eval_from_database_equals_eval_of_the_written_predictions(cli, tmp_path):
    from importlib import resources

    truth = write_truth_86_09(tmp_path / "truth.csv")
    walk_is_move = resources.files("mocapdb.shipped_models").joinpath("cmu86_labels.csv")
    cli("ingest", DATA / "cmu" / "86", "--silent")
    pred = tmp_path / "pred.csv"
    cli("annotate", "--no-keyframes", "--format", "csv", "--out", pred)
    from_db = cli("evaluate", "--truth", truth, "--label-map", walk_is_move, "--no-keyframes")
    assert from_db.exit_code == 0, from_db.output
    assert "look_around (1)" in from_db.output  # labels the model cannot produce are reported
    labels = ",".join(PAPER_LABELS)  # the default model's labels
    from_files = CliRunner().invoke(main, ["evaluate", "--truth", str(truth), "--pred", str(pred),
                                           "--label-map", str(walk_is_move), "--vocabulary", labels])
    assert from_files.exit_code == 0, from_files.output
    p1, r1, f1, p2, r2, f2 = eval_scores(from_db.output)
    assert eval_scores(from_files.output) == [p1, r1, f1, p2, r2, f2]
    assert r1 > 0.9 and p1 < 0.5  # walking is found, and without keyframes so are false kicks
    sweep = cli("evaluate", "--truth", truth, "--label-map", walk_is_move, "--no-keyframes", "--sweep-tau", "0.05:0.15:0.05")
    taus = [ln.split()[0] for ln in sweep.output.splitlines() if ln.startswith("tau=")]
    assert taus == ["tau=0.050", "tau=0.100", "tau=0.150"]


@pytest.mark.shared
def test_eval_counts_a_missing_segment(tmp_path):
    """Predictions = the truth on the 30 Hz grid minus its longest segment: P1 = P2 = 1 and
    R2 = (n − 1)/n exactly; R1 = the frames kept over all truth frames."""
    truth = write_truth_86_09(tmp_path / "truth.csv")
    from mocapdb.annotation.labels import read_labels, to_feature_grid

    rows = to_feature_grid(read_labels(truth))
    longest = int(np.argmax(rows["end"] - rows["start"]))
    pred = tmp_path / "pred.csv"
    with pred.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["document", "label", "start_frame", "end_frame"])
        for k, r in enumerate(rows):
            if k != longest:
                w.writerow([r["document"], r["label"], r["start"] + 1, r["end"] + 1])
    r = CliRunner().invoke(main, ["evaluate", "--truth", str(truth), "--pred", str(pred)])
    assert r.exit_code == 0, r.output
    p1, r1, f1, p2, r2, f2 = eval_scores(r.output)
    frames = rows["end"] - rows["start"] + 1
    assert p1 == 1.0 and p2 == 1.0
    assert r2 == round((len(rows) - 1) / len(rows), 3)
    assert r1 == round(1 - frames[longest] / frames.sum(), 3)


@pytest.mark.slow
@pytest.mark.shared
def test_learn_keyframes_is_reproducible_and_searchable(cli, tmp_path):
    root = _class_folder(tmp_path, ["squat1Reps", "kickLFront1Reps", "rotateArmsBothBackward1Reps"])
    cli("train", "--model", "three", "--folder", root, "--silent")
    args = ("learn-keyframes", "--model", "three", "--folder", root, "--runs", "2", "--generations", "8",
            "--jobs", "1", "--seed", "3", "--silent")
    r = cli(*args)
    assert r.exit_code == 0, r.output
    assert "squat1Reps" in r.output and "precision" in r.output
    query = "SELECT class, k, mask, value, position, d_min, d_max FROM keyframes WHERE model = 'three' ORDER BY ALL"
    first = cli("sql", query, "--format", "csv").output
    cli(*args)
    assert cli("sql", query, "--format", "csv").output == first
    stats = cli("sql", "SELECT count(*) FROM ga_statistics WHERE model = 'three'", "--format", "csv").output
    assert int(stats.splitlines()[1]) == 3 * 2 * 9  # classes x runs x (generations + 1)
    cli("ingest", root / "squat1Reps", "--silent")
    hits = cli("sql", "SELECT count(DISTINCT motion_id) FROM keyframe_search('squat1Reps', model := 'three')",
               "--format", "csv").output
    assert int(hits.splitlines()[1]) >= 30  # of the 40 squat clips it was trained on


def test_index_drop_and_rebuild(cli):
    cli("ingest", SAMPLE_86_09, "--silent")
    before = cli("sql", "SELECT count(*) FROM mocap_index.postings", "--format", "csv").output
    assert "keyframe index dropped" in cli("drop-index").output
    assert cli("sql", "SELECT count(*) FROM mocap_index.postings").exit_code == 1
    r = cli("create-index")
    assert r.exit_code == 0 and f"{before.splitlines()[1]} postings" in r.output


@pytest.mark.slow
@pytest.mark.shared
def test_report_figures(cli, tmp_path):
    import matplotlib  # noqa: F401  (the test extra installs it)
    out = tmp_path / "fig5.png"
    # the shipped default's queries are designed, not learned: Fig. 5 needs a model the GA trained
    r = cli("report", "--figure", "ga", "--out", out)
    assert r.exit_code == 1 and "no GA statistics" in r.output and "learn-keyframes" in r.output
    root = _class_folder(tmp_path, ["squat1Reps", "kickLFront1Reps"])
    cli("train", "--model", "two", "--folder", root, "--silent")
    cli("learn-keyframes", "--model", "two", "--folder", root, "--runs", "2", "--generations", "5", "--jobs", "1",
        "--silent")
    r = cli("report", "--figure", "ga", "--model", "two", "--out", out)
    assert r.exit_code == 0, r.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    cli("ingest", DATA / "cmu" / "86", "--silent")
    out = tmp_path / "86_09.png"
    r = cli("report", "--figure", "annotation", "--motion", "86_09", "--out", out)
    assert r.exit_code == 0 and out.stat().st_size > 10_000
    r = cli("report", "--figure", "annotation", "--out", out)
    assert r.exit_code == 1 and "needs a motion" in r.output


@pytest.mark.shared
def test_train_from_a_label_csv_over_ingested_documents(cli, tmp_path):
    """Classes cut out of ingested documents by a label CSV (native frames); the model finds them again."""
    truth = write_truth_86_09(tmp_path / "truth.csv")
    cli("ingest", DATA / "cmu" / "86", "--silent")
    r = cli("train", "--model", "cmu86", "--labels", truth, "--silent")
    assert r.exit_code == 0, r.output
    assert "model 'cmu86': 4 classes, 4 labels" in r.output  # walk, look_around, clap, stand_and_clap
    r = cli("evaluate", "--truth", truth, "--model", "cmu86", "--no-keyframes")
    p1, r1, f1, p2, r2, f2 = eval_scores(r.output)
    assert r1 > 0.8 and r2 == 1.0  # every labelled segment is found again by its own template
    bad = tmp_path / "bad.csv"
    bad.write_text("document,label,start_frame,end_frame\n86_09,walk,10,5\n")
    r = cli("train", "--model", "bad", "--labels", bad, "--silent")
    assert r.exit_code == 1 and f"{bad}:2" in r.output and "before start_frame" in r.output


def test_a_mistyped_db_is_refused_by_the_commands_that_only_read(tmp_path):
    """A --db that does not exist is an error for every command that reads an archive: no empty file appears."""
    missing = tmp_path / "mistyped.duckdb"
    truth = tmp_path / "t.csv"
    truth.write_text("document,label,start_frame,end_frame\n86_09,walk,1,120\n")
    for args in (["annotate"], ["view", "86_09", "--out", str(tmp_path / "p.html")], ["sql", "SELECT 1"],
                 ["evaluate", "--truth", str(truth)], ["delete", "1"],
                 ["create-index"], ["drop-index"], ["export-features", str(tmp_path / "x")],
                 ["relocate", "/a", "/b"], ["report", "--figure", "ga", "--out", str(tmp_path / "f.png")]):
        r = run(missing, *args, code=1)
        assert "no such database file (a mistyped --db?" in r.output, (args, r.output)
        assert not missing.exists()


@pytest.mark.shared
def test_ingest_exits_1_when_any_file_failed(tmp_path):
    d, _ = _broken_folder(tmp_path)
    r = run(tmp_path / "n.duckdb", "ingest", d, "--silent", code=1)
    assert "2 ingested, 0 skipped, 1 failed" in r.output
    r = run(tmp_path / "n.duckdb", "ingest", d / "good", "--silent")
    assert "0 ingested, 2 skipped, 0 failed" in r.output


def _broken_folder(tmp_path):
    d = tmp_path / "takes"
    (d / "good").mkdir(parents=True)
    shutil.copy(DATA / "cmu" / "02" / "02.asf", d / "good")
    for name in ("02_01.amc", "02_02.amc"):
        shutil.copy(DATA / "cmu" / "02" / name, d / "good" / name)
    (d / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    return d, d / "good"


def test_annotate_on_an_empty_database_says_ingest_first(cli):
    r = cli("annotate")
    assert r.exit_code == 1 and "holds no motions: ingest recordings first" in r.output


@pytest.mark.slow
def test_annotate_csv_given_back_as_truth_scores_one(cli, tmp_path):
    """The annotation CSV carries its frame grid (fps): as --truth it reads onto exactly its own frames
    (F1 = 1, not the 0.375 of reading 30 Hz frames as 120 Hz ones), and as --labels it trains."""
    cli("ingest", SAMPLE_86_09, "--silent")
    seg = tmp_path / "seg.csv"
    assert cli("annotate", "--format", "csv", "--out", seg).exit_code == 0
    r = cli("evaluate", "--truth", seg)
    assert r.exit_code == 0 and eval_scores(r.output) == [1.0] * 6, r.output
    r = cli("evaluate", "--truth", seg, "--pred", seg)
    assert eval_scores(r.output) == [1.0] * 6
    r = cli("train", "--model", "again", "--labels", seg, "--silent")
    assert r.exit_code == 0 and "model 'again'" in r.output
    js = json.loads(cli("annotate", "--format", "json").output)
    assert {s["fps"] for s in js} == {30} and all(round(s["start_s"], 4) == s["start_s"] for s in js)


@pytest.mark.slow
def test_the_compile_messages_say_what_happens_and_how_long(cli, tmp_path, monkeypatch):
    """First run (an empty kernel cache): the command says it compiles and, at its end, how long it took;
    a command that waits for the background warm-up says so and for how long."""
    import fcntl
    import threading
    import time

    cli("ingest", SAMPLE_86_09, "--silent")
    cold = tmp_path / "cold-cache"
    cold.mkdir()
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cold))  # read by the CLI's check; the kernels are compiled already
    r = cli("annotate", "--silent")
    assert r.output.startswith("Compiling the numba kernels: this install has no usable compiled cache (a first run, "
                               "or another numba)…")
    assert re.search(r"First run: \d+ s, most of it compiling; later runs skip that\.", r.output)
    # the cache is warm (an index this numba wrote for the source as it is), but a warm-up still compiles
    import pickle

    import numba

    from mocapdb import warmup
    source = Path(warmup.__file__).parent / "features" / "relational.py"
    folder = next(c for d, c in warmup._cache_dirs() if d == source.parent)
    folder.mkdir(parents=True)
    with open(folder / "relational._hysteresis_kernel-1.py311.nbi", "wb") as fh:
        pickle.dump(numba.__version__, fh)
        fh.write(pickle.dumps((warmup._source_stamp(source), {})))
    lock = cold / "mocapdb-compile-search.lock"
    with open(lock, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        threading.Thread(target=lambda: (time.sleep(1.5), fcntl.flock(fh, fcntl.LOCK_UN))).start()
        r = cli("annotate", "--silent")
    assert "Waiting for the numba kernels compiling in the background (first run only)…" in r.output
    waited = int(re.search(r"…compiled; waited (\d+) s\.", r.output).group(1))
    assert 1 <= waited <= 3


def test_the_readme_names_only_options_the_commands_have():
    """Each command's row of the user guide's command table names options of that command only
    (a renamed option, --map → --label-map, cannot linger), and help and the docs agree on defaults."""
    readme = (REPO / "docs" / "USER_GUIDE.md").read_text(encoding="utf-8")
    rows = re.findall(r"^\| `([a-z-]+)[^|]*\|(.*)\|$", readme, flags=re.M)
    checked = 0
    for name, text in rows:
        cmd = main.commands.get(name)
        if cmd is None:
            continue
        have = {o for p in cmd.params for o in (*p.opts, *p.secondary_opts)} | {"--help"}
        named = {m.split("/")[0] for m in re.findall(r"`(--[a-z-]+(?:/--[a-z-]+)?)", text)}
        named |= {m for m in re.findall(r"`--[a-z-]+/(--[a-z-]+)`", text)}
        assert named <= have, f"README row of {name!r} names {sorted(named - have)}, which it does not have"
        checked += 1
    assert checked >= 15
    # the --margin default: the model's, 0 (off) for the shipped models, in help and README alike
    with mocapdb.connect() as con:
        margins = dict(con.execute("SELECT model, margin FROM models WHERE shipped").fetchall())
    assert margins == {"default": 0.0, "toolbox": 0.0}
    help_text = CliRunner().invoke(main, ["annotate", "--help"]).output
    assert "default: the model's margin, 0 for the shipped models = off" in " ".join(help_text.split())
    docs = " ".join(user_docs_text().split())
    assert "default: the model's margin, which is 0, off, for both shipped models" in docs
    joint_help = " ".join(CliRunner().invoke(main, ["ingest", "--help"]).output.split())
    assert "a list of joints (their mean)" in joint_help and "a list of joints (their mean)" in docs


def test_sql_takes_a_commented_query_of_several_statements_from_an_argument_stdin_or_a_file(cli, tmp_path):
    query = ("-- a comment first, as the README's examples start\n"
             "CREATE TABLE t AS SELECT 1 AS x; INSERT INTO t VALUES (2), (3);\n"
             "SELECT count(*) AS n FROM t; -- a comment last\n")
    r = cli("sql", query)
    assert r.exit_code == 0, r.output
    assert r.output.split("\n\n") == ["ok, 1 row(s) changed", "ok, 2 row(s) changed", "n\n-\n3\n"]
    r = CliRunner().invoke(main, ["--db", str(tmp_path / "cli.duckdb"), "sql", "-", "--format", "csv"],
                           input="-- count\nSELECT count(*) AS n FROM t")
    assert r.output == "n\n3\n"
    f = tmp_path / "q.sql"
    f.write_text("SELECT sum(x) AS s FROM t")
    assert cli("sql", "--file", f, "--format", "json").output.strip() == '[\n {\n  "s": 6\n }\n]'
    r = cli("sql", "-- only a comment")
    assert r.exit_code == 2 and "holds no SQL statement" in r.output
