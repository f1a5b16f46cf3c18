"""The inverted file index and keyframe search (paper Sect. 5, KEYFRAMES.md).

:mod:`~mocapdb.keyframes.index` (runs of constant word and their posting
lists), :mod:`~mocapdb.keyframes.query` (keyframe queries) and
:mod:`~mocapdb.keyframes.search` (the keyframe-chain search); numba kernels in
``index_kernels`` and ``search_kernels``.
"""
from mocapdb.keyframes.index import (INDEX_PARTS, PART_BITS, SET_PARTS, Index, Postings, Segments, build_index, fuzzy_intervals, fuzzy_postings)
from mocapdb.keyframes.query import (TOOLBOX_SETS, UNBOUNDED, KeyframeQuery, annot_margins, choose_keyframes_equally_distributed, keyframe_mask_value, stiffness_bounds)
from mocapdb.keyframes.search import (PARALLEL_MIN_FRAMES, keyframe_hit_documents, keyframe_intervals, keyframe_postings, keyframe_search, keyframe_search_batch)

__all__ = [
    "INDEX_PARTS", "PART_BITS", "SET_PARTS", "Index", "Postings", "Segments", "build_index",
    "fuzzy_intervals", "fuzzy_postings", "UNBOUNDED", "TOOLBOX_SETS", "KeyframeQuery", "annot_margins",
    "choose_keyframes_equally_distributed", "keyframe_mask_value", "stiffness_bounds", "PARALLEL_MIN_FRAMES",
    "keyframe_hit_documents", "keyframe_intervals",
    "keyframe_postings", "keyframe_search", "keyframe_search_batch",
]
