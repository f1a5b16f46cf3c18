"""Keyframe queries that keep their recall on new actors: generalise what training does not need.

A genetic-algorithm query (paper Sect. 6) stops improving once it separates
the training clips; whatever it fixed beyond that — a keyframe entry that
happens to be constant for the training actors, a gap bound as tight as
their tempo — costs recall on an actor it has not seen (on leave-one-actor-out
hdm05_cut a query found 75 % of the held-out clips). :func:`generalise_query`
removes those: step by step it applies the single change that loosens the
query most while keeping its training fitness Fit_β, until no change keeps
it. The changes, most loosening first:

* drop a keyframe (its two gaps merge, bounds summed);
* widen a gap: ``d_min → ⌊d_min / widen⌋``, ``d_max → ⌈d_max · widen⌉``;
* turn one fixed entry of a keyframe into a wildcard.

The result is the most general query of this greedy path that still
separates the training clips as well as the GA's did: what it keeps fixed,
training needs.
"""
from __future__ import annotations

import math

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.keyframes import UNBOUNDED, KeyframeQuery, keyframe_hit_documents
from mocapdb.learning.genetic import fitness_from_hits

__all__ = ["generalise_query", "loosen_gaps", "query_changes"]

#: change kinds, most loosening first (ties in fitness go to the earlier kind)
_KINDS = ("drop_keyframe", "widen_gap", "wildcard")


def loosen_gaps(query: KeyframeQuery, widen=2.0, gaps=None) -> KeyframeQuery:
    """Gap bounds widened: ``d_min → ⌊d_min / widen⌋``, ``d_max → ⌈d_max · widen⌉`` (unbounded stays).

    Parameters
    ----------
    query : KeyframeQuery
    widen : float, default 2.0
        ≥ 1; 2 admits a new actor twice as fast or slow as the training ones.
    gaps : sequence of int, optional
        Only these gaps (default all).
    """
    if not widen >= 1:
        raise ParameterError(f"widen={widen!r}; use a number >= 1")
    d_min, d_max = query.d_min.copy(), query.d_max.copy()
    for g in range(len(d_min)) if gaps is None else gaps:
        d_min[g] = math.floor(d_min[g] / widen)
        if d_max[g] < UNBOUNDED:
            d_max[g] = min(UNBOUNDED, math.ceil(d_max[g] * widen))
    return KeyframeQuery(query.mask, query.value, query.positions, d_min, d_max, query.template_length,
                         query.feature_sets)


def _drop(query, k):
    K = query.n_keyframes
    keep = [i for i in range(K) if i != k]
    d_min, d_max = query.d_min.tolist(), query.d_max.tolist()
    if 0 < k < K - 1:  # an inner keyframe: its two gaps merge
        d_min[k - 1] += d_min[k]
        d_max[k - 1] = min(UNBOUNDED, d_max[k - 1] + d_max[k])
    g = min(k, K - 2)
    del d_min[g], d_max[g]
    return KeyframeQuery(query.mask[keep], query.value[keep], query.positions[keep], d_min, d_max,
                         query.template_length, tuple(query.feature_sets[i] for i in keep))


def query_changes(query: KeyframeQuery, *, widen=2.0, kinds=_KINDS):
    """Every single loosening step of a query of the given kinds: list of (kind, KeyframeQuery)."""
    unknown = sorted(set(kinds) - set(_KINDS))
    if unknown:
        raise ParameterError(f"unknown change kinds {unknown}; allowed: {', '.join(_KINDS)}")
    out = []
    if query.n_keyframes > 1 and "drop_keyframe" in kinds:
        out += [("drop_keyframe", _drop(query, k)) for k in range(query.n_keyframes)]
    for g in range(query.n_keyframes - 1 if "widen_gap" in kinds else 0):
        wider = loosen_gaps(query, widen, [g])
        if wider.d_min[g] != query.d_min[g] or wider.d_max[g] != query.d_max[g]:
            out.append(("widen_gap", wider))
    for k in range(query.n_keyframes if "wildcard" in kinds else 0):
        m = int(query.mask[k])
        for b in range(64):
            if (m >> b) & 1:
                mask = query.mask.copy()
                value = query.value.copy()
                mask[k] = np.uint64(m & ~(1 << b))
                value[k] = np.uint64(int(value[k]) & ~(1 << b))
                out.append(("wildcard", KeyframeQuery(mask, value, query.positions, query.d_min, query.d_max,
                                                      query.template_length, query.feature_sets)))
    return out


def _fitness(index, queries, relevant, documents, beta, cache):
    hits = keyframe_hit_documents(index, queries, cache=cache)[:, documents]
    return fitness_from_hits(hits, relevant[documents], beta=beta)


def generalise_query(query, index, relevant, documents=None, *, beta=2.0, widen=2.0, tolerance=0.0,
                     max_steps=1000, cache=None, kinds=_KINDS):
    """Loosen a query as long as its training fitness stays (module docstring).

    Parameters
    ----------
    query : KeyframeQuery
    index : mocapdb.keyframes.Index
        The training index (one document per clip, e.g. :func:`mocapdb.learning.training_index`).
    relevant : (n_docs,) bool
        T+.
    documents : (n_docs,) bool, optional
        T = T+ ∪ T− (default every document).
    beta : float, default 2.0
        Fit_β of the GA.
    widen : float, default 2.0
        Gap widening factor of one step.
    tolerance : float, default 0.0
        Accept a step that lowers Fit_β by at most this much (from the start).
    max_steps : int, default 1000
    cache : dict, optional
        Keyframe intervals kept across searches (as the GA's).
    kinds : sequence of str
        The kinds of steps allowed (default all three).

    Returns
    -------
    query : KeyframeQuery
        The loosened query.
    steps : list of str
        The kinds of the steps taken, in order.
    """
    relevant = np.asarray(relevant, dtype=bool)
    documents = np.ones(index.n_docs, bool) if documents is None else np.asarray(documents, dtype=bool)
    cache = {} if cache is None else cache
    _, _, f0 = _fitness(index, [query], relevant, documents, beta, cache)
    floor = float(f0[0]) - float(tolerance)
    steps = []
    for _ in range(int(max_steps)):
        changes = query_changes(query, widen=widen, kinds=kinds)
        if not changes:
            break
        _, _, f = _fitness(index, [q for _, q in changes], relevant, documents, beta, cache)
        ok = np.flatnonzero(f >= floor - 1e-12)
        if ok.size == 0:
            break
        # the best fitness; ties: the most loosening kind, then the first candidate
        rank = np.array([_KINDS.index(changes[i][0]) for i in ok])
        best = ok[np.lexsort((ok, rank, -f[ok]))[0]]
        steps.append(changes[best][0])
        query = changes[best][1]
    return query, steps
