"""Keyframes taken from the query itself: the preselection of a query by example (paper Sect. 5).

The annotation's keyframe queries are designed or learned per class; a query
by example has only its own stretch (or its examples' template). Its
keyframes are chosen from the query template, with the archive's frames as
the counter-examples:

* a keyframe fixes only features that hold still in the query: at template
  column i, a feature is a candidate when it is fixed with the same value on
  every column within ``stable`` × K of i (the runs of constant words; a
  learned template has wildcards where its examples vary, so its keyframes
  stay fuzzy there);
* of those, features are added one at a time, each time the one that leaves
  the fewest matching frames in a sample of the archive, until at most
  ``frequency`` of the sample matches (or ``max_features`` are fixed, or no
  feature narrows it further): the fewest features that make the pose
  rare — few, so that another actor's version of the motion still matches;
* candidate columns are spread over the template; the rarest keyframes at
  least a quarter of the template apart are kept, in time order, with the
  gap between two keyframes at columns p < q admitted from ⌈(q − p)/2⌉ to
  2(q − p) frames (the ½–2× warping of Δ's steps).

A query gets keyframe queries at several *levels* (:data:`KEYFRAME_LEVELS`),
lenient to strict: more keyframes, each matching a smaller share of the
sample. Each keyframe fixed costs recall (another actor's version of a pose
differs in some features), so the search takes the most lenient level that
leaves little enough of the archive to rank
(:func:`mocapdb.retrieval.search.preselect`). The search widens every hit by
the annotation's margins (:func:`mocapdb.keyframes.annot_margins`), so that
a match of the whole template stretched up to 2× fits in the segment.
"""
from __future__ import annotations

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.features import unpack_words
from mocapdb.keyframes import KeyframeQuery
from mocapdb.templates import QuantizedTemplate

#: at most this many features per keyframe
KEYFRAME_MAX_FEATURES = 4
#: a feature is a candidate at column i when fixed and constant within this fraction of K around i
KEYFRAME_STABLE = 0.15
#: candidate columns per query (spread evenly over the template)
KEYFRAME_CANDIDATES = 32
#: the preselection levels, lenient to strict: (keyframes, sample fraction a keyframe may match)
KEYFRAME_LEVELS = ((1, 0.3), (1, 0.1), (2, 0.3), (2, 0.1), (3, 0.1), (3, 0.03))


def stable_features(template: QuantizedTemplate, radius: int):
    """Features fixed with one value on every column within ``radius`` of each column.

    Returns
    -------
    stable : (K, 40) bool
    value : (K, 40) bool
        The template's values.
    """
    fixed = unpack_words(template.mask)
    value = unpack_words(template.value)
    K = len(template)
    ok = fixed.copy()
    cols = np.arange(K)
    for s in range(1, int(radius) + 1):
        for shifted in (np.minimum(cols + s, K - 1), np.maximum(cols - s, 0)):
            ok &= fixed[shifted] & (value[shifted] == value)
    return ok, value


def _sample_bitsets(sample):
    """Per feature and value the sample frames having it, as packed bits: (40, 2, ⌈n/64⌉) uint64."""
    bits = unpack_words(sample)  # (n, 40)
    n = bits.shape[0]
    pad = (-n) % 64
    on = np.ascontiguousarray(np.packbits(np.pad(bits, ((0, pad), (0, 0))).T, axis=1,
                                          bitorder="little")).view(np.uint64)
    valid = np.packbits(np.pad(np.ones(n, bool), (0, pad)), bitorder="little").view(np.uint64)
    return np.stack([~on & valid, on], axis=1), valid


def _greedy_path(candidates, values, sets, everything, n, max_features):
    """The greedy sequence of features of one column and the matching sample fraction after each.

    Each step adds the candidate feature that leaves the fewest matching
    sample frames (first on ties); it stops when no feature narrows the match.
    """
    cur = everything
    count = n
    path = []
    free = np.flatnonzero(candidates)
    while free.size and len(path) < max_features and count > 0:
        counts = np.bitwise_count(cur[None, :] & sets[free, values[free].astype(np.int64)]).sum(axis=1)
        k = int(np.argmin(counts))
        if counts[k] >= count:
            break
        f = int(free[k])
        cur = cur & sets[f, int(values[f])]
        count = int(counts[k])
        path.append((f, count / n))
        free = np.delete(free, k)
    return path


