"""Annotation of documents with a model of motion templates (paper Sect. 4).

TEMPLATES.md §9.1 and §10:

* :func:`extract_hits` — hits of one Δ below τ and the classification delta
  Δ̄^τ (``cd``) of §9.1;
* :func:`combine_by_label` — element-wise min over the classes of a label (§10.2);
* :func:`frame_labels` — Δmin / Δarg per frame (paper eq. (3)–(4));
* :func:`form_segments` — runs of Δarg, extended along their label's curve
  while it does not increase, merged per label and document (§10.3);
* :func:`annotate` — the whole chain, with optional keyframe preselection
  (§10.1: Δ only on given slices, +inf elsewhere).

Frames are 0-based; segment and hit ends are inclusive; ``doc`` is the index
of the document within the call.
"""
from dataclasses import dataclass

import numba
import numpy as np

from mocapdb.annotation.chain_kernels import (_count_candidates_kernel, _extract_hits_kernel, _label_scatter_kernel,
                                              _merge_kernel, _scatter_kernel, _segments_kernel, _sort_by_key)
from mocapdb.errors import ParameterError, check_nonnegative
from mocapdb.annotation.model import DEFAULT_TAU, Model
from mocapdb.annotation.postprocess import (apply_margin, drop_short_segments, drop_unwon_segments, label_min_frames,
                                           label_min_won, segment_confidence, calibrate_confidence)
from mocapdb.features import as_words as _as_words
from mocapdb.templates import ANNOTATION_STEPS, DEFAULT_CHUNK, mt_distance_slices

__all__ = ["Annotation", "HIT_DTYPE", "SEGMENT_DTYPE", "MATCH_NUM_MAX", "annotate", "annotate_sweep",
           "extract_hits", "combine_by_label", "frame_labels", "form_segments"]

#: the toolbox's limit of hits per class and document (annotationScript.m), where it stops with an
#: error: a long repetitive take (a treadmill walk) has thousands of hits of one class. annotate()
#: has no limit unless asked for one (``match_num_max=MATCH_NUM_MAX``, the toolbox's behaviour);
#: below the limit the segments are the same
MATCH_NUM_MAX = 2000

#: ``confidence`` (0–1): how far below τ the segment's best hit lies, 1 − Δ̄^τ / τ at its
#: best frame (:func:`mocapdb.annotation.postprocess.segment_confidence`); 1 is a perfect match, 0 a match at τ;
#: under a model with ``confidence_maps`` the share of such segments found right on held-out recordings
SEGMENT_DTYPE = np.dtype([("label", object), ("doc", np.int64), ("start", np.int64),
                          ("end", np.int64), ("cost", np.float64), ("confidence", np.float64)])
#: hits: ``class_id`` indexes :attr:`Annotation.class_names` (hits are many)
HIT_DTYPE = np.dtype([("class_id", np.int64), ("doc", np.int64), ("start", np.int64),
                      ("end", np.int64), ("cost", np.float64)])
#: class × frame cells per internal batch of :func:`annotate`: bounds the
#: memory on archives and keeps every per-class float64 array (16 MiB) below
#: glibc's largest mmap threshold (32 MiB), so a batch reuses the heap pages
#: of the one before instead of faulting in fresh ones
BATCH_CELLS = 1 << 21


# ---------------------------------------------------------------------------
# public steps


def _check_limit(match_num_max):
    if match_num_max is None:
        return -1
    if (isinstance(match_num_max, bool) or not isinstance(match_num_max, (int, np.integer))
            or match_num_max < 1):
        raise ParameterError(
            f"match_num_max must be a positive integer or None, got {match_num_max!r}")
    return int(match_num_max)


