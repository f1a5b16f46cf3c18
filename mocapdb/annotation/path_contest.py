"""Where two labels' hits overlap, the one whose path explains the frames better takes them.

Δ̄^τ gives every frame of a hit the hit's Δ, a mean over the template's
columns; a hit that matches its own motion well can stretch its last
columns over the first second of the next motion (an exercise hit over the
walk after it) and still beat that motion's own hits there. The local cost
of the hit's path on those frames says how badly it explains them, but raw
local costs are not comparable across templates (a coarse template is
cheap everywhere). So each class's local cost is divided by its *scale*
(``path_scale``: its own typical local cost, or τ) before two labels' paths
are compared, per run of frames with the same two best labels.

Measured behind a switch (issue 32, RESULTS.md); off by default.
"""
import os

import numpy as np

from mocapdb._numba import jit
from mocapdb.annotation.chain_kernels import _scatter_kernel
from mocapdb.templates.paths import path_local_costs

__all__ = ["contest_overlaps"]

DEBUG = None  # a list: contest_overlaps appends (first, end, label, label, cost, cost, class, class, cd, cd) per run


@jit
def _provider_kernel(offsets, cap_off, n_hits, hit_start, hit_end, prov):  # pragma: no cover
    """prov[offsets[q] + j] = global index (cap_off[q] + k) of the first hit k of task q covering frame j, or -1."""
    for q in range(offsets.shape[0] - 1):
        a = offsets[q]
        for j in range(offsets[q + 1] - a):
            prov[a + j] = -1
        for k in range(n_hits[q]):
            h = cap_off[q] + k
            for j in range(hit_start[h], hit_end[h] + 1):
                if prov[a + j] < 0:
                    prov[a + j] = h


@jit
def _two_best(cdl, f):  # pragma: no cover
    """The two labels with the lowest finite cd at frame f (first on ties), -1 where missing."""
    p1 = -1
    p2 = -1
    for p in range(cdl.shape[0]):
        v = cdl[p, f]
        if not v < np.inf:
            continue
        if p1 < 0 or v < cdl[p1, f]:
            p2 = p1
            p1 = p
        elif p2 < 0 or v < cdl[p2, f]:
            p2 = p
    return p1, p2


@jit
def _provider(class_cd, class_label, prov, p, f):  # pragma: no cover
    """(class, hit) that gives label p its cd at frame f: its first class with the minimal cd."""
    best = np.inf
    c = -1
    for k in range(class_cd.shape[0]):
        if class_label[k] == p and class_cd[k, f] < best:
            best = class_cd[k, f]
            c = k
    return c, (prov[c, f] if c >= 0 else -1)


@jit
def _needed_kernel(cdl, class_cd, class_label, prov, need):  # pragma: no cover
    """need[h] = True for every hit that gives one of the two best labels its cd on a contested frame."""
    for f in range(cdl.shape[1]):
        p1, p2 = _two_best(cdl, f)
        if p2 < 0:
            continue
        for p in (p1, p2):
            c, h = _provider(class_cd, class_label, prov, p, f)
            if h >= 0:
                need[h] = True


@jit
def _run_cost(class_cd, class_label, prov, hit_first, cost, col, cost_off, scale, soff, p, a, b):  # pragma: no cover
    """Mean scaled local cost of label p's providing paths over frames a..b-1 (+inf: none known)."""
    tot = 0.0
    n = 0
    for f in range(a, b):
        c, h = _provider(class_cd, class_label, prov, p, f)
        if h < 0 or cost_off[h + 1] == cost_off[h]:
            continue
        j = cost_off[h] + f - hit_first[h]
        v = cost[j]
        if v < np.inf:
            tot += v / scale[soff[c] + col[j]]
            n += 1
    return tot / n if n else np.inf


@jit
def _self_ref_kernel(class_cd_rows, prov, hits, hit_class, hit_first, cost, cost_off, floor, ref):  # pragma: no cover
    """ref[h]: hit h's mean local cost on the frames of its path earlier hits of its class took (its core), >= floor."""
    for t in range(hits.shape[0]):
        h = hits[t]
        c = hit_class[h]
        tot = 0.0
        m = 0
        for j in range(cost_off[h + 1] - cost_off[h]):
            k = cost_off[h] + j
            if prov[c, hit_first[h] + j] != h and cost[k] < np.inf:
                tot += cost[k]
                m += 1
        ref[h] = max(tot / m if m else np.inf, floor)


