"""The keyframe index as DuckDB tables, kept in step with ``features``.

Like DuckDB's fts extension, the index is plain tables in its own schema
(``mocap_index``), built and dropped by one call each, and queried through
macros (``keyframe_search``, sql/macros.sql). Every ingest and delete updates
it in the same transaction as ``features`` while it exists; a new database
gets it at creation.

``mocap_index.postings`` holds the runs of constant feature word of every
motion, once per index part: the toolbox's per-set indexes (``upper``,
``lower``, ``mix``: the word restricted to the set's bits, shifted to bit 0)
and ``full`` (the 40-bit word) — see benchmarks/RESULTS.md for why both.
A posting list is ``SELECT motion_id, seg … WHERE feature_set = ? AND word = ?
ORDER BY motion_id, seg``.
"""
from __future__ import annotations

import numpy as np
import pyarrow as pa

from .index import INDEX_PARTS, Index, build_index

INDEX_SCHEMA = "mocap_index"
#: index parts stored (all four: per-set for toolbox queries, 40-bit for learned ones)
STORED_PARTS = INDEX_PARTS

_DDL = f"""
CREATE SCHEMA IF NOT EXISTS {INDEX_SCHEMA};
CREATE TABLE IF NOT EXISTS {INDEX_SCHEMA}.postings (
    motion_id    INTEGER NOT NULL,
    feature_set  VARCHAR NOT NULL,     -- upper, lower, mix, full
    seg          INTEGER NOT NULL,     -- run number within (motion, feature_set), from 1
    word         UBIGINT NOT NULL,     -- the run's word (restricted to the set, shifted)
    start_frame  INTEGER NOT NULL,     -- 1-based 30 Hz frame, as features.frame
    n_frames     INTEGER NOT NULL
);
"""


def index_exists(con) -> bool:
    """Whether the database has the keyframe index tables."""
    return bool(con.execute(
        "SELECT count(*) FROM duckdb_tables() WHERE schema_name = ? AND table_name = 'postings'",
        [INDEX_SCHEMA]).fetchall()[0][0])


def postings_table(words_by_motion: dict) -> pa.Table:
    """Postings rows of motions: ``{motion_id: (n,) uint64 words}`` → Arrow table."""
    ids = list(words_by_motion)
    index = build_index([np.asarray(words_by_motion[i], dtype=np.uint64) for i in ids],
                        feature_sets=STORED_PARTS)
    cols = index.to_columns()
    motion = np.asarray(ids, dtype=np.int32)[cols["doc"]] if ids else np.zeros(0, np.int32)
    return pa.table({
        "motion_id": pa.array(motion, pa.int32()),
        # part names decoded by Arrow from the codes (not millions of Python strings)
        "feature_set": pa.DictionaryArray.from_arrays(
            pa.array(cols["feature_set"], pa.int8()), pa.array(INDEX_PARTS, pa.string())
        ).dictionary_decode(),
        "seg": pa.array(cols["seg"] + 1, pa.int32()),
        "word": pa.array(cols["word"], pa.uint64()),
        "start_frame": pa.array(cols["start_frame"] + 1, pa.int32()),
        "n_frames": pa.array(cols["n_frames"], pa.int32()),
    })


def insert_postings(con, words_by_motion: dict) -> None:
    """Add the postings of motions (inside the caller's transaction)."""
    if not words_by_motion:
        return
    table = postings_table(words_by_motion)
    con.register("_mocapdb_new_postings", table)
    try:
        con.execute(f"INSERT INTO {INDEX_SCHEMA}.postings SELECT * FROM _mocapdb_new_postings")
    finally:
        con.unregister("_mocapdb_new_postings")