def _run_hits(delta, starts, offsets, task_first, taus, limit, *, want_hits=True):
    """Allocate and run :func:`_extract_hits_kernel` over the tasks of a flat Δ.

    Without ``want_hits`` only cd and the hit counts are produced (the hit
    arrays are empty and cap_off is None).
    """
    n_tasks = offsets.shape[0] - 1
    ncand = np.empty(n_tasks, np.int64)
    _count_candidates_kernel(delta, offsets, taus, ncand)
    cap = np.minimum(ncand, limit) if limit > 0 else ncand
    if want_hits:
        cap_off = np.concatenate(([0], np.cumsum(cap))).astype(np.int64)
    else:
        cap_off = np.zeros(n_tasks + 1, np.int64)
    n_out = int(cap_off[-1])
    hs = np.empty(n_out, np.int64)
    he = np.empty(n_out, np.int64)
    hc = np.empty(n_out)
    cd = np.empty_like(delta)
    n_hits = np.empty(n_tasks, np.int64)
    # per-thread scratch for the candidates of one task and the sort
    width = int(ncand.max(initial=0))
    nthr = numba.config.NUMBA_NUM_THREADS
    _extract_hits_kernel(delta, starts, offsets, task_first, taus, limit, cap_off,
                         bool(want_hits), cd, hs, he, hc, n_hits,
                         np.empty((nthr, width), np.int64), np.empty((nthr, width), np.int64))
    return cd, hs, he, hc, (cap_off if want_hits else None), n_hits


def extract_hits(delta, starts, *, tau=DEFAULT_TAU, match_num_max=MATCH_NUM_MAX):
    """Hits of a distance function below τ and the classification delta Δ̄^τ.

    Repeatedly: take the first minimum (cost, e) of Δ over the frames not yet
    excluded; stop if cost > τ; the hit is [s, e] with s the start of Δ's path
    at e; frames of [s, e] without a value get ``cd = cost``; exclude [s, e].

    Parameters
    ----------
    delta : array_like, shape (n,), float
        Δ of one document or slice (+inf where no path ends).
    starts : array_like, shape (n,), int
        Start frame (0-based, same numbering as ``delta``) of the path ending
        at each frame (:func:`mocapdb.templates.distance.mt_distance` with ``return_starts``).
    tau : float, default 0.13
    match_num_max : int or None, default 2000
        The toolbox stops with an error when this many hits are found; None:
        no limit.

    Returns
    -------
    hits : ndarray of dtype [('start', int64), ('end', int64), ('cost', float64)]
        In extraction order (increasing cost), 0-based inclusive frames.
    cd : ndarray, shape (n,), float64
        Δ̄^τ: the cost of the first hit covering each frame, +inf elsewhere.

    Raises
    ------
    ParameterError
        If ``match_num_max`` hits are reached (raise it, or use keyframe
        preselection), or on bad input.

    References
    ----------
    TEMPLATES.md §9.1 (``motionTemplateDTWRetrievalWeightedForClassification.m``);
    paper Sect. 4 (Δ̄^τ).
    """
    d = np.ascontiguousarray(delta, dtype=np.float64)
    s = np.ascontiguousarray(starts, dtype=np.int64)
    if d.ndim != 1 or s.shape != d.shape:
        raise ParameterError(
            f"delta and starts must be 1-D of the same length, got {d.shape}, {s.shape}")
    if np.isnan(d).any():
        raise ParameterError("delta must not contain NaN (use +inf for 'no path')")
    ok = d <= tau
    if ok.any() and ((s[ok] < 0) | (s[ok] > np.flatnonzero(ok))).any():
        raise ParameterError("starts must satisfy 0 <= starts[j] <= j where delta[j] <= tau")
    limit = _check_limit(match_num_max)
    cd, hs, he, hc, cap_off, n_hits = _run_hits(
        d, s, np.array([0, d.size], np.int64), np.zeros(1, np.int64),
        np.array([check_nonnegative(tau, "tau")]), limit)
    if n_hits[0] < 0:
        raise ParameterError(
            f"match_num_max={match_num_max} hits reached (the toolbox stops with an error "
            "here); raise match_num_max or pass None")
    hits = np.empty(n_hits[0], dtype=[("start", np.int64), ("end", np.int64),
                                      ("cost", np.float64)])
    hits["start"], hits["end"], hits["cost"] = hs[:n_hits[0]], he[:n_hits[0]], hc[:n_hits[0]]
    return hits, cd


