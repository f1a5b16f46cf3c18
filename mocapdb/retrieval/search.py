"""Query by example over documents: plan a query, preselect, rank (the whole retrieval on arrays).

A query is one stretch of packed words, or several ("more like these"):

1. :func:`plan_query` — the template (:mod:`mocapdb.retrieval.queries`: the
   stretch's own words; a template learned from several), its feature
   weights and chance level from a sample of the archive
   (:mod:`mocapdb.retrieval.weights`), the hit threshold τ and the keyframe
   query taken from the template (:mod:`mocapdb.retrieval.keyframes`);
2. :func:`preselect` — the keyframe search on an index of the archive
   (:func:`mocapdb.keyframes.keyframe_search`), hits widened by the
   annotation margins: the segments where a match can lie;
3. :func:`rank_slices` — Δ of the weighted template on those segments (or
   on whole documents) and its non-overlapping local minima below τ,
   cheapest first (:mod:`mocapdb.retrieval.hits`), never touching the
   query stretches.

:func:`search_documents` does all three on documents in memory (the
evaluation, the tests); :mod:`mocapdb.storage` runs the same steps batch by
batch over a database.

**The threshold.** Δ of the weighted template is an average
information-weighted disagreement; an alignment with unrelated motion costs
about the template's chance level (:func:`mocapdb.retrieval.weights.chance_cost`,
0.44–0.67 for the HDM05 clips). τ is three quarters of it
(:data:`TAU_FACTOR`): beyond, a hit is hardly better than chance. On the
leave-one-actor-out documents (benchmarks/RESULTS.md) 99.9 % of the results
below 0.3 × chance show the query's class, 77 % between 0.4 and 0.5, 55 %
between 0.6 and 0.7, and no result among a query's first n (the
R-precision's cut) costs more than 0.72 × chance.
"""
from __future__ import annotations

import logging
import os
from dataclasses import dataclass

import numpy as np

from mocapdb.errors import ParameterError, check_nonnegative
from mocapdb.features import as_doc_lengths
from mocapdb.keyframes import Index, Segments, annot_margins, keyframe_search
from mocapdb.retrieval.hits import best_hits, check_limit, select_hits
from mocapdb.retrieval.keyframes import query_keyframes
from mocapdb.retrieval.queries import clip_template, examples_template
from mocapdb.retrieval.weights import chance_cost, feature_frequencies, information_weights
from mocapdb.templates import QuantizedTemplate, mt_distance_slices

#: τ as a fraction of the template's chance level (module docstring)
TAU_FACTOR = 0.75
#: the shortest query stretch (s): a shorter one is a few words that recur everywhere, and every "match"
#: is as short and as cheap as it (a 2-frame query returned 2-frame matches)
MIN_QUERY_S = 0.5
#: frames of the archive sample that weighs features and chooses keyframes
SAMPLE_FRAMES = 16384
#: archive frames ranked at a time: bounds a query's memory (about 40 bytes per frame)
BATCH_FRAMES = 1 << 20
#: coarse to fine (:func:`rank_slices`): the full-resolution pass looks at the best this many times
#: ``limit`` hits of the 15 Hz pass
COARSE_FACTOR = 4
#: templates of fewer columns are ranked at full resolution at once
COARSE_MIN_COLUMNS = 8
#: the coarse pass takes every step-th frame and column, the step giving about this many columns
COARSE_COLUMNS = 24
#: what Δ costs per frame besides its columns (cost, ring and output), in cells: a DP over
#: a short template is bound by its frames
FRAME_CELLS = 32
#: the environment variable that sets :data:`CELL_BUDGET` (read at import; the native ``similar_to``,
#: extension/src/similar.c, reads it at each call)
CELL_BUDGET_ENV = "MOCAPDB_CELL_BUDGET"


