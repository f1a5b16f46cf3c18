"""Keyframe preselection for annotation (paper Sect. 5, TEMPLATES.md §10.1).

For every class with a keyframe query, the keyframe search runs on the
documents and Δ of the class template is then computed only on the returned
segments, widened by 2·(pos₁ − 1) frames on the left and 2·(L − pos_K) on the
right so that a template match with up to 2× time stretching fits; Δ stays
+inf elsewhere. Classes without a query are matched on whole documents.
"""
from __future__ import annotations

import numpy as np

from .index import SET_PARTS, build_index
from .keyframes import annot_margins, keyframe_search_batch


def index_parts(queries) -> tuple:
    """Index parts the queries need: a feature set for each keyframe restricted to one,
    the 40-bit part for the others."""
    parts = set()
    for q in queries:
        for s in q.feature_sets:
            parts.add("full" if s is None else s)
    return tuple(p for p in (*SET_PARTS, "full") if p in parts)


def keyframe_preselection(words, lengths, model):
    """Per class of ``model`` the slices to compute Δ on, for concatenated documents.

    Parameters
    ----------
    words : (N,) uint64
        Packed 30 Hz words of the documents, concatenated.
    lengths : (n_docs,) int
    model : mocapdb.model.Model

    Returns
    -------
    list
        One entry per class in model order: None (no query: whole documents)
        or an ``(n, 2)`` int64 array of inclusive ``(start, end)`` word indices
        — the input ``preselection`` of :func:`mocapdb.annotation.annotate`.
    """
    lengths = np.asarray(lengths, dtype=np.int64)
    bounds = np.concatenate(([0], np.cumsum(lengths)))
    with_query = [k for k, c in enumerate(model.classes) if c.keyframe_query is not None]
    out = [None] * len(model.classes)
    if not with_query:
        return out
    queries = [model.classes[k].keyframe_query for k in with_query]
    index = build_index(np.asarray(words, dtype=np.uint64), doc_lengths=lengths,
                        feature_sets=index_parts(queries))
    margins = np.array([annot_margins(q) for q in queries], dtype=np.int64)
    found = keyframe_search_batch(index, queries, extend_left=margins[:, 0], extend_right=margins[:, 1])
    for k, segs in zip(with_query, found):
        base = bounds[segs.doc]
        out[k] = np.stack([base + segs.start, base + segs.end], axis=1) if len(segs.doc) else \
            np.zeros((0, 2), np.int64)
    return out


def uses_keyframes(model, keyframes=None) -> bool:
    """Whether annotation preselects: ``keyframes`` if given, else whether the model has queries."""
    return any(c.keyframe_query is not None for c in model.classes) if keyframes is None else bool(keyframes)


def preselection_for(words, lengths, model, keyframes=None):
    """The ``preselection`` argument of :func:`mocapdb.annotation.annotate`: the keyframe
    preselection when :func:`uses_keyframes`, else None (whole documents)."""
    return keyframe_preselection(words, lengths, model) if uses_keyframes(model, keyframes) else None


__all__ = ["keyframe_preselection", "preselection_for", "uses_keyframes", "index_parts"]