def combine_by_label(x, label_index, n_labels=None):
    """Element-wise minimum over the classes of each label (``combineDelta.m``).

    Parameters
    ----------
    x : array_like, shape (n_classes, n), float
        Per-class Δ or classification delta.
    label_index : array_like, shape (n_classes,), int
        Label of each class (index into the label order).
    n_labels : int, optional
        Default ``max(label_index) + 1``; labels without classes get +inf.

    Returns
    -------
    ndarray, shape (n_labels, n), float64

    References
    ----------
    TEMPLATES.md §10.2.
    """
    x = np.asarray(x, dtype=np.float64)
    li = np.asarray(label_index, dtype=np.int64)
    if x.ndim != 2 or li.shape != (x.shape[0],):
        raise ParameterError(
            f"x must be (n_classes, n) and label_index (n_classes,), got {x.shape}, {li.shape}")
    if n_labels is None:
        n_labels = int(li.max()) + 1 if li.size else 0
    out = np.full((n_labels, x.shape[1]), np.inf)
    for c in range(x.shape[0]):
        np.minimum(out[li[c]], x[c], out=out[li[c]])
    return out


def frame_labels(cd):
    """Δmin and Δarg (paper eq. (3)–(4)): the best label per frame.

    Parameters
    ----------
    cd : array_like, shape (n_labels, n), float
        Classification delta per label.

    Returns
    -------
    delta_min : ndarray, shape (n,), float64
    delta_arg : ndarray, shape (n,), int64
        Label index (ties: the lowest), -1 where every label is +inf.
    """
    cd = np.asarray(cd, dtype=np.float64)
    if cd.ndim != 2:
        raise ParameterError(f"cd must be (n_labels, n), got shape {cd.shape}")
    if cd.shape[0] == 0:
        return np.full(cd.shape[1], np.inf), np.full(cd.shape[1], -1, np.int64)
    arg = np.argmin(cd, axis=0).astype(np.int64)
    dmin = cd[arg, np.arange(cd.shape[1])]
    arg[~(dmin < np.inf)] = -1
    return dmin, arg


def form_segments(cd, *, doc_lengths=None, labels=None):
    """Labelled segments from per-label classification deltas (§10.3).

    Maximal runs of equal Δarg (label with minimal cd, first on ties) are
    extended to the left and right while the label's cd does not increase
    moving outward (never across a document boundary); cost = min of cd at the
    two extended ends; overlapping segments of the same label and document
    are merged (union, minimal cost).

    Parameters
    ----------
    cd : array_like, shape (n_labels, N), float
        Classification delta per label over one or several concatenated documents.
    doc_lengths : array_like of int, optional
        Default one document.
    labels : sequence of str, optional
        Label names (default ``"0"``, ``"1"``, …).

    Returns
    -------
    ndarray of SEGMENT_DTYPE
        Sorted by (label order, doc, start); ``start``/``end`` 0-based inclusive
        frames within the document.

    References
    ----------
    TEMPLATES.md §10.3 (``classificationDelta_to_classificationResult.m``); paper Sect. 4.
    """
    cdl = np.ascontiguousarray(cd, dtype=np.float64)
    if cdl.ndim != 2:
        raise ParameterError(f"cd must be (n_labels, N), got shape {cdl.shape}")
    if np.isnan(cdl).any():
        raise ParameterError("cd must not contain NaN (use +inf)")
    bounds = _doc_bounds(doc_lengths, cdl.shape[1])
    if labels is None:
        labels = tuple(str(k) for k in range(cdl.shape[0]))
    elif len(labels) != cdl.shape[0]:
        raise ParameterError(f"labels must have {cdl.shape[0]} entries, got {len(labels)}")
    return _form_segments(cdl, bounds, labels)


