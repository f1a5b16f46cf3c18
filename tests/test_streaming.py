"""Archive-wide passes hold one batch of motions at a time (issue 20 item 1).

SQL ``annotate()`` (with and without keyframe preselection), ``mt_distance()``,
``keyframe_search()``, ``keyframe_search_words()``, ``mocapdb.annotate`` and
``import-features`` read the words and postings of a batch of motions, never
the archive's; with batches of a few hundred frames every read stays within
its batch, and the answers equal those of one batch. The memory figures at
10 to 1,000 hours are in benchmarks/RESULTS.md (bench_scale.py).
"""
import numpy as np
import pytest

import mocapdb
from mocapdb import api
from mocapdb.extension.connection import NATIVE_ENV
from mocapdb.storage import cache as cache_module
from mocapdb.storage import motions as motions_module
from mocapdb.storage.cache import connection_cache
from mocapdb.storage.schema import DEFAULT_MEMORY_LIMIT

from conftest import DATA

pytestmark = pytest.mark.shared

BATCH = 400  # 30 Hz frames: a few clips, or one long motion alone

QUERIES = {
    "annotate": "SELECT motion_id, annotate(motion_id) FROM motions ORDER BY motion_id",
    "annotate_no_keyframes": "SELECT motion_id, annotate(motion_id, keyframes := false, model := 'toolbox') "
                             "FROM motions ORDER BY motion_id",
    "annotate_some": "SELECT motion_id, annotate(motion_id) FROM motions WHERE motion_id % 3 = 1 "
                     "UNION ALL SELECT NULL, annotate(NULL) UNION ALL SELECT 9999, annotate(9999) ORDER BY ALL",
    "mt_distance": "SELECT motion_id, mt_distance(motion_id, 'kickLFront1Reps') FROM motions ORDER BY motion_id",
    "keyframe_search": "SELECT * FROM keyframe_search('kickLFront1Reps', extend := true) ORDER BY ALL",
    "keyframe_search_words": "SELECT * FROM keyframe_search_words([1023], [5], [], []) ORDER BY ALL",
}


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    path = tmp_path_factory.mktemp("streaming") / "archive.duckdb"
    con = mocapdb.connect(path)
    report = mocapdb.ingest(con, [DATA / "hdm05_cut" / "kickLFront1Reps", DATA / "hdm05_cut" / "squat1Reps",
                                  DATA / "cmu" / "86" / "86_09.amc"])
    assert not report.failed
    con.close()
    return path


class Spy:
    """Records the size of every read of words and postings."""

    def __init__(self, monkeypatch):
        self.words, self.index = [], []
        check, load = motions_module.check_frames, cache_module.load_index

        def check_frames(ids, n_frames, *rows):
            self.words.append(int(np.sum(n_frames)))
            return check(ids, n_frames, *rows)

        def load_index(con, *, parts, motions):
            self.index.append(int(np.sum(motions[1])))
            return load(con, parts=parts, motions=motions)

        monkeypatch.setattr(motions_module, "check_frames", check_frames)
        monkeypatch.setattr(cache_module, "load_index", load_index)


def _longest(con):
    return con.execute("SELECT max(n_frames) FROM motions").fetchall()[0][0]


def test_sql_functions_read_a_batch_of_motions_at_a_time(db, monkeypatch):
    # the Python UDFs' batches (the native functions read batches of ≤ 10⁶ frames: bench_native.py crosses one)
    monkeypatch.setenv(NATIVE_ENV, "0")
    with mocapdb.connect(db, read_only=True) as con:
        whole = {k: con.execute(q).fetchall() for k, q in QUERIES.items()}
        total = con.execute("SELECT sum(n_frames) FROM motions").fetchall()[0][0]
        # small batches: their index pieces are other keys of the cache, so everything is read again
        connection_cache(con).batch_frames = BATCH
        spy = Spy(monkeypatch)
        for k, q in QUERIES.items():
            assert con.execute(q).fetchall() == whole[k], k
        limit = max(BATCH, _longest(con))
    assert total > 10 * BATCH
    assert len(spy.words) > 10 and max(spy.words) <= limit
    assert len(spy.index) > 10 and max(spy.index) <= limit
    assert any(len(v) for v in whole.values()) and len(whole["keyframe_search"]) >= 20


