"""Another studio's clips, each named by its action: documents, truth and the measures that tell whether labels travel.

``bandai2_dev`` (data/README.md) holds 200 BVH clips of one studio,
``dataset-2_{content}_{style}_{take}.bvh.gz``: ten contents (walk, run,
walk-turn-left/right, wave-…, raise-up-…) in five acting styles. A clip is
one action and its name is its truth (:data:`STUDIO_CONTENTS`):

* **straight** locomotion (walk, run): ``move`` over the whole clip;
* **turning** locomotion (walk-turn-left/right): ``move`` and ``turn`` over
  the whole clip (the walker walks throughout and turns by 90–105° on the way);
* **gestures** (waving, raising a hand): none of the 15 classes, so no
  truth — any label but ``neutral`` is wrong.

:func:`studio_documents` reads the clips as documents (a clip each, the
native 30 fps = the feature rate); :func:`studio_measures` computes what a
user of another studio's library would check: the share of locomotion
frames labelled ``move``, the turning clips with a ``turn``, the straight
clips with a ``turn`` (none should have one), the share of gesture frames
under a label but ``neutral``, and the paper's frame and segment P/R/F1
against that truth. :func:`studio_training` gives the clips a model may
train on — walks and runs cut into steps, gestures as motions of no class
(``others``) — one performer's, so grouped as one (τ learning leaves a
performer out, and styles of one performer are no new performers), each
clip's style in its document name, so that a fold can leave a style out
(:func:`studio_style`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocapdb.annotation.labels import LABEL_DTYPE, label_rows
from mocapdb.errors import ParameterError
from lab.documents import DocumentSet
from mocapdb.evaluation.metrics import Scores, evaluate_annotation
from mocapdb.features import motion_features
from lab.cutting import clips_from_stretches
from lab.recipe import OTHERS, Clip
from lab.travel import travelling_frames
from mocapdb.readers import read_motion

__all__ = ["STUDIO_CONTENTS", "STUDIO_FOLDER", "STUDIO_GROUP", "STUDIO_TRAINING_CLASSES", "StudioDocuments",
           "StudioScores", "studio_clip_files", "studio_documents", "studio_measures", "studio_training",
           "studio_style"]

#: the folder of the development data that holds the clips
STUDIO_FOLDER = "bandai2_dev"
#: content → (kind, labels that hold over the whole clip)
STUDIO_CONTENTS = {
    "walk": ("straight", ("move",)),
    "run": ("straight", ("move",)),
    "walk-turn-left": ("turning", ("move", "turn")),
    "walk-turn-right": ("turning", ("move", "turn")),
    **{f"{g}-{side}": ("gesture", ()) for g in ("wave", "raise-up")
       for side in ("both-hands", "left-hand", "right-hand")},
}
#: content → the learned class whose steps it trains (:func:`studio_training`); turning walks
#: are left out, since their steps turn
STUDIO_TRAINING_CLASSES = {"walk": "bandaiWalk2Steps", "run": "bandaiRun2Steps"}
#: the group of every studio clip in training: one performer (τ is learned leaving performers out)
STUDIO_GROUP = "bandai2"
_NAME = re.compile(r"^dataset-2_(?P<content>[a-z-]+?)_(?P<style>[a-z]+)_(?P<take>\d+)$")


def studio_style(document) -> str | None:
    """The acting style a studio clip's document name says (``None`` for another name)."""
    m = _NAME.match(str(document))
    return m["style"] if m else None


@dataclass(frozen=True, eq=False)
class StudioDocuments:
    """The clips as documents, with what their names say.

    Attributes
    ----------
    docs : DocumentSet
        A document per clip (30 Hz words), truth = the content's labels over the whole clip.
    contents, styles : tuple of str
        Per document.
    travelling : tuple of ndarray
        Per document, a boolean per frame: the root travels (:func:`lab.travel.travelling_frames`).
    """

    docs: DocumentSet
    contents: tuple
    styles: tuple
    travelling: tuple = ()

    def subset(self, keep) -> "StudioDocuments":
        """The documents where ``keep`` (a boolean per document) holds."""
        keep = np.asarray(keep, dtype=bool)
        d = self.docs
        off = np.concatenate(([0], np.cumsum(d.doc_lengths)))
        names = tuple(n for n, k in zip(d.names, keep) if k)
        words = np.concatenate([d.words[off[i]:off[i + 1]] for i in np.flatnonzero(keep)]) if keep.any() \
            else np.zeros(0, np.uint64)
        pick = lambda rows: rows[np.isin(rows["document"], names)]  # noqa: E731
        return StudioDocuments(DocumentSet(names, words, d.doc_lengths[keep], d.native_lengths[keep],
                                           pick(d.truth_native), pick(d.truth)),
                               tuple(c for c, k in zip(self.contents, keep) if k),
                               tuple(s for s, k in zip(self.styles, keep) if k),
                               tuple(t for t, k in zip(self.travelling, keep) if k))