def _form_segments(cdl, bounds, labels):
    """:func:`form_segments` on checked input (C-contiguous float64, no NaN)."""
    n = cdl.shape[1]
    lab = np.empty(n, np.int64)
    doc = np.empty(n, np.int64)
    st = np.empty(n, np.int64)
    en = np.empty(n, np.int64)
    co = np.empty(n)
    r = _segments_kernel(cdl, bounds, lab, doc, st, en, co)
    order = np.lexsort((st[:r], doc[:r], lab[:r]))
    lab, doc, st, en, co = (np.ascontiguousarray(a[:r][order]) for a in (lab, doc, st, en, co))
    k = _merge_kernel(lab, doc, st, en, co)
    out = np.empty(k, dtype=SEGMENT_DTYPE)
    out["label"] = np.asarray(labels, dtype=object)[lab[:k]] if k else []
    out["doc"], out["start"], out["end"], out["cost"] = doc[:k], st[:k], en[:k], co[:k]
    return out


def _tau_ratio(cd, tau):
    """Δ̄^τ / τ per cell; at τ = 0 only a perfect match is a hit, and it counts as 0 (confidence 1)."""
    out = np.full(cd.shape, np.inf)
    pos = tau > 0
    np.divide(cd, tau, out=out, where=pos)
    out[~pos & (cd <= 0)] = 0.0
    return out


def _concurrent_rows(model):
    """Label indices of the model's concurrent labels (annotated on their own, beside the others)."""
    return np.array([k for k, lab in enumerate(model.labels) if lab in model.concurrent_labels], dtype=np.int64)


def _segment_labels(label_cd, label_ratio, doc_bounds, labels, concurrent, margin, min_won):
    """Segments of one batch: the competing labels by Δarg (§10.3), each concurrent label on its own.

    A concurrent label (``Model.concurrent_labels``: a walker who turns is
    still walking) takes no frame from the others: its row leaves the
    competition, and its segments are the runs of its own matches.
    """
    own = None
    if concurrent.size:
        own = label_cd[concurrent].copy()
        label_cd = label_cd.copy()
        label_cd[concurrent] = np.inf
    apply_margin(label_cd, margin)
    segs = _form_segments(label_cd, doc_bounds, labels)
    if min_won is not None:
        segs = drop_unwon_segments(segs, label_cd, doc_bounds, labels, min_won)
    if own is not None:
        parts = [segs] + [_form_segments(own[i:i + 1], doc_bounds, (labels[k],)) for i, k in enumerate(concurrent)]
        segs = _sort_by_label(np.concatenate(parts), labels)
    segs["confidence"] = segment_confidence(segs, label_ratio, doc_bounds, labels)
    return segs


# ---------------------------------------------------------------------------
# the whole chain


@dataclass(frozen=True, eq=False)
class Annotation:
    """Result of :func:`annotate`.

    Attributes
    ----------
    segments : ndarray of SEGMENT_DTYPE
        (label, doc, start, end, cost), 0-based inclusive frames per document.
    hits : ndarray of HIT_DTYPE
        Every hit (class_id, doc, start, end, cost) per class in model order,
        then document / slice order, then extraction order; ``class_id``
        indexes ``class_names``. Empty if annotated with ``keep_hits=False``.
    labels : tuple of str
    class_names : tuple of str
    delta : ndarray, shape (n_classes, N), or None
        Raw Δ per class (+inf outside preselected slices); only with ``keep_deltas``.
    classification_delta : ndarray, shape (n_classes, N), or None
        Δ̄^τ per class; only with ``keep_deltas``.
    label_delta : ndarray, shape (n_labels, N), or None
        Δ̄^τ combined per label (the segmenter's input); only with ``keep_deltas``.
    """

    segments: np.ndarray
    hits: np.ndarray
    labels: tuple
    class_names: tuple
    delta: np.ndarray | None = None
    classification_delta: np.ndarray | None = None
    label_delta: np.ndarray | None = None


