"""Segment filters beyond the paper (issue 11), each switchable and off in the reference mode.

* **minimum length** (:func:`drop_short_segments`): a class's segment must
  last at least ``ClassModel.min_frames`` 30 Hz frames — a full match of a
  template of K columns covers at least K/2 frames (the DTW steps shrink it
  at most twice), so a shorter run of Δarg is a leftover where the label won
  only briefly between others. A label keeps segments as short as its most
  lenient class allows.
* **short documents** (:func:`document_minimum`): in a document shorter
  than twice a label's minimum, a segment over half of it is kept (and must
  win a third of that). Both filters drop leftovers *between* labels; in a
  clip of 0.7–1 s (one gait cycle, a take cut to one step) a label over
  half of it is the clip's motion, not a leftover, and a minimum longer
  than the clip dropped every segment (RESULTS.md, issue 32: single gait
  cycles). A concurrent label (``turn``) keeps its minimum: it is its own
  duration (a lasting turn), not a filter against neighbours.
* **won frames** (:func:`won_frames`, :func:`drop_unwon_segments`): a
  segment's label must be the best label (Δarg) on at least a third of its
  ``min_frames`` (:data:`WON_FRACTION`). The segmenter extends a run of
  Δarg as far as the label's Δ̄^τ does not rise, which is the whole range
  of its best hit: a weak, long hit that wins a handful of frames between
  better labels (a lie-down template over a deposit on the floor, a throw
  over a squat) becomes a segment as long as a real one. What it won is
  what the annotation knows of it.
* **confidence** (:func:`segment_confidence`): not a filter — each
  segment's ``1 − Δ̄^τ/τ`` at its best frame, so users can filter; a model
  with ``confidence_maps`` turns it into the share of right segments seen at
  that score and length on held-out recordings (:func:`calibrate_confidence`);
* **margin** (:func:`apply_margin`): a frame where the best label's Δ̄^τ
  beats the second best by less than ``Model.margin`` is left unlabelled —
  two labels fit about equally well, so neither is trusted.

All run inside :func:`mocapdb.annotation.annotate` (``min_length``,
``min_won``, ``margin``); a model without ``min_frames`` and with
``margin = 0`` (the toolbox model) annotates exactly as the paper's chain.
"""
import numpy as np

from mocapdb.annotation.chain_kernels import _margin_kernel, _segment_min_kernel, _won_kernel
from mocapdb.annotation.model import STEP_ORDER
from mocapdb.errors import ParameterError, check_nonnegative

__all__ = ["label_min_frames", "drop_short_segments", "label_min_won", "won_frames", "drop_unwon_segments",
           "document_minimum", "apply_margin", "segment_confidence", "length_score", "calibrate_confidence",
           "WON_FRACTION"]

#: a segment's label must win (be Δarg on) this share of its ``min_frames``
#: (development evaluation, RESULTS.md issue 11: 1/4 to 1/3 best everywhere)
WON_FRACTION = 1 / 3


def label_min_frames(model) -> np.ndarray:
    """(n_labels,) int64: per label the smallest ``min_frames`` of its classes (0: no minimum)."""
    out = np.full(len(model.labels), np.iinfo(np.int64).max, np.int64)
    for c, k in zip(model.classes, model.label_index):
        out[k] = min(out[k], int(c.min_frames))
    out[out == np.iinfo(np.int64).max] = 0
    return out


def document_minimum(doc_lengths) -> np.ndarray:
    """The most a label's minimum length asks of a segment in documents of these lengths: half, rounded up.

    Parameters
    ----------
    doc_lengths : array_like of int

    Returns
    -------
    ndarray of int64
        ``⌈n/2⌉`` per document (module docstring, short documents).
    """
    return (np.asarray(doc_lengths, dtype=np.int64) + 1) // 2


def drop_short_segments(segments, labels, min_frames, *, doc_lengths=None, concurrent=()):
    """Segments of at least their label's minimum length (in a short document, of half of it).

    Parameters
    ----------
    segments : ndarray of SEGMENT_DTYPE
    labels : sequence of str
        Label order of ``min_frames``.
    min_frames : (n_labels,) int
    doc_lengths : array_like of int, optional
        The length of every document ``segments["doc"]`` indexes: a label's minimum is at most
        :func:`document_minimum` of its segment's document. Default: no cap.
    concurrent : collection of str, optional
        Labels whose minimum is never capped (concurrent labels: their minimum is their own duration).

    Returns
    -------
    ndarray of SEGMENT_DTYPE
        The segments kept, in their order.
    """
    need = dict(zip(labels, np.asarray(min_frames, dtype=np.int64).tolist()))
    if not segments.size or not any(need.values()):
        return segments
    lo = np.array([need.get(lab, 0) for lab in segments["label"]], dtype=np.int64)
    if doc_lengths is not None:
        capped = np.array([lab not in concurrent for lab in segments["label"]], dtype=bool)
        half = document_minimum(doc_lengths)[segments["doc"]]
        lo = np.where(capped, np.minimum(lo, half), lo)
    return segments[segments["end"] - segments["start"] + 1 >= lo]


