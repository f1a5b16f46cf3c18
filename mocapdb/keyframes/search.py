"""Keyframe queries and the keyframe-chain search (Baak, Müller & Seidel 2008).

The search of a keyframe query (:mod:`mocapdb.keyframes.query`) returns
the document segments that contain an admissible chain of matching frames,
extended by margins and merged, exactly as the toolbox's ``C_KeyframeSearch``
(KEYFRAMES.md §3-5).

Public API
----------
keyframe_search                        one query -> segments (and raw hits)
keyframe_search_batch                  many queries on one index -> segments per query
keyframe_hit_documents                 many queries -> (n_queries, n_docs) "has a hit" (GA fitness)
keyframe_intervals, keyframe_postings  the per-keyframe intermediate results (§3)

The numba kernels live in :mod:`mocapdb.keyframes.search_kernels`.  Frames,
template positions and documents are 0-based, segment ends inclusive.
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.features import FEATURE_SETS
from mocapdb.keyframes.index import SET_PARTS, Index, Segments, fuzzy_postings
from mocapdb.keyframes.query import KeyframeQuery, set_bits
from mocapdb.keyframes.search_kernels import (_AUTO, _chain_batch_kernel, _hit_documents_kernel,
                                              _keyframe_intervals_kernel, _search_kernel)


# --------------------------------------------------------------------------
# planning: keyframes -> single-part sub-keyframes


def _check_layout(layout):
    if layout not in (None, "sets", "full"):
        raise ParameterError(f"layout={layout!r}; use None (auto), 'sets' (the toolbox's per-set "
                             "indexes) or 'full' (the 40-bit index)")


def _keyframe_subs(index: Index, mask: int, value: int, feature_set, layout):
    """Sub-keyframes ``((part id, local mask, local value), ...)`` answering one keyframe.

    None (auto): a keyframe within one feature set uses that set's part when
    the index has it, otherwise the 40-bit part; a keyframe spanning several
    sets uses the 40-bit part when present, else one sub-keyframe per set
    (their intervals are intersected).  'sets'/'full' force a layout.
    """
    sets = [name for name in SET_PARTS if mask & set_bits(name)]
    if feature_set is not None and not sets:
        sets = [feature_set]
    has_sets = all(name in index.parts for name in sets)
    if layout == "full" or (layout is None and "full" in index.parts
                            and (len(sets) > 1 or not has_sets)):
        return ((index.part_id("full"), mask, value),)
    if not sets:  # all wildcards: every frame matches, any part will do
        return ((0, 0, 0),)
    subs = []
    for name in sets:
        first, n = FEATURE_SETS[name]
        full = (1 << n) - 1
        subs.append((index.part_id(name), (mask >> first) & full, (value >> first) & full))
    return tuple(subs)


def _plan(index: Index, queries, layout):
    """Distinct keyframes of the queries and the flat arrays the kernels take."""
    _check_layout(layout)
    kf_id = {}
    q_kf = []
    q_kf_offset = [0]
    for query in queries:
        if not isinstance(query, KeyframeQuery):
            raise ParameterError(f"expected a KeyframeQuery, got {type(query).__name__}")
        for k in range(query.n_keyframes):
            subs = _keyframe_subs(index, int(query.mask[k]), int(query.value[k]),
                                  query.feature_sets[k], layout)
            q_kf.append(kf_id.setdefault(subs, len(kf_id)))
        q_kf_offset.append(len(q_kf))
    keys = list(kf_id)  # insertion order = keyframe id
    d_min = np.concatenate([q.d_min for q in queries]) if queries else np.empty(0, np.int64)
    d_max = np.concatenate([q.d_max for q in queries]) if queries else np.empty(0, np.int64)
    return keys, np.array(q_kf, np.int64), np.array(q_kf_offset, np.int64), d_min, d_max


def _sub_arrays(keys):
    sub_part, sub_mask, sub_value, kf_sub_offset = [], [], [], [0]
    for subs in keys:
        for p, m, v in subs:
            sub_part.append(p)
            sub_mask.append(m)
            sub_value.append(v)
        kf_sub_offset.append(len(sub_part))
    return (np.array(sub_part, np.int64), np.array(sub_mask, np.uint64),
            np.array(sub_value, np.uint64), np.array(kf_sub_offset, np.int64))


def _intervals(index: Index, keys, cache=None):
    """Intervals of the distinct keyframes ``keys``: (doc, start, end, kf_offset).

    With a ``cache`` dict, keyframes computed by earlier calls on the same
    index are reused and new ones are added.
    """
    if cache is None:
        return _keyframe_intervals_kernel(*index.kernel_arrays(), *_sub_arrays(keys),
                                          0, index.n_docs)
    missing = [k for k in keys if k not in cache]
    if missing:
        doc, start, end, off = _keyframe_intervals_kernel(*index.kernel_arrays(),
                                                          *_sub_arrays(missing), 0, index.n_docs)
        for i, key in enumerate(missing):
            a, b = off[i], off[i + 1]
            cache[key] = (doc[a:b].copy(), start[a:b].copy(), end[a:b].copy())
    parts = [cache[k] for k in keys]
    off = np.zeros(len(keys) + 1, np.int64)
    np.cumsum([len(x[0]) for x in parts], out=off[1:])
    return (*(np.concatenate([x[i] for x in parts]) for i in range(3)), off)


#: below this many frames a search runs on the calling thread (the hand-off to
#: a thread costs more than it saves on small indexes)
PARALLEL_MIN_FRAMES = 1 << 19
_POOL = None
_POOL_LOCK = threading.Lock()


def _pool():
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=os.cpu_count() or 1,
                                       thread_name_prefix="mocapdb-keyframes")
        return _POOL


def _shards(index: Index, n_threads):
    """Document ranges of about equal frame counts, one per thread."""
    if n_threads is None:
        n_threads = (os.cpu_count() or 1) if index.n_frames >= PARALLEL_MIN_FRAMES else 1
    if isinstance(n_threads, bool) or not isinstance(n_threads, (int, np.integer)) or n_threads < 1:
        raise ParameterError(f"n_threads={n_threads!r}; use None (auto) or a positive int")
    if n_threads == 1 or index.n_docs < 2:
        return [(0, index.n_docs)]
    cum = np.cumsum(index.doc_lengths)
    cuts = np.searchsorted(cum, cum[-1] * np.arange(1, n_threads) / n_threads)
    bounds = np.unique(np.concatenate([[0], np.minimum(cuts + 1, index.n_docs), [index.n_docs]]))
    return list(zip(bounds[:-1].tolist(), bounds[1:].tolist()))


def _search(index: Index, queries, ext_l, ext_r, want_hits, layout, n_threads, cache=None,
            strategy=_AUTO):
    """Segments (and hits) per query: lists of (n, 3) int64 row arrays."""
    keys, q_kf, q_kf_offset, d_min, d_max = _plan(index, queries, layout)
    n_q = len(queries)
    if cache is not None:
        iv = _intervals(index, keys, cache)
        segs, seg_q, hits, hit_q = _chain_batch_kernel(*iv, q_kf, q_kf_offset, d_min, d_max,
                                                       index.doc_lengths, ext_l, ext_r,
                                                       bool(want_hits))
        return ([segs[seg_q[i]:seg_q[i + 1]] for i in range(n_q)],
                [hits[hit_q[i]:hit_q[i + 1]] for i in range(n_q)])
    args = (*index.kernel_arrays(), *_sub_arrays(keys), q_kf, q_kf_offset, d_min, d_max,
            index.doc_lengths, ext_l, ext_r, 1 if want_hits else 0)
    no_hit_docs = np.zeros((0, 0), np.bool_)
    shards = _shards(index, n_threads)
    if len(shards) == 1:
        parts = [_search_kernel(*args, *shards[0], strategy, no_hit_docs)]
    else:  # documents are independent and the kernel releases the GIL
        parts = list(_pool().map(lambda sh: _search_kernel(*args, *sh, strategy, no_hit_docs),
                                 shards))
    if len(parts) == 1:
        s, s_q, h, h_q = parts[0]
        return ([s[s_q[i]:s_q[i + 1]] for i in range(n_q)],
                [h[h_q[i]:h_q[i + 1]] for i in range(n_q)])
    segs = [np.concatenate([s[s_q[i]:s_q[i + 1]] for s, s_q, _, _ in parts]) for i in range(n_q)]
    hits = [np.concatenate([h[h_q[i]:h_q[i + 1]] for _, _, h, h_q in parts]) for i in range(n_q)]
    return segs, hits


def _margins(x, n_q, name):
    a = np.asarray(x)
    if a.ndim == 0:
        a = np.full(n_q, a)
    if a.shape != (n_q,):
        raise ParameterError(f"{name} must be an int or one int per query ({n_q}), "
                             f"got shape {a.shape}")
    if a.dtype.kind not in "iu" and not (a == np.floor(a)).all():
        raise ParameterError(f"{name}={a.tolist()} must be whole frame counts")
    a = a.astype(np.int64)
    if (a < 0).any():
        raise ParameterError(f"{name}={a.tolist()} must be >= 0")
    return a


def _to_segments(rows):
    return Segments(rows[:, 0].copy(), rows[:, 1].copy(), rows[:, 2].copy())


# --------------------------------------------------------------------------
# public search API


def keyframe_intervals(index: Index, query: KeyframeQuery, *, layout=None) -> list:
    """Per-keyframe frame intervals B[k] (KEYFRAMES.md §3).

    Returns
    -------
    list of K :class:`~mocapdb.keyframes.index.Segments`
        Keyframe k's maximal runs of matching frames ``(doc, start, end)``,
        sorted by (doc, start).  The same for every layout.
    """
    keys, q_kf, _, _, _ = _plan(index, [query], layout)
    doc, s, e, off = _intervals(index, keys)
    return [Segments(doc[off[i]:off[i + 1]], s[off[i]:off[i + 1]], e[off[i]:off[i + 1]])
            for i in q_kf]


def keyframe_postings(index: Index, query: KeyframeQuery, *, layout=None) -> list:
    """Per keyframe the matching index words and the union of their posting lists (§3).

    Every keyframe must be answered by one index part (restricted to one
    feature set, or the 40-bit part).

    Returns
    -------
    list of K :class:`~mocapdb.keyframes.index.Postings`
    """
    _check_layout(layout)
    out = []
    for k in range(query.n_keyframes):
        subs = _keyframe_subs(index, int(query.mask[k]), int(query.value[k]),
                              query.feature_sets[k], layout)
        if len(subs) != 1:
            raise ParameterError(f"keyframe {k} spans several feature sets; its posting lists "
                                 "live in different per-set indexes (use a 'full' index)")
        p, m, v = subs[0]
        out.append(fuzzy_postings(index, index.parts[p], m, v))
    return out


def keyframe_search(index: Index, query: KeyframeQuery, *, extend_left=0, extend_right=0,
                    return_hits=False, layout=None, n_threads=None):
    """Segments of the documents that contain the keyframe chain (KEYFRAMES.md §5).

    Parameters
    ----------
    index : Index
    query : KeyframeQuery
    extend_left, extend_right : int, default 0
        Margins added to every hit before merging (annotation uses
        :func:`annot_margins`).
    return_hits : bool, default False
        Also return the raw hits (before extension and merging) in the
        toolbox's order (duplicates included).
    layout : {None, 'sets', 'full'}
        Which index parts answer the keyframes.  None: a keyframe within one
        feature set uses that set's index (the toolbox), a keyframe spanning
        several sets the 40-bit index if built, else the intersection of its
        per-set parts.  'sets'/'full' force one layout.  All give identical
        results.
    n_threads : int, optional
        Split the documents into this many ranges searched in parallel
        (default: every core for indexes of at least
        :data:`PARALLEL_MIN_FRAMES` frames, else 1).

    Returns
    -------
    segments : Segments
        ``(doc, start, end)``, 0-based inclusive, sorted by (doc, start),
        overlapping extended hits merged.
    hits : Segments
        Only with ``return_hits``: ``(doc, hit_start, hit_end)``.

    Notes
    -----
    With K = 1 (not defined by the toolbox) every interval of the keyframe is
    a hit.  A document is searched only if every keyframe matches in it; so
    the keyframes' posting lists first filter the documents (from the fewest
    postings up) and intervals are computed only in the documents left --
    the result is the same as with every keyframe's full intervals.

    References
    ----------
    KEYFRAMES.md §3-5; toolbox keyframeSearchEfficient.m, C_KeyframeSearch.c.
    """
    el = _margins(extend_left, 1, "extend_left")
    er = _margins(extend_right, 1, "extend_right")
    segs, hits = _search(index, [query], el, er, return_hits, layout, n_threads)
    if return_hits:
        return _to_segments(segs[0]), _to_segments(hits[0])
    return _to_segments(segs[0])


def keyframe_search_batch(index: Index, queries, *, extend_left=0, extend_right=0,
                          layout=None, n_threads=None, cache=None) -> list:
    """:func:`keyframe_search` for many queries on one index.

    Each query is searched with its own document filter (as
    :func:`keyframe_search`).  ``extend_left``/``extend_right`` are ints or
    one int per query.  ``cache``: a dict owned by the caller, used with this
    index (and layout) only and by one thread at a time, that keeps every
    keyframe's full intervals across calls, so keyframes shared between
    queries (frequent in a GA population) are matched once (the search then
    runs on the calling thread, without the document filter).

    Returns
    -------
    list of Segments, one per query.
    """
    queries = list(queries)
    el = _margins(extend_left, len(queries), "extend_left")
    er = _margins(extend_right, len(queries), "extend_right")
    if not queries:
        return []
    segs, _ = _search(index, queries, el, er, False, layout, n_threads, cache)
    return [_to_segments(x) for x in segs]


def keyframe_hit_documents(index: Index, queries, *, layout=None, cache=None) -> np.ndarray:
    """Which documents each query hits (the GA fitness, KEYFRAMES.md §8.2).

    Document d is hit iff :func:`keyframe_search` returns a segment in it;
    the search of a document stops at its first hit.  Runs on the calling
    thread (and releases the GIL): parallelise over independent GA runs.

    Parameters
    ----------
    index : Index
    queries : sequence of KeyframeQuery
    layout : {None, 'sets', 'full'}
        As in :func:`keyframe_search`.
    cache : dict, optional
        As in :func:`keyframe_search_batch`; a GA keeps one per training
        index (offspring mostly reuse their parents' keyframes).

    Returns
    -------
    (n_queries, n_docs) bool
    """
    queries = list(queries)
    out = np.zeros((len(queries), index.n_docs), np.bool_)
    if not queries:
        return out
    keys, q_kf, q_kf_offset, d_min, d_max = _plan(index, queries, layout)
    if cache is None:  # each query's intervals only where all its keyframes match
        zeros = np.zeros(len(queries), np.int64)
        _search_kernel(*index.kernel_arrays(), *_sub_arrays(keys), q_kf, q_kf_offset, d_min,
                       d_max, index.doc_lengths, zeros, zeros, 2, 0, index.n_docs, _AUTO, out)
        return out
    iv = _intervals(index, keys, cache)
    _hit_documents_kernel(*iv, q_kf, q_kf_offset, d_min, d_max, index.doc_lengths, out)
    return out


__all__ = ["PARALLEL_MIN_FRAMES", "keyframe_hit_documents", "keyframe_intervals", "keyframe_postings",
           "keyframe_search", "keyframe_search_batch"]
