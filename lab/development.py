"""The development evaluation: annotation quality on data the model was not trained on.

data/README.md fixes what the project's own evaluation reports (the documents
are in :mod:`lab.documents`):

* **loao** — leave-one-actor-out on ``hdm05_cut`` (actors bd, bk, dg, mm):
  a model built without one actor's clips annotates documents joined from
  that actor's clips;
* **loao_mirrored** (optional) — the same documents mirrored left/right, the
  right-handed truth dropped: how a model copes with the other side
  (right-footed kicks, right-foot starts) that hdm05_cut lacks;
* **cmu86_09**, **mocap6** — the real CMU documents with their ground truth;
  a model that trains templates on CMU stretches (``cmu_training``) is
  built without the stretches of the document it annotates
  (leave-one-document-out), so no document is annotated by a model that saw
  it;
* **cmu** (both CMU sets) and **all** (loao and cmu), concatenated, as the
  paper scores its evaluation set;
* **bandai2** — another studio's clips named by their action
  (:mod:`lab.studio`): a model that trains on the studio's
  clips is built without the style it annotates (leave-one-style-out),
  and :attr:`DevelopmentEvaluation.studio` holds the measures that tell
  whether labels travel (locomotion labelled ``move``, turns, silence on
  gestures);
* **accad** — a third lab's clips with what a user expects of each
  (:mod:`lab.lab_clips`): never trained on, annotated by the
  model of all the other data; :attr:`DevelopmentEvaluation.lab` holds the
  per-clip measures (its truth is per clip, not per frame, so it has no
  P/R/F and is not one of :data:`SETTINGS`).

``leave_out_lab`` replaces these folds by leave-one-lab-out (:data:`LABS`):
every lab annotated by a model trained on none of its clips — what a
stranger with another lab's recordings sees.

The truths of loao, cmu86_09 and mocap6 label one activity per frame and
never a turn (11 HDM05 classes; walks, claps and exercises): a turn there —
a circle jog, a walker who turns round — can be neither right nor wrong, so
those settings do not score ``turn`` (:data:`UNSCORED`); bandai2's truth
carries it beside ``move``.

:func:`development_evaluation` builds one model per fold — by default the
toolbox's way (a template per HDM05 class, :func:`mocapdb.learning.train_model`),
or by any ``build(clips, name)`` (e.g. the default model's recipe,
:func:`lab.recipe.build_model`) — annotates each fold's documents
in one or several annotation ``modes`` (keyframes on/off, τ, segment
filters) and scores every setting with the paper's P1/R1/F1 and P2/R2/F2
(:mod:`mocapdb.evaluation.metrics`), restricted to a label vocabulary
(ground-truth labels outside it are dropped and reported).
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocapdb.annotation import annotate, annotate_sweep
from mocapdb.annotation.labels import LABEL_DTYPE, class_labels as shipped_class_labels, label_rows, segments_to_rows
from mocapdb.annotation.model import DEFAULT_DELTA
from mocapdb.annotation.preselection import preselection_for
from mocapdb.errors import ParameterError
from lab.documents import (CLIPS_PER_DOCUMENT, MOCAP6_TRIALS, DocumentSet, _loao_from_clips,
                                          cmu86_documents, cmu_stretches, concatenate_motions, loao_documents,
                                          mirror_document_set, mocap6_documents, pose_clips)
from mocapdb.evaluation.metrics import evaluate_annotation
from lab.lab_clips import LAB_FOLDER, lab_documents, lab_measures
from lab.studio import STUDIO_FOLDER, studio_documents, studio_measures, studio_training
from mocapdb.features import motion_features
from lab.cutting import clips_from_stretches
from lab.recipe import Clip, default_recipe
from mocapdb.learning.class_templates import clip_actor, clip_files, train_model
from mocapdb.readers import read_motion

__all__ = ["DocumentSet", "DevelopmentEvaluation", "DevelopmentData", "concatenate_motions", "loao_documents",
           "cmu86_documents", "mocap6_documents", "development_evaluation", "development_data",
           "MOCAP6_TRIALS", "CLIPS_PER_DOCUMENT", "SETTINGS", "UNSCORED", "LABS", "LAB_SETTINGS"]

log = logging.getLogger("mocapdb")

#: the settings :func:`development_evaluation` scores, in report order
SETTINGS = ("loao", "loao_mirrored", "cmu86_09", "mocap6", "cmu", "all", "bandai2")
#: the labs of the development data, each a fold of the leave-one-lab-out evaluation, with its settings
LAB_SETTINGS = {"hdm05": ("loao", "loao_mirrored"), "cmu": ("cmu86_09", "mocap6", "cmu"), "bandai2": ("bandai2",),
                "accad": ("accad",)}
LABS = tuple(LAB_SETTINGS)
#: labels a setting's truth can never carry, left out of its scores (module docstring)
UNSCORED = {s: ("turn",) for s in ("loao", "loao_mirrored", "cmu86_09", "mocap6", "cmu", "all")}


# ---------------------------------------------------------------------------
# the training data of the folds


@dataclass(frozen=True, eq=False)
class DevelopmentData:
    """Everything the folds train on: HDM05 clips and (optionally) CMU stretches.

    Attributes
    ----------
    hdm05 : dict of str to list of (Clip, Motion)
        Class → its clips (group = actor) with their motions, file-name order.
    cmu_words : dict of str to (n,) uint64
        CMU documents with training stretches.
    cmu_rows : ndarray of LABEL_DTYPE
        The stretches (30 Hz, 0-based inclusive), labelled with their class.
    cmu_groups : dict of str to str
        CMU document → subject.
    poses : dict of str to list of Clip
        Poses held still in HDM05 full documents (:func:`lab.documents.pose_clips`).
    studio : StudioDocuments or None
        Another studio's clips (:func:`lab.studio.studio_documents`).
    studio_trains : bool
        Whether a model may learn from them (:func:`lab.studio.studio_training`: one
        performer's walks and runs, cut per fold, and gestures as motions of no class).
    lab : LabDocuments or None
        A third lab's clips with per-clip truth (:func:`lab.lab_clips.lab_documents`):
        annotated only, never trained on.
    """

    hdm05: dict
    cmu_words: dict = field(default_factory=dict)
    cmu_rows: np.ndarray = field(default_factory=lambda: np.empty(0, LABEL_DTYPE))
    cmu_groups: dict = field(default_factory=dict)
    poses: dict = field(default_factory=dict)
    studio: object = None
    studio_trains: bool = False
    lab: object = None

    @property
    def styles(self):
        return sorted(set(self.studio.styles)) if self.studio is not None else []

    @property
    def studio_clips(self):
        """What a model may learn from the studio's clips, all styles cut together (empty when it may not)."""
        return studio_training(self.studio) if self.studio_trains and self.studio is not None else {}

    @property
    def actors(self):
        return sorted({c.group for cl in self.hdm05.values() for c, _ in cl if c.group})

    def clips(self, *, without_actor=None, without_document=None, without_style=None, without_lab=None,
              cut_params=None):
        """Training clips of a fold: class → list of Clip (HDM05 clips, CMU repetitions, the studio's).

        Stretches are cut per fold, after the held-out part is dropped, so the
        cut (its anchor feature) never sees what the fold annotates: the CMU
        stretches of ``without_document``, the studio's clips of
        ``without_style``. ``without_lab`` (one of :data:`LABS`) leaves out
        everything of that lab: HDM05's clips and the poses of its full
        documents, CMU's stretches, the studio's clips (the third lab's never
        train).
        """
        if without_lab is not None and without_lab not in LABS:
            raise ParameterError(f"without_lab must be one of {list(LABS)}, got {without_lab!r}")
        out = {}
        if without_lab != "hdm05":
            out = {c: [clip for clip, _ in cl if clip.group != without_actor] for c, cl in self.hdm05.items()}
            for c, cl in self.poses.items():
                out[c] = [clip for clip in cl if clip.group != without_actor and clip.document != without_document]
        out = {c: v for c, v in out.items() if v}
        rows = self.cmu_rows[self.cmu_rows["document"] != without_document] if without_document else self.cmu_rows
        if rows.size and without_lab != "cmu":
            cut = clips_from_stretches(self.cmu_words, rows, groups=self.cmu_groups.get, **(cut_params or {}))
            for c, items in cut.items():
                out.setdefault(c, []).extend(Clip(n, w, g, d) for n, g, d, w in items)
        if self.studio_trains and self.studio is not None and without_lab != "bandai2":
            keep = np.array(self.studio.styles) != without_style
            for c, items in studio_training(self.studio.subset(keep), **(cut_params or {})).items():
                out.setdefault(c, []).extend(items)
        return out


def development_data(data_dir, *, classes=None, cmu_training=True, definitions=None, studio=True) -> DevelopmentData:
    """Read the training material of the development folds.

    Parameters
    ----------
    data_dir : str or Path
    classes : sequence of str, optional
        HDM05 classes (default all).
    cmu_training : bool, default True
        Also the CMU training stretches (:func:`lab.documents.cmu_stretches`)
        and the poses of the HDM05 full documents (:func:`lab.documents.pose_clips`).
    definitions : sequence of ClassDefinition, optional
        The definitions that find the poses (default the shipped ones).
    studio : bool, default True
        Also the studio's clips (``bandai2_dev``), where the folder exists:
        documents to annotate and, with ``cmu_training``, material to learn from.
    """
    files = clip_files(Path(data_dir) / "hdm05_cut", classes=classes)
    hdm05 = {}
    for c, ps in files.items():
        hdm05[c] = []
        for p in ps:
            m = read_motion(p)
            hdm05[c].append((Clip(p.stem, motion_features(m), clip_actor(p.stem) or "", p.stem), m))
    docs = studio_documents(data_dir) if studio and (Path(data_dir) / STUDIO_FOLDER).is_dir() else None
    lab = lab_documents(data_dir) if studio and (Path(data_dir) / LAB_FOLDER).is_dir() else None
    if not cmu_training:
        return DevelopmentData(hdm05, studio=docs, lab=lab)
    words, rows, groups = cmu_stretches(data_dir)
    defs = default_recipe().definitions if definitions is None else definitions
    return DevelopmentData(hdm05, words, rows, groups, pose_clips(data_dir, defs), docs, docs is not None, lab)


# ---------------------------------------------------------------------------
# the whole evaluation


@dataclass(frozen=True, eq=False)
class DevelopmentEvaluation:
    """Result of :func:`development_evaluation` (for one annotation mode).

    Attributes
    ----------
    scores : dict of str to Scores
        Per setting of :data:`SETTINGS` present.
    truth, auto : dict of str to ndarray of LABEL_DTYPE
        Ground truth and annotation per setting (30 Hz, 0-based inclusive,
        documents by name).
    models : dict of str to Model
        ``"without_<actor>"`` per held-out actor; ``"all"`` (the model of
        every CMU document not held out) and ``"without_<document>"`` for
        CMU documents whose stretches trained it.
    documents : dict of str to DocumentSet
    sweep : list of (float, Scores) or None
        LOAO scores per τ (paper Fig. 8), if requested.
    timings : dict of str to float
        Seconds: ``read``, ``train``, ``annotate``, ``sweep``, ``total``.
    preselected : dict of str to ndarray of LABEL_DTYPE
        Per setting, the frames each label's classes were matched on (the
        keyframe preselection's slices; whole documents for a class without
        query or without keyframes): where a label *can* be found.
    vocabulary : dict of str to tuple of str
        The labels scored per setting.
    studio : StudioScores or None
        The studio measures of the bandai2 setting (:func:`lab.studio.studio_measures`).
    lab : LabScores or None
        The per-clip measures of the accad setting (:func:`lab.lab_clips.lab_measures`).
    hit_frames : dict of str to int
        Class → the lengths of its hits (Δ below its τ) summed over every setting annotated, in 30 Hz
        frames (hits of one class may share frames, which then count once per hit): a class
        that finds nothing anywhere shows 0 (the quality guard keeps these).
    confidence : dict of str to ndarray of float64
        Per setting, each annotation segment's confidence, row for row with ``auto``
        (:func:`lab.calibration.confidence_calibration` scores it).
    """

    scores: dict
    truth: dict
    auto: dict
    models: dict
    documents: dict
    sweep: list | None = None
    timings: dict = field(default_factory=dict)
    preselected: dict = field(default_factory=dict)
    vocabulary: dict = field(default_factory=dict)
    studio: object = None
    lab: object = None
    hit_frames: dict = field(default_factory=dict)
    confidence: dict = field(default_factory=dict)


def _preselect(preselection, model, docs, keyframes):
    if preselection is not None:
        return preselection(model, docs.words, docs.doc_lengths)
    return preselection_for(docs.words, docs.doc_lengths, model, keyframes)


def _preselected_rows(model, docs, pre):
    """Label rows of the frames each label's classes are matched on (see DevelopmentEvaluation)."""
    bounds = np.concatenate(([0], np.cumsum(docs.doc_lengths)))
    out = []
    for k, c in enumerate(model.classes):
        sl = None if pre is None else (pre.get(c.name) if isinstance(pre, dict) else pre[k])
        if sl is None:
            sl = np.stack([bounds[:-1], bounds[1:] - 1], axis=1)
        sl = np.asarray(sl, dtype=np.int64).reshape(-1, 2)
        sl = sl[sl[:, 1] >= sl[:, 0]]
        if sl.size == 0:
            continue
        d = np.searchsorted(bounds, sl[:, 0], side="right") - 1
        out.append(label_rows([docs.names[i] for i in d], [c.label] * len(d), sl[:, 0] - bounds[d],
                              sl[:, 1] - bounds[d]))
    return np.concatenate(out) if out else np.empty(0, LABEL_DTYPE)


def _check_modes(modes):
    if modes is None:
        return None
    if not isinstance(modes, dict) or not modes:
        raise ParameterError("modes must be a non-empty dict: mode name -> annotate options")
    for name, opts in modes.items():
        if not isinstance(opts, dict):
            raise ParameterError(f"modes[{name!r}] must be a dict of annotate options (keyframes, tau, …)")
    return modes


def _annotate_modes(docs, model, modes, preselection):
    """Per mode: (annotation rows, preselected rows)."""
    out = {}
    cache = {}
    for mode, opts in modes.items():
        opts = dict(opts)
        kf = opts.pop("keyframes", None)
        key = (id(model), kf)
        if key not in cache:
            cache[key] = _preselect(preselection, model, docs, kf)
        pre = cache[key]
        ann = annotate(docs.words, model, doc_lengths=docs.doc_lengths, preselection=pre, **opts)
        lengths = np.bincount(ann.hits["class_id"], weights=ann.hits["end"] - ann.hits["start"] + 1,
                              minlength=len(ann.class_names))
        out[mode] = (segments_to_rows(ann.segments, docs.names), _preselected_rows(model, docs, pre),
                     dict(zip(ann.class_names, lengths.astype(np.int64).tolist())),
                     np.asarray(ann.segments["confidence"], dtype=np.float64))
    return out


def development_evaluation(data_dir, *, seed=0, tau=None, delta=DEFAULT_DELTA,
                           clips_per_document=CLIPS_PER_DOCUMENT, held_out=None, classes=None,
                           class_labels=None, real_documents=True, preselection=None,
                           keyframes=None, sweep_taus=None, progress=None, build=None, cmu_training=None,
                           mirrored=False, vocabulary=None, modes=None, data=None, cut_params=None,
                           studio=True, leave_out_lab=False):
    """Leave-one-actor-out and real-document evaluation of the annotation.

    For each held-out actor: build a model without that actor's clips,
    annotate that actor's LOAO documents (and their mirror images with
    ``mirrored``). Then (``real_documents``) annotate CMU 86_09 and the
    mocap6 takes with a model built from all actors — without the stretches
    of the annotated document when CMU stretches train. Score each setting.

    Parameters
    ----------
    data_dir : str or Path
        The development data folder (``hdm05_cut/``, ``cmu/``, ``labels/``).
    seed : int, default 0
        Seed of the LOAO document composition.
    tau : float, optional
        Hit threshold τ for every class (default: each class's own τ).
    delta : float, default 0.05
        Quantization threshold δ of the default build.
    clips_per_document : int, default 15
    held_out : sequence of str, optional
        Actors to hold out in turn (default: every actor of ``hdm05_cut``).
    classes : sequence of str, optional
        Only these HDM05 classes (default all 11).
    class_labels : mapping of str to str, optional
        Class → coarse label of the LOAO truth and the default build
        (default: the shipped ``hdm05`` mapping).
    real_documents : bool, default True
        Also evaluate CMU 86_09 and mocap6.
    preselection : callable, optional
        ``preselection(model, words, doc_lengths)`` → the ``preselection``
        argument of :func:`mocapdb.annotation.annotate`. Default: the keyframe
        preselection when the model has keyframe queries (and the mode's
        ``keyframes`` allows), else none.
    keyframes : callable, optional
        Default build only: ``keyframes(model, clips)`` → the model with
        keyframe queries, given its training clips (class → list of
        (name, words)).
    sweep_taus : sequence of float, optional
        Also score the LOAO setting for each of these τ (first mode only).
    progress : callable, optional
        ``progress(n_done, n_steps, what)`` after each fold.
    build : callable, optional
        ``build(clips, name)`` → Model, given the fold's training clips
        (class → list of :class:`lab.recipe.Clip`: HDM05 clips,
        then CMU repetitions). Default: a template per class by
        :func:`mocapdb.learning.train_model` with ``class_labels``, δ, and
        ``keyframes``.
    cmu_training : bool, optional
        CMU stretches in the training clips (default: with ``build``).
    mirrored : bool, default False
        Also score the mirrored LOAO documents (``loao_mirrored``).
    vocabulary : sequence of str, optional
        Labels scored in every setting (e.g. the paper's 15); default each
        setting's models' labels.
    modes : dict of str to dict, optional
        Annotate every fold in several modes, e.g. ``{"reference":
        {"keyframes": False}, "default": {}}``: options of
        :func:`mocapdb.annotation.annotate` (and ``keyframes``). Then the
        result is a dict mode → DevelopmentEvaluation.
    data : DevelopmentData, optional
        Already read material (:func:`development_data`); default read here.
    cut_params : dict, optional
        Options of :func:`lab.cutting.cut_repetitions` for the CMU stretches.
    studio : bool, default True
        Also the bandai2 setting, where ``data`` holds the studio's clips: a
        model built without each style annotates that style's clips when the
        studio trains (``cmu_training``), else the model of every fold's data.
        Likewise the accad setting (``data.lab``), whose clips never train: the
        model of every fold's data annotates them.
    leave_out_lab : bool, default False
        Leave one lab out instead (:data:`LABS`): each lab's settings are
        annotated by a model trained on none of its clips
        (:meth:`DevelopmentData.clips` ``without_lab``) — HDM05's documents of
        every actor by the model of CMU and the studio, CMU's documents by the
        model of HDM05 and the studio, the studio's clips by the model of HDM05
        and CMU, the third lab's by the model of all three.

    Returns
    -------
    DevelopmentEvaluation, or dict of str to DevelopmentEvaluation with ``modes``

    References
    ----------
    data/README.md (development evaluation); paper Sect. 7, Table 2, Fig. 8.
    """
    t_start = time.perf_counter()
    timings = {"read": 0.0, "train": 0.0, "annotate": 0.0, "sweep": 0.0}
    single = modes is None
    modes = {"": {"tau": tau}} if single else _check_modes(modes)
    if not single and tau is not None:
        modes = {k: {"tau": tau, **v} for k, v in modes.items()}
    labels = shipped_class_labels("hdm05") if class_labels is None else dict(class_labels)
    cmu_training = build is not None if cmu_training is None else bool(cmu_training)
    t0 = time.perf_counter()
    if data is None:
        data = development_data(data_dir, classes=classes, cmu_training=cmu_training and real_documents,
                                studio=studio)
    actors = data.actors
    held_out = actors if held_out is None else [str(a) for a in held_out]
    unknown = sorted(set(held_out) - set(actors))
    if unknown:
        raise ParameterError(f"held_out actors {unknown} have no clips; available: {actors}")
    timings["read"] += time.perf_counter() - t0

    def make(clips, name):
        t = time.perf_counter()
        if build is not None:
            model = build(clips, name)
        else:
            hdm = {c: [(x.name, x.words) for x in v] for c, v in clips.items() if c in data.hdm05}
            model = train_model(hdm, name=name, labels=labels, delta=delta)
            if keyframes is not None:
                model = keyframes(model, hdm)
        timings["train"] += time.perf_counter() - t
        return model

    n_steps = len(held_out) + bool(real_documents)
    models, documents = {}, {}
    parts = {m: {} for m in modes}       # mode -> setting -> list of (truth, auto, preselected)
    sweep_parts = []

    hit_frames = {m: {} for m in modes}  # mode -> class -> its hits' lengths summed, over every setting

    def add(setting, docs, model):
        t = time.perf_counter()
        for m, (rows, pre, hits, conf) in _annotate_modes(docs, model, modes, preselection).items():
            parts[m].setdefault(setting, []).append((docs.truth, rows, pre, model.labels, conf))
            for c, n in hits.items():
                hit_frames[m][c] = hit_frames[m].get(c, 0) + n
        timings["annotate"] += time.perf_counter() - t

    def lab_model(lab):
        if f"without_{lab}" not in models:
            models[f"without_{lab}"] = make(data.clips(without_lab=lab, cut_params=cut_params), f"without_{lab}")
        return models[f"without_{lab}"]

    loao_docs, mirror_docs = [], []
    for k, actor in enumerate(held_out):
        if leave_out_lab:
            model = lab_model("hdm05")
        else:
            model = make(data.clips(without_actor=actor, cut_params=cut_params), f"without_{actor}")
            models[model.name] = model
        t0 = time.perf_counter()
        items = [(c, m) for c, cl in data.hdm05.items() for clip, m in cl if clip.group == actor]
        docs = _loao_from_clips(items, actor, seed=seed, clips_per_document=clips_per_document,
                                class_labels=labels)
        timings["read"] += time.perf_counter() - t0
        loao_docs.append(docs)
        add("loao", docs, model)
        if mirrored:
            mdocs = mirror_document_set(docs)
            mirror_docs.append(mdocs)
            add("loao_mirrored", mdocs, model)
        if sweep_taus is not None:
            t0 = time.perf_counter()
            first = next(iter(modes.values()))
            pre = _preselect(preselection, model, docs, first.get("keyframes"))
            segs = annotate_sweep(docs.words, model, sweep_taus, doc_lengths=docs.doc_lengths, preselection=pre)
            sweep_parts.append((docs.truth, [segments_to_rows(s, docs.names) for s in segs], model.labels))
            timings["sweep"] += time.perf_counter() - t0
        if progress is not None:
            progress(k + 1, n_steps, f"held out {actor}")
    if held_out:
        documents["loao"] = DocumentSet.concat(loao_docs)
        if mirrored:
            documents["loao_mirrored"] = DocumentSet.concat(mirror_docs)
    if real_documents:
        t0 = time.perf_counter()
        documents["cmu86_09"] = cmu86_documents(data_dir)
        documents["mocap6"] = mocap6_documents(data_dir)
        timings["read"] += time.perf_counter() - t0
        if leave_out_lab:
            full = lab_model("cmu")
        else:
            full = models["all"] = make(data.clips(cut_params=cut_params), "all")
        trained_on = set(data.cmu_rows["document"].tolist()) if cmu_training and not leave_out_lab else set()
        for s in ("cmu86_09", "mocap6"):
            ds = documents[s]
            off = np.concatenate(([0], np.cumsum(ds.doc_lengths)))
            for k, name in enumerate(ds.names):
                one = _subset(ds, k, off)
                model = full
                if name in trained_on:
                    model = make(data.clips(without_document=name, cut_params=cut_params), f"without_{name}")
                    models[model.name] = model
                add(s, one, model)
        documents["cmu"] = DocumentSet.concat([documents["cmu86_09"], documents["mocap6"]])
        if progress is not None:
            progress(n_steps, n_steps, "CMU documents")
    if studio and data.studio is not None:
        documents["bandai2"] = data.studio.docs
        if leave_out_lab:
            add("bandai2", data.studio.docs, lab_model("bandai2"))
        elif cmu_training and data.studio_trains:
            for style in data.styles:
                model = make(data.clips(without_style=style, cut_params=cut_params), f"without_{style}")
                models[model.name] = model
                add("bandai2", data.studio.subset(np.array(data.studio.styles) == style).docs, model)
        else:
            if "all" not in models:
                models["all"] = make(data.clips(cut_params=cut_params), "all")
            add("bandai2", data.studio.docs, models["all"])
        if progress is not None:
            progress(n_steps, n_steps, "studio clips")
    if studio and data.lab is not None:
        documents["accad"] = data.lab.docs
        if leave_out_lab:
            model = lab_model("accad")
        else:
            if "all" not in models:
                models["all"] = make(data.clips(cut_params=cut_params), "all")
            model = models["all"]
        add("accad", data.lab.docs, model)
        if progress is not None:
            progress(n_steps, n_steps, "the third lab's clips")
    results = {}
    for m in modes:
        results[m] = _scores(parts[m], vocabulary, models, documents, timings, sweep_parts if m == next(iter(modes))
                             else [], sweep_taus)
        if "bandai2" in results[m].auto:
            object.__setattr__(results[m], "studio", studio_measures(data.studio, results[m].auto["bandai2"],
                                                                      vocabulary=results[m].vocabulary["bandai2"]))
        object.__setattr__(results[m], "hit_frames", hit_frames[m])
        if "accad" in results[m].auto:
            object.__setattr__(results[m], "lab", lab_measures(data.lab, results[m].auto["accad"]))
    timings["total"] = time.perf_counter() - t_start
    log.info("development evaluation: %s", {m: {s: round(v.f1, 3) for s, v in r.scores.items()}
                                            for m, r in results.items()})
    return results[""] if single else results


def _subset(ds, k, off):
    """Document k of a DocumentSet as a DocumentSet of its own."""
    name = ds.names[k]
    return DocumentSet((name,), ds.words[off[k]:off[k + 1]], ds.doc_lengths[k:k + 1], ds.native_lengths[k:k + 1],
                       ds.truth_native[ds.truth_native["document"] == name], ds.truth[ds.truth["document"] == name])


def _scores(parts, vocabulary, models, documents, timings, sweep_parts, sweep_taus):
    """Concatenate the folds of each setting, build cmu and all, score."""
    truth, auto, pre, vocab, conf = {}, {}, {}, {}, {}
    for s, items in parts.items():
        truth[s] = np.concatenate([t for t, _, _, _, _ in items])
        auto[s] = np.concatenate([a for _, a, _, _, _ in items])
        pre[s] = np.concatenate([p for _, _, p, _, _ in items])
        vocab[s] = tuple(dict.fromkeys(lab for _, _, _, labs, _ in items for lab in labs))
        conf[s] = np.concatenate([c for _, _, _, _, c in items])
    for s, members in (("cmu", ("cmu86_09", "mocap6")), ("all", ("loao", "cmu86_09", "mocap6"))):
        have = [x for x in members if x in truth]
        if have and (s != "cmu" or len(have) == 2):
            truth[s] = np.concatenate([truth[x] for x in have])
            auto[s] = np.concatenate([auto[x] for x in have])
            pre[s] = np.concatenate([pre[x] for x in have])
            conf[s] = np.concatenate([conf[x] for x in have])
            vocab[s] = tuple(dict.fromkeys(lab for x in have for lab in vocab[x]))
    if vocabulary is not None:
        vocab = {s: tuple(vocabulary) for s in vocab}
    vocab = {s: tuple(lab for lab in v if lab not in UNSCORED.get(s, ())) for s, v in vocab.items()}
    scores = {s: evaluate_annotation(truth[s], auto[s], labels=vocab[s]) for s in SETTINGS if s in truth}
    sweep = None
    if sweep_taus is not None and sweep_parts:
        t0 = time.perf_counter()
        lv = tuple(vocabulary) if vocabulary is not None else tuple(
            dict.fromkeys(lab for _, _, labs in sweep_parts for lab in labs))
        tr = np.concatenate([t for t, _, _ in sweep_parts])
        sweep = [(float(t), evaluate_annotation(tr, np.concatenate([p[i] for _, p, _ in sweep_parts]), labels=lv))
                 for i, t in enumerate(np.atleast_1d(sweep_taus))]
        timings["sweep"] += time.perf_counter() - t0
    return DevelopmentEvaluation(scores, truth, auto, models, documents, sweep, timings, pre, vocab,
                                 confidence=conf)