def studio_clip_files(data_dir) -> list:
    """``(path, name, content, style)`` of every studio clip (``<data_dir>/bandai2_dev``), in file-name order.

    Raises
    ------
    ParameterError
        No clips, or a clip whose name does not say its content.
    """
    folder = Path(data_dir) / STUDIO_FOLDER
    paths = sorted(p for p in folder.glob("*.bvh*") if p.is_file())
    if not paths:
        raise ParameterError(f"no studio clips (*.bvh, *.bvh.gz) in {str(folder)!r}")
    out = []
    for p in paths:
        stem = p.name.split(".bvh")[0]
        m = _NAME.match(stem)
        if m is None or m["content"] not in STUDIO_CONTENTS:
            raise ParameterError(f"{p}: the name does not say a known content ({sorted(STUDIO_CONTENTS)})")
        out.append((p, stem, m["content"], m["style"]))
    return out


def studio_documents(data_dir, *, styles=None) -> StudioDocuments:
    """Read the studio's clips (``<data_dir>/bandai2_dev``) as documents with their truth.

    Parameters
    ----------
    data_dir : str or Path
        The development data folder.
    styles : sequence of str, optional
        Only these acting styles (default all).

    Returns
    -------
    StudioDocuments
        Documents in file-name order.

    Raises
    ------
    ParameterError
        No clips, or a clip whose name does not say its content.
    """
    folder = Path(data_dir) / STUDIO_FOLDER
    names, contents, style_of, words, native, truth_n, truth, travelling = [], [], [], [], [], [], [], []
    for p, stem, content, style in studio_clip_files(data_dir):
        if styles is not None and style not in styles:
            continue
        motion = read_motion(p)
        w = motion_features(motion)
        labels = STUDIO_CONTENTS[content][1]
        names.append(stem)
        contents.append(content)
        style_of.append(style)
        words.append(w)
        native.append(motion.n_frames)
        travelling.append(travelling_frames(motion))
        if labels:  # a gesture's truth is empty
            truth_n.append(label_rows([stem] * len(labels), labels, 1, motion.n_frames))
            truth.append(label_rows([stem] * len(labels), labels, 0, w.size - 1))
    if not names:
        raise ParameterError(f"no studio clips of the styles {list(styles)} in {str(folder)!r}")
    docs = DocumentSet(tuple(names), np.concatenate(words), np.array([w.size for w in words], np.int64),
                       np.array(native, np.int64), np.concatenate(truth_n), np.concatenate(truth))
    return StudioDocuments(docs, tuple(contents), tuple(style_of), tuple(travelling))


def studio_training(studio: StudioDocuments, **cut_params) -> dict:
    """The clips a model may learn from the studio: one performer's (group :data:`STUDIO_GROUP`).

    Their documents say their style (:func:`studio_style`), so that a fold
    can leave a style out; τ learning sees one performer, and a class learned
    only from them takes the τ at which it claims no other label's clip
    (:func:`lab.thresholds.learn_taus`).

    * walks and runs (:data:`STUDIO_TRAINING_CLASSES`), each clip a stretch,
      cut into two-step repetitions by :func:`lab.cutting.clips_from_stretches`;
    * gestures, whole, as :data:`lab.recipe.OTHERS`: motions of
      no class, which τ learning keeps every class from claiming.

    Returns
    -------
    dict of str to list of Clip
    """
    d = studio.docs
    off = np.concatenate(([0], np.cumsum(d.doc_lengths)))
    words = {n: d.words[off[k]:off[k + 1]] for k, n in enumerate(d.names)}
    rows = [(n, STUDIO_TRAINING_CLASSES[c], 0, int(d.doc_lengths[k]) - 1)
            for k, (n, c) in enumerate(zip(d.names, studio.contents)) if c in STUDIO_TRAINING_CLASSES]
    out = {}
    if rows:
        cut = clips_from_stretches(words, label_rows(*zip(*rows)), groups=lambda doc: STUDIO_GROUP, **cut_params)
        out = {c: [Clip(n, w, g, doc) for n, g, doc, w in items] for c, items in cut.items()}
    others = [Clip(n, words[n], STUDIO_GROUP, n) for n, c in zip(d.names, studio.contents)
              if STUDIO_CONTENTS[c][0] == "gesture"]
    if others:
        out[OTHERS] = others
    return out