@jit
def _self_ratio(class_cd, class_label, prov, hit_first, cost, cost_off, ref, p, a, b):  # pragma: no cover
    """Mean over frames a..b-1 of label p's providing path cost relative to that hit's own core (ref)."""
    tot = 0.0
    n = 0
    for f in range(a, b):
        c, h = _provider(class_cd, class_label, prov, p, f)
        if h < 0 or cost_off[h + 1] == cost_off[h]:
            continue
        v = cost[cost_off[h] + f - hit_first[h]]
        if v < np.inf:
            tot += v / ref[h]
            n += 1
    return tot / n if n else 0.0


@jit
def _winner_tail(cdl, class_cd, class_label, prov, is_tail, f, p1):  # pragma: no cover
    """Whether the Δarg label p1's value at frame f comes from a tail hit (False without tail flags)."""
    if is_tail.shape[0] == 0:
        return True
    c, h = _provider(class_cd, class_label, prov, p1, f)
    return h >= 0 and is_tail[h]


@jit
def _contest_kernel(cdl, class_cd, class_label, prov, hit_first, cost, col, cost_off, scale, soff, bounds,
                    is_tail, ref, limit):  # pragma: no cover
    """Per run of frames with the same two best labels (within a document), the label with
    the higher mean scaled path cost gets +inf there (in place on cdl). With tail flags
    (``is_tail`` non-empty) only runs where the Δarg label's value comes from a tail are contested."""
    for d in range(bounds.shape[0] - 1):
        f = bounds[d]
        while f < bounds[d + 1]:
            p1, p2 = _two_best(cdl, f)
            if p2 < 0:
                f += 1
                continue
            lo = min(p1, p2)
            hi = max(p1, p2)
            tail = _winner_tail(cdl, class_cd, class_label, prov, is_tail, f, p1)
            g = f + 1
            while g < bounds[d + 1]:
                q1, q2 = _two_best(cdl, g)
                if min(q1, q2) != lo or max(q1, q2) != hi:
                    break
                if _winner_tail(cdl, class_cd, class_label, prov, is_tail, g, q1) != tail:
                    break
                g += 1
            if not tail or (ref.shape[0] > 0
                            and _self_ratio(class_cd, class_label, prov, hit_first, cost, cost_off, ref, p1, f, g) <= limit):
                f = g
                continue
            c_lo = _run_cost(class_cd, class_label, prov, hit_first, cost, col, cost_off, scale, soff, lo, f, g)
            c_hi = _run_cost(class_cd, class_label, prov, hit_first, cost, col, cost_off, scale, soff, hi, f, g)
            if c_lo < np.inf and c_hi < np.inf and c_lo != c_hi:
                loser = hi if c_hi > c_lo else lo
                for k in range(f, g):
                    cdl[loser, k] = np.inf
            f = g


@jit
def _tail_kernel(offsets, cap_off, n_hits, hit_start, is_tail):  # pragma: no cover
    """is_tail[h]: an earlier (better) hit of the same task starts at the same frame (its path runs on past that one's)."""
    for q in range(offsets.shape[0] - 1):
        a = cap_off[q]
        for k in range(n_hits[q]):
            for k2 in range(k):
                if hit_start[a + k2] == hit_start[a + k]:
                    is_tail[a + k] = True
                    break


@jit
def _cut_tails_kernel(class_cd, prov, tail_hits, hit_class, hit_first, cost, col, cost_off, scale, soff, limit,
                      self_floor):  # pragma: no cover
    """A tail's frames whose scaled local cost is above ``limit`` stop counting for its class (+inf)."""
    for t in range(tail_hits.shape[0]):
        h = tail_hits[t]
        c = hit_class[h]
        n = cost_off[h + 1] - cost_off[h]
        ref = -1.0
        if self_floor > 0:
            # the hit's own range: its path's mean local cost on the frames earlier hits of its class took
            tot = 0.0
            m = 0
            for j in range(n):
                k = cost_off[h] + j
                if prov[c, hit_first[h] + j] != h and cost[k] < np.inf:
                    tot += cost[k]
                    m += 1
            ref = max(tot / m if m else np.inf, self_floor)
        for j in range(n):
            f = hit_first[h] + j
            k = cost_off[h] + j
            r = ref if ref > 0 else scale[soff[c] + col[k]]
            if prov[c, f] == h and col[k] >= 0 and cost[k] / r > limit:
                class_cd[c, f] = np.inf


