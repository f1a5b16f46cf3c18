"""What a viewer page and a per-motion figure show, read from the database.

:func:`motion_view` annotates one stored motion with a model, keeping the
distance functions (Δ̄^τ per class and per label, paper Fig. 3) and the
motion's ground truth when a truth file is given; :func:`motion_poses`
re-reads the motion's source file for the skeleton at the feature rate.

Poses are not stored: 24 joints × 3 coordinates per frame would be ~36× the
8-byte feature word of a frame (a 100-hour archive, 10.8 M frames at 30 Hz:
~3.1 GB as float32 against 86 MB of features); the source path is stored
absolute and :func:`mocapdb.storage.motions.source_motion` re-reads it with
the skeleton and reader options it was ingested with.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapdb.annotation import annotate, read_truth
from mocapdb.errors import SchemaError
from mocapdb.features import grid_source_frames
from mocapdb.storage.annotations import motion_sources, stored_preselection
from mocapdb.storage.cache import connection_cache
from mocapdb.storage.motions import motion_documents, motion_ids, source_motion

__all__ = ["MotionView", "motion_view", "motion_poses"]


@dataclass(frozen=True, eq=False)
class MotionView:
    """One stored motion annotated by a model, with its distance functions.

    Frames are 0-based and on the feature grid (30 Hz) throughout.

    Attributes
    ----------
    motion_id : int
    name : str
    source_path : str
    fps : float
        Feature rate (30 Hz).
    source_fps : float
        Native rate of the recording.
    n_frames : int
        Feature frames.
    n_source_frames : int
    model : str
    labels : tuple of str
        The model's labels (row order of ``label_delta``).
    class_names : tuple of str
        The model's classes (row order of ``class_delta``).
    class_labels : tuple of str
        The label of each class.
    taus : (n_classes,) float64
        The hit threshold τ each class was annotated with.
    keyframes : bool
        Whether keyframe preselection was used.
    segments : ndarray of mocapdb.annotation.SEGMENT_DTYPE
        The motion's segments (``doc`` = 0).
    truth : ndarray of mocapdb.annotation.LABEL_DTYPE or None
        The motion's ground truth on the feature grid (labels mapped).
    class_delta : (n_classes, n_frames) float64
        Δ̄^τ per class (inf above τ and outside preselected slices).
    label_delta : (n_labels, n_frames) float64
        Δ̄^τ per label: the minimum over the label's classes.
    """

    motion_id: int
    name: str
    source_path: str
    fps: float
    source_fps: float
    n_frames: int
    n_source_frames: int
    model: str
    labels: tuple
    class_names: tuple
    class_labels: tuple
    taus: np.ndarray
    keyframes: bool
    segments: np.ndarray
    truth: np.ndarray | None
    class_delta: np.ndarray
    label_delta: np.ndarray


def motion_view(con, motion, *, model="default", tau=None, keyframes=None, truth=None, label_map=None):
    """Annotate one stored motion, keeping Δ̄^τ, and read its ground truth.

    The segments are those :func:`mocapdb.api.annotate` gives with the same
    model, τ and keyframe setting.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motion : int or str
        Motion id or name (the first motion of that name).
    model : str, keyword-only
    tau : float, optional
        One hit threshold for every class (default: each class's τ).
    keyframes : bool, optional
        Keyframe preselection (default: when the model has keyframe queries).
    truth : str or Path, optional
        Ground truth (label CSV or ELAN file, native frames); the rows of
        this motion are kept.
    label_map : str, Path or dict, optional
        Truth label → model label.

    Returns
    -------
    MotionView
    """
    cache = connection_cache(con)
    key, m = cache.model(model)
    docs = motion_documents(con, motion_ids(con, [motion])[:1])
    pre = stored_preselection(cache, key, m, docs.motion_ids, docs.lengths, keyframes=keyframes)
    ann = annotate(docs.words, m, doc_lengths=docs.lengths, preselection=pre, tau=tau, keep_deltas=True,
                   keep_hits=False)
    name = docs.names[0]
    truth_rows = None
    if truth is not None:
        rows = read_truth(truth, label_map=label_map, n_frames={name: int(docs.n_source_frames[0])},
                          fps={name: float(docs.source_fps[0])})
        truth_rows = rows[rows["document"] == name]
    return MotionView(
        motion_id=int(docs.motion_ids[0]), name=name, source_path=motion_sources(con, docs.motion_ids)[0]["source_path"], fps=float(docs.fps[0]),
        source_fps=float(docs.source_fps[0]), n_frames=int(docs.lengths[0]),
        n_source_frames=int(docs.n_source_frames[0]), model=model, labels=tuple(m.labels),
        class_names=tuple(m.class_names), class_labels=tuple(c.label for c in m.classes),
        taus=np.array([c.tau if tau is None else tau for c in m.classes], np.float64), keyframes=pre is not None,
        segments=ann.segments, truth=truth_rows, class_delta=ann.classification_delta,
        label_delta=ann.label_delta)


def motion_poses(con, motion_id, n_frames=None):
    """The 24 canonical joints of a stored motion on the feature grid, re-read from its source.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
    motion_id : int
    n_frames : int, optional
        The motion's feature frames: the re-read must give as many (else the
        source changed since ingest).

    Returns
    -------
    (n_frames, 24, 3) float64
        The source frame nearest to each 30 Hz grid time
        (:func:`mocapdb.features.grid_source_frames`): native frames 0, 4, 8, …
        of a 120 Hz recording, the frames the features were computed on.

    Raises
    ------
    SchemaError
        The source no longer gives the stored number of frames.
    ParseError, FileNotFoundError
        The source file moved or cannot be read.
    """
    motion = source_motion(con, motion_id)
    joints = motion.joints[grid_source_frames(motion.n_frames, motion.fps)]
    if n_frames is not None and joints.shape[0] != int(n_frames):
        raise SchemaError(f"motion {motion_id}: its source file now gives {joints.shape[0]} frames at the feature "
                          f"rate, the database holds {int(n_frames)}; the file changed since ingest (re-ingest it)")
    return joints
