"""Training clips cut out of labelled stretches of repeated motion (walks, jogs, exercise sets).

A label file marks a whole stretch — 9 s of walking, 5 s of jumping jacks —
while a motion template stands for one realisation (the authors' fine classes
are "2 steps" or "1 repetition"). :func:`cut_repetitions` cuts a class's
stretches into single repetitions by one stated rule, the same for every
class, with no frame numbers typed by hand:

1. **Period.** The autocorrelation of each stretch's feature matrix (each
   feature centred), averaged over the class's stretches (weighted by
   overlap), for lags of ``min_period`` to ``max_period`` seconds. The
   period P is the shortest lag at a local maximum that reaches half of the
   highest local maximum (a multiple of the period peaks too).
2. **Anchor.** An onset of a feature is a frame where it turns on after at
   least ``min_off`` frames off. Among the features whose median interval
   between successive onsets lies within [P/1.3, 1.3·P], the anchor is the
   one whose repetitions (below) cover the most frames. (Jumping jacks:
   "left hand moves up"; jogging: "left hand moves away from the root"; the
   rule finds them.)
3. **Repetitions.** Each interval of the anchor from one onset to the frame
   before the next is a clip, kept if its length lies within
   ``[P/tolerance, tolerance·P]``.

:func:`clips_from_stretches` applies it to label rows over documents.

Poses held still (a T-pose, a neutral stand) do not repeat; :func:`matching_runs`
finds them by the fuzzy word that defines them (e.g. the one phase of a class
definition): the runs of frames that match it, at least as long as the
definition asks.
"""
from __future__ import annotations

import logging

import numpy as np

from mocapdb.annotation.labels import as_label_rows
from mocapdb.errors import ParameterError
from mocapdb.features import FEATURE_RATE, N_FEATURES, unpack_words

log = logging.getLogger("mocapdb")

__all__ = ["onsets", "period", "choose_anchor", "cut_repetitions", "clips_from_stretches", "matching_runs"]


def onsets(x, *, min_off=2):
    """Frames where a boolean series turns on after at least ``min_off`` frames off.

    Parameters
    ----------
    x : (n,) bool
    min_off : int, default 2

    Returns
    -------
    (m,) int64
        0-based frames (frame 0 never counts: what came before is unknown).
    """
    x = np.asarray(x, dtype=bool)
    out, off = [], 0
    for t, v in enumerate(x.tolist()):
        if v:
            if off >= min_off and t > 0:
                out.append(t)
            off = 0
        else:
            off += 1
    return np.array(out, dtype=np.int64)


def period(stretches, *, min_period=0.5, max_period=5.0):
    """The repetition period of a class's stretches (rule 1 of the module docstring).

    Parameters
    ----------
    stretches : sequence of (n_i, 40) bool
    min_period, max_period : float
        Seconds.

    Returns
    -------
    float or None
        30 Hz frames; None if the autocorrelation has no positive local maximum.
    """
    lo = max(1, int(round(min_period * FEATURE_RATE)))
    hi = int(round(max_period * FEATURE_RATE))
    num = np.zeros(hi + 2)
    den = np.zeros(hi + 2)
    for U in stretches:
        X = np.asarray(U, dtype=np.float64)
        X = X - X.mean(axis=0)
        n = X.shape[0]
        for lag in range(lo - 1, min(hi + 1, n - 2) + 1):
            a, b = X[:-lag], X[lag:]
            norm = np.sqrt((a * a).sum() * (b * b).sum())
            if norm > 0:
                num[lag] += (a * b).sum() / norm * (n - lag)
                den[lag] += n - lag
    ac = np.where(den > 0, num / np.maximum(den, 1), np.nan)
    peaks = [lag for lag in range(lo, hi + 1)
             if np.isfinite(ac[lag - 1:lag + 2]).all() and ac[lag] > ac[lag - 1] and ac[lag] >= ac[lag + 1]]
    if not peaks:
        return None
    top = max(ac[lag] for lag in peaks)
    if not top > 0:
        return None  # no lag resembles the motion more than chance: nothing repeats
    return float(next(lag for lag in peaks if ac[lag] >= 0.5 * top))


