"""Motion templates and the distance function Δ (paper Sect. 3, TEMPLATES.md).

:mod:`~mocapdb.templates.template` (real-valued and quantized templates),
:mod:`~mocapdb.templates.averaging` (learning a template from clips by
iterative warping and averaging) and :mod:`~mocapdb.templates.distance`
(subsequence DTW: Δ of a quantized template against packed words).
"""
from mocapdb.templates.template import (MotionTemplate, QuantizedTemplate, quantize)
from mocapdb.templates.averaging import (average_step, balance_weighted, contract_weighted, expand_weighted, learn_template, weighted_dtw)
from mocapdb.templates.distance import (ANNOTATION_STEPS, DEFAULT_CHUNK, RETRIEVAL_STEPS, RULES, cost_table, mt_distance, mt_distance_slices, subsequence_dtw, weighted_cost_tables)

__all__ = [
    "DEFAULT_CHUNK",
    "MotionTemplate", "QuantizedTemplate", "quantize", "learn_template", "weighted_dtw", "average_step",
    "expand_weighted", "contract_weighted", "balance_weighted", "ANNOTATION_STEPS", "RETRIEVAL_STEPS",
    "RULES", "cost_table", "mt_distance", "mt_distance_slices", "subsequence_dtw", "weighted_cost_tables",
]
