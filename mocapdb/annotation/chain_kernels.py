"""Numba kernels of the annotation chain (:mod:`mocapdb.annotation.chain`).

Hit extraction (TEMPLATES.md §9.1), segment runs and merging (§10.3), the
scatter of per-task results into per-class / per-label rows, and the
post-processing filters (:mod:`mocapdb.annotation.postprocess`).
"""
import numba
import numpy as np

from mocapdb._numba import jit, pjit, prange

@pjit
def _count_candidates_kernel(delta, offsets, tau, out):  # pragma: no cover
    """out[q] = number of frames of task q with Δ <= tau[q]."""
    for q in prange(offsets.shape[0] - 1):
        n = 0
        for j in range(offsets[q], offsets[q + 1]):
            if delta[j] <= tau[q]:
                n += 1
        out[q] = n


@jit
def _sort_by_key(idx, tmp, n, key, a):  # pragma: no cover
    """Stable sort of idx[:n] by key[a + idx[k]], in place (tmp: n scratch slots).

    Insertion sort of runs of 16, then bottom-up merges (ties keep the
    earlier element): the order of ``np.argsort(kind="mergesort")`` without
    allocating. Keys must not be NaN.
    """
    run = 16
    for lo in range(0, n, run):
        hi = min(lo + run, n)
        for i in range(lo + 1, hi):
            x = idx[i]
            v = key[a + x]
            k = i - 1
            while k >= lo and key[a + idx[k]] > v:
                idx[k + 1] = idx[k]
                k -= 1
            idx[k + 1] = x
    src, dst = idx, tmp
    in_tmp = False
    width = run
    while width < n:
        for lo in range(0, n, 2 * width):
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i, j = lo, mid
            for k in range(lo, hi):
                if j >= hi or (i < mid and key[a + src[i]] <= key[a + src[j]]):
                    dst[k] = src[i]
                    i += 1
                else:
                    dst[k] = src[j]
                    j += 1
        src, dst = dst, src
        in_tmp = not in_tmp
        width *= 2
    if in_tmp:
        for k in range(n):
            idx[k] = tmp[k]


@pjit
def _extract_hits_kernel(delta, starts, offsets, task_first, tau, limit, cap_off, want_hits,
                         cd, hit_start, hit_end, hit_cost, n_hits, cand_buf,
                         tmp_buf):  # pragma: no cover
    """Hit extraction (§9.1) for many tasks (slices of the flat Δ) in parallel.

    Task q owns delta[offsets[q]:offsets[q+1]]; starts are word indices,
    task_first[q] the word index of its first frame. Repeatedly taking the
    first minimum of Δ over the frames not yet excluded equals walking the
    frames with Δ <= τ in (Δ, frame) order and skipping excluded ones, since
    exclusion only raises values to +inf. A frame is excluded once a hit
    covers it, i.e. once its cd is no longer +inf (hit costs are <= τ, never
    +inf). Writes cd (Δ̄^τ) over the task and, if want_hits, at most
    min(#candidates, limit) hits at cap_off[q]...; n_hits[q] = count, or -1
    if the limit was reached (the toolbox raises an error then).
    cand_buf, tmp_buf: one row of scratch per worker thread
    (numba.get_thread_id()), at least as long as any task's candidate count.
    """
    for q in prange(offsets.shape[0] - 1):
        tid = numba.get_thread_id()
        cand = cand_buf[tid]
        a = offsets[q]
        n = offsets[q + 1] - a
        ncand = np.int64(0)
        for j in range(n):
            cd[a + j] = np.inf
            if delta[a + j] <= tau[q]:
                cand[ncand] = j
                ncand += 1
        _sort_by_key(cand, tmp_buf[tid], ncand, delta, a)
        h = 0
        o = cap_off[q]
        for k in range(ncand):
            e = cand[k]
            if cd[a + e] < np.inf:
                continue
            cost = delta[a + e]
            s = starts[a + e] - task_first[q]
            for f in range(s, e + 1):
                if cd[a + f] == np.inf:
                    cd[a + f] = cost
            if want_hits:
                hit_start[o + h] = s
                hit_end[o + h] = e
                hit_cost[o + h] = cost
            h += 1
            if h == limit:
                h = -1
                break
        n_hits[q] = h


@jit
def _best_label(cdl, f):  # pragma: no cover
    """Δarg at frame f: the first label with the minimal cd, -1 where all are +inf."""
    lab = -1
    best = np.inf
    for p in range(cdl.shape[0]):
        if cdl[p, f] < best:
            best = cdl[p, f]
            lab = p
    return lab


