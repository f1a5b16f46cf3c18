"""Segment filters beyond the paper (issue 11), each switchable and off in the reference mode.

* **minimum length** (:func:`drop_short_segments`): a class's segment must
  last at least ``ClassModel.min_frames`` 30 Hz frames — a full match of a
  template of K columns covers at least K/2 frames (the DTW steps shrink it
  at most twice), so a shorter run of Δarg is a leftover where the label won
  only briefly between others. A label keeps segments as short as its most
  lenient class allows.
* **margin** (:func:`apply_margin`): a frame where the best label's Δ̄^τ
  beats the second best by less than ``Model.margin`` is left unlabelled —
  two labels fit about equally well, so neither is trusted.

Both run inside :func:`mocapdb.annotation.annotate` (``min_length``,
``margin``); a model without ``min_frames`` and with ``margin = 0`` (the
toolbox model) annotates exactly as the paper's chain.
"""
import numpy as np

from mocapdb.annotation.chain_kernels import _margin_kernel
from mocapdb.errors import ParameterError

__all__ = ["label_min_frames", "drop_short_segments", "apply_margin"]


def label_min_frames(model) -> np.ndarray:
    """(n_labels,) int64: per label the smallest ``min_frames`` of its classes (0: no minimum)."""
    out = np.full(len(model.labels), np.iinfo(np.int64).max, np.int64)
    for c, k in zip(model.classes, model.label_index):
        out[k] = min(out[k], int(c.min_frames))
    out[out == np.iinfo(np.int64).max] = 0
    return out


def drop_short_segments(segments, labels, min_frames):
    """Segments of at least their label's minimum length.

    Parameters
    ----------
    segments : ndarray of SEGMENT_DTYPE
    labels : sequence of str
        Label order of ``min_frames``.
    min_frames : (n_labels,) int

    Returns
    -------
    ndarray of SEGMENT_DTYPE
        The segments kept, in their order.
    """
    need = dict(zip(labels, np.asarray(min_frames, dtype=np.int64).tolist()))
    if not segments.size or not any(need.values()):
        return segments
    lo = np.array([need.get(lab, 0) for lab in segments["label"]], dtype=np.int64)
    return segments[segments["end"] - segments["start"] + 1 >= lo]


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
    if not (np.isfinite(margin) and margin >= 0):
        raise ParameterError(f"margin must be a non-negative number, got {margin!r}")
    if margin > 0:
        _margin_kernel(label_cd, float(margin))
    return label_cd
