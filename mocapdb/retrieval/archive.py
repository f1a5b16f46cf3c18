"""The archive's words where a query needs them, read from the keyframe index.

The index's ``full`` part holds every motion as runs of constant 40-bit word
(paper Sect. 5), so any stretch of any motion can be rebuilt from it exactly,
without reading the ``features`` table: :func:`index_words` rebuilds frame
ranges (the preselected segments a query ranks), :func:`index_sample` the
archive sample (:func:`mocapdb.retrieval.search.sample_step`: the frames whose
1-based number is a multiple of the step, as in the database).
"""
from __future__ import annotations

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.keyframes import Index
from mocapdb.retrieval.kernels import _runs_to_words_kernel


def _full_part(index: Index):
    p = index.part_id("full")
    words = index.words[index.part_word_offset[p]:index.part_word_offset[p + 1]]
    return index.doc_seg_offset[p], words


def index_words(index: Index, doc, start, stop) -> np.ndarray:
    """The words of frame ranges, rebuilt from the index's ``full`` runs.

    Parameters
    ----------
    index : Index
        With the ``full`` part.
    doc, start, stop : (n,) int
        Index document and half-open frame range ``[start, stop)`` (0-based) of each range.

    Returns
    -------
    ndarray, shape (Σ (stop − start),), uint64
        The ranges' words, concatenated in order.
    """
    doc, start, stop = (np.ascontiguousarray(x, dtype=np.int64).ravel() for x in (doc, start, stop))
    if not doc.shape == start.shape == stop.shape:
        raise ParameterError("doc, start and stop must have the same length")
    if doc.size and ((doc < 0).any() or (doc >= index.n_docs).any() or (start < 0).any() or (stop < start).any()
                     or (stop > index.doc_lengths[np.clip(doc, 0, index.n_docs - 1)]).any()):
        raise ParameterError("ranges must lie within the index's documents (0 <= start <= stop <= length)")
    seg_offset, words = _full_part(index)
    out_off = np.concatenate(([0], np.cumsum(stop - start))).astype(np.int64)
    out = np.empty(int(out_off[-1]), np.uint64)
    keep = stop > start
    _runs_to_words_kernel(seg_offset, index.seg_start, index.seg_len, index.seg_wid, words, doc[keep], start[keep],
                          stop[keep], out_off[:-1][keep], out)
    return out


def index_sample(index: Index, step: int) -> np.ndarray:
    """The words of every motion's frames whose 1-based number is a multiple of ``step``."""
    lengths = index.doc_lengths
    per_doc = lengths // int(step)
    doc = np.repeat(np.arange(index.n_docs), per_doc)
    k = np.arange(int(per_doc.sum())) - np.repeat(np.cumsum(per_doc) - per_doc, per_doc)
    frame = (k + 1) * int(step) - 1  # 0-based
    return index_words(index, doc, frame, frame + 1)


__all__ = ["index_words", "index_sample"]