def _won_need(min_frames):
    """Frames a segment must win for a minimum length: ⌈:data:`WON_FRACTION` · min_frames⌉."""
    return np.ceil(np.asarray(min_frames, dtype=np.int64) * WON_FRACTION - 1e-9).astype(np.int64)


def label_min_won(model) -> np.ndarray:
    """(n_labels,) int64: frames a segment of each label must win, ⌈:data:`WON_FRACTION` · min_frames⌉."""
    return _won_need(label_min_frames(model))


def won_frames(segments, label_cd, doc_bounds, labels) -> np.ndarray:
    """Frames of each segment on which its label is Δarg.

    Parameters
    ----------
    segments : ndarray of SEGMENT_DTYPE
        Frames within documents.
    label_cd : (n_labels, N) float64
        Δ̄^τ per label over the concatenated documents (the segmenter's input).
    doc_bounds : (n_docs + 1,) int
        Document starts in ``label_cd`` and its end.
    labels : sequence of str
        Label order of ``label_cd``.

    Returns
    -------
    (n_segments,) int64
    """
    cdl = np.ascontiguousarray(label_cd, dtype=np.float64)
    lab, first, last = _segment_rows(segments, doc_bounds, labels, cdl.shape[1])
    out = np.zeros(segments.size, np.int64)
    _won_kernel(cdl, lab, first, last, out)
    return out


def _segment_rows(segments, doc_bounds, labels, n_frames):
    """Each segment's label row and first/last frame in per-label arrays over the concatenated documents."""
    li = {lab: k for k, lab in enumerate(labels)}
    unknown = sorted(set(segments["label"].tolist()) - set(li))
    if unknown:
        raise ParameterError(f"segments have labels {unknown} that the per-label rows lack")
    lab = np.array([li[x] for x in segments["label"]], dtype=np.int64)
    b = np.asarray(doc_bounds, dtype=np.int64)
    first = (b[segments["doc"]] + segments["start"]).astype(np.int64)
    last = (b[segments["doc"]] + segments["end"]).astype(np.int64)
    if segments.size and (first.min() < 0 or last.max() >= n_frames or (last < first).any()):
        raise ParameterError("segments must lie within their documents")
    return lab, first, last


def segment_confidence(segments, label_ratio, doc_bounds, labels) -> np.ndarray:
    """Per segment, how far its best match lies below τ: ``1 − min Δ̄^τ/τ`` over its frames, in [0, 1].

    Parameters
    ----------
    segments : ndarray of SEGMENT_DTYPE
        Frames within documents.
    label_ratio : (n_labels, N) float64
        Per label and frame the smallest Δ̄^τ / τ among its classes (+inf where
        none matches).
    doc_bounds : (n_docs + 1,) int
    labels : sequence of str
        Label order of ``label_ratio``.

    Returns
    -------
    (n_segments,) float64
        1 for a perfect match, 0 for one at τ (a segment that only its
        extension reaches, with no hit inside, gets 0).
    """
    ratio = np.ascontiguousarray(label_ratio, dtype=np.float64)
    lab, first, last = _segment_rows(segments, doc_bounds, labels, ratio.shape[1])
    best = np.empty(segments.size)
    _segment_min_kernel(ratio, lab, first, last, best)
    return np.clip(1.0 - best, 0.0, 1.0)


def length_score(raw, length, length_weight, full_length, product=False) -> np.ndarray:
    """A :class:`~mocapdb.annotation.ConfidenceMap`'s score of segments, with ``ℓ = min(n, F) / F`` (``w`` =
    ``length_weight``, ``F`` = ``full_length``, ``n`` the length in 30 Hz frames): ``raw · (1 + w · ℓ) / (1 + w)``
    with ``product`` (the length lifts the match), else ``(raw + w · ℓ) / (1 + w)``; in [0, 1], ``raw`` itself,
    bit for bit, where ``w`` is 0. The fit (:func:`mocapdb.learning.confidence_maps.fit_confidence_maps`) and the
    calibration score alike; extension/src/annotation.c does these operations in this order."""
    w = np.float64(length_weight)
    share = np.minimum(np.asarray(length), full_length).astype(np.float64) / np.float64(full_length)
    raw = np.asarray(raw, dtype=np.float64)
    if product:
        return raw * (np.float64(1.0) + w * share) / (np.float64(1.0) + w)
    return (raw + w * share) / (np.float64(1.0) + w)


