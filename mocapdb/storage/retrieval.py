"""Query by example over a database: "find motions like this one" (issue 21; :mod:`mocapdb.retrieval`).

:func:`query_stretch` resolves a motion and a range to its words;
:func:`similar_stretches` runs the query over every motion and returns the
ranked result rows. Where the archive's words come from:

* with the keyframe index (every database has it unless dropped): the
  index a batch of motions at a time, through the connection's cache
  (:mod:`mocapdb.storage.cache`), whose ``full`` runs rebuild any stretch
  exactly (:mod:`mocapdb.retrieval.archive`);
* without it: the ``features`` table, a batch of ranges at a time.

Either way a query holds at most :data:`mocapdb.retrieval.BATCH_FRAMES`
archive frames at once.
"""
from __future__ import annotations

import dataclasses
import functools
import logging

import numpy as np
import pyarrow as pa

from mocapdb.errors import ParameterError, SchemaError
from mocapdb.retrieval import (BATCH_FRAMES, CELL_BUDGET, MIN_QUERY_S, best_hits, plan_query, preselect,
                               query_keyframes, rank_cells, sample_step, search_segments)
from mocapdb.retrieval.archive import index_words
from mocapdb.storage.cache import NO_INDEX, UNKNOWN, connection_cache
from mocapdb.storage.motions import frame_batches
from mocapdb.storage.postings import index_version
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered

log = logging.getLogger("mocapdb")

#: columns of a result row (frames 1-based inclusive at 30 Hz, seconds from the motion's start)
RESULT_COLUMNS = ("document", "motion_id", "start_frame", "end_frame", "start_s", "end_s", "cost")


def _sql(name):
    return statement("retrieval.sql", name)


def query_stretch(con, motion_id, start_frame=None, end_frame=None, *, start=None, end=None):
    """One query stretch: a motion and a range of it (:func:`check_range`), with its words.

    Returns
    -------
    (motion_id, first, last, words)
        0-based inclusive frames and the stretch's words.

    Raises
    ------
    SchemaError
        No such motion.
    ParameterError
        As :func:`check_range`, or a stretch shorter than :data:`mocapdb.retrieval.MIN_QUERY_S`.
    """
    rows = con.execute(_sql("motion_meta"), {"ids": [int(motion_id)]}).fetchall()
    if not rows:
        raise SchemaError(f"no motion with id {motion_id} (see: SELECT motion_id, name FROM motions)")
    _, name, fps, n = rows[0]
    first, last = check_range(f"motion {motion_id} ({name!r})", n, fps, start_frame, end_frame, start=start, end=end)
    if (last - first + 1) / fps < MIN_QUERY_S - 1e-9:
        raise ParameterError(f"the query stretch {first + 1}–{last + 1} of motion {motion_id} ({name!r}) is "
                             f"{last - first + 1} frame(s), {(last - first + 1) / fps:.2f} s; a query needs at least "
                             f"{MIN_QUERY_S:g} s ({int(np.ceil(MIN_QUERY_S * fps - 1e-9))} frames at {fps:g} Hz): "
                             "a shorter one is a few words found everywhere, and every match would be as short")
    words = np.asarray(con.execute(_sql("motion_words"), {"id": int(motion_id)}).fetchnumpy()["bits"], np.uint64)
    return int(motion_id), first, last, words[first:last + 1]


def _sql_fetch(con):
    def fetch(motion, start, stop):
        ranges = pa.table({"ord": pa.array(np.arange(len(motion)), pa.int64()),
                           "motion_id": pa.array(motion, pa.int32()),
                           "first": pa.array(start + 1, pa.int32()), "last": pa.array(stop, pa.int32())})
        with registered(con, mocap_ranges=ranges):
            return con.execute(_sql("range_words")).fetchnumpy()["bits"]
    return fetch


def check_range(what, n_frames, fps, start_frame=None, end_frame=None, *, start=None, end=None):
    """A query range as 0-based inclusive frames ``(first, last)``; the whole motion without one.

    Parameters
    ----------
    what : str
        The motion, for the messages (``"motion 'kick1'"``).
    n_frames : int
    fps : float
    start_frame, end_frame : int, optional
        30 Hz frames, 1-based inclusive.
    start, end : float, optional
        Seconds from the motion's start (instead of frames): the frames
        whose span [k/fps, (k+1)/fps) lies in [start, end).

    Raises
    ------
    ParameterError
        Frames and seconds both given, an empty range, or a range outside the motion.
    """
    if (start_frame is not None or end_frame is not None) and (start is not None or end is not None):
        raise ParameterError("give the range in frames (start_frame, end_frame) or in seconds (start, end), "
                             "not both")
    where = f"{what} ({n_frames} frames at {fps:g} Hz, {n_frames / fps:.2f} s)"
    if start is not None or end is not None:
        s = 0.0 if start is None else float(start)
        e = n_frames / fps if end is None else float(end)
        if not (np.isfinite(s) and np.isfinite(e)) or s < 0 or e > n_frames / fps + 1e-9:
            raise ParameterError(f"the range {s:g}–{e:g} s lies outside {where}")
        first, last = int(np.floor(s * fps + 1e-9)), int(np.ceil(e * fps - 1e-9)) - 1
        if last < first:
            raise ParameterError(f"the range {s:g}–{e:g} s of {where} holds no frame; give end > start")
        return first, last
    first = 0 if start_frame is None else int(start_frame) - 1
    last = n_frames - 1 if end_frame is None else int(end_frame) - 1
    if first < 0 or last > n_frames - 1:
        raise ParameterError(f"the range {first + 1}–{last + 1} lies outside {where}; frames are 1-based, "
                             f"1–{n_frames}")
    if last < first:
        raise ParameterError(f"the range {first + 1}–{last + 1} of {where} is empty; give start_frame <= end_frame")
    return first, last


