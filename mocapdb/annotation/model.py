"""Annotation models: the classes an annotation run distinguishes (no I/O here).

A :class:`Model` is an ordered set of :class:`ClassModel` (fine classes, e.g.
``squat1Reps``), each mapped to a (coarser) label (e.g. ``exercise``); the
label order breaks ties in Δarg (TEMPLATES.md §10.2–§10.3, paper Sect. 4).
Storage (DuckDB / Parquet) lives elsewhere.
"""
import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mocapdb.errors import ParameterError, check_nonnegative
from mocapdb.templates import MotionTemplate, QuantizedTemplate

__all__ = ["ClassModel", "ConfidenceMap", "Model", "DEFAULT_DELTA", "DEFAULT_TAU", "STEP_ORDER"]

#: quantization threshold δ used by the annotation scripts (TEMPLATES.md §8)
DEFAULT_DELTA = 0.05
#: hit threshold τ of annotationScript.m (TEMPLATES.md §9.1)
DEFAULT_TAU = 0.13
#: how far towards the next step's value a segment's score moves its calibrated confidence within a step
#: of a :class:`ConfidenceMap` (a hundredth: the step's value stands, the score orders its segments);
#: extension/src/annotation.c's MDB_STEP_ORDER is the same number
STEP_ORDER = 0.01


@dataclass(frozen=True, eq=False)
class ClassModel:
    """One motion class of a model.

    Attributes
    ----------
    name : str
        Fine class name (e.g. ``"squat1Reps"``).
    label : str
        Label the class annotates with (e.g. ``"exercise"``); several classes
        may share a label (their classification deltas are combined by min).
    template : MotionTemplate or None
        The real-valued template (None if only the quantized one is known).
    quantized : QuantizedTemplate or None
        The template used for Δ; if None it is ``template.quantize(delta)``.
    delta : float, default 0.05
        Quantization threshold δ the quantized template was made with.
    tau : float, default 0.13
        Hit threshold τ (TEMPLATES.md §9.1).
    keyframe_query : object, optional
        The learned keyframe query (owned by the keyframe module), or None.
    min_frames : int, default 0
        Shortest segment (30 Hz frames) the class's label keeps through this
        class (:mod:`mocapdb.annotation.postprocess`); 0: no minimum (the paper).
    """

    name: str
    label: str
    template: MotionTemplate | None = None
    quantized: QuantizedTemplate | None = None
    delta: float = DEFAULT_DELTA
    tau: float = DEFAULT_TAU
    keyframe_query: Any = None
    min_frames: int = 0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError(f"name must be a non-empty string, got {self.name!r}")
        if not isinstance(self.label, str) or not self.label:
            raise ParameterError(
                f"label of class {self.name!r} must be a non-empty string, got {self.label!r}")
        if self.template is not None and not isinstance(self.template, MotionTemplate):
            raise ParameterError(
                f"template of class {self.name!r} must be a MotionTemplate, "
                f"got {type(self.template).__name__}")
        if self.quantized is None:
            if self.template is None:
                raise ParameterError(
                    f"class {self.name!r} needs a template or a quantized template")
            object.__setattr__(self, "quantized", self.template.quantize(self.delta))
        elif not isinstance(self.quantized, QuantizedTemplate):
            raise ParameterError(
                f"quantized of class {self.name!r} must be a QuantizedTemplate, "
                f"got {type(self.quantized).__name__}")
        check_nonnegative(self.tau, f"tau of class {self.name!r}")
        if (isinstance(self.min_frames, bool) or not isinstance(self.min_frames, (int, np.integer))
                or self.min_frames < 0):
            raise ParameterError(
                f"min_frames of class {self.name!r} must be a non-negative integer, got {self.min_frames!r}")