@jit
def _segments_kernel(cdl, bounds, out_label, out_doc, out_start, out_end,
                     out_cost):  # pragma: no cover
    """Runs of Δarg extended along their label's cd (§10.3), per document.

    cdl (n_labels, N); documents bounds[d]:bounds[d+1]. Writes one record per
    run (label, doc, start, end in N's frames, cost); returns the count.
    """
    r = 0
    for d in range(bounds.shape[0] - 1):
        a = bounds[d]
        b = bounds[d + 1]
        f = a
        prev = -1
        run_start = a
        while f <= b:
            lab = _best_label(cdl, f) if f < b else -1
            if f == b or lab != prev:
                if prev >= 0 and f > a:
                    # run [run_start, f-1] of label prev: extend outward while the
                    # label's cd does not increase; cost = min at the two ends
                    s = run_start
                    s_cost = cdl[prev, s]
                    while s - 1 >= a and cdl[prev, s - 1] <= s_cost:
                        s -= 1
                        s_cost = cdl[prev, s]
                    e = f - 1
                    e_cost = cdl[prev, e]
                    while e + 1 < b and cdl[prev, e + 1] <= e_cost:
                        e += 1
                        e_cost = cdl[prev, e]
                    out_label[r] = prev
                    out_doc[r] = d
                    out_start[r] = s - a
                    out_end[r] = e - a
                    out_cost[r] = min(s_cost, e_cost)
                    r += 1
                prev = lab
                run_start = f
            f += 1
    return r


@jit
def _merge_kernel(label, doc, start, end, cost):  # pragma: no cover
    """Merge overlapping records of the same (label, doc), sorted by (label, doc, start).

    Overlap means sharing a frame (start <= previous end); merged ranges are
    unions with the minimal cost. In place; returns the number kept.
    """
    n = label.shape[0]
    if n == 0:
        return 0
    k = 0
    for i in range(1, n):
        if label[i] == label[k] and doc[i] == doc[k] and start[i] <= end[k]:
            end[k] = max(end[k], end[i])
            cost[k] = min(cost[k], cost[i])
        else:
            k += 1
            label[k] = label[i]
            doc[k] = doc[i]
            start[k] = start[i]
            end[k] = end[i]
            cost[k] = cost[i]
    return k + 1


@jit
def _scatter_kernel(flat, offsets, row, first, out):  # pragma: no cover
    """out[row[q], first[q]:...] = flat[offsets[q]:offsets[q+1]], tasks in order
    (a later slice overwrites an earlier overlapping one, as in annotationScript.m)."""
    for q in range(row.shape[0]):
        a = offsets[q]
        for j in range(offsets[q + 1] - a):
            out[row[q], first[q] + j] = flat[a + j]


@jit
def _label_scatter_kernel(flat, offsets, row, first, label, stamp, out):  # pragma: no cover
    """Per label, the minimum over its classes of each class's tasks scattered as
    :func:`_scatter_kernel` does (a later task of a class overwrites an earlier one):
    tasks are visited last to first and a frame takes a class's value only once
    (``stamp`` remembers the last class that wrote it). ``out`` starts at +inf."""
    for q in range(row.shape[0] - 1, -1, -1):
        c = row[q]
        lab = label[c]
        a = offsets[q]
        for j in range(offsets[q + 1] - a):
            f = first[q] + j
            if stamp[f] != c:
                stamp[f] = c
                v = flat[a + j]
                if v < out[lab, f]:
                    out[lab, f] = v


@jit
def _margin_kernel(cdl, margin):  # pragma: no cover
    """Frames whose best label beats the second best by less than ``margin``: every label +inf.

    cdl (n_labels, N) in place. A frame with a single finite label keeps it.
    """
    L, N = cdl.shape
    for f in range(N):
        best = np.inf
        second = np.inf
        for p in range(L):
            v = cdl[p, f]
            if v < best:
                second = best
                best = v
            elif v < second:
                second = v
        if best < np.inf and second - best < margin:
            for p in range(L):
                cdl[p, f] = np.inf


@jit
def _won_kernel(cdl, seg_label, seg_first, seg_last, out):  # pragma: no cover
    """out[s] = frames of [seg_first[s], seg_last[s]] whose Δarg is seg_label[s].

    Δarg as the segmenter's (§10.3): the first label with the minimal cd; a
    frame where every label is +inf belongs to none.
    """
    for s in range(seg_label.shape[0]):
        n = 0
        for f in range(seg_first[s], seg_last[s] + 1):
            if _best_label(cdl, f) == seg_label[s]:
                n += 1
        out[s] = n


@jit
def _segment_min_kernel(x, seg_label, seg_first, seg_last, out):  # pragma: no cover
    """out[s] = min of x[seg_label[s], seg_first[s] … seg_last[s]] (+inf if the segment is empty)."""
    for s in range(seg_label.shape[0]):
        best = np.inf
        row = seg_label[s]
        for f in range(seg_first[s], seg_last[s] + 1):
            if x[row, f] < best:
                best = x[row, f]
        out[s] = best
