"""The quality guard: the headline figures of every development set, and the records they must keep.

A change that helps one labelled set at another's cost should fail where it
is made, not surface on other studios' recordings later. The shipped model's
headline figures on every set (:func:`headline_figures`: F1 per set; on the
studio's clips the share of locomotion labelled ``move``, the turning clips
found, the straight clips and gesture frames wrongly labelled; on the third
lab's clips the clips entirely right, locomotion with ``move``, turns found
and wrong, clips of no class left silent, hops found; per set the recall of
``move``) are recorded in the repository with the model's fingerprint
(``tests/quality_records.json``). Every label of the model is watched: on
each set whose truth lacks a label, the share of its frames under that label
is capped at its record (``share_<label>``, lower is better), so a label
cannot spread unseen where no truth would score it; and every class's hits
(their lengths summed over every set: where its Δ falls below its τ) are kept under
:data:`CLASSES`, so a model with a class deleted fails (its figure is not
measured) and one whose class stops finding what it found (below
:data:`CLASS_FLOOR` of its record) fails too. :func:`guard` lists every
figure that fell more than a tolerance (0.01) below its record — above it,
for the figures where lower is better — and every set where the keyframe
preselection costs ``move`` recall (with keyframes below without by more
than the tolerance). :func:`raised_records` moves records only up: a new
model that raises a figure raises its record in the same commit.
"""
from __future__ import annotations

import json
from pathlib import Path

from mocapdb.errors import ParameterError
from mocapdb.evaluation.metrics import evaluate_by_label

__all__ = ["HEADLINE", "TOLERANCE", "MODES", "CAPPED_SETS", "CLASSES", "CLASS_FLOOR", "SHARE", "label_shares",
           "headline_figures", "guard", "raised_records", "read_records",
           "write_records", "model_figures"]

#: set → figure → +1 where higher is better, −1 where lower is better
HEADLINE = {
    **{s: {"f1": 1, "move_recall": 1} for s in ("loao", "loao_mirrored", "cmu86_09", "mocap6", "cmu", "all")},
    "bandai2": {"f1": 1, "move_recall": 1, "move_share": 1, "move_share_travelling": 1, "turning_with_turn": 1,
                "straight_with_turn": -1, "gesture_wrong": -1},
    "accad": {"clips_right": 1, "move_found": 1, "move_share": 1, "move_share_travelling": 1, "turning_with_turn": 1,
              "straight_with_turn": -1, "silent_right": 1, "hops_found": 1},
}
#: the sets annotated as such (not joined from others), where a label the truth lacks gets a frame-share cap
CAPPED_SETS = ("loao", "loao_mirrored", "cmu86_09", "mocap6", "bandai2", "accad")
#: figure name of a label's frame share on a set whose truth lacks the label (lower is better)
SHARE = "share_"
#: the pseudo-set of each class's hits (their lengths summed over every set): a class deleted is not measured,
#: one that stops finding what it found fails when it keeps less than :data:`CLASS_FLOOR` of its record
CLASSES = "classes"
CLASS_FLOOR = 0.5
#: how far a figure may fall below its record
TOLERANCE = 0.01


def _sign(s, name):
    """+1 where higher is better, −1 where lower is better."""
    return -1 if name.startswith(SHARE) else HEADLINE.get(s, {}).get(name, 1)


def _truth_labels(result, s) -> set:
    """The labels a set's truth can carry (silence, ``neutral``, on the sets that expect it)."""
    if s == "accad":
        return set(result.lab.expected)
    out = set(result.truth[s]["label"].tolist())
    return out | {"neutral"} if s == "bandai2" else out


def label_shares(result, s, labels) -> dict:
    """Frames of set ``s`` under each of ``labels``, as shares of all its frames."""
    auto, n = result.auto[s], int(result.documents[s].doc_lengths.sum())
    return {lab: float((auto["end"][auto["label"] == lab] - auto["start"][auto["label"] == lab] + 1).sum()) / n
            for lab in labels}
#: the annotation modes the guard keeps records of
MODES = {"keyframes": {}, "no keyframes": {"keyframes": False}}


