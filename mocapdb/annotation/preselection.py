"""Keyframe preselection for annotation (paper Sect. 5, TEMPLATES.md §10.1).

For every class with a keyframe query, the keyframe search runs on an index of
the documents, and Δ of the class template is then computed only on the
returned segments, widened by 2·(pos₁ − 1) frames on the left and 2·(L − pos_K)
on the right so that a template match with up to 2× time stretching fits; Δ
stays +inf elsewhere. Classes without a query are matched on whole documents.

Two steps, so that a database searches its stored index once and annotates
any subset of its motions (:mod:`mocapdb.storage.cache`):

* :func:`keyframe_preselection` — the search: per class the segments of the
  index's documents;
* :func:`preselection_slices` — those segments as word slices of some of the
  documents, concatenated (the ``preselection`` input of
  :func:`mocapdb.annotation.annotate`).

:func:`preselection_for` does both on documents given as words (an in-memory
index of just them).
"""
from __future__ import annotations

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.keyframes import SET_PARTS, annot_margins, build_index, keyframe_search_batch


def index_parts(queries) -> tuple:
    """Index parts the queries need: a feature set for each keyframe restricted to one,
    the 40-bit part for the others."""
    parts = set()
    for q in queries:
        for s in q.feature_sets:
            parts.add("full" if s is None else s)
    return tuple(p for p in (*SET_PARTS, "full") if p in parts)


def model_index_parts(model) -> tuple:
    """:func:`index_parts` of all keyframe queries of a model."""
    return index_parts([c.keyframe_query for c in model.classes if c.keyframe_query is not None])


def keyframe_preselection(index, model) -> list:
    """Run every class's keyframe query of ``model`` on ``index``.

    Parameters
    ----------
    index : mocapdb.keyframes.Index
        Must hold the parts of :func:`model_index_parts`.
    model : mocapdb.annotation.Model

    Returns
    -------
    list
        One entry per class in model order: None (no query: whole documents)
        or :class:`mocapdb.keyframes.Segments` (document = index document,
        0-based inclusive frames), already widened by the annotation margins.
    """
    with_query = [k for k, c in enumerate(model.classes) if c.keyframe_query is not None]
    out = [None] * len(model.classes)
    if not with_query:
        return out
    queries = [model.classes[k].keyframe_query for k in with_query]
    margins = np.array([annot_margins(q) for q in queries], dtype=np.int64)
    found = keyframe_search_batch(index, queries, extend_left=margins[:, 0], extend_right=margins[:, 1])
    for k, segs in zip(with_query, found):
        out[k] = segs
    return out


def preselection_slices(found, docs, doc_lengths) -> list:
    """Segments of index documents as slices of the concatenation of some of them.

    Parameters
    ----------
    found : list
        :func:`keyframe_preselection` output.
    docs : (n,) int
        Index document of each document to annotate, in concatenation order
        (each at most once).
    doc_lengths : (n,) int
        Their lengths (as in the index).

    Returns
    -------
    list
        Per class None or an ``(m, 2)`` int64 array of inclusive ``(start, end)``
        word indices into the concatenation.
    """
    docs = np.asarray(docs, dtype=np.int64)
    lengths = np.asarray(doc_lengths, dtype=np.int64)
    if docs.shape != lengths.shape:
        raise ParameterError(f"docs and doc_lengths must have the same shape, got {docs.shape}, {lengths.shape}")
    base = np.concatenate(([0], np.cumsum(lengths)[:-1])).astype(np.int64)
    n_index_docs = 1 + max([int(docs.max(initial=-1))] + [int(s.doc.max(initial=-1)) for s in found if s is not None])
    position = np.full(n_index_docs, -1, np.int64)
    position[docs] = np.arange(docs.size)
    out = []
    for segs in found:
        if segs is None:
            out.append(None)
            continue
        pos = position[segs.doc]
        keep = pos >= 0
        b = base[pos[keep]]
        out.append(np.stack([b + segs.start[keep], b + segs.end[keep]], axis=1).astype(np.int64)
                   if keep.any() else np.zeros((0, 2), np.int64))
    return out


def uses_keyframes(model, keyframes=None) -> bool:
    """Whether annotation preselects: ``keyframes`` if given, else whether the model has queries."""
    return any(c.keyframe_query is not None for c in model.classes) if keyframes is None else bool(keyframes)


def preselection_for(words, lengths, model, keyframes=None):
    """The ``preselection`` of :func:`mocapdb.annotation.annotate` for documents given as words.

    The keyframe preselection on an in-memory index of the documents when
    :func:`uses_keyframes`, else None (whole documents).
    """
    if not uses_keyframes(model, keyframes):
        return None
    lengths = np.asarray(lengths, dtype=np.int64)
    parts = model_index_parts(model) or ("full",)
    index = build_index(np.asarray(words, dtype=np.uint64), doc_lengths=lengths, feature_sets=parts)
    return preselection_slices(keyframe_preselection(index, model), np.arange(lengths.size), lengths)


__all__ = ["keyframe_preselection", "preselection_slices", "preselection_for", "uses_keyframes", "index_parts",
           "model_index_parts"]
