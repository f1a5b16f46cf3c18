"""Short clips: a walk or run of one gait cycle, and short excerpts of other motions, each a file of its own.

A library's clips are not all takes of several seconds: a game's looping
cycles, a take trimmed to one step. A clip of 0.7–1 s of one walk or run
cycle should get ``move`` (issue 32 item 3), and a short excerpt of any
other motion nothing it is not. The labelled sets hold long clips, so the
short ones are cut from them here — from the motion, so that the features
are computed on the excerpt alone, as on a file of that length:

* **cycles**: of every clip that is locomotion throughout (HDM05's sneaks and
  circle jogs, CMU 02's walks and jog, the studio's walks, runs and walking
  turns, ACCAD's clips whose truth is :attr:`lab.lab_clips.ClipTruth.locomotion`)
  one window of each length in :data:`SHORT_SECONDS`, centred on the frames
  where its root travels (:mod:`lab.travel`): ``move`` expected;
* **excerpts**: windows of the same lengths end to end over the clips of
  other motions — HDM05's clips of the other classes (their own label
  allowed), the studio's gestures (none), ACCAD's clips that require no
  ``move`` (their truth's allowed labels) —: a label outside the allowed
  ones (``neutral`` always allowed) is wrong.

:func:`short_clip_measures` annotates them (each window a document) with a
model and counts cycles with ``move`` and excerpts with a wrong label, per
length.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mocapdb.annotation import annotate, preselection_for
from mocapdb.annotation.labels import class_labels as shipped_class_labels
from mocapdb.errors import ParseError
from mocapdb.features import motion_features
from mocapdb.readers import read_motion
from lab.documents import CMU_WHOLE_DOCUMENTS
from lab.lab_clips import SILENT, lab_clip_files
from lab.studio import STUDIO_CONTENTS, studio_clip_files
from lab.travel import travelling_frames

__all__ = ["SHORT_SECONDS", "ShortClips", "gait_cycle", "short_clips", "short_clip_measures"]

#: the lengths of the short clips, seconds: one gait cycle of a run (0.7) and of a walk (1.0)
SHORT_SECONDS = (0.7, 1.0)


@dataclass(frozen=True, eq=False)
class ShortClips:
    """One lab's short clips of one length.

    Attributes
    ----------
    seconds : float
    cycles : list of ndarray of uint64
        The words of each gait cycle (``move`` expected).
    excerpts : list of (ndarray of uint64, frozenset of str)
        The words of each excerpt of another motion and the labels allowed on it.
    """

    seconds: float
    cycles: list
    excerpts: list


def _window(motion, seconds, start):
    k = int(round(seconds * motion.fps))
    rot = motion.root_rotation
    return dataclasses.replace(motion, joints=motion.joints[start:start + k],
                               root_rotation=None if rot is None else rot[start:start + k])


def gait_cycle(motion, seconds):
    """The words of a window of ``seconds`` centred on the middle of the frames where the root travels."""
    n, k = motion.n_frames, int(round(seconds * motion.fps))
    travel = np.flatnonzero(travelling_frames(motion))
    # travelling frames are 30 Hz feature frames: back to native frames
    mid = int(travel[travel.size // 2] * motion.fps / 30.0) if travel.size else n // 2
    start = min(max(0, mid - k // 2), max(0, n - k))
    return motion_features(_window(motion, seconds, start))


def _excerpts(motion, seconds):
    """The words of windows of ``seconds`` end to end over the motion (the last one short of its end left out)."""
    k = int(round(seconds * motion.fps))
    return [motion_features(_window(motion, seconds, a)) for a in range(0, motion.n_frames - k + 1, k)]


def short_clips(data_dir, data, *, seconds=SHORT_SECONDS) -> dict:
    """Per lab (``hdm05``, ``cmu``, ``bandai2``, ``accad``), per length, its :class:`ShortClips`.

    Parameters
    ----------
    data_dir : str or Path
        The development data folder.
    data : lab.development.DevelopmentData
        Its HDM05 clips (their motions, read once).
    seconds : sequence of float
    """
    data_dir = Path(data_dir)
    labels = shipped_class_labels("hdm05")
    sources = {lab: ([], []) for lab in ("hdm05", "cmu", "bandai2", "accad")}   # (cycle motions, (motion, allowed))
    for c, clips in data.hdm05.items():
        for _, m in clips:
            if labels.get(c, c) == "move":
                sources["hdm05"][0].append(m)
            else:
                sources["hdm05"][1].append((m, frozenset({labels.get(c, c), SILENT})))
    asf = data_dir / "cmu" / "02" / "02.asf"
    sources["cmu"][0].extend(read_motion(data_dir / "cmu" / "02" / f"{d}.amc", asf=asf) for d in CMU_WHOLE_DOCUMENTS)
    for p, _, content, _ in studio_clip_files(data_dir):
        if STUDIO_CONTENTS[content][1]:
            sources["bandai2"][0].append(read_motion(p))
        else:
            sources["bandai2"][1].append((read_motion(p), frozenset({SILENT})))
    for path, truth, _ in lab_clip_files(data_dir):
        try:
            motion = read_motion(path)
        except ParseError:      # a file the reader refuses: a user gets nothing there
            continue
        if truth.locomotion:
            sources["accad"][0].append(motion)
        elif not any("move" in r for r in truth.required):
            sources["accad"][1].append((motion, truth.allowed))
    return {lab: {s: ShortClips(s, [gait_cycle(m, s) for m in cyc],
                                [(w, ok) for m, ok in other for w in _excerpts(m, s)])
                  for s in seconds}
            for lab, (cyc, other) in sources.items()}


def _labels_per_document(words, model, keyframes):
    """The set of labels annotated on each of ``words`` (a list of documents)."""
    if not words:
        return []
    lengths = np.array([w.size for w in words], np.int64)
    flat = np.concatenate(words)
    pre = preselection_for(flat, lengths, model) if keyframes else None
    segs = annotate(flat, model, doc_lengths=lengths, preselection=pre, keep_hits=False).segments
    out = [set() for _ in words]
    for lab, d in zip(segs["label"], segs["doc"]):
        out[d].add(lab)
    return out


def short_clip_measures(clips: ShortClips, model, *, keyframes=True) -> dict:
    """What ``model`` annotates on one lab's short clips of one length.

    Returns
    -------
    dict
        ``cycles``, ``cycles with move`` (share), ``excerpts``, ``excerpts with a wrong label`` (share; None
        without excerpts), ``wrong by label`` (excerpts with each wrong label).
    """
    found = _labels_per_document(clips.cycles, model, keyframes)
    seen = _labels_per_document([w for w, _ in clips.excerpts], model, keyframes)
    wrong = [sorted(s - ok) for s, (_, ok) in zip(seen, clips.excerpts)]
    by_label = {}
    for w in wrong:
        for lab in w:
            by_label[lab] = by_label.get(lab, 0) + 1
    return {"cycles": len(found), "cycles with move": float(np.mean(["move" in s for s in found])) if found else None,
            "excerpts": len(seen), "excerpts with a wrong label": float(np.mean([bool(w) for w in wrong]))
            if seen else None, "wrong by label": dict(sorted(by_label.items()))}
