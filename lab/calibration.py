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
:func:`top_share_right` compares two confidences at the same coverage: the
share right of the k segments each trusts most (the share of segments ≥ 0.5
alone favours the confidence that trusts fewer).

The shipped model's confidence is calibrated
(:func:`mocapdb.learning.confidence_maps.fit_confidence_maps`) on the
segments of a leave-one-lab-out evaluation, raw scores judged here
(:func:`held_out_segments`). Judging that calibration on those same
segments would be judging it on what it was fitted to:
:func:`calibrated_by_lab` fits, for each lab, the maps on the other labs'
segments only and applies them to that lab's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapdb.evaluation.metrics import segments_correct

__all__ = ["Calibration", "segment_verdicts", "confidence_calibration", "CALIBRATED", "held_out_segments",
           "fit_maps", "recipe_confidence_maps", "calibrated_by_lab", "top_share_right"]

#: the sets whose segments' confidence is judged (each annotated as such, not joined from others), and the lab
#: each belongs to
CALIBRATED = {"loao": "hdm05", "loao_mirrored": "hdm05", "cmu86_09": "cmu", "mocap6": "cmu",
              "bandai2": "bandai2", "accad": "accad"}


@dataclass(frozen=True)
class Calibration:
    """Attributes: ``segments`` scored, ``confident`` (confidence ≥ 0.5), ``confident_right`` (their share
    right, NaN without any), ``right`` (share of all right), ``auc`` (NaN without both kinds)."""

    segments: int
    confident: int
    confident_right: float
    right: float
    auc: float


def segment_verdicts(result, setting, *, segments=False):
    """(confidence, right) of the segments of one setting that can be judged (module docstring);
    ``segments``: (the segments, confidence, right)."""
    from lab.development import UNSCORED

    auto, conf = result.auto[setting], result.confidence[setting]
    if setting == "accad":
        truth = result.lab.clip_truth
        keep = np.array([r["label"] != "neutral" or any("neutral" in x for x in truth[r["document"]].required)
                         for r in auto], dtype=bool)
        right = np.array([r["label"] in truth[r["document"]].allowed for r in auto], dtype=bool)
        out = conf[keep], right[keep]
        return (auto[keep], *out) if segments else out
    truth = result.truth[setting]
    carried = set(truth["label"].tolist())
    skip = set(UNSCORED.get(setting, ())) | ({"neutral"} - carried)
    keep = ~np.isin(auto["label"], list(skip)) if skip else np.ones(auto.size, dtype=bool)
    out = conf[keep], segments_correct(truth, auto[keep])
    return (auto[keep], *out) if segments else out


def held_out_segments(result):
    """Per judged set of an evaluation (:data:`CALIBRATED`): (segments, raw confidence, right)."""
    return {s: segment_verdicts(result, s, segments=True) for s in CALIBRATED if s in result.auto}


def fit_maps(model_labels, parts, *, leave_out=None):
    """The confidence maps fitted on ``parts`` (:func:`held_out_segments`), without the sets of lab ``leave_out``."""
    from mocapdb.learning.confidence_maps import fit_confidence_maps

    use = [v for s, v in parts.items() if CALIBRATED[s] != leave_out]
    segs = np.concatenate([x[["start", "end"]] for x, _, _ in use])
    return fit_confidence_maps(model_labels, segs, *(np.concatenate(x) for x in list(zip(*use))[1:]))


def recipe_confidence_maps(data_dir, data, recipe, model_labels, *, vocabulary, seed=0):
    """The maps a model of ``recipe`` ships with: fitted on the segments of a leave-one-lab-out evaluation of the
    recipe (keyframes on, as annotation runs by default), each lab annotated by the recipe trained without it."""
    from lab.default_model import train_recipe
    from lab.development import development_evaluation

    cache = {}
    res = development_evaluation(data_dir, data=data, modes={"keyframes": {}}, leave_out_lab=True,
                                 vocabulary=vocabulary, mirrored=True, seed=seed,
                                 build=lambda clips, name: train_recipe(clips, recipe, name=name, seed=seed,
                                                                        cache=cache).model)["keyframes"]
    return fit_maps(model_labels, held_out_segments(res))


def calibrated_by_lab(model_labels, parts):
    """Per set, (calibrated confidence, right): each lab's segments through maps fitted on the other labs'."""
    from mocapdb.annotation.postprocess import calibrate_confidence

    out = {}
    for lab in dict.fromkeys(CALIBRATED[s] for s in parts):
        maps = fit_maps(model_labels, parts, leave_out=lab)
        for s, (segs, raw, right) in parts.items():
            if CALIBRATED[s] == lab:
                out[s] = (calibrate_confidence(segs, raw, maps), right)
    return out


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


def top_share_right(confidence, right, k) -> float:
    """Share right of the ``k`` segments with the highest confidence; segments tied at the cut count at their
    mean (as if the tie were broken at random). NaN for ``k`` = 0."""
    c = np.asarray(confidence, dtype=np.float64)
    r = np.asarray(right, dtype=bool)
    k = min(int(k), c.size)
    if k <= 0:
        return float("nan")
    cut = np.sort(c)[::-1][k - 1]
    above, at = c > cut, c == cut
    return float((r[above].sum() + (k - above.sum()) * r[at].mean()) / k)
