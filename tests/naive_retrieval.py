"""Slow, obviously correct references for mocapdb.retrieval's kernels.

* :func:`naive_select_hits` — the retrieval hits restated on intervals: among
  the frames with Δ <= τ (local minima only, if asked) not yet looked at,
  take the cheapest (earliest on ties); its path [s, e] is a hit unless it
  shares a frame with an earlier hit or a forbidden stretch; stop at
  ``limit`` hits.
* :func:`naive_weighted_costs` — the feature-weighted local cost of a
  template column against a frame, feature by feature.
* :func:`naive_words_of_runs` — a document's words from its runs, frame by frame.
"""
import numpy as np


def naive_select_hits(delta, starts, offsets, task_first, tau, limit, taken=None, minima=False):
    """Hits per task as a list of (task, start, end, cost), task-local frames, cost order within a task.

    With ``minima`` only frames no neighbour (within the task) undercuts may end a hit."""
    out = []
    for q in range(len(offsets) - 1):
        a, b = offsets[q], offsets[q + 1]
        forbidden = [j - a for j in range(a, b) if taken is not None and taken[j]]
        hits = []
        seen = set()
        while len(hits) < limit:
            best = None
            for j in range(a, b):
                if j - a in seen or not delta[j] <= tau:
                    continue
                if minima and ((j > a and delta[j - 1] < delta[j]) or (j + 1 < b and delta[j + 1] < delta[j])):
                    continue
                if best is None or delta[j] < delta[best]:
                    best = j
            if best is None:
                break
            e = best - a
            seen.add(e)
            s = starts[best] - task_first[q]
            clash = any(not (e < hs or he < s) for _, hs, he, _ in hits) or any(s <= f <= e for f in forbidden)
            if not clash:
                hits.append((q, s, e, float(delta[best])))
        out.extend(hits)
    return out


def naive_weighted_costs(template_dense, column_weights, feature_weights, frames):
    """C[i, j] = (w_i + 1)/2 / K · Σ_f W[i, f]·[f fixed and differs] / Σ_f W[i, f]·[f fixed].

    template_dense (K, 40) of 0/1/0.5, frames (n, 40) of 0/1.
    """
    K = template_dense.shape[0]
    C = np.zeros((K, frames.shape[0]))
    for i in range(K):
        total = sum(feature_weights[i, f] for f in range(40) if template_dense[i, f] != 0.5)
        for j in range(frames.shape[0]):
            if total == 0:
                continue
            s = 0.0
            for f in range(40):
                if template_dense[i, f] != 0.5 and template_dense[i, f] != frames[j, f]:
                    s += feature_weights[i, f]
            C[i, j] = s / total * (column_weights[i] + 1.0) / 2.0 / K
    return C


def naive_words_of_runs(starts, lengths, words, n_frames):
    """The frame-by-frame word sequence of one document's runs."""
    out = np.zeros(n_frames, np.uint64)
    for s, n, w in zip(starts, lengths, words):
        for f in range(s, s + n):
            out[f] = w
    return out
