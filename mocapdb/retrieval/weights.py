"""How much a feature value says: weights of the query template's features from the archive.

A feature value that most frames of the archive share (hands low, feet on
the floor) tells little about a motion; a rare one (the left foot raised
with the knee straight, the spine horizontal) tells a lot. The query's local
cost therefore weighs each fixed feature of each template column by its
self-information in the archive, ``w = −log₂ p(feature = the column's
value)`` (Shannon), with ``p`` from the archive's frames (Laplace-smoothed,
so a value never seen still has a finite weight). The cost stays a fraction
of disagreeing features — of their information instead of their number —
and Δ stays in [0, 1] (:func:`mocapdb.templates.weighted_cost_tables`).

The same frequencies give the chance level of a template
(:func:`chance_cost`): the expected local cost against a frame drawn from
the archive with independent features, the scale of the hit threshold.
"""
from __future__ import annotations

import math

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.features import N_FEATURES, unpack_words
from mocapdb.templates import QuantizedTemplate


def feature_frequencies(words) -> np.ndarray:
    """P(feature on) over archive frames, Laplace-smoothed: ``(count + 1) / (n + 2)``.

    Parameters
    ----------
    words : (n,) uint64
        Packed 30 Hz words of the archive, or a sample of its frames.

    Returns
    -------
    ndarray, shape (40,), float64
        In (0, 1).
    """
    w = np.asarray(words)
    if w.ndim != 1 or w.dtype != np.uint64:
        raise ParameterError(f"words must be a 1-D uint64 array of packed 30 Hz words, got dtype {w.dtype} "
                             f"shape {w.shape}")
    counts = unpack_words(w).sum(axis=0, dtype=np.int64)
    return (counts + 1.0) / (w.size + 2.0)


def _value_probability(template: QuantizedTemplate, p_on):
    """P(feature = the column's value) per column and feature, its self-information, and the fixed features.

    The self-information is ``-log2`` of the C library (``math.log2``) on the 80 probabilities
    ``p_on`` and ``1 - p_on`` — not ``np.log2``, whose AVX-512 code differs from the C library's in
    the last bit of about 0.2 % of these values: the weights would change with the CPU, and the
    native ``similar_to`` (extension/src/similar_plan.c, glibc's ``log2``) would not reproduce them.
    """
    p = np.asarray(p_on, dtype=np.float64)
    if p.shape != (N_FEATURES,) or not ((p > 0) & (p < 1)).all():
        raise ParameterError(f"p_on must be ({N_FEATURES},) probabilities in (0, 1), got shape {p.shape}")
    q = 1.0 - p
    value = unpack_words(template.value)
    info_on = np.array([-math.log2(x) for x in p])
    info_off = np.array([-math.log2(x) for x in q])
    return (np.where(value, p[None, :], q[None, :]), np.where(value, info_on[None, :], info_off[None, :]),
            unpack_words(template.mask))


def information_weights(template: QuantizedTemplate, p_on) -> np.ndarray:
    """Self-information ``−log₂ p(value)`` of every fixed feature of every column.

    Parameters
    ----------
    template : QuantizedTemplate
        K columns.
    p_on : (40,) float
        :func:`feature_frequencies` of the archive.

    Returns
    -------
    ndarray, shape (K, 40), float64
        0 at wildcards.
    """
    _, info, fixed = _value_probability(template, p_on)
    return np.where(fixed, info, 0.0)


def chance_cost(template: QuantizedTemplate, p_on, weights=None) -> float:
    """Expected local cost of the weighted template against archive frames with independent features.

    Per column the weighted fraction of fixed features that a random frame
    (feature f on with probability ``p_on[f]``) disagrees with, averaged over
    the columns (weighted by the column weights, as Δ is): the Δ of an
    alignment that matches nothing in particular.

    Parameters
    ----------
    template : QuantizedTemplate
    p_on : (40,) float
    weights : (K, 40) float, optional
        The feature weights; default :func:`information_weights`.

    Returns
    -------
    float
        In [0, 1]; 0 for a template without fixed features.
    """
    pv, info, fixed = _value_probability(template, p_on)
    w = np.where(fixed, info if weights is None else np.asarray(weights, np.float64), 0.0)
    total = w.sum(axis=1)
    per_column = np.divide((w * (1.0 - pv)).sum(axis=1), total, out=np.zeros(len(template)), where=total > 0)
    return float(np.average(per_column, weights=template.weights))


__all__ = ["feature_frequencies", "information_weights", "chance_cost"]