def search_archive(cache, stretches, *, limit=10, features="all", tau=None, keyframes=None,
                   batch_frames=BATCH_FRAMES, version=UNKNOWN, stats=None) -> np.ndarray:
    """The query over the archive's keyframe index, a batch of motions at a time.

    Each batch's postings come from the connection's cache
    (:meth:`mocapdb.storage.cache.ConnectionCache.batch_index`, the pieces
    ``annotate()`` uses too), whose ``full`` runs rebuild any stretch exactly
    (:mod:`mocapdb.retrieval.archive`): memory follows the batch, not the
    archive. The archive sample that weighs the features comes from
    ``features`` (:data:`mocapdb.retrieval.SAMPLE_FRAMES` frames).

    Parameters
    ----------
    cache : ConnectionCache
    stretches : sequence of (motion_id, first, last, words)
    limit, features, tau, batch_frames
        As :func:`similar_stretches`.
    keyframes : bool, optional
        Preselect with the query's keyframes: None as far as the archive's
        size needs, True always, False never. Each batch takes its share of
        :data:`mocapdb.retrieval.CELL_BUDGET` (its frames' part of the
        archive) and the most lenient keyframe level that stays within it
        (:func:`mocapdb.retrieval.preselect`).
    version : int, optional
        The index version (default: ask the database).
    stats : dict, optional
        Filled with ``archive_frames`` and ``ranked_frames`` (the frames
        the preselection kept; all of them without one), for benchmarks.

    Returns
    -------
    ndarray of mocapdb.retrieval.RESULT_DTYPE
        ``doc`` = motion id.
    """
    version = cache.version(version)
    with cache.cursor() as cur:
        ids, lengths = _whole_motions(cur)
        n_frames = int(lengths.sum())
        if n_frames == 0:
            raise SchemaError("the archive is empty: ingest motions first")
        sample = np.asarray(cur.execute(_sql("sample_words"), {"step": sample_step(n_frames)})
                            .fetchnumpy()["bits"], np.uint64)
    words = [s[3] for s in stretches]
    query = plan_query(words, sample, features=features, tau=tau, keyframes=False)
    # the archive within the budget: no preselection anywhere (unless forced), and no keyframes to
    # take from the query (that costs more than ranking a small archive)
    whole = keyframes is False or (not keyframes and rank_cells(n_frames, query) <= CELL_BUDGET)
    if not whole:
        query = dataclasses.replace(query, keyframes=query_keyframes(query.template, sample))
        whole = not query.keyframes
    found, ranked = [], 0
    for a, b in frame_batches(lengths, cache.batch_frames):
        cache.check()  # a cancelled request stops here, between two batches of kernel work
        index = cache.batch_index(ids[a:b], lengths[a:b], ("full",), version=version)
        share = int(CELL_BUDGET * lengths[a:b].sum() / n_frames)
        segs = None if whole else preselect(index, query, budget=share, force=True)
        if segs is None:
            doc, start, stop = np.arange(index.n_docs), np.zeros(index.n_docs, np.int64), index.doc_lengths
        else:
            doc, start, stop = segs.doc, segs.start, segs.end + 1
        ranked += int(np.sum(stop - start))
        # the query stretches of this batch's motions are no hits (batch positions; ids ascend)
        here = np.searchsorted(ids[a:b], [s[0] for s in stretches])
        exclude = [(int(d), s[1], s[2]) for d, s in zip(here, stretches)
                   if d < b - a and ids[a + d] == s[0]]
        hits = search_segments(functools.partial(_checked_words, cache, index), doc, start, stop, query,
                               limit=limit, exclude=exclude, batch_frames=batch_frames)
        hits["doc"] = ids[a:b][hits["doc"]]
        found.append(hits)
    if stats is not None:
        stats.update(archive_frames=n_frames, ranked_frames=ranked)
    return best_hits(found, limit, key=("cost", "doc", "start"))


