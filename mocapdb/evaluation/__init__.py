"""Evaluation (paper Sect. 7): the paper's measures, the development evaluation, figures.

:mod:`~mocapdb.evaluation.metrics` (P/R/F on frames and segments, Eq. 5–8; τ
sweeps), :mod:`~mocapdb.evaluation.development` (leave-one-actor-out and the
real CMU documents) and :mod:`~mocapdb.evaluation.figures` (matplotlib, the
plot extra).
"""
from mocapdb.evaluation.metrics import (Scores, evaluate_annotation, evaluate_by_label, f_measure, frame_measures, parse_tau_grid, restrict_labels, segment_measures, sweep_tau, tau_grid)
from mocapdb.evaluation.development import (CLIPS_PER_DOCUMENT, MOCAP6_TRIALS, SETTINGS, DevelopmentEvaluation, DocumentSet, cmu86_documents, concatenate_motions, development_evaluation, loao_documents, mocap6_documents)

__all__ = [
    "Scores", "f_measure", "frame_measures", "segment_measures", "evaluate_annotation", "evaluate_by_label",
    "restrict_labels", "sweep_tau", "tau_grid", "parse_tau_grid", "DocumentSet",
    "DevelopmentEvaluation", "concatenate_motions", "loao_documents", "cmu86_documents", "mocap6_documents",
    "development_evaluation", "MOCAP6_TRIALS", "CLIPS_PER_DOCUMENT", "SETTINGS",
]