def _per_class(flat, offsets, row, first, shape, *, tiled):
    """Task results (flat) as a (n_classes, n_frames) array, +inf outside the tasks.

    With whole-document tasks in class-major order (``tiled``) the flat buffer
    already has that layout.
    """
    if tiled:
        return flat.reshape(shape)
    out = np.full(shape, np.inf)
    _scatter_kernel(flat, offsets, row, first, out)
    return out


def _doc_bounds(doc_lengths, n):
    if doc_lengths is None:
        return np.array([0, n], dtype=np.int64)
    lens = np.asarray(doc_lengths, dtype=np.int64).ravel()
    if (lens < 0).any() or lens.sum() != n:
        raise ParameterError(
            f"doc_lengths must be non-negative and sum to the number of frames {n}, "
            f"got sum {int(lens.sum())}")
    return np.concatenate(([0], np.cumsum(lens))).astype(np.int64)


def _preselection_tasks(preselection, model, bounds):
    """(class, start, stop) tasks: whole documents, or the given inclusive slices."""
    n_cls = len(model.classes)
    n_doc = bounds.size - 1
    if preselection is None:
        per_class = [None] * n_cls
    elif isinstance(preselection, dict):
        unknown = sorted(set(preselection) - set(model.class_names))
        if unknown:
            raise ParameterError(f"preselection names unknown classes {unknown}")
        per_class = [preselection.get(c.name) for c in model.classes]
    else:
        per_class = list(preselection)
        if len(per_class) != n_cls:
            raise ParameterError(
                f"preselection must have one entry per class ({n_cls}), got {len(per_class)}")
    tc, ta, tb = [], [], []
    for c, sl in enumerate(per_class):
        if sl is None:
            tc.append(np.full(n_doc, c))
            ta.append(bounds[:-1])
            tb.append(bounds[1:])
            continue
        s = np.asarray(sl, dtype=np.int64).reshape(-1, 2)
        if s.size == 0:
            continue
        a, e = s[:, 0], s[:, 1]
        if (a < 0).any() or (e < a).any() or (e >= bounds[-1]).any():
            raise ParameterError(
                f"preselection of class {model.classes[c].name!r}: slices must be "
                f"(start, end) with 0 <= start <= end < {bounds[-1]}")
        da = np.searchsorted(bounds, a, side="right") - 1
        de = np.searchsorted(bounds, e, side="right") - 1
        if (da != de).any():
            k = int(np.flatnonzero(da != de)[0])
            raise ParameterError(
                f"preselection of class {model.classes[c].name!r}: slice "
                f"({a[k]}, {e[k]}) crosses a document boundary; split it per document")
        tc.append(np.full(a.size, c))
        ta.append(a)
        tb.append(e + 1)
    if not tc:
        return (np.zeros(0, np.int64),) * 3
    return tuple(np.concatenate(x).astype(np.int64) for x in (tc, ta, tb))


