"""A template per class from labelled clips: an annotation :class:`~mocapdb.annotation.model.Model`.

* :func:`train_model` — one motion template per class (TEMPLATES.md §7,
  :func:`mocapdb.templates.learn_template`), quantized with δ, τ attached,
  classes mapped to (coarse) labels;
* :func:`clip_files` / :func:`clips_from_folders` — training clips from the
  HDM05 "cut" layout (one folder per class, ``HDM_<actor>_<class>_<take>_120.amc``,
  the actor skeletons ``HDM_<actor>.asf`` in the root), in file-name order —
  the order the toolbox oracle's templates were learned in (TEMPLATES.md §1);
* :func:`clips_from_segments` — training clips cut out of whole documents by
  label rows.

A clip is an ``(n,)`` uint64 array of packed 30 Hz feature words
(:func:`mocapdb.features.motion_features` of the clip on its own). The order
of the clips of a class matters: the learned template is the one of the first
clip's slot and ties in the DTW depend on it.
"""
from __future__ import annotations

import logging
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.features import motion_features
from mocapdb.annotation.labels import as_label_rows
from mocapdb.annotation.model import DEFAULT_DELTA, DEFAULT_TAU, ClassModel, Model
from mocapdb.readers import SUPPORTED_EXTENSIONS, read_motion
from mocapdb.templates import learn_template

__all__ = ["train_model", "clip_files", "clip_actor", "read_clip", "clips_from_folders",
           "clips_from_segments"]

log = logging.getLogger("mocapdb")

_HDM_ACTOR = re.compile(r"^HDM_([A-Za-z0-9]+)_")


def _clip_words(clip, cls, k):
    """The word array of one clip entry: words, or a (name, words) pair."""
    if isinstance(clip, tuple) and len(clip) == 2 and isinstance(clip[0], str):
        clip = clip[1]
    w = np.asarray(clip)
    if w.ndim != 1 or w.dtype != np.uint64:
        raise ParameterError(
            f"clips[{cls!r}][{k}] must be a 1-D uint64 array of packed 30 Hz words "
            f"(or a (name, words) pair), got dtype {w.dtype} shape {w.shape}; "
            "use mocapdb.features.motion_features")
    if w.size == 0:
        raise ParameterError(f"clips[{cls!r}][{k}] has no frames; drop empty clips")
    return w


def train_model(clips, *, name, labels=None, delta=DEFAULT_DELTA, tau=DEFAULT_TAU,
                iter_max=10, iter_thresh=0.005, progress=None):
    """Learn a model: one motion template per class from its labelled clips.

    Parameters
    ----------
    clips : mapping of str to sequence
        Class name → its training clips in a deterministic order, each an
        ``(n,)`` uint64 array of packed 30 Hz words or a ``(name, words)``
        pair (what :func:`clips_from_folders` returns). Class order = the
        model's class order.
    name : str
        Model name.
    labels : mapping of str to str, optional
        Class → (coarse) label, e.g. :func:`mocapdb.annotation.labels.class_labels`
        ``("hdm05")``; may hold more classes than ``clips``. The label order
        of the model (Δarg ties) is the order of first appearance in this
        mapping. Default: every class is its own label, in class order.
    delta : float, default 0.05
        Quantization threshold δ (TEMPLATES.md §8, the annotation scripts' value).
    tau : float, default 0.13
        Hit threshold τ stored with every class (TEMPLATES.md §9.1).
    iter_max : int, default 10
    iter_thresh : float, default 0.005
        Stopping parameters of the learner (TEMPLATES.md §7).
    progress : callable, optional
        Called as ``progress(n_done, n_classes, class_name)`` after each class.

    Returns
    -------
    Model
        ``classes[k].template`` is the real-valued template (with
        ``n_clips``, iterations and errors), ``classes[k].quantized`` its
        δ-quantization.

    Raises
    ------
    ParameterError
        No classes, a class without clips, a clip that is not a word array, a
        class missing from ``labels``, or bad learning parameters.

    References
    ----------
    TEMPLATES.md §1, §7, §8; paper Sect. 3 and 7.
    """
    if not isinstance(clips, Mapping) or not clips:
        raise ParameterError("clips must be a non-empty mapping of class name -> clips")
    if labels is not None:
        missing = [c for c in clips if c not in labels]
        if missing:
            raise ParameterError(f"labels lacks the classes {missing}; add them to the "
                                 "mapping or pass labels=None (each class its own label)")
    classes = []
    for k, (cls, cl) in enumerate(clips.items()):
        cl = list(cl)
        if not cl:
            raise ParameterError(f"class {cls!r} has no clips; drop it or add clips")
        words = [_clip_words(c, cls, j) for j, c in enumerate(cl)]
        mt = learn_template(words, iter_max=iter_max, iter_thresh=iter_thresh)
        log.debug("trained %s from %d clips: K=%d, %d iterations, max error %.5f",
                  cls, mt.n_clips, len(mt), mt.iterations,
                  mt.error_max[-1] if mt.error_max.size else float("nan"))
        classes.append(ClassModel(cls, cls if labels is None else labels[cls], template=mt,
                                  delta=delta, tau=tau))
        if progress is not None:
            progress(k + 1, len(clips), cls)
    used = {c.label for c in classes}
    order = (None if labels is None
             else tuple(lab for lab in dict.fromkeys(labels.values()) if lab in used))
    return Model(name, tuple(classes), labels=order)


