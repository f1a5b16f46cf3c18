"""Retrieval by example (paper Sects. 3–5 used for retrieval): "find motions like this one".

:mod:`~mocapdb.retrieval.queries` (the query template: a stretch's own words,
or a template learned from several examples), :mod:`~mocapdb.retrieval.weights`
(feature weights and chance level from the archive),
:mod:`~mocapdb.retrieval.keyframes` (keyframes taken from the query, for
preselection), :mod:`~mocapdb.retrieval.hits` (non-overlapping local minima
of Δ), :mod:`~mocapdb.retrieval.archive` (archive words rebuilt from the
keyframe index) and :mod:`~mocapdb.retrieval.search` (the steps together);
numba kernels in ``kernels``.
"""
from mocapdb.retrieval.queries import FEATURE_CHOICES, clip_template, examples_template, feature_mask, mirror_template
from mocapdb.retrieval.weights import chance_cost, feature_frequencies, information_weights
from mocapdb.retrieval.keyframes import KEYFRAME_LEVELS, query_keyframes
from mocapdb.retrieval.hits import HIT_DTYPE, best_hits, select_hits
from mocapdb.retrieval.search import (BATCH_FRAMES, CELL_BUDGET, MIN_QUERY_S, RESULT_DTYPE, SAMPLE_FRAMES,
                                      TAU_FACTOR, RetrievalQuery, archive_sample, plan_query, preselect, rank_cells,
                                      rank_slices, sample_step, search_documents, search_segments, template_query)

__all__ = [
    "FEATURE_CHOICES", "clip_template", "examples_template", "feature_mask", "mirror_template", "chance_cost",
    "feature_frequencies", "information_weights", "KEYFRAME_LEVELS", "query_keyframes", "HIT_DTYPE", "best_hits",
    "select_hits", "BATCH_FRAMES", "CELL_BUDGET", "MIN_QUERY_S", "RESULT_DTYPE", "SAMPLE_FRAMES", "TAU_FACTOR",
    "RetrievalQuery", "archive_sample", "plan_query", "preselect", "rank_cells", "rank_slices", "sample_step",
    "search_documents", "search_segments", "template_query",
]