def test_a_pass_larger_than_the_index_cache_finds_its_first_batches_again(db, monkeypatch):
    """The cache keeps the first batches of a pass (it evicts the batch used last): the second
    pass over an archive larger than the cache reads only the batches that did not fit, and a
    pass within the cache reads nothing (the Python UDFs' cache)."""
    monkeypatch.setenv(NATIVE_ENV, "0")
    con = mocapdb.connect(db, read_only=True)
    try:
        cache = connection_cache(con)
        cache.batch_frames = BATCH
        query = QUERIES["keyframe_search"]
        want = con.execute(query).fetchall()
        sizes = [x.nbytes for x in cache._indexes.values()]
        # room for the first two batches of a pass and one more
        monkeypatch.setattr(cache_module, "INDEX_CACHE_BYTES", sum(sizes[:2]) + max(sizes))
        cache._indexes.clear()
        spy = Spy(monkeypatch)
        assert con.execute(query).fetchall() == want
        first = len(spy.index)
        assert con.execute(query).fetchall() == want
        second = len(spy.index) - first
        monkeypatch.setattr(cache_module, "INDEX_CACHE_BYTES", 2**40)
        assert con.execute(query).fetchall() == want  # fills the cache
        before = len(spy.index)
        assert con.execute(query).fetchall() == want
        third = len(spy.index) - before
    finally:
        con.close()
    assert len(sizes) > 5 and first == len(sizes)
    assert second == first - 2  # the first two batches were kept for the next pass
    assert third == 0


def test_the_api_annotates_and_stores_a_batch_at_a_time(db, tmp_path, monkeypatch):
    import shutil

    copy = tmp_path / "copy.duckdb"
    shutil.copy(db, copy)
    with mocapdb.connect(copy) as con:
        whole = api.annotate(con, store=False)
        connection_cache(con).batch_frames = BATCH
        spy = Spy(monkeypatch)
        pieces = api.annotate(con)
        stored = con.execute("SELECT count(*) FROM annotations WHERE model = 'default'").fetchall()[0][0]
        limit = max(BATCH, _longest(con))
    assert pieces.equals(whole) and stored == whole.num_rows > 0
    assert len(spy.words) > 5 and max(spy.words) <= limit


def test_import_reads_and_stores_a_batch_at_a_time(db, tmp_path, monkeypatch):
    from mocapdb.storage.parquet import export_features, import_features

    with mocapdb.connect(db, read_only=True) as con:
        export_features(con, tmp_path / "export")
        expected = con.execute("SELECT m.sha256, f.frame, f.bits FROM features f JOIN motions m USING (motion_id) "
                               "ORDER BY ALL").fetchall()
        n = con.execute("SELECT count(*) FROM motions").fetchall()[0][0]
    with mocapdb.connect(tmp_path / "fresh.duckdb") as fresh:
        reads = []
        real = motions_module.check_frames

        def check_frames(ids, n_frames, *rows):
            reads.append(int(np.sum(n_frames)))
            return real(ids, n_frames, *rows)

        monkeypatch.setattr("mocapdb.storage.parquet.check_frames", check_frames)
        report = import_features(fresh, tmp_path / "export", max_frames=BATCH)
        assert not report.failed and len(report.imported) == n
        got = fresh.execute("SELECT m.sha256, f.frame, f.bits FROM features f JOIN motions m USING (motion_id) "
                            "ORDER BY ALL").fetchall()
        limit = max(BATCH, _longest(fresh))
        # the postings were built batch by batch too: the same keyframe search as the source
        hits = fresh.execute("SELECT count(*) FROM keyframe_search('kickLFront1Reps')").fetchall()
    assert got == expected
    assert len(reads) > 5 and max(reads) <= limit
    with mocapdb.connect(db, read_only=True) as con:
        assert hits == con.execute("SELECT count(*) FROM keyframe_search('kickLFront1Reps')").fetchall()


def test_duckdb_runs_within_a_memory_limit(tmp_path, monkeypatch):
    """DuckDB's own default (80 % of RAM) would let its cache of table blocks grow with the archive."""
    def limit(con):
        return con.execute("SELECT current_setting('memory_limit')").fetchall()[0][0]

    monkeypatch.delenv("MOCAPDB_MEMORY_LIMIT", raising=False)
    with mocapdb.connect(tmp_path / "a.duckdb") as con:
        default = limit(con)
    assert default == "488.2 MiB" and DEFAULT_MEMORY_LIMIT == "512MB"
    with mocapdb.connect(tmp_path / "a.duckdb", memory_limit="2GB") as con:
        assert limit(con) == "1.8 GiB"
    monkeypatch.setenv("MOCAPDB_MEMORY_LIMIT", "300MB")
    with mocapdb.connect(tmp_path / "a.duckdb", read_only=True) as con:
        assert limit(con) == "286.1 MiB"
    with pytest.raises(mocapdb.SchemaError, match="memory_limit: 'lots' is not a memory size"):
        mocapdb.connect(tmp_path / "a.duckdb", memory_limit="lots")