def _cell_budget(default=200_000_000) -> int:
    """:data:`CELL_BUDGET`: ``MOCAPDB_CELL_BUDGET`` when it is a positive integer below 2**31, else
    ``default`` (the native function's bound: its batch share stays an exact double product)."""
    text = os.environ.get(CELL_BUDGET_ENV, "").strip()
    if not text:
        return default
    if text.isascii() and text.isdigit() and 0 < int(text) < 1 << 31:
        return int(text)
    logging.getLogger("mocapdb").warning("%s=%r is not a positive integer below 2**31: the cell budget stays %d",
                                         CELL_BUDGET_ENV, text, default)
    return default


#: Δ cells (:func:`rank_cells`) a query may rank: the preselection takes the most lenient keyframe
#: level that stays below (about half a second on two cores; the speed and the quality it costs at
#: 100 h: benchmarks/RESULTS.md). A smaller budget (:data:`CELL_BUDGET_ENV`) preselects smaller
#: archives too: faster queries on a slow machine, fewer matches where the keyframes miss.
CELL_BUDGET = _cell_budget()

#: a retrieval result: ``doc`` a document (or motion id), frames 0-based inclusive
RESULT_DTYPE = np.dtype([("doc", np.int64), ("start", np.int64), ("end", np.int64), ("cost", np.float64)])


@dataclass(frozen=True, eq=False)
class RetrievalQuery:
    """What a query by example matches, and how (:func:`plan_query`).

    Attributes
    ----------
    template : QuantizedTemplate
        K columns.
    weights : ndarray, shape (K, 40)
        Information weight of every feature of every column (0 at wildcards).
    tau : float
        Hit threshold on the weighted Δ.
    chance : float
        The template's chance level.
    keyframes : tuple of KeyframeQuery
        The preselection levels, lenient to strict (empty: search everything).
    """

    template: QuantizedTemplate
    weights: np.ndarray
    tau: float
    chance: float
    keyframes: tuple = ()