@dataclass(frozen=True, eq=False)
class ConfidenceMap:
    """Calibrated confidence of a label's segments: a rising step function of the raw score and the length.

    The raw score of a segment is ``1 − Δ̄^τ/τ`` at its best frame
    (:func:`mocapdb.annotation.postprocess.segment_confidence`); its length
    ``n`` is ``end − start + 1`` (30 Hz frames). A segment takes the map of
    its label with the largest ``min_length`` it reaches (none: it keeps the
    raw score). With ``ℓ = min(n, full_length) / full_length`` and ``w`` the
    ``length_weight``, the map's score of the segment is, with
    ``length_product``, ``s = raw · (1 + w · ℓ) / (1 + w)`` — the length
    lifts a match by up to its weight and lifts no match at all, so a long
    segment barely under τ is not trusted for its length — and otherwise
    (maps fitted before it) ``s = (raw + w · ℓ) / (1 + w)``; in [0, 1] either
    way, ``raw`` itself where ``w`` is 0: a better match and a longer
    segment, up to ``full_length``, both count for it. Its
    confidence is ``values[j]`` for the last ``j`` with ``cuts[j] <= s``
    (``values[0]`` below ``cuts[0]``): the share of right segments seen at
    that score on recordings the model was not trained on
    (:func:`mocapdb.learning.confidence_maps.fit_confidence_maps`) — plus,
    so that the score still orders the segments of one step, a hundredth
    (:data:`STEP_ORDER`) of the way to the next step's value (1 after the
    last) as the score goes from ``cuts[j]`` to the next cut (1): a step
    claims what its segments showed, and a better one within it ranks
    higher. IEEE operations in a fixed order, so that every implementation
    (the native extension too) gives the same number bit for bit.

    Attributes
    ----------
    label : str
    cuts : tuple of float
        Ascending scores where a step starts.
    values : tuple of float
        Non-decreasing confidences in [0, 1], one per cut.
    min_length : int, default 0
        Shortest segment (30 Hz frames) the map is for (the fitted maps are
        for every length: the length is in their score).
    length_weight : float, default 0
        Weight of the length in the score, ≥ 0 (0: the raw score alone).
    full_length : int, default 90
        Length (30 Hz frames) from which a segment counts as long as any, ≥ 1.
    length_product : bool, default False
        The length scales the raw score (``raw · (1 + w · ℓ) / (1 + w)``)
        instead of adding to it (``(raw + w · ℓ) / (1 + w)``, the maps of
        mocapdb before it, read from their archives as they were).
    """

    label: str
    cuts: tuple
    values: tuple
    min_length: int = 0
    length_weight: float = 0.0
    full_length: int = 90
    length_product: bool = False

    def __post_init__(self):
        cuts = tuple(float(x) for x in self.cuts)
        values = tuple(float(x) for x in self.values)
        if not cuts or len(cuts) != len(values):
            raise ParameterError(f"confidence map of {self.label!r}: cuts and values must be non-empty and "
                                 f"as many, got {len(cuts)} and {len(values)}")
        if any(not b > a for a, b in zip(cuts, cuts[1:])) or not all(np.isfinite(cuts)):
            raise ParameterError(f"confidence map of {self.label!r}: cuts must be finite and ascending, got {cuts}")
        if any(not 0.0 <= v <= 1.0 for v in values) or any(b < a for a, b in zip(values, values[1:])):
            raise ParameterError(f"confidence map of {self.label!r}: values must be non-decreasing in [0, 1], "
                                 f"got {values}")
        if isinstance(self.min_length, bool) or not isinstance(self.min_length, (int, np.integer)) \
                or self.min_length < 0:
            raise ParameterError(f"confidence map of {self.label!r}: min_length must be a non-negative integer, "
                                 f"got {self.min_length!r}")
        object.__setattr__(self, "cuts", cuts)
        object.__setattr__(self, "values", values)
        if isinstance(self.full_length, bool) or not isinstance(self.full_length, (int, np.integer)) \
                or self.full_length < 1:
            raise ParameterError(f"confidence map of {self.label!r}: full_length must be a positive integer, "
                                 f"got {self.full_length!r}")
        weight = float(self.length_weight)
        if not (np.isfinite(weight) and weight >= 0.0):
            raise ParameterError(f"confidence map of {self.label!r}: length_weight must be finite and >= 0, "
                                 f"got {self.length_weight!r}")
        object.__setattr__(self, "min_length", int(self.min_length))
        object.__setattr__(self, "length_weight", weight + 0.0)   # -0.0 as 0.0: one stored weight per value
        object.__setattr__(self, "full_length", int(self.full_length))
        if not isinstance(self.length_product, (bool, np.bool_)):
            raise ParameterError(f"confidence map of {self.label!r}: length_product must be True or False, "
                                 f"got {self.length_product!r}")
        object.__setattr__(self, "length_product", bool(self.length_product))