def choose_anchor(stretches, *, min_period=0.5, max_period=5.0, tolerance=1.6, min_off=2):
    """The period and anchor feature of a class's stretches (rules 1–2 of the module docstring).

    Parameters
    ----------
    stretches : sequence of (n_i,) uint64
        Packed 30 Hz words of each labelled stretch.
    min_period, max_period : float, default 0.5, 5.0
        Seconds.
    tolerance : float, default 1.6
        Repetitions of [P/tolerance, tolerance·P] frames count.
    min_off : int, default 2

    Returns
    -------
    feature : int
        0-based feature index.
    period : float
        P, 30 Hz frames.

    Raises
    ------
    ParameterError
        No period, or no feature recurs with it.
    """
    U = [unpack_words(np.asarray(s, dtype=np.uint64)) for s in stretches]
    P = period(U, min_period=min_period, max_period=max_period)
    if P is None:
        raise ParameterError(f"these {len(U)} stretches show no repetition period of {min_period}-{max_period} s; "
                             "give longer stretches or label single repetitions")
    best = None
    for f in range(N_FEATURES):
        gaps = [np.diff(onsets(u[:, f], min_off=min_off)) for u in U]
        iv = np.concatenate(gaps) if gaps else np.zeros(0, np.int64)
        iv = iv[iv >= min_period * FEATURE_RATE]
        if iv.size == 0 or not P / 1.3 <= float(np.median(iv)) <= 1.3 * P:
            continue
        covered = sum(int(g[(g >= P / tolerance) & (g <= P * tolerance)].sum()) for g in gaps)
        if best is None or covered > best[0]:
            best = (covered, f)
    if best is None or best[0] == 0:
        raise ParameterError(f"no feature turns on once per period ({P:.0f} frames) in these {len(U)} stretches; "
                             "label single repetitions instead")
    return best[1], P


def cut_repetitions(stretches, *, min_period=0.5, max_period=5.0, tolerance=1.6, min_off=2):
    """Cut a class's labelled stretches into single repetitions (module docstring).

    Parameters
    ----------
    stretches : sequence of (n_i,) uint64
    min_period, max_period, tolerance, min_off
        See :func:`choose_anchor`.

    Returns
    -------
    anchor : int
        The anchor feature (0-based).
    cuts : list of (int, int, int)
        ``(stretch index, start, end)`` per repetition, 0-based inclusive frames
        of the stretch, in stretch then time order.
    """
    if not tolerance >= 1:
        raise ParameterError(f"tolerance={tolerance!r}; use a number >= 1")
    anchor, P = choose_anchor(stretches, min_period=min_period, max_period=max_period, tolerance=tolerance,
                              min_off=min_off)
    cuts = []
    for k, s in enumerate(stretches):
        on = onsets(unpack_words(np.asarray(s, dtype=np.uint64))[:, anchor], min_off=min_off)
        for a, b in zip(on[:-1].tolist(), on[1:].tolist()):
            if P / tolerance <= b - a <= P * tolerance:
                cuts.append((k, a, b - 1))
    return anchor, cuts


def clips_from_stretches(words_by_document, label_rows, *, groups=None, **cut_params):
    """Training clips per class: the labelled stretches cut into repetitions (:func:`cut_repetitions`).

    Parameters
    ----------
    words_by_document : mapping of str to (n_d,) uint64
        Packed 30 Hz words of each document.
    label_rows : ndarray of LABEL_DTYPE or iterable of (document, label, start, end)
        Stretches on the 30 Hz grid, 0-based inclusive; the label names the class.
    groups : callable, optional
        ``groups(document)`` → the group (actor, subject) of a document; kept
        with each clip (default: the document name).
    **cut_params
        Passed to :func:`cut_repetitions`.

    Returns
    -------
    dict of str to list of (str, str, str, ndarray)
        Class → ``(clip name, group, document, words)`` in row order; the clip
        name is ``"<document>[<start>:<end>]"`` (30 Hz frames of the document).
        A class whose stretches :func:`choose_anchor` cannot cut is left out
        (and logged).
    """
    rows = as_label_rows(label_rows, "label_rows")
    by_class = {}
    for k, r in enumerate(rows):
        doc, lab, s, e = str(r["document"]), str(r["label"]), int(r["start"]), int(r["end"])
        if doc not in words_by_document:
            raise ParameterError(f"label_rows[{k}] names document {doc!r}, which is not in words_by_document")
        w = np.asarray(words_by_document[doc], dtype=np.uint64)
        if not 0 <= s <= e < w.shape[0]:
            raise ParameterError(f"label_rows[{k}] = ({doc!r}, {lab!r}, {s}, {e}) is outside the document's "
                                 f"{w.shape[0]} frames")
        by_class.setdefault(lab, []).append((doc, s, w[s:e + 1]))
    out = {}
    for lab, items in by_class.items():
        try:
            _, cuts = cut_repetitions([w for _, _, w in items], **cut_params)
        except ParameterError as e:
            log.warning("class %s: no repetitions cut (%s)", lab, e)
            continue
        out[lab] = []
        for i, a, b in cuts:
            doc, s, w = items[i]
            group = doc if groups is None else groups(doc)
            out[lab].append((f"{doc}[{s + a}:{s + b}]", group, doc, w[a:b + 1].copy()))
    return out


def matching_runs(words, mask, value, *, min_frames=1):
    """Maximal runs of frames whose word matches a fuzzy word (``w & mask == value``).

    Parameters
    ----------
    words : (n,) uint64
    mask, value : int
        40-bit fuzzy word (mask bit 0 = wildcard).
    min_frames : int, default 1
        Shorter runs are dropped.

    Returns
    -------
    list of (int, int)
        ``(start, end)``, 0-based inclusive.
    """
    w = np.asarray(words, dtype=np.uint64)
    ok = (w & np.uint64(mask)) == np.uint64(value)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], ok.astype(np.int8), [0]))))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2]) if b - a >= min_frames]
