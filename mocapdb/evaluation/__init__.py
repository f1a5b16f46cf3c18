"""Evaluation (paper Sect. 7): the paper's measures and its figures.

:mod:`~mocapdb.evaluation.metrics` (P/R/F on frames and segments, Eq. 5–8; τ
sweeps: what ``mocapdb evaluate`` computes) and :mod:`~mocapdb.evaluation.figures`
(matplotlib, the plot extra). The project's own development evaluation — its
documents and folds, leave-one-lab-out, the quality guard's records, the
default model's recipe — is the ``lab/`` folder of the repository, which is
not installed: users get the measures, not the harness they were made with.
"""
from mocapdb.evaluation.metrics import (Scores, evaluate_annotation, evaluate_by_label, f_measure, frame_measures, parse_tau_grid, restrict_labels, segment_measures, sweep_tau, tau_grid)

__all__ = [
    "Scores", "evaluate_annotation", "evaluate_by_label", "f_measure", "frame_measures", "parse_tau_grid", "restrict_labels", "segment_measures", "sweep_tau", "tau_grid",
]