def _checked_words(cache, index, doc, start, stop):
    """The index's words of the ranges, once the cache's connection says the work goes on (a batch of
    kernel work at a time: a cancelled request stops between two)."""
    cache.check()
    return index_words(index, doc, start, stop)


def _search_features(con, stretches, *, limit, features, tau, batch_frames):
    """The query over the ``features`` table (no keyframe index), a batch of motions at a time."""
    n_frames = con.execute(_sql("archive_frames")).fetchall()[0][1]
    sample = np.asarray(con.execute(_sql("sample_words"), {"step": sample_step(n_frames)}).fetchnumpy()["bits"],
                        np.uint64)
    if sample.size == 0:
        raise SchemaError("the archive is too small to search: ingest motions first")
    query = plan_query([s[3] for s in stretches], sample, features=features, tau=tau, keyframes=False)
    motion, lengths = _whole_motions(con)
    return search_segments(_sql_fetch(con), motion, np.zeros(motion.size, np.int64), lengths, query, limit=limit,
                           exclude=[(s[0], s[1], s[2]) for s in stretches], batch_frames=batch_frames)


def _whole_motions(con):
    """Ids and lengths of the motions whose feature rows are their frames 1 … n, ascending: a motion without
    them (a part of an attached archive deleted, an older partial import) is never ranked — its index runs
    could be ranked, but not its features shown — and is logged."""
    meta = con.execute(_sql("motion_lengths")).fetchnumpy()
    complete = np.asarray(meta["complete"], bool)
    if not complete.all():
        bad = [f"{m} ({n})" for m, n in zip(np.asarray(meta["motion_id"])[~complete],
                                             np.asarray(meta["name"], dtype=object)[~complete])]
        log.warning("similar: %d motion(s) without their feature rows are not ranked: %s%s", len(bad),
                    ", ".join(bad[:5]), " …" if len(bad) > 5 else "")
    return (np.asarray(meta["motion_id"], np.int64)[complete], np.asarray(meta["n_frames"], np.int64)[complete])


def similar_stretches(con, stretches, *, limit=10, features="all", tau=None, keyframes=None,
                      batch_frames=BATCH_FRAMES):
    """Rank every motion's stretches by their likeness to the query stretches.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    stretches : sequence of (motion_id, first, last, words)
        :func:`query_stretch` results: one query, or several examples (a
        template is learned from them).
    limit : int
    features : str or sequence of str
        Feature subset (:func:`mocapdb.retrieval.feature_mask`).
    tau : float, optional
        Hit threshold (default: :data:`mocapdb.retrieval.TAU_FACTOR` × the query's chance level).
    keyframes : bool, optional
        Preselect with keyframes taken from the query (needs the keyframe
        index): None (default) as far as the archive's size needs
        (:data:`mocapdb.retrieval.CELL_BUDGET`), True always, False never.
    batch_frames : int

    Returns
    -------
    pyarrow.Table
        :data:`RESULT_COLUMNS`, ranked by cost (then motion id, start frame);
        no row overlaps another or a query stretch.
    """
    cur = con.cursor()
    try:
        version = index_version(cur)
        if keyframes and version is None:
            raise SchemaError(NO_INDEX)
        if version is None:
            hits = _search_features(cur, stretches, limit=limit, features=features, tau=tau,
                                    batch_frames=batch_frames)
        else:
            hits = search_archive(connection_cache(con), stretches, limit=limit, features=features, tau=tau,
                                  keyframes=keyframes, batch_frames=batch_frames, version=version)
        return result_table(cur, hits)
    finally:
        cur.close()


def result_table(con, hits) -> pa.Table:
    """Result rows of hits (``doc`` = motion id, 0-based inclusive frames): names, 1-based frames, seconds."""
    ids = np.asarray(hits["doc"], np.int64)
    meta = con.execute(_sql("motion_meta"), {"ids": sorted(set(ids.tolist()))}).fetchnumpy()
    pos = np.searchsorted(np.asarray(meta["motion_id"], np.int64), ids)
    fps = np.asarray(meta["fps"], np.float64)[pos]
    return pa.table({
        "document": pa.array(np.asarray(meta["name"], dtype=object)[pos] if ids.size else [], pa.string()),
        "motion_id": pa.array(ids, pa.int32()),
        "start_frame": pa.array(hits["start"] + 1, pa.int32()),
        "end_frame": pa.array(hits["end"] + 1, pa.int32()),
        "start_s": pa.array(hits["start"] / fps, pa.float64()),
        "end_s": pa.array((hits["end"] + 1) / fps, pa.float64()),
        "cost": pa.array(hits["cost"], pa.float64()),
    })


__all__ = ["RESULT_COLUMNS", "check_range", "query_stretch", "search_archive", "similar_stretches", "result_table"]
