"""Calibrated confidence: a monotone map from a segment's raw score and length to the share of right segments.

The raw score of a segment (``1 − Δ̄^τ/τ`` at its best frame) ranks
segments within a label but says nothing about how often they are right: a
designed class (turn, neutral, tpose) matches its phases exactly or not at
all, so its raw score is always 1, and a learned class's τ is set per class.
What else a wrong segment shows, on three labs of four left out: it is short
(median 32–58 frames against 88–105 right, RESULTS.md issue 32 item 4).
:func:`fit_confidence_maps` learns, from segments the model's recipe
annotated on recordings left out of its training (leave-one-lab-out folds,
each judged right or wrong), one score of the two —
``s = raw · (1 + w · ℓ) / (1 + w)``, ``ℓ = min(length, FULL_LENGTH) / FULL_LENGTH``,
the weight ``w`` the ratio of the coefficient of ``raw · ℓ`` to the raw
score's in a logistic regression of right-or-wrong on both
(:func:`length_weight`): the length lifts a match by up to ``w`` and lifts no
match at all — and
a non-decreasing step function of that score: isotonic regression (pool
adjacent violators) of right-or-wrong on ``s``, its steps joined until each
stands on :data:`MIN_STEP` segments; a step's value is a cautious share
right: the posterior of its segments (a Beta, with the share right of all
as :data:`PRIOR_SEGMENTS` pseudo-segments) less :data:`CAUTION` standard
deviations, so a step that stands on few segments claims less. The point
estimate alone made the maps fragile: a handful of right segments at one raw
score moved a whole step across 0.5 on the next lab (held out, the share
right of segments ≥ 0.5 swung 0.80–0.91 with a design added or the step
size moved, RESULTS.md issue 32); the cautious value holds over those
changes. A confidence of 0.8 thus reads "of held-out segments like this one,
at least about 80 % were right"; within a step the score still orders the
segments (:data:`mocapdb.annotation.model.STEP_ORDER`: up to a hundredth of
the way to the next step's value). The length enters the score, not as
bands with a map each (the maps before): a map per band ranked a
middle-length segment of a poor match above a long one of a good match
where the other labs' middle band happened to be right more often, and the
held-out ranking (AUC) stayed under 0.85 on HDM05 and the CMU documents; one
rising map of a score rising in both cannot invert them (RESULTS.md issue
32, "Length in the score"). The length multiplies the match rather than
adding to it (the maps before, ``(raw + w · ℓ) / (1 + w)``, still read as
they were): added, any segment of 3 s scored at least ``w / (1 + w)``
however poorly it matched, and a long wrong segment barely under τ (an
exercise template's hit running on over the next motion) was trusted more
than a short right one; multiplied, held out, the share right of segments
≥ 0.5 rose on every lab but one (RESULTS.md issue 32, "The length lifts a
match"). The maps pool all labels: maps per label,
fitted on the other labs, were worse on the lab left out than none (a
label's reliability is its lab's: `move` is right on every studio walk and
on half of HDM05's, whose truth calls the steps around a kick the kick).
Every label of the model gets the map
(:class:`mocapdb.annotation.ConfidenceMap`, stored with the model), applied
after the raw score (:func:`mocapdb.annotation.postprocess.calibrate_confidence`).
"""
from __future__ import annotations

import numpy as np

from mocapdb.annotation.model import ConfidenceMap
from mocapdb.annotation.postprocess import length_score
from mocapdb.errors import ParameterError

__all__ = ["fit_confidence_maps", "length_weight", "PRIOR_SEGMENTS", "MIN_STEP", "CAUTION", "FULL_LENGTH",
           "RIDGE", "MAX_LENGTH_WEIGHT"]

