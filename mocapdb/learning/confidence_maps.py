"""Calibrated confidence: a monotone map from a segment's raw score, per length, to the share of right segments.

The raw score of a segment (``1 − Δ̄^τ/τ`` at its best frame) ranks
segments within a label but says nothing about how often they are right: a
designed class (turn, neutral, tpose) matches its phases exactly or not at
all, so its raw score is always 1, and a learned class's τ is set per class.
What else a wrong segment shows, on three labs of four left out: it is short
(median 32–58 frames against 88–105 right, RESULTS.md issue 32 item 4).
:func:`fit_confidence_maps` learns, from segments the model's recipe
annotated on recordings left out of its training (leave-one-lab-out folds,
each judged right or wrong), for each length band (:data:`LENGTH_EDGES`) a
non-decreasing step function of the raw score — isotonic regression (pool
adjacent violators) of right-or-wrong on the raw score, its steps joined
until each stands on :data:`MIN_STEP` segments; a step's value is a cautious
share right: the posterior of its segments (a Beta, with the band's share
right as :data:`PRIOR_SEGMENTS` pseudo-segments) less :data:`CAUTION`
standard deviations, so a step that stands on few segments claims less. The
point estimate alone made the maps fragile: a handful of right segments at
one raw score moved a whole step across 0.5 on the next lab (held out, the
share right of segments ≥ 0.5 swung 0.80–0.91 with a design added or the
step size moved, RESULTS.md issue 32); the cautious value holds 0.91–0.93
over those changes. A confidence of 0.8 thus reads "of held-out segments
like this one, at least about 80 % were right"; within a step the raw score
still orders the segments (:data:`mocapdb.annotation.model.STEP_ORDER`: up to
a hundredth of the way to the next step's value — the steps alone tied a
step's segments, which cost the ranking held out, RESULTS.md issue 32). The bands pool
all labels: maps per label, fitted on the other labs, were worse on the lab
left out than none (a label's reliability is its lab's: `move` is right on
every studio walk and on half of HDM05's, whose truth calls the steps around
a kick the kick). Every label of the model gets the maps
(:class:`mocapdb.annotation.ConfidenceMap`, stored with the model), applied
after the raw score (:func:`mocapdb.annotation.postprocess.calibrate_confidence`).
"""
from __future__ import annotations

import numpy as np

from mocapdb.annotation.model import ConfidenceMap
from mocapdb.errors import ParameterError

__all__ = ["fit_confidence_maps", "PRIOR_SEGMENTS", "MIN_STEP", "CAUTION", "LENGTH_EDGES"]

#: weight, in segments, of the prior each step is shrunk towards (a label's share right, all labels' share)
PRIOR_SEGMENTS = 4.0
#: fewest held-out segments a step of the map stands on (isotonic regression alone makes steps of one or two)
MIN_STEP = 5
#: standard deviations of a step's posterior share right taken off its mean (one: a step's value is exceeded
#: by its true share right about five times in six)
CAUTION = 1.0
#: the length bands (shortest segment of each, 30 Hz frames): under 1.5 s, 1.5–3 s, longer (RESULTS.md issue 32:
#: of the bands tried, the best held out)
LENGTH_EDGES = (0, 45, 90)


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


def _step_map(raw, right, prior):
    """(cuts, values): isotonic steps over raw scores, each the cautious share right of its posterior."""
    order = np.argsort(raw, kind="stable")
    x, y = raw[order], right[order].astype(np.float64)
    # equal raw scores form one point: a step cannot split them
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


def fit_confidence_maps(model_labels, segments, raw, right, *, length_edges=LENGTH_EDGES) -> tuple:
    """The :class:`~mocapdb.annotation.ConfidenceMap` of every label of a model, learned from held-out segments.

    Parameters
    ----------
    model_labels : sequence of str
        The model's labels: each gets the maps.
    segments : ndarray with fields ``start``, ``end``
        The held-out segments (30 Hz frames, inclusive).
    raw : (n,) float
        Each segment's raw score in [0, 1] (``1 − Δ̄^τ/τ``, as annotated by a model without maps).
    right : (n,) bool
        Whether the segment is right (:func:`lab.calibration.segment_verdicts`).
    length_edges : sequence of int
        Ascending, from 0: the shortest segment of each length band.

    Returns
    -------
    tuple of ConfidenceMap
        Per label, per band; a band with fewer than :data:`MIN_STEP` segments takes the map of all of them.
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
    edges = [int(e) for e in length_edges]
    if not edges or edges[0] != 0 or any(b <= a for a, b in zip(edges, edges[1:])):
        raise ParameterError(f"length_edges must ascend from 0, got {tuple(length_edges)}")
    overall = _step_map(raw, right, float(right.mean()))
    band = np.searchsorted(edges, length, side="right") - 1
    bands = []
    for k, lo in enumerate(edges):
        on = band == k
        cuts, values = overall if on.sum() < MIN_STEP else _step_map(raw[on], right[on], float(right[on].mean()))
        bands.append((lo, cuts, values))
    return tuple(ConfidenceMap(lab, cuts, values, lo) for lab in model_labels for lo, cuts, values in bands)