def create_index(con, *, batch_frames: int = 4_000_000) -> int:
    """(Re)build the keyframe index from ``features`` in one transaction.

    Returns the number of postings rows.
    """
    con.begin()
    try:
        con.execute(f"DROP SCHEMA IF EXISTS {INDEX_SCHEMA} CASCADE")
        con.execute(_DDL)
        meta = con.execute("SELECT motion_id, n_frames FROM motions ORDER BY motion_id").fetchall()
        batch, frames = [], 0
        for mid, n in meta + [(None, 0)]:
            if mid is not None:
                batch.append(mid)
                frames += n
            if batch and (mid is None or frames >= batch_frames):
                bits = con.execute(
                    f"SELECT motion_id, bits FROM features WHERE motion_id BETWEEN ? AND ? "
                    f"ORDER BY motion_id, frame", [batch[0], batch[-1]]).fetchnumpy()
                ids, starts = np.unique(bits["motion_id"], return_index=True)
                chunks = np.split(np.asarray(bits["bits"], np.uint64), starts[1:])
                insert_postings(con, dict(zip(ids.tolist(), chunks)))
                batch, frames = [], 0
        n = con.execute(f"SELECT count(*) FROM {INDEX_SCHEMA}.postings").fetchall()[0][0]
        con.commit()
    except BaseException:
        con.rollback()
        raise
    _refresh_macros(con)
    return n


def _refresh_macros(con):
    """Re-install the keyframe search macros after the index appeared or vanished
    (on connections where the extension is registered; schema setup runs before)."""
    from .database import sql_text

    registered = con.execute("SELECT count(*) FROM duckdb_functions() "
                             "WHERE function_name = 'mocap_keyframe_search'").fetchall()[0][0]
    if registered:
        con.execute(sql_text("keyframe_macros.sql" if index_exists(con) else "keyframe_macros_missing.sql"))


def drop_index(con) -> None:
    """Remove the keyframe index (``DROP SCHEMA mocap_index CASCADE``)."""
    con.execute(f"DROP SCHEMA IF EXISTS {INDEX_SCHEMA} CASCADE")
    _refresh_macros(con)


def motion_positions(ids, motion_id) -> np.ndarray:
    """Position of every ``motion_id`` in the ascending id list ``ids`` (all must occur).

    A lookup table when the ids are dense enough (millions of rows: ~20x
    faster than a binary search each), else a binary search.
    """
    ids = np.asarray(ids, dtype=np.int64)
    motion_id = np.asarray(motion_id, dtype=np.int64)
    if len(ids) and 0 <= ids[0] and ids[-1] < 4 * len(ids) + (1 << 20):
        lut = np.zeros(int(ids[-1]) + 1, np.int64)
        lut[ids] = np.arange(len(ids))
        return lut[motion_id]
    return np.searchsorted(ids, motion_id)


def load_index(con, motion_ids=None, *, parts=STORED_PARTS) -> tuple[Index, list]:
    """The stored postings as a searchable :class:`~mocapdb.index.Index`.

    Returns
    -------
    index : Index
        Document ``d`` is ``motion_ids[d]``.
    motion_ids : list of int
    """
    where, params = "", []
    if motion_ids is not None:
        motion_ids = [int(i) for i in motion_ids]
        where, params = f"WHERE motion_id IN ({', '.join('?' * len(motion_ids))})", motion_ids
    meta = con.execute(f"SELECT motion_id, n_frames FROM motions {where} ORDER BY motion_id", params).fetchall()
    ids = [m[0] for m in meta]
    marks = ", ".join("?" * len(parts))
    # the part as its integer code, computed by DuckDB: millions of Python
    # strings would cost more than the rest of the load together
    names = "[" + ", ".join(f"'{name}'" for name in INDEX_PARTS) + "]"
    rows = con.execute(
        f"SELECT motion_id, coalesce(list_position({names}, feature_set), 0)::TINYINT - 1 AS part, "
        f"seg - 1 AS seg, word, start_frame - 1 AS start_frame, n_frames FROM {INDEX_SCHEMA}.postings "
        f"WHERE feature_set IN ({marks}) {('AND ' + where[6:]) if where else ''}",
        [*parts, *params]).fetchnumpy()
    doc = motion_positions(ids, rows["motion_id"])
    index = Index.from_columns(doc, rows["part"], rows["seg"], rows["word"], rows["start_frame"],
                               rows["n_frames"], doc_lengths=[m[1] for m in meta])
    return index, ids


__all__ = ["INDEX_SCHEMA", "index_exists", "create_index", "drop_index", "insert_postings", "load_index",
           "motion_positions", "postings_table"]
