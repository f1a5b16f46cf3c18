"""Numba kernels of retrieval: hits (:mod:`mocapdb.retrieval.hits`), words from runs (:mod:`mocapdb.retrieval.archive`).

* the greedy selection of non-overlapping minima of Δ per task, cheapest
  first, frames already taken (earlier hits, the query's own stretch) being
  off limits;
* a document's words from its runs of constant word (the keyframe index).
"""
import numpy as np

from mocapdb._numba import jit, pjit, prange


@jit
def _candidate(delta, a, b, j, tau, minima):  # pragma: no cover
    """Whether frame j of the task delta[a:b] may end a hit: Δ <= tau, and with ``minima``
    no neighbour lower (a local minimum)."""
    v = delta[j]
    if not v <= tau:
        return False
    if minima:
        if j > a and delta[j - 1] < v:
            return False
        if j + 1 < b and delta[j + 1] < v:
            return False
    return True


@pjit
def _select_hits_kernel(delta, starts, offsets, task_first, tau, minima, limit, taken, out_off,
                        hit_start, hit_end, hit_cost, n_hits):  # pragma: no cover
    """Non-overlapping hits of many tasks (slices of a flat Δ), in parallel.

    Task q owns ``delta[offsets[q]:offsets[q+1]]``; ``starts`` are word
    indices of each Δ path's first frame, ``task_first[q]`` the word index of
    the task's first frame. The candidate frames (:func:`_candidate`) are
    visited in (Δ, frame) order; a frame's path [s, e] becomes a hit when none of its
    frames is taken (``taken``, flat like delta, starts with the frames no
    hit may touch), and then takes them. At most ``limit`` hits per task are
    written at ``out_off[q]`` (task-local frames, cost order); ``n_hits[q]``
    their number. Tasks write only their own part of ``taken`` and outputs.
    """
    for q in prange(offsets.shape[0] - 1):
        a = offsets[q]
        n = offsets[q + 1] - a
        cand = np.empty(n, np.int64)
        k = 0
        for j in range(n):
            if _candidate(delta, a, a + n, a + j, tau, minima):
                cand[k] = j
                k += 1
        cand = cand[:k]
        # stable: equal costs keep frame order
        order = np.argsort(delta[a + cand], kind="mergesort")
        h = 0
        o = out_off[q]
        for r in range(k):
            if h >= limit:
                break
            e = cand[order[r]]
            if taken[a + e]:
                continue
            s = starts[a + e] - task_first[q]
            free = True
            f = e - 1
            while f >= s:
                if taken[a + f]:
                    free = False
                    break
                f -= 1
            if not free:
                continue
            for f in range(s, e + 1):
                taken[a + f] = True
            hit_start[o + h] = s
            hit_end[o + h] = e
            hit_cost[o + h] = delta[a + e]
            h += 1
        n_hits[q] = h


@pjit
def _runs_to_words_kernel(seg_offset, seg_start, seg_len, seg_wid, words, doc, start, stop, out_off,
                          out):  # pragma: no cover
    """Words of frame ranges from runs of constant word, in parallel over the ranges.

    Document d's runs are ``seg_offset[d]:seg_offset[d+1]`` (first frame
    ``seg_start``, length ``seg_len``, word ``words[seg_wid]``), tiling it.
    Range q, frames ``start[q]:stop[q]`` of document ``doc[q]``, is written
    to ``out[out_off[q]:out_off[q] + stop[q] - start[q]]``.
    """
    for q in prange(doc.shape[0]):
        a = seg_offset[doc[q]]
        b = seg_offset[doc[q] + 1]
        # the last run starting at or before the range's first frame
        lo = a
        hi = b - 1
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if seg_start[mid] <= start[q]:
                lo = mid
            else:
                hi = mid - 1
        g = lo
        o = out_off[q] - start[q]
        for f in range(start[q], stop[q]):
            while seg_start[g] + seg_len[g] <= f:
                g += 1
            out[o + f] = words[seg_wid[g]]