#: weight, in segments, of the prior each step is shrunk towards (a label's share right, all labels' share)
PRIOR_SEGMENTS = 4.0
#: fewest held-out segments a step of the map stands on (isotonic regression alone makes steps of one or two)
MIN_STEP = 5
#: standard deviations of a step's posterior share right taken off its mean (one: a step's value is exceeded
#: by its true share right about five times in six)
CAUTION = 1.0
#: the length (30 Hz frames) from which a segment counts as long as any in the score: 3 s (held out, 2–3 s
#: ranked best; 4–5 s let the long segments of a poor match, HDM05's exercises, outrank short right ones)
FULL_LENGTH = 90
#: L2 penalty on the two slopes of the logistic regression that weighs the length against the raw score
#: (the weight moves little with it: 0.49–0.78 without, 0.45–0.72 with 1, 0.38–0.62 with 10, over the folds)
RIDGE = 1.0
#: the largest length weight: where the raw scores barely rank (all alike, their slope near 0) the ratio
#: grows without bound; capped, the length decides and the weight stays a number to store
MAX_LENGTH_WEIGHT = 1000.0
#: a fitted slope at most this is none: far above the rounding of coefficients of order 1
_SLOPE_EPS = 1e-9


def _pav(y, w):
    """Pool adjacent violators: block starts and means of the non-decreasing fit to ``y`` (weights ``w``)."""
    starts, means, weights = [], [], []
    for i, (v, x) in enumerate(zip(y, w)):
        starts.append(i)
        means.append(float(v))
        weights.append(float(x))
        while len(means) > 1 and means[-2] >= means[-1]:  # equal neighbours too: one step
            m = (means[-2] * weights[-2] + means[-1] * weights[-1]) / (weights[-2] + weights[-1])
            weights[-2] += weights[-1]
            means[-2] = m
            del starts[-1], means[-1], weights[-1]
    return np.array(starts, dtype=np.int64), np.array(means), np.array(weights)


def _coarsen(starts, means, weights):
    """Neighbouring steps joined, from the lowest up, until each holds :data:`MIN_STEP` segments (the last
    joins its lower neighbour when short): joining neighbours of a rising fit keeps it rising."""
    out_s, out_m, out_w = [], [], []
    for a, m, w in zip(starts, means, weights):
        if out_w and out_w[-1] < MIN_STEP:
            out_m[-1] = (out_m[-1] * out_w[-1] + m * w) / (out_w[-1] + w)
            out_w[-1] += w
        else:
            out_s.append(a)
            out_m.append(m)
            out_w.append(w)
    if len(out_w) > 1 and out_w[-1] < MIN_STEP:
        out_m[-2] = (out_m[-2] * out_w[-2] + out_m[-1] * out_w[-1]) / (out_w[-2] + out_w[-1])
        out_w[-2] += out_w[-1]
        del out_s[-1], out_m[-1], out_w[-1]
    return np.array(out_s, dtype=np.int64), np.array(out_m), np.array(out_w)


def _step_map(score, right, prior):
    """(cuts, values): isotonic steps over scores, each the cautious share right of its posterior."""
    order = np.argsort(score, kind="stable")
    x, y = score[order], right[order].astype(np.float64)
    # equal scores form one point: a step cannot split them
    ux, first, counts = np.unique(x, return_index=True, return_counts=True)
    sums = np.add.reduceat(y, first)
    starts, means, weights = _coarsen(*_pav(sums / counts, counts))
    # Beta(a, b): the step's right and wrong segments plus the prior's pseudo-segments
    a = means * weights + PRIOR_SEGMENTS * prior
    b = (1.0 - means) * weights + PRIOR_SEGMENTS * (1.0 - prior)
    n = a + b
    cautious = a / n - CAUTION * np.sqrt(a * b / (n * n * (n + 1.0)))
    # steps of unequal weights may fall out of order: pool again
    s2, m2, _ = _pav(cautious, n)
    cuts = ux[starts[s2]]
    cuts[0] = min(cuts[0], 0.0)
    return tuple(cuts.tolist()), tuple(np.clip(m2, 0.0, 1.0).tolist())


def _logistic(x, y, ridge):
    """Coefficients of the logistic regression of ``y`` (0/1) on the columns of ``x`` (the first all ones,
    unpenalized), maximising the log-likelihood less ``ridge / 2`` times the other coefficients' squares: Newton's
    method (the objective is concave; the ridge keeps it strictly so when the classes separate)."""
    penalty = np.diag([0.0] + [ridge] * (x.shape[1] - 1))
    b = np.zeros(x.shape[1])
    for _ in range(100):
        p = 1.0 / (1.0 + np.exp(-(x @ b)))
        grad = x.T @ (y - p) - penalty @ b
        hess = x.T @ (x * (p * (1.0 - p))[:, None]) + penalty + 1e-12 * np.eye(x.shape[1])
        step = np.linalg.solve(hess, grad)
        b += step
        if np.abs(step).max() < 1e-10:
            break
    return b


