"""Annotation quality: the paper's frame- and segment-level precision and recall.

Paper Sect. 7, Eq. (5)–(8): for documents D (evaluated concatenated, as the
paper does for its whole evaluation set)

* M(D) = {(ℓ, p) : frame ℓ manually annotated with label p},
* A(D) = {(ℓ, p) : frame ℓ automatically annotated with label p},
* P1 = |M ∩ A| / |A|, R1 = |M ∩ A| / |M|, F1 = 2·P1·R1 / (P1 + R1).

These are *sets*: a frame carries every label of every segment covering it
(segments of different labels may overlap — the annotation's extension step
produces such overlaps — and all of them count), and overlapping segments of
the same label count each frame once.

Segment level ("we only check for overlaps of a manually annotated motion
segment and an automatically generated segment both bearing the same class
label p"): P2 = the fraction of automatic segments that share at least one
frame with a manual segment of the same label in the same document; R2 = the
fraction of manual segments sharing a frame with such an automatic segment;
F2 from P2 and R2 like F1.

Conventions: a ratio whose denominator is 0 is defined as **0** (no
automatic annotation → P = 0; no ground truth → R = 0), and F = 0 when
P + R = 0. Inputs are rows (document, label, start, end) on one common frame
grid — the 30 Hz feature grid, 0-based inclusive, after
:func:`mocapdb.annotation.labels.to_feature_grid` for ground truth read from a label CSV.

:func:`sweep_tau` scores many hit thresholds τ (paper Fig. 8) from one
computation of Δ (:func:`mocapdb.annotation.annotate_sweep`).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from mocapdb.annotation import annotate_sweep, as_label_rows, segments_to_rows
from mocapdb.errors import ParameterError

__all__ = ["Scores", "f_measure", "frame_measures", "segment_measures",
           "evaluate_annotation", "evaluate_by_label", "restrict_labels", "segments_correct",
           "sweep_tau", "tau_grid", "parse_tau_grid"]


@dataclass(frozen=True)
class Scores:
    """Frame- and segment-level precision, recall and F-measure (paper Eq. (5)–(8)).

    Attributes
    ----------
    p1, r1, f1 : float
        Frame level; 0 where a denominator is 0.
    p2, r2, f2 : float
        Segment level; 0 where a denominator is 0.
    truth_frames, auto_frames, common_frames : int
        |M|, |A|, |M ∩ A| (pairs (frame, label)).
    truth_segments, auto_segments : int
        Numbers of manual and automatic segments evaluated.
    truth_found, auto_correct : int
        Manual segments overlapped by an automatic one of the same label, and
        automatic segments overlapping a manual one of the same label.
    dropped_truth, dropped_auto : dict of str to int
        Segments left out because their label is not in the vocabulary
        (``labels=`` of :func:`evaluate_annotation`), per label.
    """

    p1: float
    r1: float
    f1: float
    p2: float
    r2: float
    f2: float
    truth_frames: int = 0
    auto_frames: int = 0
    common_frames: int = 0
    truth_segments: int = 0
    auto_segments: int = 0
    truth_found: int = 0
    auto_correct: int = 0
    dropped_truth: dict = field(default_factory=dict)
    dropped_auto: dict = field(default_factory=dict)

    def as_dict(self):
        """All fields as a plain dict (e.g. for JSON)."""
        return asdict(self)


def f_measure(p, r):
    """Harmonic mean 2PR / (P + R); 0 when P + R = 0 (paper Eq. (8))."""
    p, r = float(p), float(r)
    return 2.0 * p * r / (p + r) if p + r > 0 else 0.0


def _ratio(a, b):
    return float(a) / float(b) if b else 0.0


# ---------------------------------------------------------------------------
# input normalisation


def _coerce(rows, name):
    """(documents, labels, start, end) arrays from rows; validates the ranges."""
    r = as_label_rows(rows, name)
    s = np.asarray(r["start"], dtype=np.int64)
    e = np.asarray(r["end"], dtype=np.int64)
    if s.size and ((s < 0).any() or (e < s).any()):
        k = int(np.flatnonzero((s < 0) | (e < s))[0])
        raise ParameterError(f"{name}[{k}] = {tuple(r[k])}: need 0 <= start <= end "
                             "(0-based inclusive frames on a common grid)")
    return r["document"].astype(str), r["label"].astype(str), s, e


def _global_line(truth, auto):
    """Map both row sets onto one frame line: each (document, label) key gets
    its own stretch, so intervals of different keys never touch or overlap."""
    td, tl, ts, te = truth
    ad, al, as_, ae = auto
    docs, dinv = np.unique(np.concatenate([td, ad]), return_inverse=True)
    labs, linv = np.unique(np.concatenate([tl, al]), return_inverse=True)
    key = dinv.astype(np.int64) * max(labs.size, 1) + linv
    end = np.concatenate([te, ae])
    stride = int(end.max()) + 2 if end.size else 1
    base = key * stride
    gs = base + np.concatenate([ts, as_])
    ge = base + end
    n = ts.size
    return (gs[:n], ge[:n]), (gs[n:], ge[n:])


def _frame_counts(t, a):
    """|M|, |A|, |M ∩ A| of two interval sets on the global line (sweep over events)."""
    (ts, te), (as_, ae) = t, a
    pos = np.concatenate([ts, te + 1, as_, ae + 1])
    nt, na = ts.size, as_.size
    dm = np.concatenate([np.ones(nt, np.int64), -np.ones(nt, np.int64),
                         np.zeros(2 * na, np.int64)])
    da = np.concatenate([np.zeros(2 * nt, np.int64), np.ones(na, np.int64),
                         -np.ones(na, np.int64)])
    if pos.size == 0:
        return 0, 0, 0
    order = np.argsort(pos, kind="stable")
    pos = pos[order]
    cm = np.cumsum(dm[order])[:-1] > 0   # covered by M on [pos[i], pos[i+1])
    ca = np.cumsum(da[order])[:-1] > 0
    gap = np.diff(pos)
    return int(gap[cm].sum()), int(gap[ca].sum()), int(gap[cm & ca].sum())


def _overlapped(qs, qe, rs, re):
    """For each query interval: does any reference interval share a frame with it?

    On the global line (one stretch per key), the reference interval with the
    largest end among those starting at or before the query's end overlaps
    the query iff that end reaches the query's start; it necessarily has the
    query's key (earlier keys end before the query's stretch begins).
    """
    if qs.size == 0 or rs.size == 0:
        return np.zeros(qs.size, dtype=bool)
    order = np.argsort(rs, kind="stable")
    rs_sorted = rs[order]
    max_end = np.maximum.accumulate(re[order])
    idx = np.searchsorted(rs_sorted, qe, side="right") - 1
    ok = idx >= 0
    out = np.zeros(qs.size, dtype=bool)
    out[ok] = max_end[idx[ok]] >= qs[ok]
    return out


# ---------------------------------------------------------------------------
# measures


def frame_measures(truth, auto):
    """Frame-level P1, R1, F1 (paper Eq. (5)–(8)).

    Parameters
    ----------
    truth, auto : ndarray of LABEL_DTYPE (or with a ``doc`` field) or iterable of
        (document, label, start, end)
        Manual and automatic segments, 0-based inclusive frames on a common grid.

    Returns
    -------
    p1, r1, f1 : float
        0 where a denominator is 0.
    counts : tuple of int
        (|M|, |A|, |M ∩ A|).
    """
    t, a = _global_line(_coerce(truth, "truth"), _coerce(auto, "auto"))
    m, n_a, both = _frame_counts(t, a)
    p, r = _ratio(both, n_a), _ratio(both, m)
    return p, r, f_measure(p, r), (m, n_a, both)


def segment_measures(truth, auto):
    """Segment-level P2, R2, F2 (paper Sect. 7, after Table 2).

    A segment is a hit if it shares at least one frame with a segment of the
    other side that has the same label and document.

    Parameters
    ----------
    truth, auto : as in :func:`frame_measures`

    Returns
    -------
    p2, r2, f2 : float
        0 where a denominator is 0.
    counts : tuple of int
        (manual segments, automatic segments, manual found, automatic correct).
    """
    (ts, te), (as_, ae) = _global_line(_coerce(truth, "truth"), _coerce(auto, "auto"))
    found = int(_overlapped(ts, te, as_, ae).sum())
    correct = int(_overlapped(as_, ae, ts, te).sum())
    p, r = _ratio(correct, as_.size), _ratio(found, ts.size)
    return p, r, f_measure(p, r), (ts.size, as_.size, found, correct)


def segments_correct(truth, auto) -> np.ndarray:
    """Per automatic segment: does it share a frame with a truth segment of its label and document?

    The segment-level correctness of :func:`segment_measures` (P2), row for row.
    """
    (ts, te), (as_, ae) = _global_line(_coerce(truth, "truth"), _coerce(auto, "auto"))
    return _overlapped(as_, ae, ts, te)


def restrict_labels(rows, labels):
    """Split rows into those whose label is in ``labels`` and a count of the rest.

    Returns
    -------
    kept : ndarray of LABEL_DTYPE
    dropped : dict of str to int
        Number of rows left out per label.
    """
    r = as_label_rows(rows)
    vocab = {str(x) for x in labels}
    keep = np.array([x in vocab for x in r["label"]], dtype=bool)
    lab, cnt = np.unique(r["label"][~keep].astype(str), return_counts=True)
    return r[keep], {str(k): int(v) for k, v in zip(lab, cnt)}


def evaluate_annotation(truth, auto, *, labels=None):
    """All six measures of the paper for one evaluation (documents concatenated).

    Parameters
    ----------
    truth, auto : ndarray of LABEL_DTYPE (or with a ``doc`` field) or iterable of
        (document, label, start, end)
        Manual (ground truth) and automatic segments, 0-based inclusive frames
        on a common grid (30 Hz). Documents are matched by name (or index);
        use :func:`mocapdb.annotation.labels.segments_to_rows` to name annotation output.
    labels : sequence of str, optional
        The label vocabulary of the model. Segments with other labels are left
        out of the evaluation and reported in ``dropped_truth``/``dropped_auto``
        — ground truth the model cannot produce (e.g. 86_09's ``look_around``
        and ``clap``) would otherwise only lower the recall. Default: keep all.

    Returns
    -------
    Scores

    References
    ----------
    Paper Sect. 7, Eq. (5)–(8) and the paragraph after Table 2.
    """
    dropped_t, dropped_a = {}, {}
    if labels is not None:
        truth, dropped_t = restrict_labels(truth, labels)
        auto, dropped_a = restrict_labels(auto, labels)
    t, a = _coerce(truth, "truth"), _coerce(auto, "auto")
    (ts, te), (as_, ae) = _global_line(t, a)
    m, n_a, both = _frame_counts((ts, te), (as_, ae))
    found = int(_overlapped(ts, te, as_, ae).sum())
    correct = int(_overlapped(as_, ae, ts, te).sum())
    p1, r1 = _ratio(both, n_a), _ratio(both, m)
    p2, r2 = _ratio(correct, as_.size), _ratio(found, ts.size)
    return Scores(p1, r1, f_measure(p1, r1), p2, r2, f_measure(p2, r2),
                  truth_frames=m, auto_frames=n_a, common_frames=both,
                  truth_segments=int(ts.size), auto_segments=int(as_.size),
                  truth_found=found, auto_correct=correct,
                  dropped_truth=dropped_t, dropped_auto=dropped_a)


def evaluate_by_label(truth, auto, *, labels=None):
    """:func:`evaluate_annotation` for every label separately.

    Returns
    -------
    dict of str to Scores
        One entry per label of ``labels`` (default: every label of either side).
    """
    t = as_label_rows(truth, "truth")
    a = as_label_rows(auto, "auto")
    if labels is None:
        labels = sorted(set(t["label"]) | set(a["label"]))
    return {str(p): evaluate_annotation(t[t["label"] == p], a[a["label"] == p])
            for p in labels}


# ---------------------------------------------------------------------------
# τ sweep (paper Fig. 8)


def tau_grid(start=0.05, stop=0.25, step=0.01):
    """The τ values start, start+step, …, stop (inclusive), rounded to 1e-9.

    ``tau_grid()`` is the CLI's ``--sweep-tau 0.05:0.25:0.01``.
    """
    if not (step > 0 and stop >= start >= 0):
        raise ParameterError(f"need 0 <= start <= stop and step > 0, got "
                             f"{start}:{stop}:{step}")
    n = int(np.floor((stop - start) / step + 1e-9)) + 1
    return np.round(start + step * np.arange(n), 9)


def parse_tau_grid(text):
    """``"start:stop:step"`` (the CLI's ``--sweep-tau``) → :func:`tau_grid`.

    Raises
    ------
    ParameterError
        If the text is not three numbers separated by colons.
    """
    try:
        start, stop, step = (float(x) for x in str(text).split(":"))
    except ValueError:
        raise ParameterError(f"a tau range must be start:stop:step, e.g. 0.05:0.25:0.01; "
                             f"got {text!r}") from None
    return tau_grid(start, stop, step)


def sweep_tau(words, model, truth, taus, *, documents, doc_lengths=None, preselection=None,
              labels=None, **kwargs):
    """Scores of the annotation for many τ (paper Fig. 8), from one Δ.

    Parameters
    ----------
    words : array_like, shape (N,), uint64
    model : Model
    truth : ground-truth rows (document, label, start, end), 30 Hz 0-based
    taus : sequence of float (e.g. :func:`tau_grid`)
    documents : sequence of str
        Names of the documents of ``words`` (as in ``truth``).
    doc_lengths, preselection
        As in :func:`mocapdb.annotation.annotate`.
    labels : sequence of str, optional
        Vocabulary (default: the model's labels).
    **kwargs
        Passed to :func:`mocapdb.annotation.annotate_sweep`.

    Returns
    -------
    list of (float, Scores)
    """
    taus = [float(t) for t in np.atleast_1d(np.asarray(taus, dtype=np.float64))]
    segs = annotate_sweep(words, model, taus, doc_lengths=doc_lengths,
                          preselection=preselection, **kwargs)
    vocab = model.labels if labels is None else labels
    return [(t, evaluate_annotation(truth, segments_to_rows(s, documents), labels=vocab))
            for t, s in zip(taus, segs)]