def calibrate_confidence(segments, raw, maps) -> np.ndarray:
    """Segments' confidences through their :class:`~mocapdb.annotation.ConfidenceMap` (raw where none).

    Parameters
    ----------
    segments : ndarray of SEGMENT_DTYPE
        Their labels and lengths (``end − start + 1``, 30 Hz frames) choose the map and enter its score.
    raw : (n,) float64
        Each segment's raw score (:func:`segment_confidence`).
    maps : sequence of ConfidenceMap
        ``Model.confidence_maps``.

    Returns
    -------
    (n,) float64
        Per segment, of its label's map with the largest ``min_length`` ≤ its length, the score
        (:func:`length_score`: ``w`` the map's ``length_weight``, ``F`` its ``full_length``, its
        ``length_product``), then ``values[j]`` for the last ``j`` with ``cuts[j] <= s`` (``values[0]`` below the
        first cut), plus :data:`STEP_ORDER` of the way to the next step's value (1 after the last) as far as
        ``s`` lies from ``cuts[j]`` towards the next cut (1): the order of scores kept within a step
        (:class:`~mocapdb.annotation.ConfidenceMap`; extension/src/annotation.c does the same operations in
        the same order); the raw score where no map applies.
    """
    raw = np.asarray(raw, dtype=np.float64)
    out = raw.copy()
    labels = np.asarray(segments["label"])
    length = np.asarray(segments["end"] - segments["start"] + 1, dtype=np.int64)
    chosen = np.full(raw.size, -1, dtype=np.int64)         # min_length of the map each segment takes
    for m in maps:
        on = (labels == m.label) & (length >= m.min_length) & (m.min_length > chosen)
        if on.any():
            cuts, values = np.asarray(m.cuts, dtype=np.float64), np.asarray(m.values, dtype=np.float64)
            r = length_score(raw[on], length[on], m.length_weight, m.full_length, m.length_product)
            j = np.maximum(np.searchsorted(cuts, r, side="right") - 1, 0)
            c0, v0 = cuts[j], values[j]
            c1, v1 = np.append(cuts[1:], 1.0)[j], np.append(values[1:], 1.0)[j]
            frac = np.zeros(r.size)
            wide = c1 > c0
            frac[wide] = (r[wide] - c0[wide]) / (c1[wide] - c0[wide])
            frac = np.clip(frac, 0.0, 1.0)
            # nothing added where nothing is to add: a step's value stands as stored (-0.0 too)
            out[on] = np.where((frac > 0.0) & (v1 > v0), v0 + STEP_ORDER * (v1 - v0) * frac, v0)
            chosen[on] = m.min_length
    return out


def drop_unwon_segments(segments, label_cd, doc_bounds, labels, min_won):
    """Segments whose label wins at least its ``min_won`` frames (see :func:`won_frames`).

    Parameters
    ----------
    segments, label_cd, doc_bounds, labels
        As :func:`won_frames`.
    min_won : (n_labels,) int
        Per label (``labels`` order); 0 keeps every segment of the label. In a short document at most
        what a third of :func:`document_minimum` asks.

    Returns
    -------
    ndarray of SEGMENT_DTYPE
        The segments kept, in their order.
    """
    need = np.asarray(min_won, dtype=np.int64)
    if not segments.size or not need.any():
        return segments
    lo = dict(zip(labels, need.tolist()))
    want = np.array([lo[x] for x in segments["label"]], dtype=np.int64)
    b = np.asarray(doc_bounds, dtype=np.int64)
    want = np.minimum(want, _won_need(document_minimum(b[1:] - b[:-1]))[segments["doc"]])
    check = want > 0
    keep = np.ones(segments.size, dtype=bool)
    if check.any():
        keep[check] = won_frames(segments[check], label_cd, doc_bounds, labels) >= want[check]
    return segments[keep]


def apply_margin(label_cd, margin):
    """Leave frames unlabelled where the best label wins by less than ``margin`` (in place).

    Parameters
    ----------
    label_cd : (n_labels, N) float64, C-contiguous
        Δ̄^τ per label.
    margin : float
        ≥ 0; 0 changes nothing.

    Returns
    -------
    label_cd
    """
    margin = check_nonnegative(margin, "margin")
    if margin > 0:
        _margin_kernel(label_cd, float(margin))
    return label_cd