def length_weight(raw, length, right, *, full_length=FULL_LENGTH, ridge=RIDGE, product=True) -> float:
    """How much a segment's length counts against its raw score for being right: ``b_ℓ / b_raw`` of the
    logistic regression ``P(right) = σ(b_0 + b_raw · raw + b_ℓ · raw · ℓ)``, ``ℓ = min(length, full_length) /
    full_length`` (with ``product``; without, ``b_ℓ · ℓ``: the weight of the maps before it) — Newton's method,
    ``ridge`` on the two slopes; 0 where the length's slope is not positive (the raw score alone: a length that
    does not help gives no ratio to trust); :data:`MAX_LENGTH_WEIGHT`, the length alone, where the raw score's is
    not (raw scores all alike, or ranking the wrong way) — and never more.

    Parameters
    ----------
    raw : (n,) float
        Raw scores in [0, 1].
    length : (n,) int
        Segment lengths, 30 Hz frames.
    right : (n,) bool
    full_length : int
    ridge : float
    product : bool
        The weight of ``length_score(…, product=True)`` (:func:`mocapdb.annotation.postprocess.length_score`).

    Returns
    -------
    float
        The weight ``w`` ≥ 0 of :class:`~mocapdb.annotation.ConfidenceMap`.
    """
    raw = np.asarray(raw, dtype=np.float64)
    share = np.minimum(np.asarray(length, dtype=np.float64), full_length) / full_length
    x = np.column_stack([np.ones(len(raw)), raw, raw * share if product else share])
    b = _logistic(x, np.asarray(right, dtype=np.float64), ridge)
    # a slope within rounding of 0 (raw scores all alike leave theirs to the intercept) counts as none
    raw_slope, length_slope = (float(v) if v > _SLOPE_EPS else 0.0 for v in b[1:])
    if not length_slope:
        return 0.0
    return min(length_slope / raw_slope, MAX_LENGTH_WEIGHT) if raw_slope else MAX_LENGTH_WEIGHT


def fit_confidence_maps(model_labels, segments, raw, right) -> tuple:
    """The :class:`~mocapdb.annotation.ConfidenceMap` of every label of a model, learned from held-out segments.

    Parameters
    ----------
    model_labels : sequence of str
        The model's labels: each gets the map.
    segments : ndarray with fields ``start``, ``end``
        The held-out segments (30 Hz frames, inclusive).
    raw : (n,) float
        Each segment's raw score in [0, 1] (``1 − Δ̄^τ/τ``, as annotated by a model without maps).
    right : (n,) bool
        Whether the segment is right (:func:`lab.calibration.segment_verdicts`).

    Returns
    -------
    tuple of ConfidenceMap
        One per label, all alike: for every length (``min_length`` 0), the steps over the score where the
        length lifts the match (``length_product``) by :func:`length_weight` up to :data:`FULL_LENGTH`.
    """
    raw = np.asarray(raw, dtype=np.float64)
    right = np.asarray(right, dtype=bool)
    length = np.asarray(segments["end"] - segments["start"] + 1, dtype=np.int64)
    if not (length.shape == raw.shape == right.shape) or raw.ndim != 1:
        raise ParameterError(f"segments, raw and right must be 1-d and as long, got {length.shape}, {raw.shape}, "
                             f"{right.shape}")
    if not raw.size:
        raise ParameterError("fitting confidence maps needs held-out segments; got none")
    if not np.all((raw >= 0) & (raw <= 1)):
        raise ParameterError("raw scores must lie in [0, 1]")
    if (length < 1).any():
        raise ParameterError("segments must end at or after their start")
    w = length_weight(raw, length, right)
    cuts, values = _step_map(length_score(raw, length, w, FULL_LENGTH, product=True), right, float(right.mean()))
    return tuple(ConfidenceMap(lab, cuts, values, 0, w, FULL_LENGTH, length_product=True) for lab in model_labels)
