"""Retrieval hits: the non-overlapping local minima of Δ, cheapest first.

The annotation takes every local minimum of Δ below τ as a hit and lets hits
of one class overlap (the toolbox's rule, paper Sect. 4); a retrieval answer
is a ranked list of distinct places, so here a hit is only taken when it
overlaps no cheaper hit and no excluded stretch (the query itself). The
length of a hit needs no rule of its own: the annotation steps (1,1), (1,2),
(2,1) bound a match of a K-column template to ⌈K/2⌉ … 2K − 1 frames, i.e.
½ to 2 times the query.

* :func:`select_hits` — per task (a slice of Δ), the greedy selection;
* :func:`best_hits` — the ``limit`` best hits of several batches, ranked.
"""
from __future__ import annotations

import numpy as np

from mocapdb.errors import ParameterError, check_nonnegative
from mocapdb.retrieval.kernels import _select_hits_kernel

#: one hit: ``task`` indexes the tasks of the call (or a caller's documents), frames 0-based inclusive
HIT_DTYPE = np.dtype([("task", np.int64), ("start", np.int64), ("end", np.int64), ("cost", np.float64)])


def check_limit(limit) -> int:
    """``limit`` as a positive int (ParameterError otherwise), at most 2**62: hits never outnumber the
    archive's frames, and the kernels count in int64 (a limit of 10**20 meant "all of them")."""
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 1:
        raise ParameterError(f"limit must be a positive integer, got {limit!r}")
    return min(int(limit), 1 << 62)


def select_hits(delta, starts, offsets, task_first, *, tau, limit, taken=None, minima=False):
    """Non-overlapping hits of Δ per task, cheapest first (the module docstring).

    Parameters
    ----------
    delta : (N,) float64
        Δ of every task, concatenated (+inf where no path ends).
    starts : (N,) int64
        Word index of the first frame of the Δ path ending at each frame
        (:func:`mocapdb.templates.mt_distance_slices` with ``return_starts``).
    offsets : (n_tasks + 1,) int64
        Task q owns ``delta[offsets[q]:offsets[q+1]]``.
    task_first : (n_tasks,) int64
        Word index of each task's first frame.
    tau : float
        Only frames with Δ <= τ end a hit.
    limit : int
        At most this many hits per task.
    taken : (N,) bool, optional
        Frames no hit may touch (e.g. the query's own stretch); not modified.
    minima : bool, default False
        Only frames where Δ is a local minimum (no neighbour lower) end
        hits: far fewer candidates, for a coarse look (a frame next to a
        rejected minimum can no longer become a hit).

    Returns
    -------
    ndarray of HIT_DTYPE
        Per task in task order, its hits in cost order; ``start``/``end``
        relative to the task's first frame, inclusive.
    """
    d = np.ascontiguousarray(delta, dtype=np.float64)
    s = np.ascontiguousarray(starts, dtype=np.int64)
    off = np.ascontiguousarray(offsets, dtype=np.int64)
    first = np.ascontiguousarray(task_first, dtype=np.int64)
    if d.ndim != 1 or s.shape != d.shape or off.ndim != 1 or off.size < 1 or first.shape != (off.size - 1,) \
            or off[0] != 0 or off[-1] != d.size or (np.diff(off) < 0).any():
        raise ParameterError("delta and starts (N,), offsets (n_tasks + 1,) from 0 to N and task_first "
                             "(n_tasks,) must agree")
    if np.isnan(d).any():
        raise ParameterError("delta must not contain NaN (use +inf for 'no path')")
    tau = check_nonnegative(tau, "tau")
    limit = check_limit(limit)
    n_tasks = off.size - 1
    ok = d <= tau
    if ok.any():
        task_of = np.repeat(np.arange(n_tasks), np.diff(off))[ok]
        local = s[ok] - first[task_of]
        if (local < 0).any() or (local > (np.flatnonzero(ok) - off[task_of])).any():
            raise ParameterError("starts must lie within each task, at or before the frame of their path's end")
    mark = np.zeros(d.size, np.bool_) if taken is None else np.array(taken, dtype=np.bool_, copy=True)
    if mark.shape != d.shape:
        raise ParameterError(f"taken must have the shape of delta {d.shape}, got {mark.shape}")
    cap = np.minimum(np.diff(off), limit)  # a task's hits never outnumber its frames
    out_off = np.concatenate(([0], np.cumsum(cap))).astype(np.int64)
    hs = np.empty(int(out_off[-1]), np.int64)
    he = np.empty_like(hs)
    hc = np.empty(int(out_off[-1]))
    n_hits = np.empty(n_tasks, np.int64)
    _select_hits_kernel(d, s, off, first, tau, bool(minima), limit, mark, out_off, hs, he, hc, n_hits)
    first_hit = np.cumsum(n_hits) - n_hits
    keep = np.repeat(out_off[:-1] - first_hit, n_hits) + np.arange(int(n_hits.sum()))
    out = np.empty(keep.size, HIT_DTYPE)
    out["task"] = np.repeat(np.arange(n_tasks), n_hits)
    out["start"], out["end"], out["cost"] = hs[keep], he[keep], hc[keep]
    return out


def best_hits(parts, limit, *, key=("cost", "task", "start")):
    """The ``limit`` best hits of several arrays: sorted by ``key`` (cost, then place), cut.

    Parameters
    ----------
    parts : sequence of structured arrays
        Hits with at least the ``key`` fields (same dtype).
    limit : int
    key : tuple of str
        Sort fields, most significant first; later fields break ties
        deterministically.

    Returns
    -------
    structured ndarray
    """
    parts = [p for p in parts if p is not None]
    if not parts:
        return np.empty(0, HIT_DTYPE)
    hits = np.concatenate(parts)
    order = np.lexsort(tuple(hits[k] for k in reversed(key)))
    return hits[order[:check_limit(limit)]]


__all__ = ["HIT_DTYPE", "select_hits", "best_hits", "check_limit"]
