"""Ingest on worker processes (issue 35): the same words and the same outcome per file as before.

An archive's files are fingerprinted and read in worker processes
(``mocapdb.storage.ingest_pool``); a few files stay on threads. Whichever
runs, every file must end as it did: stored with the same words, skipped, or
refused with the same reason, and a worker that dies costs its own file only.
The words of every recording of ``../shared/data`` are checked against
digests made by d3b3f07, the code before this work (``tests/feature_digests.py``).
"""
import importlib.util
import json
import math
import os
import shutil

import numpy as np
import pytest

import mocapdb
import mocapdb.storage.ingest_pool as ingest_pool
from mocapdb.storage.ingest_pool import WorkerDied, executor, ordered

from conftest import DATA
from feature_digests import DIGESTS, ingest_digests


@pytest.fixture
def on_processes(monkeypatch):
    """Every ingest of the test on worker processes, however few its files and busy the machine."""
    monkeypatch.setattr(ingest_pool, "PROCESS_MIN_BYTES", 0)
    monkeypatch.setattr(ingest_pool, "_idle_cores", lambda: 2.0)


def test_processes_only_for_enough_work_and_a_free_core(monkeypatch):
    monkeypatch.setattr(ingest_pool, "_idle_cores", lambda: 1.5)
    assert ingest_pool.use_processes(100, 1 << 30, 2)
    assert not ingest_pool.use_processes(100, 1 << 20, 2)     # a few MB: threads
    assert not ingest_pool.use_processes(3, 1 << 30, 2)       # fewer files than two per worker
    assert not ingest_pool.use_processes(100, 1 << 30, 1)
    monkeypatch.setattr(ingest_pool, "_idle_cores", lambda: 0.2)
    assert not ingest_pool.use_processes(100, 1 << 30, 2)     # every core busy: threads


def test_the_pool_answers_in_order_and_a_bad_item_costs_only_itself():
    items = [4.0, 9.0, -1.0, 16.0] * 5   # math.sqrt(-1) raises in the worker
    with executor(2, True) as pool:
        got = list(ordered(pool, math.sqrt, items, window=2, chunk=3))
        assert [g for g in got if not isinstance(g, WorkerDied)] == [2.0, 3.0, 4.0] * 5
        bad = [g for g in got if isinstance(g, WorkerDied)]
        assert len(bad) == 5 and all("ValueError" in str(b) for b in bad)
        assert [i for i, g in enumerate(got) if isinstance(g, WorkerDied)] == [2, 6, 10, 14, 18]
        # a worker that dies (a crash in a native library) is replaced; its own task reports it
        died = list(ordered(pool, os._exit, [3], window=1))
        assert isinstance(died[0], WorkerDied) and "exit status 3" in str(died[0])
        assert list(ordered(pool, abs, [-2, -3, 5], window=2, chunk=2)) == [2, 3, 5]
        # the workers run this very mocapdb (a checkout on sys.path as much as an install)
        spec, = ordered(pool, importlib.util.find_spec, ["mocapdb"], window=1)
        assert spec.origin == mocapdb.__file__