def _batches(bounds, n_frames):
    """Batches (first doc, end doc) of whole documents of about ``n_frames`` frames.

    A batch takes the documents that start within one window of
    ``n_frames`` frames (a longer document makes a batch of its own).
    """
    n_doc = bounds.size - 1
    if n_doc == 0:
        return [(0, 0)]
    window = bounds[:-1] // n_frames
    edges = np.concatenate(([0], np.flatnonzero(np.diff(window)) + 1, [n_doc]))
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def _annotate_batch(w, model, bounds, g0, g1, tasks, taus, limit, match_num_max, steps, rule,
                    *, tiled, keep_hits, keep_deltas, margin=0.0, min_won=None):
    """:func:`annotate` on documents g0..g1-1 for every row of ``taus``.

    Δ is computed once; hits, Δ̄^τ and segments once per τ (Δ does not depend
    on τ). One function per batch so that its arrays are freed before the next.

    Returns
    -------
    list of (segments, hits or None, deltas or None), one per row of ``taus``
        ``hits``: (task, class_id, doc, start, end, cost) arrays in task, then
        extraction order (``task`` indexes ``tasks``).
    """
    tc, ta, tb, task_doc = tasks
    f0, f1 = int(bounds[g0]), int(bounds[g1])
    sel = np.flatnonzero((task_doc >= g0) & (task_doc < g1))
    tc, ta, tb, task_doc = tc[sel], ta[sel], tb[sel], task_doc[sel]
    n_cls, labels = len(model.classes), model.labels
    delta, offsets, starts = mt_distance_slices(
        w, [c.quantized for c in model.classes], tc, ta, tb,
        steps=steps, rule=rule, return_starts=True, chunk_size=DEFAULT_CHUNK)
    out = []
    for class_taus in taus:
        cd, hs, he, hc, cap_off, n_hits = _run_hits(delta, starts, offsets, ta, class_taus[tc], limit,
                                                    want_hits=keep_hits)
        if (n_hits < 0).any():
            q = int(np.flatnonzero(n_hits < 0)[0])
            d = int(task_doc[q])
            raise ParameterError(
                f"class {model.classes[tc[q]].name!r}: match_num_max={match_num_max} hits reached at "
                f"tau={class_taus[tc[q]]:g} in the document of doc_lengths[{d}] (words {int(bounds[d])}…"
                f"{int(bounds[d + 1]) - 1}), where the toolbox stops with an error; pass "
                "match_num_max=None (the default) for no limit")
        hits = None
        if keep_hits:
            # class, doc, start/end within the document
            tot = int(n_hits.sum())
            qq = np.repeat(np.arange(n_hits.size), n_hits)
            idx = cap_off[:-1][qq] + (np.arange(tot) - (np.cumsum(n_hits) - n_hits)[qq])
            hdoc = task_doc[qq]
            first_in_doc = ta[qq] - bounds[hdoc]
            hits = (sel[qq], tc[qq], hdoc, hs[idx] + first_in_doc, he[idx] + first_in_doc, hc[idx])
        # Δ̄^τ per label over the batch, +inf outside the tasks; and Δ̄^τ / τ (the confidence)
        kept = None
        ratio = _tau_ratio(cd, np.repeat(class_taus[tc], np.diff(offsets)))
        if keep_deltas or tiled:
            full_cd = _per_class(cd, offsets, tc, ta - f0, (n_cls, f1 - f0), tiled=tiled)
            label_cd = combine_by_label(full_cd, model.label_index, len(labels))
            label_ratio = combine_by_label(_per_class(ratio, offsets, tc, ta - f0, (n_cls, f1 - f0), tiled=tiled),
                                           model.label_index, len(labels))
            if keep_deltas:
                full_delta = _per_class(delta, offsets, tc, ta - f0, (n_cls, f1 - f0), tiled=tiled)
                kept = (full_delta, full_cd, label_cd)
        else:  # preselected slices: straight into the label rows, no per-class arrays
            label_cd = np.full((len(labels), f1 - f0), np.inf)
            label_ratio = np.full((len(labels), f1 - f0), np.inf)
            _label_scatter_kernel(cd, offsets, tc, ta - f0, model.label_index, np.full(f1 - f0, -1, np.int64),
                                  label_cd)
            _label_scatter_kernel(ratio, offsets, tc, ta - f0, model.label_index, np.full(f1 - f0, -1, np.int64),
                                  label_ratio)
        doc_bounds = bounds[g0:g1 + 1] - bounds[g0]
        segs = _segment_labels(label_cd, label_ratio, doc_bounds, labels, _concurrent_rows(model), margin, min_won)
        segs["doc"] += g0
        out.append((segs, hits, kept))
    return out


def _sort_by_label(segments, labels):
    """Batches are each sorted by (label, doc, start) and follow in document order:
    a stable sort by label order finishes the job."""
    li = {lab: k for k, lab in enumerate(labels)}
    names, inv = np.unique(segments["label"], return_inverse=True)
    rank = np.array([li[x] for x in names], dtype=np.int64)[inv]
    return segments[np.argsort(rank, kind="stable")]