def contest_overlaps(label_cd, class_cd, class_label, scale, words, templates, *, offsets, cap_off, n_hits,
                     hit_start, hit_end, task_row, task_first, f0, doc_bounds, tiled):
    """Give each contested run of frames to the label whose path explains it better (in place on ``label_cd``).

    ``label_cd`` (n_labels, n) holds the competing labels only (concurrent
    rows +inf); ``class_cd`` (n_classes, n) Δ̄^τ per class over the same
    frames (word ``f0`` is frame 0); the hits are the chain's flat per-task
    hits (task-relative inclusive frames at ``cap_off[q]``…); ``per_class``
    scatters a flat per-task array into (n_classes, n) rows.
    """
    prov_flat = np.empty(int(offsets[-1]), np.int64)
    _provider_kernel(offsets, cap_off, n_hits, hit_start, hit_end, prov_flat)
    if tiled:
        prov = prov_flat.reshape(class_cd.shape)
    else:
        prov = np.full(class_cd.shape, -1, np.int64)
        _scatter_kernel(prov_flat, offsets, task_row, task_first - f0, prov)
    hs_len = int(cap_off[-1])
    need = np.zeros(hs_len, np.bool_)
    mode = os.environ.get("MOCAPDB_PATH_MODE", "contest")
    if mode == "tail":
        _tail_kernel(offsets, cap_off, n_hits, hit_start, need)
    else:
        _needed_kernel(label_cd, class_cd, class_label, prov, need)
    task_of = np.repeat(np.arange(offsets.size - 1), np.diff(cap_off))
    hit_first = (task_first[task_of] + hit_start[:hs_len]).astype(np.int64) - f0
    idx = np.flatnonzero(need)
    costs, off, cols = path_local_costs(words, templates, task_row[task_of[idx]], hit_first[idx] + f0,
                                  task_first[task_of[idx]] + hit_end[idx])
    soff = np.concatenate(([0], np.cumsum([len(x) for x in scale]))).astype(np.int64)
    scale = np.concatenate(scale).astype(np.float64)
    cost_off = np.zeros(hs_len + 1, np.int64)
    lens = np.zeros(hs_len, np.int64)
    lens[idx] = np.diff(off)
    cost_off[1:] = np.cumsum(lens)
    if mode == "tail":
        class_cd = class_cd.copy()
        if DEBUG is not None:
            tc_ = task_row[task_of]
            for t in idx:
                c = tc_[t]
                k0, k1 = cost_off[t], cost_off[t + 1]
                DEBUG.append((c, f0 + hit_first[t], costs[k0:k1] / np.where(cols[k0:k1] >= 0, scale[soff[c] + cols[k0:k1]], np.inf),
                              prov[c, hit_first[t]:hit_first[t] + k1 - k0] == t, costs[k0:k1]))
        _cut_tails_kernel(class_cd, prov, idx, task_row[task_of], hit_first, costs, cols, cost_off, scale, soff,
                          float(os.environ.get("MOCAPDB_PATH_R", "3")), float(os.environ.get("MOCAPDB_PATH_SELF", "0")))
        rows = np.isfinite(label_cd).any(axis=1)  # competing labels (concurrent rows are +inf throughout)
        new = np.full_like(label_cd, np.inf)
        for k in range(class_cd.shape[0]):
            np.minimum(new[class_label[k]], class_cd[k], out=new[class_label[k]])
        label_cd[rows] = new[rows]
        return label_cd
    is_tail = np.zeros(0, np.bool_)
    ref = np.zeros(0)
    if mode in ("tailcontest", "selfcontest"):
        is_tail = np.zeros(hs_len, np.bool_)
        _tail_kernel(offsets, cap_off, n_hits, hit_start, is_tail)
    if mode == "selfcontest":
        ref = np.full(hs_len, np.inf)
        _self_ref_kernel(class_cd, prov, idx, task_row[task_of], hit_first, costs, cost_off,
                         float(os.environ.get("MOCAPDB_PATH_SELF", "0.02")), ref)
    _contest_kernel(label_cd, np.ascontiguousarray(class_cd), class_label, prov, hit_first, costs, cols, cost_off,
                    scale, soff, doc_bounds, is_tail, ref, float(os.environ.get("MOCAPDB_PATH_R", "3")))
    return label_cd