def clip_actor(name):
    """The actor of an HDM05 clip name (``HDM_bd_squat1Reps_001_120`` → ``bd``), or None."""
    m = _HDM_ACTOR.match(Path(name).name)
    return m.group(1) if m else None


def clip_files(root, *, classes=None, actors=None):
    """The training clip files of an HDM05 "cut" folder, per class in file-name order.

    Parameters
    ----------
    root : str or Path
        Folder with one sub-folder per class holding the clips (``.amc``,
        ``.bvh``); AMC skeletons are found by :func:`mocapdb.readers.find_skeleton`
        (``HDM_<actor>.asf`` in the root).
    classes : sequence of str, optional
        Only these classes, in this order (default: every sub-folder with
        clips, sorted by name).
    actors : sequence of str, optional
        Only clips of these actors (``HDM_<actor>_…`` names) — e.g. three of
        the four for leave-one-actor-out training. Classes left without clips
        are omitted.

    Returns
    -------
    dict of str to list of Path

    Raises
    ------
    ParameterError
        If ``root`` is not a folder or a requested class has no folder.
    """
    root = Path(root)
    if not root.is_dir():
        raise ParameterError(f"root must be a folder of class folders, got {str(root)!r}")
    if classes is None:
        folders = sorted(p for p in root.iterdir() if p.is_dir())
    else:
        folders = [root / c for c in classes]
        missing = [f.name for f in folders if not f.is_dir()]
        if missing:
            have = sorted(p.name for p in root.iterdir() if p.is_dir())
            raise ParameterError(f"classes {missing} have no folder in {str(root)!r}; "
                                 f"available: {have}")
    keep = None if actors is None else {str(a) for a in actors}
    out = {}
    for f in folders:
        files = sorted((p for p in f.iterdir()
                        if p.is_file() and p.suffix.lower() in SUPPORTED_EXTENSIONS),
                       key=lambda p: p.name)
        if keep is not None:
            files = [p for p in files if clip_actor(p.stem) in keep]
        if files:
            out[f.name] = files
    return out


def read_clip(path, *, asf=None):
    """Packed 30 Hz feature words of one clip file (read + features).

    Returns
    -------
    ndarray, shape (ceil(n/4),), uint64
    """
    return motion_features(read_motion(path, asf=asf))


def clips_from_folders(root, *, classes=None, actors=None, progress=None):
    """Read the training clips of an HDM05 "cut" folder (see :func:`clip_files`).

    Parameters
    ----------
    root, classes, actors
        As in :func:`clip_files`.
    progress : callable, optional
        Called as ``progress(n_done, n_files, path)`` after each file.

    Returns
    -------
    dict of str to list of (str, ndarray)
        Class → (clip name, packed 30 Hz words) in file-name order; ready for
        :func:`train_model`.

    Raises
    ------
    ParameterError, ParseError
    """
    files = clip_files(root, classes=classes, actors=actors)
    total = sum(len(v) for v in files.values())
    out = {}
    done = 0
    for cls, paths in files.items():
        out[cls] = []
        for p in paths:
            out[cls].append((p.stem, read_clip(p)))
            done += 1
            if progress is not None:
                progress(done, total, p)
    return out


def clips_from_segments(words_by_document, label_rows):
    """Cut training clips out of documents by labelled segments.

    Parameters
    ----------
    words_by_document : mapping of str to ndarray (n_d,) uint64
        Packed 30 Hz words of each document.
    label_rows : ndarray of LABEL_DTYPE or iterable of (document, label, start, end)
        Segments on the 30 Hz grid, 0-based inclusive
        (:func:`mocapdb.annotation.labels.to_feature_grid` of a label CSV).

    Returns
    -------
    dict of str to list of (str, ndarray)
        Label → (``"<document>[<start>:<end>]"``, words) in row order; labels
        in order of first appearance.

    Raises
    ------
    ParameterError
        A row names an unknown document or lies outside it.
    """
    rows = as_label_rows(label_rows, "label_rows")
    out = {}
    for k, r in enumerate(rows):
        doc, lab, s, e = str(r["document"]), str(r["label"]), int(r["start"]), int(r["end"])
        if doc not in words_by_document:
            raise ParameterError(f"label_rows[{k}] names document {doc!r}, which is not in "
                                 "words_by_document")
        w = np.asarray(words_by_document[doc])
        if not 0 <= s <= e < w.shape[0]:
            raise ParameterError(
                f"label_rows[{k}] = ({doc!r}, {lab!r}, {s}, {e}) is outside the document's "
                f"{w.shape[0]} frames (0-based inclusive 30 Hz frames expected; convert "
                "label CSV rows with mocapdb.annotation.labels.to_feature_grid)")
        out.setdefault(lab, []).append((f"{doc}[{s}:{e}]", w[s:e + 1].copy()))
    return out
