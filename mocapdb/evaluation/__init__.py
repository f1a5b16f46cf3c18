"""Evaluation (paper Sect. 7): the paper's measures, the development evaluation, figures.

:mod:`~mocapdb.evaluation.metrics` (P/R/F on frames and segments, Eq. 5–8; τ
sweeps), :mod:`~mocapdb.evaluation.documents` (the documents: leave-one-actor-out, the
real CMU documents, CMU training stretches), :mod:`~mocapdb.evaluation.development`
(folds and scores; leave-one-lab-out), :mod:`~mocapdb.evaluation.studio` (another studio's clips named by
their action: the measures that tell whether labels travel), :mod:`~mocapdb.evaluation.lab_clips`
(a third lab's clips with what a user expects of each), :mod:`~mocapdb.evaluation.calibration`
(does a segment's confidence say it is right),
:mod:`~mocapdb.evaluation.records` (the quality guard: headline figures and their
records) and :mod:`~mocapdb.evaluation.figures` (matplotlib, the plot extra).
"""
from mocapdb.evaluation.metrics import (Scores, evaluate_annotation, evaluate_by_label, f_measure, frame_measures, parse_tau_grid, restrict_labels, segment_measures, sweep_tau, tau_grid)
from mocapdb.evaluation.documents import (CLIPS_PER_DOCUMENT, CMU_STRETCH_CLASSES, MOCAP6_TRIALS, DocumentSet, cmu86_documents, cmu_stretches, concatenate_motions, loao_documents, mirror_document_set, mocap6_documents)
from mocapdb.evaluation.studio import (STUDIO_CONTENTS, StudioDocuments, StudioScores, studio_documents, studio_measures,
                                       studio_training)
from mocapdb.evaluation.lab_clips import LabDocuments, LabScores, lab_documents, lab_measures
from mocapdb.evaluation.development import (LABS, SETTINGS, UNSCORED, DevelopmentData, DevelopmentEvaluation,
                                            development_data, development_evaluation)
from mocapdb.evaluation.calibration import Calibration, confidence_calibration, segment_verdicts
from mocapdb.evaluation.records import (guard, headline_figures, model_figures, raised_records, read_records,
                                       write_records)

__all__ = [
    "Scores", "f_measure", "frame_measures", "segment_measures", "evaluate_annotation", "evaluate_by_label",
    "restrict_labels", "sweep_tau", "tau_grid", "parse_tau_grid", "DocumentSet",
    "DevelopmentEvaluation", "concatenate_motions", "loao_documents", "cmu86_documents", "mocap6_documents",
    "development_evaluation", "MOCAP6_TRIALS", "CLIPS_PER_DOCUMENT", "SETTINGS", "CMU_STRETCH_CLASSES",
    "cmu_stretches", "mirror_document_set", "DevelopmentData", "development_data", "UNSCORED",
    "STUDIO_CONTENTS", "StudioDocuments", "StudioScores", "studio_documents", "studio_measures", "studio_training",
    "LabDocuments", "LabScores", "lab_documents", "lab_measures", "LABS", "Calibration", "confidence_calibration",
    "segment_verdicts",
    "guard", "headline_figures", "model_figures", "raised_records", "read_records", "write_records",
]