def column_paths(template: QuantizedTemplate, sample, *, max_features=KEYFRAME_MAX_FEATURES,
                 stable=KEYFRAME_STABLE, candidates=KEYFRAME_CANDIDATES):
    """Per candidate column its greedy feature path (module docstring).

    Returns
    -------
    list of (column, [(feature, matching sample fraction), …])
    """
    sample = np.asarray(sample, dtype=np.uint64)
    if sample.ndim != 1 or sample.size == 0:
        raise ParameterError("the archive sample must be a non-empty 1-D array of words")
    if max_features < 1 or stable < 0 or candidates < 1:
        raise ParameterError("need max_features >= 1, stable >= 0, candidates >= 1")
    K = len(template)
    ok, value = stable_features(template, max(1, round(stable * K)))
    sets, everything = _sample_bitsets(sample)
    cols = np.unique(np.linspace(0, K - 1, min(K, candidates)).round().astype(np.int64))
    return [(int(i), _greedy_path(ok[i], value[i], sets, everything, sample.size, max_features)) for i in cols], value


def pick_keyframes(paths, value, K, *, n_keyframes, frequency):
    """A keyframe query from the columns' paths: each column's shortest prefix matching at most
    ``frequency`` of the sample (or its whole path), the rarest columns a quarter of K apart.

    Returns
    -------
    KeyframeQuery or None
    """
    scored = []
    for i, path in paths:
        if not path:
            continue
        k = next((j for j, (_, freq) in enumerate(path) if freq <= frequency), len(path) - 1)
        scored.append((path[k][1], k + 1, i, [f for f, _ in path[:k + 1]]))
    scored.sort(key=lambda x: x[:3])
    picked = []
    for item in scored:
        if all(abs(item[2] - p[2]) >= K / 4 for p in picked):
            picked.append(item)
        if len(picked) == n_keyframes:
            break
    if not picked:
        return None
    picked.sort(key=lambda x: x[2])
    masks = [sum(1 << f for f in feats) for *_, feats in picked]
    values = [sum(1 << f for f in feats if value[i, f]) for _, _, i, feats in picked]
    pos = np.array([i for _, _, i, _ in picked], np.int64)
    gaps = np.diff(pos)
    return KeyframeQuery(np.array(masks, np.uint64), np.array(values, np.uint64), pos, np.ceil(gaps / 2), 2 * gaps, K)


def query_keyframes(template: QuantizedTemplate, sample, *, levels=KEYFRAME_LEVELS, **options) -> tuple:
    """The keyframe queries of a query template, one per level of :data:`KEYFRAME_LEVELS` (module docstring).

    Parameters
    ----------
    template : QuantizedTemplate
    sample : (n,) uint64
        Words of frames drawn from the archive.
    levels : sequence of (n_keyframes, frequency)
        Lenient to strict.
    **options
        ``max_features``, ``stable``, ``candidates`` of :func:`column_paths`.

    Returns
    -------
    tuple of KeyframeQuery
        Distinct queries, lenient first; empty when no column has a stable
        feature that narrows the sample (nothing to preselect with).
    """
    paths, value = column_paths(template, sample, **options)
    out = []
    for n_keyframes, frequency in levels:
        q = pick_keyframes(paths, value, len(template), n_keyframes=n_keyframes, frequency=frequency)
        if q is not None and not any(np.array_equal(q.mask, p.mask) and np.array_equal(q.value, p.value)
                                     and np.array_equal(q.positions, p.positions) for p in out):
            out.append(q)
    return tuple(out)


__all__ = ["KEYFRAME_LEVELS", "KEYFRAME_MAX_FEATURES", "KEYFRAME_STABLE", "KEYFRAME_CANDIDATES", "stable_features",
           "column_paths", "pick_keyframes", "query_keyframes"]
