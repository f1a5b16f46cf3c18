"""The keyframe index as DuckDB tables (``sql/index.sql``), kept in step with ``features``.

Like DuckDB's fts extension, the index is plain tables in its own schema
(``mocap_index``): ``postings`` holds the runs of constant feature word of
every motion, once per index part — the toolbox's per-set indexes (``upper``,
``lower``, ``mix``) and ``full`` (the 40-bit word), see benchmarks/RESULTS.md
for why both — and ``state`` holds a version number that every change bumps.
A new database gets the index; :func:`drop_index` removes the postings and
:func:`create_index` rebuilds them from ``features``. Ingest, delete and
import update them in their own transaction while they exist.

:func:`load_index` reads the postings back as a searchable
:class:`mocapdb.keyframes.Index` (the connection cache of
:mod:`mocapdb.storage.cache` keeps one per connection).
"""
from __future__ import annotations

import numpy as np
import pyarrow as pa

from mocapdb.errors import SchemaError
from mocapdb.keyframes import INDEX_PARTS, Index, build_index
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction

#: index parts stored (all four: per-set for toolbox queries, 40-bit for learned ones)
STORED_PARTS = INDEX_PARTS


def _sql(name):
    return statement("index.sql", name)


def create_index_schema(con) -> None:
    """Create the schema and its ``state`` table if missing (no postings)."""
    con.execute(_sql("create_schema"))


def index_version(con):
    """The index version (bumped by every change), or None when no index is built."""
    rows = con.execute(_sql("version")).fetchall()
    return rows[0][0] if rows else None


def index_exists(con) -> bool:
    """Whether the keyframe index is built (``mocap_index.postings`` exists)."""
    return index_version(con) is not None


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


def index_motions(con, words_by_motion: dict) -> None:
    """Add the postings of new motions and bump the version (inside the caller's transaction).

    Does nothing when the index is not built.
    """
    if not index_exists(con):
        return
    if words_by_motion:
        with registered(con, mocap_new_postings=postings_table(words_by_motion)):
            con.execute(_sql("insert_postings"))
    con.execute(_sql("bump_version"))


def unindex_motions(con, motion_ids) -> None:
    """Remove the postings of motions and bump the version (inside the caller's transaction)."""
    if not index_exists(con):
        return
    con.execute(_sql("delete_postings"), {"ids": [int(i) for i in motion_ids]})
    con.execute(_sql("bump_version"))


def create_index(con, *, batch_frames: int = 4_000_000) -> int:
    """(Re)build the keyframe index from ``features`` in one transaction.

    Returns
    -------
    int
        The number of postings rows.
    """
    with transaction(con):
        create_index_schema(con)
        con.execute(_sql("create_postings"))
        con.execute(_sql("bump_version"))
        meta = con.execute(_sql("motion_lengths")).fetchall()
        batch, frames = [], 0
        for mid, n in meta + [(None, 0)]:
            if mid is not None:
                batch.append(mid)
                frames += n
            if batch and (mid is None or frames >= batch_frames):
                bits = con.execute(_sql("features_of_motions"), {"first": batch[0], "last": batch[-1]}).fetchnumpy()
                ids, starts = np.unique(bits["motion_id"], return_index=True)
                chunks = np.split(np.asarray(bits["bits"], np.uint64), starts[1:])
                index_motions(con, dict(zip(ids.tolist(), chunks)))
                batch, frames = [], 0
        return con.execute(_sql("count_postings")).fetchall()[0][0]


def drop_index(con) -> None:
    """Remove the keyframe index's postings (the version becomes NULL: no index)."""
    with transaction(con):
        create_index_schema(con)
        con.execute(_sql("drop_postings"))


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


def load_index(con, *, parts=STORED_PARTS, motions=None) -> tuple[Index, np.ndarray]:
    """The stored postings as a searchable :class:`~mocapdb.keyframes.Index`.

    Parameters
    ----------
    parts : sequence of str
        The index parts to load (default all).
    motions : (motion_ids, n_frames), optional
        Only these motions (ids ascending, with their frame counts): a batch
        of an archive-wide pass, whose memory then does not grow with the
        archive (:mod:`mocapdb.storage.cache`). Default: every motion.

    Returns
    -------
    index : Index
        Document ``d`` is motion ``motion_ids[d]``.
    motion_ids : (n_docs,) int64, ascending

    Raises
    ------
    SchemaError
        A motion with frames has no postings (it was stored without the index).
    """
    # the part as its integer code, computed by DuckDB: millions of Python
    # strings would cost more than the rest of the load together
    params = {"parts": list(parts), "all_parts": list(INDEX_PARTS)}
    if motions is None:
        meta = con.execute(_sql("motion_lengths")).fetchnumpy()
        ids = np.asarray(meta["motion_id"], dtype=np.int64)
        lengths = np.asarray(meta["n_frames"], np.int64)
        rows = con.execute(_sql("load"), params).fetchnumpy()
    else:
        ids, lengths = (np.asarray(x, dtype=np.int64) for x in motions)
        rows = con.execute(_sql("load_motions"), {**params, "ids": ids.tolist(), "lo": int(ids[0]) if len(ids) else 0,
                                                  "hi": int(ids[-1]) if len(ids) else -1}).fetchnumpy()
    doc = motion_positions(ids, rows["motion_id"])
    indexed = np.zeros(len(ids), bool)
    indexed[doc] = True
    missing = ids[(lengths > 0) & ~indexed]
    if len(missing):
        raise SchemaError(f"motions {missing[:10].tolist()}{' …' if len(missing) > 10 else ''} are not in the "
                          "keyframe index; rebuild it with `mocapdb create-index`")
    index = Index.from_columns(doc, rows["part"], rows["seg"], rows["word"], rows["start_frame"],
                               rows["n_frames"], doc_lengths=lengths, parts=parts)
    return index, ids


__all__ = ["STORED_PARTS", "index_exists", "index_version", "create_index", "drop_index", "create_index_schema",
           "index_motions", "unindex_motions", "load_index", "motion_positions", "postings_table"]