def headline_figures(result) -> dict:
    """The headline figures of one annotation mode of a development evaluation.

    Parameters
    ----------
    result : DevelopmentEvaluation

    Returns
    -------
    dict of str to dict of str to float
        Set → figure → value, for the sets of :data:`HEADLINE` the result
        holds. Clip counts are shares (turning clips with a turn of all
        turning clips), so that every figure lies in [0, 1].
    """
    out = {}
    model_labels = {lab for m in result.models.values() for lab in m.labels}
    for s in CAPPED_SETS:
        if s in result.auto and s in result.documents:
            lacking = sorted(model_labels - _truth_labels(result, s))
            out.setdefault(s, {}).update({SHARE + k: round(v, 4)
                                          for k, v in label_shares(result, s, lacking).items()})
    if result.hit_frames:
        out[CLASSES] = {c: int(n) for c, n in result.hit_frames.items()}
    lab = result.lab
    if lab is not None:
        out.setdefault("accad", {}).update({k: round(v, 4) for k, v in {
            "clips_right": lab.clips_right / max(1, lab.clips), "move_found": lab.move_found / max(1, lab.move_clips),
            "move_share": lab.move_share, "turning_with_turn": lab.turning_with_turn / max(1, lab.turning_clips),
            "straight_with_turn": lab.straight_with_turn / max(1, lab.straight_clips),
            "silent_right": lab.silent_right / max(1, lab.silent_clips),
            "hops_found": lab.hops_found / max(1, lab.hop_clips)}.items()})
        if lab.move_share_travelling is not None:   # `move` over the frames where the root travels (lab/travel.py)
            out["accad"]["move_share_travelling"] = round(lab.move_share_travelling, 4)
    for s, wanted in HEADLINE.items():
        if s not in result.scores:
            continue
        fig = {"f1": float(result.scores[s].f1)}
        if "move" in result.vocabulary.get(s, ()):
            fig["move_recall"] = float(evaluate_by_label(result.truth[s], result.auto[s], labels=["move"])["move"].r1)
        st = result.studio if s == "bandai2" else None
        if st is not None:
            fig.update(move_share=float(st.move_share),
                       turning_with_turn=st.turning_with_turn / max(1, st.turning_clips),
                       straight_with_turn=st.straight_with_turn / max(1, st.straight_clips),
                       gesture_wrong=float(st.gesture_wrong))
            if st.move_share_travelling is not None:
                fig["move_share_travelling"] = float(st.move_share_travelling)
        out.setdefault(s, {}).update({k: round(v, 4) for k, v in fig.items() if k in wanted})
    return out


def guard(figures, records, *, tolerance=TOLERANCE) -> list:
    """The figures that fell below their records, and the sets where keyframes cost ``move`` recall.

    Parameters
    ----------
    figures : dict of str to dict
        Mode (``"keyframes"``, ``"no keyframes"``) → :func:`headline_figures`.
    records : dict of str to dict
        The same shape, as recorded.
    tolerance : float, default 0.01

    Returns
    -------
    list of str
        One line per failure; empty when every figure keeps its record.
    """
    fails = []
    for mode, sets in records.items():
        have = figures.get(mode, {})
        for s, figs in sets.items():
            for name, rec in figs.items():
                sign = _sign(s, name)
                got = have.get(s, {}).get(name)
                if got is None:
                    fails.append(f"{mode}, {s}: {name} was not measured (record {rec:.3f})")
                elif s == CLASSES:
                    if got < CLASS_FLOOR * rec:
                        fails.append(f"{mode}: class {name}'s hits span {got} frames, less than {CLASS_FLOOR:g} "
                                     f"of its record {rec}")
                elif sign * (got - rec) < -tolerance:
                    fails.append(f"{mode}, {s}: {name} {got:.3f} is {'below' if sign > 0 else 'above'} its record "
                                 f"{rec:.3f} by more than {tolerance}")
    with_kf, without = figures.get("keyframes", {}), figures.get("no keyframes", {})
    for s in with_kf:
        a, b = with_kf[s].get("move_recall"), without.get(s, {}).get("move_recall")
        if a is not None and b is not None and a < b - tolerance:
            fails.append(f"{s}: move recall with keyframes {a:.3f} is below {b:.3f} without by more than {tolerance}")
    return fails


def raised_records(records, figures) -> dict:
    """Records moved up to the figures where they are better (never down); classes' hit frames replaced."""
    out = json.loads(json.dumps(records))
    for mode, sets in figures.items():
        for s, figs in sets.items():
            for name, v in figs.items():
                sign = _sign(s, name)
                rec = out.setdefault(mode, {}).setdefault(s, {}).get(name)
                # a class's hit frames say that it still finds what it found, not that more is better:
                # they follow the model
                out[mode][s][name] = v if rec is None or s == CLASSES or sign * (v - rec) > 0 else rec
    return out


def read_records(path) -> dict:
    """``{"fingerprint": …, "figures": {mode: {set: {figure: value}}}}`` from a records file."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ParameterError(f"quality records {str(path)!r} do not read: {exc}") from None
    if not isinstance(data, dict) or not {"fingerprint", "figures"} <= set(data):
        raise ParameterError(f"quality records {str(path)!r} need the keys fingerprint and figures")
    return data


def write_records(path, fingerprint, figures) -> None:
    """Write a records file (sorted keys, so that a change shows in a diff)."""
    Path(path).write_text(json.dumps({"fingerprint": fingerprint, "figures": figures}, indent=1, sort_keys=True)
                          + "\n", encoding="utf-8")


def model_figures(model, data_dir, *, data=None, seed=0, modes=MODES) -> dict:
    """:func:`headline_figures` of a fixed model on every development set, with and without keyframes.

    The model annotates every set as it is (no fold is trained): the figures
    the quality guard keeps for the shipped model.

    Parameters
    ----------
    model : Model
    data_dir : str or Path
    data : DevelopmentData, optional
        Already read (:func:`mocapdb.evaluation.development_data`).
    seed : int, default 0
        Seed of the LOAO document composition.
    modes : dict, default :data:`MODES`
        The annotation modes (a subset of :data:`MODES`).

    Returns
    -------
    dict of str to dict
        Mode → :func:`headline_figures`: ``{"keyframes": …, "no keyframes": …}``.
    """
    from lab.development import development_evaluation
    from lab.recipe import PAPER_LABELS

    res = development_evaluation(data_dir, data=data, build=lambda clips, name: model, cmu_training=True,
                                 mirrored=True, seed=seed, vocabulary=PAPER_LABELS, modes=modes)
    return {m: headline_figures(r) for m, r in res.items()}