def _archive(tmp_path):
    """Real takes (three HDM05 classes, CMU 86_09, the pymo BVH walk) and broken files beside them:
    a truncated AMC, a BVH of garbage, a copy of a take under another name, a copy of the broken one."""
    root = tmp_path / "archive"
    cut = root / "hdm05_cut"
    cut.mkdir(parents=True)
    for asf in (DATA / "hdm05_cut").glob("*.asf"):
        shutil.copyfile(asf, cut / asf.name)
    for cls in ("kickLFront1Reps", "hopBothLegs1hops", "lieDownFloor"):
        shutil.copytree(DATA / "hdm05_cut" / cls, cut / cls)
    shutil.copytree(DATA / "cmu" / "86", root / "cmu86")
    shutil.copyfile(DATA / "foreign" / "bvh" / "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh", root / "walk.bvh")
    broken = cut / "broken"
    broken.mkdir()
    take = sorted((cut / "kickLFront1Reps").glob("*.amc"))[0]
    data = take.read_bytes()
    (broken / "HDM_bd_cut_001_120.amc").write_bytes(data[: len(data) // 2] + b"\n12x 0 0\n")
    (broken / "HDM_bd_cut_002_120.amc").write_bytes(data[: len(data) // 2] + b"\n12x 0 0\n")
    (broken / "HDM_bd_copy_001_120.amc").write_bytes(data)
    (root / "garbage.bvh").write_bytes(b"HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 zero\n")
    return root


def _outcome(con, report):
    words = {}
    for path, bits in con.execute("SELECT m.source_path, list(f.bits ORDER BY f.frame) FROM motions m "
                                  "JOIN features f USING (motion_id) GROUP BY ALL").fetchall():
        words[path] = np.array(bits, dtype=np.uint64)
    log = sorted(con.execute("SELECT path, outcome, reason FROM ingest_log").fetchall())
    return ([(p, n) for p, _, n in report.ingested], report.failed, report.skipped, report.notes, words, log)


@pytest.mark.shared
def test_a_worker_started_during_the_walk_ends_when_the_walk_fails(tmp_path, monkeypatch, open_db):
    monkeypatch.setattr(ingest_pool, "_idle_cores", lambda: 2.0)
    started, cancelled = [], []
    worker = ingest_pool._Worker
    monkeypatch.setattr(ingest_pool, "_Worker", lambda: started.append(worker()) or started[-1])
    cancel = worker.cancel
    monkeypatch.setattr(worker, "cancel", lambda self: cancelled.append(self) or cancel(self))
    con = open_db(tmp_path / "db.duckdb")
    with pytest.raises(mocapdb.errors.ParameterError, match="not_there"):
        mocapdb.ingest(con, [DATA / "hdm05_cut", tmp_path / "not_there"])
    assert len(started) == 1 and cancelled == started
    started[0].proc.wait(timeout=10)
    assert started[0].proc.returncode == -9   # killed, not left importing
    assert con.execute("select count(*) from motions").fetchone()[0] == 0


@pytest.mark.shared
def test_processes_store_what_threads_store_and_refuse_what_they_refuse(tmp_path, monkeypatch, open_db):
    root = _archive(tmp_path)
    results = {}
    monkeypatch.setattr(ingest_pool, "_idle_cores", lambda: 2.0)
    started = []
    worker = ingest_pool._Worker
    monkeypatch.setattr(ingest_pool, "_Worker", lambda: started.append(1) or worker())
    cancelled = []
    cancel = worker.cancel
    monkeypatch.setattr(worker, "cancel", lambda self: cancelled.append(1) or cancel(self))
    for mode, threshold in (("threads", 1 << 62), ("processes", 0)):
        monkeypatch.setattr(ingest_pool, "PROCESS_MIN_BYTES", threshold)
        con = open_db(tmp_path / f"{mode}.duckdb")
        ticks = []
        report = mocapdb.ingest(con, [root], progress=lambda done, total, path: ticks.append((done, total)))
        results[mode] = _outcome(con, report)
        assert ticks[-1][0] == ticks[-1][1] == len(report.ingested) + len(report.failed) + len(report.skipped)
        assert [done for done, _ in ticks] == list(range(1, len(ticks) + 1))   # the writer thread ticks too
        again = mocapdb.ingest(con, [root])   # re-ingest: a no-op, decided by the workers' hashes
        assert not again.ingested and len(again.skipped) == len(report.ingested) + 1
        # one worker starts while the folder is walked (ended unused when the ingest runs on threads), and the
        # pool takes it: two workers per ingest on processes, the re-ingest's too
        assert (len(started), len(cancelled)) == ((2, 2) if mode == "threads" else (6, 2))
    ingested, failed, skipped, notes, words, log = results["processes"]
    assert results["threads"][:4] == results["processes"][:4]
    assert results["threads"][5] == log
    assert words.keys() == results["threads"][4].keys()
    for path, w in words.items():
        np.testing.assert_array_equal(w, results["threads"][4][path], err_msg=path)
    assert len(ingested) == 24 + 33 + 18 + 1 + 1
    assert sorted(os.path.basename(p) for p, _ in failed) == ["HDM_bd_cut_001_120.amc", "HDM_bd_cut_002_120.amc",
                                                              "garbage.bvh"]
    # the copy and its original: whichever the walk meets first is stored, the other skipped
    assert [os.path.basename(p) for p, _ in skipped] == ["HDM_bd_kickLFront1Reps_001_120.amc"]
    assert "same bytes as" in skipped[0][1] and "HDM_bd_copy_001_120.amc" in skipped[0][1]
    assert any("same bytes as" in reason and "which failed" in reason for _, reason in failed)


@pytest.mark.shared
def test_every_shared_recording_stores_the_words_d3b3f07_stored(tmp_path, on_processes):
    """Issue 35: features bit-identical to the code before it, for every recording of ../shared/data,
    ingested on worker processes (digests of the stored words made by d3b3f07: tests/feature_digests.py; the
    three ACCAD takes d3b3f07 refused, read since cd10d4b, by cd10d4b)."""
    want = json.loads(DIGESTS.read_text())["files"]
    got = ingest_digests(mocapdb, DATA, tmp_path / "all.duckdb")
    assert got.keys() == want.keys()
    differ = [p for p in want if got[p] != want[p]]
    assert not differ, differ[:10]
    stored = [v for v in want.values() if v != "failed"]
    assert len(stored) > 500 and sum(v["n_source_frames"] for v in stored) > 150_000


@pytest.mark.shared
def test_the_folder_listing_behind_the_skeleton_rule_sees_new_entries(tmp_path):
    """The folder's only ASF (the rule for takes that follow no name pattern) is listed once per folder,
    and listed again when the folder changes: a second ASF makes it ambiguous, removing it finds it again."""
    from mocapdb.readers import find_skeleton

    take = tmp_path / "walk_take.amc"
    shutil.copyfile(DATA / "cmu" / "02" / "02_01.amc", take)
    assert find_skeleton(take) is None
    shutil.copyfile(DATA / "cmu" / "02" / "02.asf", tmp_path / "subject.asf")
    assert find_skeleton(take) == tmp_path / "subject.asf"
    shutil.copyfile(DATA / "cmu" / "86" / "86.asf", tmp_path / "other.asf")
    assert find_skeleton(take) is None
    (tmp_path / "subject.asf").unlink()
    assert find_skeleton(take) == tmp_path / "other.asf"


@pytest.mark.shared
def test_a_take_is_read_once_and_a_stored_one_only_hashed(tmp_path, monkeypatch, open_db):
    """Issue 35: ingest hashes a plain take and reads it from the same bytes (one read of the file);
    a re-ingest hashes the takes and reads none of them."""
    import mocapdb.readers.sources as sources
    import mocapdb.storage.ingest_read as ingest_read

    root = tmp_path / "takes"
    shutil.copytree(DATA / "cmu" / "86", root / "cmu86")
    shutil.copyfile(DATA / "foreign" / "bvh" / "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh", root / "walk.bvh")
    takes = sorted(str(p) for p in root.rglob("*") if p.suffix in (".amc", ".bvh"))
    streamed, held, read = [], [], []
    raw, read_held, read_options = sources._raw_stream, sources.read_held, ingest_read.read_options
    monkeypatch.setattr(sources, "_raw_stream", lambda p: streamed.append(str(p)) or raw(p))
    monkeypatch.setattr(ingest_read, "read_held", lambda p: held.append(str(p)) or read_held(p))
    monkeypatch.setattr(ingest_read, "read_options",
                        lambda p, o, checked=False: read.append((str(p), checked)) or read_options(p, o, checked=checked))
    con = open_db()
    report = mocapdb.ingest(con, [root])   # a few files: on threads, in this process
    assert sorted(p for p, _, _ in report.ingested) == takes and not report.failed
    assert sorted(held) == takes and sorted(p for p, _ in read) == takes
    assert all(checked for _, checked in read)   # the held bytes the fingerprint checked are not checked again
    assert not set(streamed) & set(takes)   # no take opened again: hash and reader had the one read's bytes
    assert any(p.endswith(".asf") for p in streamed)   # the skeleton is read as before
    held.clear(), read.clear()
    again = mocapdb.ingest(con, [root])
    assert not again.ingested and len(again.skipped) == len(takes)
    assert sorted(held) == takes and read == []   # hashed, not read


@pytest.mark.shared
def test_stored_bytes_read_with_another_skeleton_are_read_again(tmp_path, open_db):
    """A take whose bytes are stored, given another skeleton, is a new motion: its hash prefix is among the
    stored ones, so the pool holds it back, and ingest reads it after the pass (the words of that skeleton)."""
    take = DATA / "cmu" / "86" / "86_09.amc"
    con = open_db(tmp_path / "a.duckdb")
    first = mocapdb.ingest(con, [take])
    second = mocapdb.ingest(con, [take], asf=DATA / "cmu" / "02" / "02.asf")
    assert len(first.ingested) == len(second.ingested) == 1 and not second.skipped
    fresh = open_db(tmp_path / "b.duckdb")
    mocapdb.ingest(fresh, [take], asf=DATA / "cmu" / "02" / "02.asf")
    words = "SELECT list(bits ORDER BY frame) FROM features WHERE motion_id = ?"
    got = con.execute(words, [second.ingested[0][1]]).fetchone()[0]
    assert got == fresh.execute("SELECT list(bits ORDER BY frame) FROM features").fetchone()[0]
    assert got != con.execute(words, [first.ingested[0][1]]).fetchone()[0]


@pytest.mark.shared
def test_a_copy_of_a_take_in_the_same_ingest_is_only_hashed(tmp_path, monkeypatch, open_db):
    """The pool remembers what it read in this ingest: a later copy of the same bytes is hashed, not read
    (one worker here, so the order is the files'), and skipped as a copy."""
    import mocapdb.storage.ingest_read as ingest_read
    from mocapdb.storage.ingest import ingest_files

    root = tmp_path / "takes"
    shutil.copytree(DATA / "cmu" / "86", root / "a")
    shutil.copyfile(root / "a" / "86_09.amc", root / "a" / "86_99.amc")
    read, read_options = [], ingest_read.read_options
    monkeypatch.setattr(ingest_read, "read_options",
                        lambda p, o, checked=False: read.append(p.name) or read_options(p, o, checked=checked))
    report = ingest_files(open_db(), [root], workers=1)
    assert "86_09.amc" in read and "86_99.amc" not in read and len(read) == len(set(read))
    assert [(os.path.basename(p), r) for p, r in report.skipped] == [
        ("86_99.amc", f"same bytes as {root / 'a' / '86_09.amc'} of this ingest")]
