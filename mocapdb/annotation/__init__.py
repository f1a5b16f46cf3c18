"""Annotation (paper Sect. 4, TEMPLATES.md §9–§10): a model of class templates labels documents.

:mod:`~mocapdb.annotation.model` (classes, labels, τ), :mod:`~mocapdb.annotation.preselection`
(keyframe preselection, Sect. 5), :mod:`~mocapdb.annotation.chain` (Δ → hits →
Δ̄^τ → segments, one chain for one or many τ), :mod:`~mocapdb.annotation.labels`
(label rows and label files: the shape of segments and ground truth) and
:mod:`~mocapdb.annotation.elan` (ELAN ``.eaf`` files in and out).
"""
from mocapdb.annotation.model import (DEFAULT_DELTA, DEFAULT_TAU, ClassModel, ConfidenceMap, Model)
from mocapdb.annotation.chain import (HIT_DTYPE, MATCH_NUM_MAX, SEGMENT_DTYPE, Annotation, annotate, annotate_sweep, combine_by_label, extract_hits, form_segments, frame_labels)
from mocapdb.annotation.preselection import (index_parts, keyframe_preselection, model_index_parts, preselection_for,
                                            preselection_slices, uses_keyframes)
from mocapdb.annotation.elan import EAF_FPS_PROPERTY, eaf_document, eaf_source_fps, is_eaf, read_eaf, write_eaf
from mocapdb.annotation.labels import (LABEL_COLUMNS, LABEL_DTYPE, SHIPPED_CLASS_LABELS, as_label_rows, class_labels, feature_to_native_frames, label_documents, label_rows, map_labels, native_factor, native_to_feature_frames, read_class_labels, read_labels, read_segments, read_text, read_truth, segments_to_rows, to_feature_grid, to_native_grid, write_class_labels, write_labels)
from mocapdb.annotation.results import SEGMENT_ARROW, SEGMENT_COLUMNS, SEGMENT_SCHEMA, segment_table

__all__ = [
    "ClassModel", "Model", "DEFAULT_DELTA", "DEFAULT_TAU", "Annotation", "HIT_DTYPE", "SEGMENT_DTYPE",
    "MATCH_NUM_MAX", "annotate", "annotate_sweep", "extract_hits", "combine_by_label", "frame_labels", "form_segments",
    "keyframe_preselection", "preselection_slices", "model_index_parts", "preselection_for", "uses_keyframes", "index_parts", "LABEL_COLUMNS",
    "LABEL_DTYPE", "label_rows", "label_documents", "EAF_FPS_PROPERTY", "eaf_document", "eaf_source_fps", "is_eaf", "read_eaf",
    "write_eaf", "as_label_rows", "read_labels", "read_segments", "read_truth", "write_labels",
    "native_to_feature_frames", "feature_to_native_frames", "native_factor", "to_feature_grid", "to_native_grid",
    "segments_to_rows", "map_labels", "read_class_labels", "write_class_labels", "class_labels", "read_text",
    "SHIPPED_CLASS_LABELS", "SEGMENT_SCHEMA", "SEGMENT_COLUMNS", "SEGMENT_ARROW", "segment_table",
]
