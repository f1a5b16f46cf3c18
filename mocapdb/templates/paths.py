"""The local cost along a hit's DTW path, frame by frame (TEMPLATES.md §9).

Δ of a hit is a mean over the template's columns: a path that explains most
columns well keeps Δ low even where a few columns are stretched over frames
they explain badly (an exercise hit running on into the next clip's walk).
:func:`path_local_costs` re-traces the path of given hits and reports, for
every document frame of the hit, the local cost c·K (the scale of Δ) of the
template column the path matches it with.

The path is the one Δ ended with: the dynamic programme of
:func:`mocapdb.templates.distance.mt_distance` (toolbox rule: the predecessor
with the smallest accumulated cost, first step on ties) run on the hit's
frames alone. Cells on the path keep their accumulated costs there (the
predecessors it drops are not on the path, and dropping options only raises
the others), so the re-traced path is the same.
"""
import numpy as np

from mocapdb._numba import jit, pjit, prange
from mocapdb.templates.distance import (ANNOTATION_STEPS, _as_templates, _check_steps, _popcount, cost_table)

__all__ = ["path_local_costs"]


@jit
def _trace_one(words, masks, values, tables, k0, K, a, n, di, dj, w, out, col, o):  # pragma: no cover
    """Local cost ·K along the toolbox path of one template (rows k0..k0+K-1) ending at frame a+n-1.

    Writes out[o:o+n]: a frame on the path takes its cell's cost; a frame a
    step skips (Δj > 1) takes the cheaper of the two columns it lies between;
    a frame before the path's start stays +inf.
    """
    C = np.empty((K, n))
    for j in range(n):
        wd = words[a + j]
        for i in range(K):
            C[i, j] = tables[k0 + i, _popcount((values[k0 + i] ^ wd) & masks[k0 + i])] * K
    D = np.full((K, n), np.inf)
    choice = np.full((K, n), -1, np.int64)
    nS = di.shape[0]
    for j in range(n):
        D[0, j] = C[0, j]
        for i in range(1, K):
            best = np.inf
            bs = -1
            for s in range(nS):
                pi = i - di[s]
                pj = j - dj[s]
                v = D[pi, pj] if pi >= 0 and pj >= 0 else np.inf
                if bs < 0 or v < best:
                    best = v
                    bs = s
            if best < np.inf:
                D[i, j] = best + w[bs] * C[i, j]
                choice[i, j] = bs
    for j in range(n):
        out[o + j] = np.inf
        col[o + j] = -1
    i = K - 1
    j = n - 1
    while j >= 0:
        out[o + j] = C[i, j]
        col[o + j] = i
        if i == 0:
            break
        s = choice[i, j]
        if s < 0:
            break
        for jj in range(j - dj[s] + 1, j):
            out[o + jj] = min(C[i - 1, jj], C[i, jj]) if i >= 1 else C[i, jj]
            col[o + jj] = i - 1 if i >= 1 and C[i - 1, jj] < C[i, jj] else i
        i -= di[s]
        j -= dj[s]


@pjit
def _trace_kernel(words, masks, values, tables, toff, hit_template, hit_start, hit_end, off, di, dj, w,
                  out, col):  # pragma: no cover
    for h in prange(hit_template.shape[0]):
        t = hit_template[h]
        _trace_one(words, masks, values, tables, toff[t], toff[t + 1] - toff[t], hit_start[h],
                   hit_end[h] - hit_start[h] + 1, di, dj, w, out, col, off[h])


def path_local_costs(words, templates, hit_template, hit_start, hit_end, *, steps=ANNOTATION_STEPS, expand=True):
    """Local cost ·K of every frame of each hit along its DTW path (toolbox rule).

    Parameters
    ----------
    words : array_like, shape (N,), uint64
    templates : sequence of QuantizedTemplate
    hit_template : array_like, shape (n_hits,), int
        Index into ``templates``.
    hit_start, hit_end : array_like, shape (n_hits,), int
        Inclusive word indices of each hit (its path's start and end frame).
    steps, expand
        As in :func:`mocapdb.templates.distance.mt_distance`.

    Returns
    -------
    costs : ndarray, shape (Σ hit lengths,), float64
        Hit h's frames at ``costs[offsets[h]:offsets[h+1]]``: the local cost
        (the fraction of the column's fixed features that disagree, times
        the column's weight factor: Δ is their weighted mean over the path)
        of the column the path matches the frame with; a frame a (1, 2)
        step skips takes the cheaper of its two neighbouring columns.
    offsets : ndarray, shape (n_hits + 1,), int64
    columns : ndarray, shape (Σ hit lengths,), int64
        The (expanded) template column of each frame (-1 before the path's start).
    """
    ts, _ = _as_templates(templates)
    if expand:
        ts = [t.expand() for t in ts]
    di, dj, w = (np.asarray(x) for x in _check_steps(steps))
    toff = np.concatenate(([0], np.cumsum([len(t) for t in ts]))).astype(np.int64)
    masks = np.concatenate([t.mask for t in ts]) if ts else np.zeros(0, np.uint64)
    values = np.concatenate([t.value for t in ts]) if ts else np.zeros(0, np.uint64)
    tables = np.concatenate([cost_table(t) for t in ts]) if ts else np.zeros((0, 42))
    ht = np.ascontiguousarray(hit_template, dtype=np.int64)
    hs = np.ascontiguousarray(hit_start, dtype=np.int64)
    he = np.ascontiguousarray(hit_end, dtype=np.int64)
    off = np.concatenate(([0], np.cumsum(he - hs + 1))).astype(np.int64)
    out = np.empty(int(off[-1]))
    col = np.empty(int(off[-1]), np.int64)
    _trace_kernel(np.ascontiguousarray(words, dtype=np.uint64), masks, values, tables, toff, ht, hs, he, off,
                  di.astype(np.int64), dj.astype(np.int64), w.astype(np.float64), out, col)
    return out, off, col