def sample_step(n_frames: int, n_sample: int = SAMPLE_FRAMES) -> int:
    """Every ``step``-th frame of each motion (1-based frame numbers divisible by it) is sampled."""
    return max(1, int(n_frames) // int(n_sample))


def archive_sample(words, doc_lengths, n_sample: int = SAMPLE_FRAMES) -> np.ndarray:
    """The archive sample of documents in memory: frames whose 1-based number in their
    document is a multiple of :func:`sample_step` (the database takes the same frames)."""
    lengths = as_doc_lengths(doc_lengths, len(words))
    step = sample_step(int(lengths.sum()), n_sample)
    first = np.repeat(np.concatenate(([0], np.cumsum(lengths)[:-1])), lengths)
    frame = np.arange(int(lengths.sum())) - first + 1
    return np.asarray(words, dtype=np.uint64)[frame % step == 0]


def plan_query(stretches, sample, *, features="all", tau=None, keyframes=True) -> RetrievalQuery:
    """The template, weights, threshold and keyframes of a query (module docstring).

    Parameters
    ----------
    stretches : sequence of (n_i,) uint64
        One query stretch, or several examples (a template is learned from them).
    sample : (m,) uint64
        Frames of the archive (:func:`archive_sample`); at least one.
    features : str or sequence of str
        Feature subset (:func:`mocapdb.retrieval.queries.feature_mask`).
    tau : float, optional
        Hit threshold; default :data:`TAU_FACTOR` × the chance level.
    keyframes : bool
        Take keyframes from the template for preselection.

    Returns
    -------
    RetrievalQuery
    """
    stretches = list(stretches)
    if not stretches:
        raise ParameterError("a query needs at least one stretch")
    template = (clip_template(stretches[0], features=features) if len(stretches) == 1
                else examples_template(stretches, features=features))
    return template_query(template, sample, tau=tau, keyframes=keyframes)


def template_query(template: QuantizedTemplate, sample, *, tau=None, keyframes=True) -> RetrievalQuery:
    """:func:`plan_query` for a template made otherwise (e.g. :func:`mocapdb.retrieval.mirror_template`)."""
    sample = np.asarray(sample, dtype=np.uint64)
    if sample.ndim != 1 or sample.size == 0:
        raise ParameterError("the archive sample must be a non-empty 1-D array of words (an empty archive?)")
    p_on = feature_frequencies(sample)
    chance = chance_cost(template, p_on)
    tau = TAU_FACTOR * chance if tau is None else check_nonnegative(tau, "tau")
    levels = query_keyframes(template, sample) if keyframes else ()
    return RetrievalQuery(template, information_weights(template, p_on), tau, chance, levels)


def preselect(index: Index, query: RetrievalQuery, *, budget=CELL_BUDGET, force=False) -> Segments | None:
    """The archive segments where the query can match (module docstring of
    :mod:`mocapdb.retrieval.keyframes`): the keyframe search of the most
    lenient level that leaves at most ``budget`` Δ cells (frames × K).

    Parameters
    ----------
    index : mocapdb.keyframes.Index
    query : RetrievalQuery
    budget : int
        Δ cells the ranking may take; an archive within it is not preselected
        at all (unless ``force``). When no level gets below it, the strictest.
    force : bool
        Preselect even when the whole archive is within the budget (the
        most lenient level).

    Returns
    -------
    Segments or None
        Widened by the annotation margins; None: rank the whole archive.
    """
    if not query.keyframes or (not force and rank_cells(index.n_frames, query) <= budget):
        return None
    for kq in query.keyframes:
        left, right = annot_margins(kq)
        segs = keyframe_search(index, kq, extend_left=left, extend_right=right)
        if rank_cells(segs.n_frames, query) <= budget:
            break
    return segs


def coarse_step(K: int) -> int:
    """Frames (and template columns) per step of the coarse pass of a K-column template: at
    least 2, and about :data:`COARSE_COLUMNS` columns for long templates; 1 (no coarse pass)
    below :data:`COARSE_MIN_COLUMNS`."""
    return 1 if K < COARSE_MIN_COLUMNS else max(2, K // COARSE_COLUMNS)


def rank_cells(n_frames, query: RetrievalQuery) -> int:
    """The work of ranking ``n_frames`` archive frames, in Δ cells: the frames of the first pass
    (every :func:`coarse_step`-th frame, :func:`rank_slices`; the fine pass is small) times its
    template columns plus :data:`FRAME_CELLS` (what a frame costs besides)."""
    K = len(query.template)
    step = coarse_step(K)
    return -(-int(n_frames) // step) * (-(-K // step) + FRAME_CELLS)


def _rank(words, template, weights, tau, ta, tb, limit, taken, minima=False):
    """One pass of Δ and hit selection on word slices: RESULT rows (``doc`` = slice, word indices)."""
    delta, offsets, starts = mt_distance_slices(words, [template], np.zeros(ta.size, np.int64), ta, tb,
                                                return_starts=True, feature_weights=[weights])
    flat_taken = None
    if taken is not None:  # the slices' frames of ``taken``, in the layout of delta
        flat_taken = taken[np.repeat(ta - offsets[:-1], tb - ta) + np.arange(offsets[-1])]
    hits = select_hits(delta, starts, offsets, ta, tau=tau, limit=limit, taken=flat_taken, minima=minima)
    out = np.empty(hits.size, RESULT_DTYPE)
    out["doc"] = hits["task"]
    out["start"] = hits["start"] + ta[hits["task"]]
    out["end"] = hits["end"] + ta[hits["task"]]
    out["cost"] = hits["cost"]
    return best_hits([out], limit, key=("cost", "doc", "start"))


def rank_slices(words, query: RetrievalQuery, task_start, task_stop, *, limit, taken=None, coarse=True) -> np.ndarray:
    """The best non-overlapping hits of the query on word slices.

    Coarse to fine (``coarse``, for templates of at least
    :data:`COARSE_MIN_COLUMNS` columns): Δ first on every
    :func:`coarse_step`-th frame with every step-th template column (15 Hz
    or coarser: a quarter of the cells or less), whose best
    :data:`COARSE_FACTOR` × ``limit`` local minima mark where to look; then
    at full resolution on those places widened by the template's length on
    both sides (a 30 Hz match near a coarse one lies within).

    Parameters
    ----------
    words : (N,) uint64
    query : RetrievalQuery
    task_start, task_stop : (n,) int
        Half-open slices of ``words`` (each one document or part of one),
        in increasing order, disjoint.
    limit : int
    taken : (N,) bool, optional
        Frames no hit may touch (the query stretches).
    coarse : bool, default True

    Returns
    -------
    ndarray of RESULT_DTYPE
        ``doc`` = the slice's index, ``start``/``end`` word indices into
        ``words``; at most ``limit`` rows by (cost, slice, start).
    """
    limit = check_limit(limit)
    ta = np.asarray(task_start, dtype=np.int64)
    tb = np.asarray(task_stop, dtype=np.int64)
    taken = None if taken is None else np.asarray(taken, dtype=np.bool_)
    t, K = query.template, len(query.template)
    step = coarse_step(K)
    if not coarse or step == 1:
        return _rank(words, t, query.weights, query.tau, ta, tb, limit, taken)
    # the slices' frames ta, ta + step, … and the template's columns 0, step, …
    cn = -(-(tb - ta) // step)
    cbase = np.concatenate(([0], np.cumsum(cn))).astype(np.int64)
    pick = np.repeat(ta - step * cbase[:-1], cn) + step * np.arange(cbase[-1])
    sparse = QuantizedTemplate(t.mask[::step], t.value[::step], t.weights[::step])
    found = _rank(np.asarray(words, dtype=np.uint64)[pick], sparse, query.weights[::step], query.tau, cbase[:-1],
                  cbase[1:], COARSE_FACTOR * limit, None if taken is None else taken[pick], minima=True)
    q = found["doc"]
    lo = np.maximum(ta[q], ta[q] + step * (found["start"] - cbase[q]) - K)
    hi = np.minimum(tb[q], ta[q] + step * (found["end"] - cbase[q]) + step + K)
    order = np.argsort(lo, kind="stable")
    lo, hi = lo[order], hi[order]
    # merge overlapping windows (not touching ones: windows of neighbouring slices touch)
    new = np.ones(lo.size, bool)
    if lo.size:
        new[1:] = lo[1:] >= np.maximum.accumulate(hi)[:-1]
    group = np.cumsum(new) - 1
    wlo = lo[new]
    whi = np.zeros(wlo.size, np.int64)
    np.maximum.at(whi, group, hi)
    hits = _rank(words, t, query.weights, query.tau, wlo, whi, limit, taken)
    hits["doc"] = np.searchsorted(ta, wlo[hits["doc"]], side="right") - 1
    return best_hits([hits], limit, key=("cost", "doc", "start"))


def search_segments(fetch, doc, start, stop, query: RetrievalQuery, *, limit, exclude=(),
                    batch_frames=BATCH_FRAMES) -> np.ndarray:
    """Rank a query on archive segments, batch by batch (a query's memory does not grow with the archive).

    Parameters
    ----------
    fetch : callable
        ``fetch(doc, start, stop)`` → the words of the half-open frame ranges,
        concatenated ((Σ (stop − start),) uint64).
    doc, start, stop : (n,) int
        The segments: a document id (any integers, e.g. motion ids) and a
        half-open frame range; in the order to rank them (ties go to the
        smaller id, then the earlier frame, whatever the order).
    query : RetrievalQuery
    limit : int
    exclude : iterable of (doc, start, end)
        0-based inclusive stretches no result may overlap (the query's).
    batch_frames : int
        Frames fetched and ranked at a time (a segment longer than this is
        a batch of its own).

    Returns
    -------
    ndarray of RESULT_DTYPE
        ``doc`` the document id, frames within it; ranked by (cost, doc, start).
    """
    limit = check_limit(limit)
    doc, start, stop = (np.asarray(x, dtype=np.int64).ravel() for x in (doc, start, stop))
    exclude = [tuple(int(v) for v in x) for x in exclude]
    lengths = stop - start
    # batches: runs of consecutive segments of about batch_frames frames
    window = np.concatenate(([0], np.cumsum(lengths)))[:-1] // max(1, int(batch_frames))
    edges = np.concatenate(([0], np.flatnonzero(np.diff(window)) + 1, [doc.size])) if doc.size else np.zeros(1, int)
    best = np.empty(0, RESULT_DTYPE)
    for a, b in zip(edges[:-1], edges[1:]):
        d, s0, s1 = doc[a:b], start[a:b], stop[a:b]
        words = np.asarray(fetch(d, s0, s1), dtype=np.uint64)
        base = np.concatenate(([0], np.cumsum(s1 - s0))).astype(np.int64)
        if words.shape != (base[-1],):
            raise ParameterError(f"fetch returned {words.shape[0]} words for {base[-1]} frames")
        taken = None
        for xd, xs, xe in exclude:
            for k in np.flatnonzero((d == xd) & (s0 <= xe) & (s1 > xs)):
                taken = np.zeros(words.size, np.bool_) if taken is None else taken
                taken[base[k] + max(xs, s0[k]) - s0[k]:base[k] + min(xe + 1, s1[k]) - s0[k]] = True
        hits = rank_slices(words, query, base[:-1], base[1:], limit=limit, taken=taken)
        k = hits["doc"]
        hits["start"] += s0[k] - base[k]
        hits["end"] += s0[k] - base[k]
        hits["doc"] = d[k]
        best = best_hits([best, hits], limit, key=("cost", "doc", "start"))
    return best


def search_documents(words, doc_lengths, query: RetrievalQuery, *, limit, index=None, exclude=(),
                     batch_frames=BATCH_FRAMES, budget=CELL_BUDGET, force=False) -> np.ndarray:
    """A query over documents in memory: preselect (when ``index`` is given and the query
    has keyframes), rank, never touching the ``exclude`` stretches.

    Parameters
    ----------
    words : (N,) uint64
        The documents, concatenated.
    doc_lengths : (n_docs,) int
    query : RetrievalQuery
    limit : int
    index : mocapdb.keyframes.Index, optional
        An index of exactly these documents (with the ``full`` part).
    exclude : iterable of (doc, start, end)
        0-based inclusive stretches no result may overlap.
    batch_frames : int
        As :func:`search_segments`.
    budget, force
        As :func:`preselect`.

    Returns
    -------
    ndarray of RESULT_DTYPE
        ``doc`` the document, frames within it; ranked by (cost, doc, start).
    """
    w = np.asarray(words, dtype=np.uint64)
    lengths = as_doc_lengths(doc_lengths, len(w))
    base = np.concatenate(([0], np.cumsum(lengths))).astype(np.int64)
    for d, s, e in exclude:
        if not 0 <= d < lengths.size or not 0 <= s <= e < lengths[d]:
            raise ParameterError(f"exclude stretch {(d, s, e)} lies outside the documents")
    segs = preselect(index, query, budget=budget, force=force) if index is not None else None
    if segs is None:
        doc, start, stop = np.arange(lengths.size), np.zeros(lengths.size, np.int64), lengths
    else:
        if index.n_docs != lengths.size or not np.array_equal(index.doc_lengths, lengths):
            raise ParameterError("index must be an index of exactly these documents")
        doc, start, stop = segs.doc, segs.start, segs.end + 1

    def fetch(d, s0, s1):
        n = s1 - s0
        return w[np.repeat(base[d] + s0 - np.concatenate(([0], np.cumsum(n)[:-1])), n) + np.arange(n.sum())]

    return search_segments(fetch, doc, start, stop, query, limit=limit, exclude=exclude, batch_frames=batch_frames)


__all__ = ["RetrievalQuery", "RESULT_DTYPE", "TAU_FACTOR", "MIN_QUERY_S", "SAMPLE_FRAMES", "sample_step", "archive_sample",
           "plan_query", "template_query", "preselect", "rank_slices", "search_segments", "search_documents",
           "BATCH_FRAMES", "CELL_BUDGET", "CELL_BUDGET_ENV", "COARSE_FACTOR", "COARSE_MIN_COLUMNS", "COARSE_COLUMNS", "FRAME_CELLS", "coarse_step", "rank_cells"]
