"""Does a segment's confidence mean something? Right and wrong segments of an evaluation, and how they rank.

A segment's confidence (:func:`mocapdb.annotation.postprocess.segment_confidence`:
1 − Δ̄^τ/τ at its best frame) should say how likely the segment is right.
:func:`segment_verdicts` decides, per segment of a setting of a
:class:`~lab.development.DevelopmentEvaluation`, whether it
is right:

* on sets with per-frame truth: it shares a frame with a truth segment of its
  label (the paper's segment-level correctness, P2); labels the set cannot
  score (:data:`~lab.development.UNSCORED`) and ``neutral``
  where the truth never carries it (silence is not wrong) are left out;
* on the third lab's clips (per-clip truth): its label is one the clip's
  truth requires or accepts; ``neutral`` is left out unless required.

:func:`confidence_calibration` gives what a user relies on: the share of
segments with confidence ≥ 0.5 that are right, and the ranking of right over
wrong segments (AUC: the chance that a random right segment has a higher
confidence than a random wrong one, ties counted half).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapdb.evaluation.metrics import segments_correct

__all__ = ["Calibration", "segment_verdicts", "confidence_calibration"]


@dataclass(frozen=True)
class Calibration:
    """Attributes: ``segments`` scored, ``confident`` (confidence ≥ 0.5), ``confident_right`` (their share
    right, NaN without any), ``right`` (share of all right), ``auc`` (NaN without both kinds)."""

    segments: int
    confident: int
    confident_right: float
    right: float
    auc: float


def segment_verdicts(result, setting):
    """(confidence, right) of the segments of one setting that can be judged (module docstring)."""
    from lab.development import UNSCORED

    auto, conf = result.auto[setting], result.confidence[setting]
    if setting == "accad":
        truth = result.lab.clip_truth
        keep = np.array([r["label"] != "neutral" or any("neutral" in x for x in truth[r["document"]].required)
                         for r in auto], dtype=bool)
        right = np.array([r["label"] in truth[r["document"]].allowed for r in auto], dtype=bool)
        return conf[keep], right[keep]
    truth = result.truth[setting]
    carried = set(truth["label"].tolist())
    skip = set(UNSCORED.get(setting, ())) | ({"neutral"} - carried)
    keep = ~np.isin(auto["label"], list(skip)) if skip else np.ones(auto.size, dtype=bool)
    return conf[keep], segments_correct(truth, auto[keep])


def confidence_calibration(confidence, right) -> Calibration:
    """:class:`Calibration` of segments' confidences against whether each is right."""
    c = np.asarray(confidence, dtype=np.float64)
    r = np.asarray(right, dtype=bool)
    sure = c >= 0.5
    auc = float("nan")
    if r.any() and (~r).any():
        # Mann–Whitney: ranks of all confidences (ties averaged), the right ones' rank sum
        order = np.argsort(c, kind="stable")
        ranks = np.empty(c.size)
        ranks[order] = np.arange(1, c.size + 1)
        vals, inv = np.unique(c, return_inverse=True)
        ranks = (np.bincount(inv, weights=ranks) / np.bincount(inv))[inv]
        n1, n0 = int(r.sum()), int((~r).sum())
        auc = (ranks[r].sum() - n1 * (n1 + 1) / 2) / (n1 * n0)
    return Calibration(int(c.size), int(sure.sum()), float(r[sure].mean()) if sure.any() else float("nan"),
                       float(r.mean()) if r.size else float("nan"), float(auc))
