"""Each class's own local path cost on its training clips: the scale of :mod:`mocapdb.annotation.path_contest`.

A template explains its own motion at some typical local cost per frame
(coarse templates cheaply, detailed ones less so). The cost of its path on
frames where it competes with another label's hit means little until it is
put against that: ``path_scale`` is a quantile of the per-frame local cost
along the best path of the template on each of its training clips (mirror
images for mirrored classes). Classes without clips (designed, reversed)
take the median ratio of scale to τ of the learned classes times their own τ.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from mocapdb.annotation.model import Model
from mocapdb.templates import ANNOTATION_STEPS, mt_distance_slices
from mocapdb.templates.paths import path_local_costs
from lab.recipe import build_model, recipe_clips

__all__ = ["path_scales", "with_path_scales"]


def _own_path_costs(model: Model, held) -> dict:
    """Class → the local costs along its best path on each of the given clips of its own (class → words)."""
    out = {}
    for c in model.classes:
        own = [np.asarray(w, dtype=np.uint64) for w in held.get(c.name, ())]
        own = [w for w in own if w.size]
        if not own:
            continue
        flat = np.concatenate(own)
        bounds = np.concatenate(([0], np.cumsum([w.size for w in own]))).astype(np.int64)
        n = len(own)
        delta, offsets, starts = mt_distance_slices(flat, [c.quantized], np.zeros(n, np.int64), bounds[:-1],
                                                    bounds[1:], steps=ANNOTATION_STEPS, return_starts=True)
        hs, he = [], []
        for d in range(n):
            seg = delta[offsets[d]:offsets[d + 1]]
            if seg.size and np.isfinite(seg).any():
                e = int(np.argmin(seg))
                hs.append(int(starts[offsets[d] + e]))
                he.append(int(bounds[d] + e))
        if hs:
            costs, _, cols = path_local_costs(flat, [c.quantized], np.zeros(len(hs), np.int64), hs, he)
            ok = np.isfinite(costs)
            out[c.name] = (costs[ok], cols[ok] / max(1, len(c.quantized.expand()) - 1))  # column as a fraction
    return out


def path_scales(clips, recipe, *, q=0.5, cache=None, model=None, per_column=False, K_of=None) -> dict:
    """Class → the ``q`` quantile of its local path cost on its own clips of groups its template did not see.

    Leave-one-group-out as :func:`lab.thresholds.learn_taus`: in-sample a
    quantized template matches its own clips almost everywhere at cost 0.
    """
    every = recipe_clips(clips, recipe)
    groups = sorted({x.group for v in every.values() for x in v})
    pooled = {}
    if model is not None:  # in-sample: the model's templates on the clips they were learned from
        groups = []
        for c, costs in _own_path_costs(model, {c: [x.words for x in v] for c, v in every.items()}).items():
            pooled[c] = [costs]
    ks = {}
    for g in groups:
        held = {c: [x.words for x in v if x.group == g] for c, v in every.items()}
        if not any(held.values()):
            continue
        rest = {c: [x for x in v if x.group != g] for c, v in clips.items()}
        model = build_model(rest, recipe, name=f"without_{g}", cache=cache)
        for c, costs in _own_path_costs(model, held).items():
            pooled.setdefault(c, []).append(costs)
    stat = (lambda x: float(x.mean())) if q == "mean" else (lambda x: float(np.quantile(x, q)))
    out = {}
    for c, v in pooled.items():
        cost = np.concatenate([x[0] for x in v])
        if not cost.size:
            continue
        if not per_column:
            out[c] = stat(cost)
            continue
        # per (expanded) column: the column's own mean, shrunk towards the template's (few frames per column)
        K = K_of[c]  # folds' templates differ in length: columns by their place in the template
        col = np.rint(np.concatenate([x[1] for x in v]) * (K - 1)).astype(np.int64)
        n = np.bincount(col, minlength=K)[:K].astype(float)
        tot = np.bincount(col, weights=cost, minlength=K)[:K]
        prior, k0 = stat(cost), 5.0
        out[c] = (tot + k0 * prior) / (n + k0)
    return out


def with_path_scales(model: Model, scales) -> Model:
    """A copy of ``model`` with ``path_scale`` per class; classes without one: τ × the learned classes' median ratio."""
    ratio = [np.mean(scales[c.name]) / c.tau for c in model.classes if c.name in scales and c.tau > 0]
    r = float(np.median(ratio)) if ratio else 1.0
    return dataclasses.replace(model, classes=tuple(
        dataclasses.replace(c, path_scale=scales.get(c.name, r * c.tau)) for c in model.classes))