@dataclass(frozen=True, eq=False)
class Model:
    """An annotation model: classes plus the order of their labels.

    Attributes
    ----------
    name : str
    classes : tuple of ClassModel
        Fine classes; their order is the order of Δ rows and of hits.
    labels : tuple of str, optional
        Label order (ties in Δarg go to the earlier label). Default: order of
        first appearance in ``classes``. Must contain every class label; extra
        labels are allowed (they never annotate).
    margin : float, default 0.0
        Frames whose best label's Δ̄^τ beats the second best by less than this
        stay unlabelled (:mod:`mocapdb.annotation.postprocess`); 0: the paper.
    concurrent_labels : tuple of str, default ()
        Labels annotated on their own, beside the others instead of against
        them (beyond the paper, whose segmenter gives each frame one label):
        a walker who turns round is walking and turning, so ``turn`` takes no
        frame from ``move``. Each must be a label of the model; () is the paper.
    confidence_maps : tuple of ConfidenceMap, default ()
        Per label (and shortest segment length) the map from a segment's raw
        score and length to its calibrated confidence (beyond the paper),
        kept in label and length order; a label without one keeps the raw
        score.
    """

    name: str
    classes: tuple = field(default_factory=tuple)
    labels: tuple | None = None
    margin: float = 0.0
    concurrent_labels: tuple = ()
    confidence_maps: tuple = ()

    def __post_init__(self):
        classes = tuple(self.classes)
        for k, c in enumerate(classes):
            if not isinstance(c, ClassModel):
                raise ParameterError(
                    f"classes[{k}] must be a ClassModel, got {type(c).__name__}")
        names = [c.name for c in classes]
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ParameterError(f"class names must be unique; repeated: {dup}")
        if self.labels is None:
            labels = tuple(dict.fromkeys(c.label for c in classes))
        else:
            labels = tuple(self.labels)
            if len(set(labels)) != len(labels):
                raise ParameterError(f"labels must be unique, got {labels}")
            missing = sorted({c.label for c in classes} - set(labels))
            if missing:
                raise ParameterError(f"labels lacks the class labels {missing}; add them")
        check_nonnegative(self.margin, "margin")
        if isinstance(self.concurrent_labels, str):
            raise ParameterError(f"concurrent_labels must be a sequence of labels, got {self.concurrent_labels!r}")
        concurrent = tuple(dict.fromkeys(str(x) for x in self.concurrent_labels))
        stray = sorted(set(concurrent) - set(labels))
        if stray:
            raise ParameterError(f"concurrent_labels {stray} are not labels of the model {labels}")
        object.__setattr__(self, "concurrent_labels", concurrent)
        maps = tuple(self.confidence_maps)
        if any(not isinstance(m, ConfidenceMap) for m in maps):
            raise ParameterError("confidence_maps must be ConfidenceMap objects")
        mapped = [(m.label, m.min_length) for m in maps]
        if len(set(mapped)) != len(mapped) or {lab for lab, _ in mapped} - set(labels):
            raise ParameterError(f"confidence_maps must be for labels of the model {labels}, one per label and "
                                 f"min_length, got {mapped}")
        object.__setattr__(self, "confidence_maps",
                           tuple(sorted(maps, key=lambda m: (labels.index(m.label), m.min_length))))
        object.__setattr__(self, "classes", classes)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "margin", float(self.margin))

    @property
    def class_names(self):
        """Fine class names in model order."""
        return tuple(c.name for c in self.classes)

    @property
    def label_index(self):
        """(n_classes,) int64: index into ``labels`` of each class."""
        pos = {lab: k for k, lab in enumerate(self.labels)}
        return np.array([pos[c.label] for c in self.classes], dtype=np.int64)

    def __len__(self):
        return len(self.classes)

    def with_keyframe_queries(self, queries):
        """A copy whose classes carry the given keyframe queries.

        Parameters
        ----------
        queries : mapping of str to KeyframeQuery
            Class name → query; classes not in it keep theirs.
        """
        unknown = sorted(set(queries) - set(self.class_names))
        if unknown:
            raise ParameterError(f"queries name classes {unknown} that the model does not have")
        classes = tuple(dataclasses.replace(c, keyframe_query=queries[c.name]) if c.name in queries else c
                        for c in self.classes)
        return dataclasses.replace(self, classes=classes)