@dataclass(frozen=True)
class StudioScores:
    """What :func:`studio_measures` finds.

    Attributes
    ----------
    move_share : float
        Locomotion frames (straight and turning clips) labelled ``move``.
    move_by_content : dict of str to float
        The same per locomotion content.
    move_share_travelling : float or None
        Locomotion frames where the root travels (:mod:`lab.travel`) labelled ``move``; None without
        :attr:`StudioDocuments.travelling`.
    turning_with_turn, turning_clips : int
        Turning clips with a ``turn`` segment, of all turning clips.
    straight_with_turn, straight_clips : int
        Straight clips with a ``turn`` segment (none should have one), of all.
    gesture_wrong : float
        Gesture frames under any label but ``neutral``.
    wrong_by_label : dict of str to float
        Gesture frames under each wrong label (shares of all gesture frames).
    scores : Scores
        The paper's P/R/F (Eq. 5–8) against the clips' truth.
    """

    move_share: float
    move_by_content: dict
    turning_with_turn: int
    turning_clips: int
    straight_with_turn: int
    straight_clips: int
    gesture_wrong: float
    wrong_by_label: dict
    scores: Scores = field(repr=False)
    move_share_travelling: float | None = None


def _covered(rows, doc, labels, n):
    """Frames 0…n−1 of ``doc`` covered by rows with one of ``labels``."""
    out = np.zeros(n, dtype=bool)
    for r in rows[(rows["document"] == doc) & np.isin(rows["label"], list(labels))]:
        out[int(r["start"]):int(r["end"]) + 1] = True
    return out


def studio_measures(studio: StudioDocuments, auto, *, vocabulary=None) -> StudioScores:
    """The measures of :class:`StudioScores` for an annotation of the studio's documents.

    Parameters
    ----------
    studio : StudioDocuments
    auto : ndarray of LABEL_DTYPE
        The annotation (30 Hz, 0-based inclusive, documents by name).
    vocabulary : sequence of str, optional
        Labels the P/R/F scores (default every label of either side).
    """
    auto = np.asarray(auto)
    if auto.dtype != LABEL_DTYPE:
        raise ParameterError("auto must be label rows (mocapdb.annotation.labels.LABEL_DTYPE)")
    d = studio.docs
    move = {}
    travel = [0, 0]   # travelling locomotion frames under move, of all
    travelling = dict(zip(d.names, studio.travelling))
    turning = straight = turning_hits = straight_hits = 0
    gesture_frames = 0
    wrong = {}
    for name, content, n in zip(d.names, studio.contents, d.doc_lengths.tolist()):
        kind = STUDIO_CONTENTS[content][0]
        if kind == "gesture":
            gesture_frames += n
            mine = auto[(auto["document"] == name) & (auto["label"] != "neutral")]
            any_wrong = _covered(mine, name, set(mine["label"].tolist()), n)
            wrong["any"] = wrong.get("any", 0) + int(any_wrong.sum())
            for lab in set(mine["label"].tolist()):
                wrong[lab] = wrong.get(lab, 0) + int(_covered(mine, name, {lab}, n).sum())
            continue
        m = move.setdefault(content, [0, 0])
        covered = _covered(auto, name, {"move"}, n)
        m[0] += int(covered.sum())
        m[1] += n
        if name in travelling:
            travel[0] += int((covered & travelling[name]).sum())
            travel[1] += int(travelling[name].sum())
        has_turn = bool(((auto["document"] == name) & (auto["label"] == "turn")).any())
        if kind == "turning":
            turning += 1
            turning_hits += has_turn
        else:
            straight += 1
            straight_hits += has_turn
    frames = sum(v[1] for v in move.values())
    return StudioScores(
        move_share=sum(v[0] for v in move.values()) / frames if frames else 0.0,
        move_by_content={c: v[0] / v[1] for c, v in sorted(move.items())},
        turning_with_turn=turning_hits, turning_clips=turning,
        straight_with_turn=straight_hits, straight_clips=straight,
        gesture_wrong=wrong.pop("any", 0) / gesture_frames if gesture_frames else 0.0,
        wrong_by_label={k: v / gesture_frames for k, v in sorted(wrong.items(), key=lambda kv: -kv[1])},
        scores=evaluate_annotation(d.truth, auto, labels=vocabulary),
        move_share_travelling=(travel[0] / travel[1] if travel[1] else 0.0) if studio.travelling else None)