def _filters(model, min_length, min_won, margin):
    """(per-label minimum lengths or None, per-label won frames or None, margin) from the switches (None: the model's)."""
    for name, v in (("min_length", min_length), ("min_won", min_won)):
        if v is not None and not isinstance(v, (bool, np.bool_)):
            raise ParameterError(f"{name} must be True, False or None (the model's), got {v!r}")
    lengths = None if min_length is False else label_min_frames(model)
    won = None if min_won is False else label_min_won(model)
    margin = check_nonnegative(margin, "margin", none="the model's")
    return lengths, won, model.margin if margin is None else margin


def _chain(words, model, taus, *, doc_lengths, preselection, match_num_max, steps, rule, keep_deltas, keep_hits,
           min_length=None, min_won=None, margin=None):
    """The annotation chain for one or several τ settings: one Annotation per setting."""
    if not isinstance(model, Model):
        raise ParameterError(f"model must be a mocapdb.annotation.Model, got {type(model).__name__}")
    min_frames, won, margin = _filters(model, min_length, min_won, margin)
    w = _as_words(words)
    bounds = _doc_bounds(doc_lengths, w.shape[0])
    limit = _check_limit(match_num_max)
    taus = [np.array([check_nonnegative(c.tau if tau is None else tau, "tau") for c in model.classes]) for tau in taus]
    tc, ta, tb = _preselection_tasks(preselection, model, bounds)
    tasks = (tc, ta, tb, np.searchsorted(bounds, ta, side="right") - 1)
    labels = model.labels
    n_cls = len(model.classes)
    # batches of whole documents bound the memory of the per-class arrays
    if keep_deltas:
        groups = [(0, bounds.size - 1)]
    else:
        groups = _batches(bounds, max(1, BATCH_CELLS // max(1, n_cls)))
    per_tau = [([], [], None) for _ in taus]
    for g0, g1 in groups:
        results = _annotate_batch(
            w, model, bounds, g0, g1, tasks, taus, limit, match_num_max, steps, rule,
            tiled=preselection is None, keep_hits=keep_hits, keep_deltas=keep_deltas, margin=margin, min_won=won)
        for k, (segs, hits, kept) in enumerate(results):
            per_tau[k][0].append(segs)
            if keep_hits:
                per_tau[k][1].append(hits)
            per_tau[k] = (per_tau[k][0], per_tau[k][1], kept)
    out = []
    for seg_parts, hit_parts, kept in per_tau:
        segments = np.concatenate(seg_parts)
        if len(seg_parts) > 1:
            segments = _sort_by_label(segments, labels)
        if min_frames is not None:
            segments = drop_short_segments(segments, labels, min_frames, doc_lengths=bounds[1:] - bounds[:-1],
                                           concurrent=model.concurrent_labels)
        if model.confidence_maps:
            segments["confidence"] = calibrate_confidence(segments, segments["confidence"], model.confidence_maps)
        hits = np.empty(0, dtype=HIT_DTYPE)
        if keep_hits:
            # tasks are class-major, then document / slice order (the preselection's);
            # batches took them by document: order by task, then extraction order
            htask, *cols = (np.concatenate(x) for x in zip(*hit_parts))
            order = np.argsort(htask, kind="stable")
            hits = np.empty(order.size, dtype=HIT_DTYPE)
            for name, x in zip(HIT_DTYPE.names, cols):
                hits[name] = x[order]
        out.append(Annotation(segments, hits, labels, model.class_names, *(kept or ())))
    return out


def annotate(words, model, *, doc_lengths=None, preselection=None, tau=None,
             match_num_max=None, steps=ANNOTATION_STEPS, rule="toolbox",
             keep_deltas=False, keep_hits=True, min_length=None, min_won=None, margin=None):
    """Annotate documents with a model of motion templates (the whole chain).

    For every class: Δ of its quantized template on every document (or only
    on the preselected slices), hits below τ and Δ̄^τ (§9.1); Δ̄^τ combined
    per label (§10.2); segments from Δarg with extension and merging (§10.3).

    Parameters
    ----------
    words : array_like, shape (N,), uint64
        Packed 30 Hz feature words of one or several concatenated documents.
    model : Model
    doc_lengths : array_like of int, optional
        Lengths of the concatenated documents (default: one document).
    preselection : sequence or dict, optional
        Keyframe preselection (§10.1): per class (in model order, or a dict by
        class name) a sequence of ``(start, end)`` inclusive word indices, each
        within one document — Δ is computed on each slice as a document of its
        own, +inf elsewhere (a later slice overwrites an earlier overlapping
        one); ``None`` for a class (or for all) means whole documents.
    tau : float, optional
        Hit threshold for every class; default each class's ``tau``.
    match_num_max : int, optional
        Stop with an error once this many hits of a class are found in one
        document or slice, as the toolbox does (:data:`MATCH_NUM_MAX`);
        default no limit: memory and time stay linear in the document's
        length, and below the limit the segments are the same.
    steps, rule
        See :func:`mocapdb.templates.distance.mt_distance`.
    keep_deltas : bool, default False
        Keep Δ, Δ̄^τ per class and per label in the result (memory: 3 float64
        arrays of n_classes × N).
    keep_hits : bool, default True
        Collect the hits (40 bytes each; on the real data about 0.8 per
        frame with 15 classes). False leaves ``Annotation.hits`` empty; the
        segments are the same.
    min_length : bool, optional
        Drop segments shorter than their label's ``min_frames``, or than
        half their document where that is shorter (a clip of one gait
        cycle; not for a concurrent label,
        :func:`mocapdb.annotation.postprocess.drop_short_segments`);
        default True (a class without ``min_frames`` keeps everything, as
        the toolbox).
    min_won : bool, optional
        Drop segments whose label is the best label (Δarg) on fewer than a
        third of its ``min_frames`` frames
        (:func:`mocapdb.annotation.postprocess.drop_unwon_segments`);
        default True (no effect without ``min_frames``).
    margin : float, optional
        Leave frames unlabelled where the best label wins by less than this;
        default the model's ``margin`` (0 for the toolbox model).

    Returns
    -------
    Annotation

    Raises
    ------
    ParameterError
        On bad input, or if ``match_num_max`` (when given) hits are reached for a class.

    References
    ----------
    TEMPLATES.md §9–§10; paper Sect. 4.
    """
    return _chain(words, model, [tau], doc_lengths=doc_lengths, preselection=preselection,
                  match_num_max=match_num_max, steps=steps, rule=rule, keep_deltas=keep_deltas,
                  keep_hits=keep_hits, min_length=min_length, min_won=min_won, margin=margin)[0]


def annotate_sweep(words, model, taus, *, doc_lengths=None, preselection=None, match_num_max=None,
                   steps=ANNOTATION_STEPS, rule="toolbox", min_length=None, min_won=None, margin=None):
    """Annotation segments for many hit thresholds τ, computing Δ once (paper Fig. 8).

    The same chain as :func:`annotate`: Δ does not depend on τ, so each batch
    of documents computes Δ once and then hits, Δ̄^τ and segments per τ.

    Parameters
    ----------
    words : array_like, shape (N,), uint64
    model : Model
    taus : sequence of float
        One hit threshold for every class per entry.
    doc_lengths, preselection, match_num_max, steps, rule, min_length, min_won, margin
        As in :func:`annotate`.

    Returns
    -------
    list of ndarray of SEGMENT_DTYPE
        ``annotate(words, model, tau=t, …).segments`` for every t in ``taus``.
    """
    taus = [float(t) for t in np.atleast_1d(np.asarray(taus, dtype=np.float64))]
    for t in taus:
        check_nonnegative(t, "taus")
    return [a.segments for a in _chain(words, model, taus, doc_lengths=doc_lengths, preselection=preselection,
                                       match_num_max=match_num_max, steps=steps, rule=rule, keep_deltas=False,
                                       keep_hits=False, min_length=min_length, min_won=min_won,
                                       margin=margin)]
