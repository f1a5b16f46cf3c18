"""Genetic operators on keyframe queries (paper Sect. 6, KEYFRAMES.md §8.2).

Initialisation (:func:`random_query`, :func:`gap_bounds`), parent selection
(:func:`stochastic_universal_sampling`), :func:`recombine` and :func:`mutate`.
The GA loop of :mod:`mocapdb.learning.genetic` calls the private genome
functions underneath them directly.
"""
from __future__ import annotations

import bisect
import math
from typing import NamedTuple

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.features import N_FEATURES
from mocapdb.keyframes import UNBOUNDED, KeyframeQuery
from mocapdb.templates import QuantizedTemplate

_ALL40 = (1 << N_FEATURES) - 1

#: mutation operations and their probabilities: the paper's three kinds
#: (add/remove a keyframe; specialise/generalise an entry; change a gap
#: bound) equally likely, each kind's two directions equally likely (proposed)
MUTATIONS = {"add": 1 / 6, "remove": 1 / 6, "specialise": 1 / 6, "generalise": 1 / 6,
             "gap": 1 / 3}


# --------------------------------------------------------------------------
# operators
#
# The GA loop works on light genomes (lists of Python ints) and builds one
# validated KeyframeQuery per offspring: numpy calls on 1-8 element arrays and
# the query's validation would otherwise cost more than the search itself.
# The public operators wrap the same functions.


def _rng(random_state):
    return np.random.default_rng(random_state)


class _Genome(NamedTuple):
    """An individual as lists: keyframe words, positions, gap bounds."""

    mask: list
    value: list
    pos: list
    d_min: list
    d_max: list


class _Columns(NamedTuple):
    """The quantized templates' columns as lists of Python ints."""

    strict_mask: list
    strict_value: list
    loose_mask: list
    loose_value: list
    length: int


def _columns(strict: QuantizedTemplate, loose: QuantizedTemplate = None) -> _Columns:
    loose = strict if loose is None else loose
    if len(loose) != len(strict):
        raise ParameterError(f"strict and loose templates differ in length ({len(strict)} vs "
                             f"{len(loose)}); quantize the same MotionTemplate twice")
    return _Columns(strict.mask.tolist(), strict.value.tolist(), loose.mask.tolist(),
                    loose.value.tolist(), len(strict))


def _genome(q: KeyframeQuery) -> _Genome:
    return _Genome(q.mask.tolist(), q.value.tolist(), q.positions.tolist(), q.d_min.tolist(),
                   q.d_max.tolist())


def _to_query(g: _Genome, length: int) -> KeyframeQuery:
    return KeyframeQuery(np.array(g.mask, np.uint64), np.array(g.value, np.uint64),
                         np.array(g.pos, np.int64), np.array(g.d_min, np.int64),
                         np.array(g.d_max, np.int64), length)


def _randint(rng, n):
    """Uniform integer in 0..n-1 (n >= 1)."""
    return min(int(rng.random() * n), n - 1)


def _sample(rng, n, k):
    """k distinct integers of 0..n-1, ascending."""
    if k == 0:
        return []
    return sorted(np.argsort(rng.random(n), kind="stable")[:k].tolist())


def _gaps(pos, rng, tolerance):
    n = len(pos) - 1
    if n <= 0:
        return [], []
    lo, hi = tolerance
    u = (lo + (hi - lo) * rng.random(n)).tolist()
    d_min, d_max = [], []
    for g in range(n):
        delta = pos[g + 1] - pos[g]
        d_min.append(max(math.floor(delta * (1.0 - u[g])), 0))
        d_max.append(math.ceil(delta * (1.0 + u[g])))
    return d_min, d_max


def _random_genome(cols: _Columns, rng, mean_keyframes, std_keyframes, max_keyframes,
                   tolerance) -> _Genome:
    L = cols.length
    n = int(min(max(round(rng.normal(mean_keyframes, std_keyframes)), 1),
                min(max_keyframes, L)))
    pos = _sample(rng, L, n)
    d_min, d_max = _gaps(pos, rng, tolerance)
    return _Genome([cols.strict_mask[c] for c in pos], [cols.strict_value[c] for c in pos],
                   pos, d_min, d_max)


def _recombine(a: _Genome, b: _Genome, rng, tolerance) -> _Genome:
    ka, kb = len(a.pos), len(b.pos)
    na, nb = _randint(rng, ka + 1), _randint(rng, kb + 1)
    if na + nb == 0:
        if rng.random() < 0.5:
            na = 1
        else:
            nb = 1
    # (position, parent, rank): sorting merges by position, parent a first
    picked = sorted([(a.pos[i], 0, i) for i in _sample(rng, ka, na)]
                    + [(b.pos[i], 1, i) for i in _sample(rng, kb, nb)])
    mask, value, pos, seen = [], [], [], set()
    for p, src, i in picked:
        par = b if src else a
        key = (p, par.mask[i], par.value[i])
        if key not in seen:  # the same keyframe of both parents once
            seen.add(key)
            mask.append(par.mask[i])
            value.append(par.value[i])
            pos.append(p)
    d_min, d_max = _gaps(pos, rng, tolerance)
    return _Genome(mask, value, pos, d_min, d_max)


def _bits(word: int) -> list:
    return [i for i in range(N_FEATURES) if (word >> i) & 1]


def _applicable(g: _Genome) -> list:
    ops = ["add"]
    if len(g.pos) > 1:
        ops += ["remove", "gap"]
    if any(m != _ALL40 for m in g.mask):
        ops.append("specialise")
    if any(m != 0 for m in g.mask):
        ops.append("generalise")
    return ops


def _mutate(g: _Genome, cols: _Columns, rng, operation, tolerance, gap_step) -> _Genome:
    if operation is None:
        ops = _applicable(g)
        w = [MUTATIONS[o] for o in ops]
        x = rng.random() * sum(w)
        operation = ops[-1]
        for o, wo in zip(ops, w):
            if x < wo:
                operation = o
                break
            x -= wo
    mask, value, pos = list(g.mask), list(g.value), list(g.pos)
    d_min, d_max = list(g.d_min), list(g.d_max)
    K = len(pos)
    if operation == "add":
        col = _randint(rng, cols.length)
        k = bisect.bisect_right(pos, col)  # after the keyframes at positions <= col
        mask.insert(k, cols.strict_mask[col])
        value.insert(k, cols.strict_value[col])
        pos.insert(k, col)
        lo, hi = _gaps(pos[max(k - 1, 0):k + 2], rng, tolerance)
        # the new gaps (prev -> new, new -> next) replace the old gap k-1
        a, b = max(k - 1, 0), min(k, K - 1)
        d_min[a:b] = lo
        d_max[a:b] = hi
    elif operation == "remove":
        k = _randint(rng, K)
        if 0 < k < K - 1:  # inner keyframe: its two gaps merge
            d_min[k - 1] += d_min[k]
            d_max[k - 1] = min(d_max[k - 1] + d_max[k], UNBOUNDED)
        g_del = min(k, K - 2)
        del mask[k], value[k], pos[k], d_min[g_del], d_max[g_del]
    elif operation == "specialise":
        cand = [k for k in range(K) if mask[k] != _ALL40]
        k = cand[_randint(rng, len(cand))]
        free = _bits(_ALL40 & ~mask[k])
        b = free[_randint(rng, len(free))]
        col = pos[k]
        if col < len(cols.loose_mask) and (cols.loose_mask[col] >> b) & 1:
            bit = (cols.loose_value[col] >> b) & 1
        else:
            bit = _randint(rng, 2)
        mask[k] |= 1 << b
        value[k] |= bit << b
    elif operation == "generalise":
        cand = [k for k in range(K) if mask[k] != 0]
        k = cand[_randint(rng, len(cand))]
        fixed = _bits(mask[k])
        b = fixed[_randint(rng, len(fixed))]
        mask[k] &= ~(1 << b)
        value[k] &= ~(1 << b)
    elif operation == "gap":
        gi = _randint(rng, K - 1)
        delta = pos[gi + 1] - pos[gi]
        step = 1 + _randint(rng, max(1, math.ceil(gap_step * delta)))
        if rng.random() < 0.5:
            step = -step
        if rng.random() < 0.5:
            d_min[gi] = min(max(d_min[gi] + step, 0), d_max[gi])
        else:
            d_max[gi] = max(min(d_max[gi] + step, UNBOUNDED), d_min[gi])
    return _Genome(mask, value, pos, d_min, d_max)


def gap_bounds(positions, *, random_state=None, tolerance=(0.2, 1.0)):
    """Gap bounds from keyframe positions with a random tolerance (initialisation).

    For every gap with column distance Δ a tolerance u ~ U[lo, hi) gives
    ``d_min = floor(Δ·(1-u))``, ``d_max = ceil(Δ·(1+u))`` (proposed form of
    the paper's "distances of the chosen keyframes admitting some randomly
    chosen tolerance").

    Parameters
    ----------
    positions : (K,) int, non-decreasing
    random_state : None, int or numpy.random.Generator
    tolerance : (float, float), default (0.2, 1.0)

    Returns
    -------
    d_min, d_max : (K-1,) int64
    """
    d_min, d_max = _gaps(np.asarray(positions, dtype=np.int64).tolist(), _rng(random_state),
                         tolerance)
    return np.array(d_min, np.int64), np.array(d_max, np.int64)


def random_query(strict: QuantizedTemplate, *, random_state=None, mean_keyframes=3.0,
                 std_keyframes=1.0, max_keyframes=8, tolerance=(0.2, 1.0)) -> KeyframeQuery:
    """One individual of the initial population Π⁰.

    N = round(normal(mean, std)) clipped to [1, min(max_keyframes, L)]; N
    distinct template columns drawn at random and sorted are the keyframes;
    gap bounds by :func:`gap_bounds`.

    Parameters
    ----------
    strict : QuantizedTemplate
        The δ = 0 quantized template of T+ (L columns).
    random_state : None, int or numpy.random.Generator
    mean_keyframes : float, default 3.0
        The paper's mean.
    std_keyframes : float, default 1.0
        (proposed)
    max_keyframes : int, default 8
        (proposed) upper clip of N.
    tolerance : (float, float), default (0.2, 1.0)
        (proposed) see :func:`gap_bounds`.

    Returns
    -------
    KeyframeQuery
        40-bit keyframes, 0-based positions, ``template_length = L``.

    References
    ----------
    Paper Sect. 6 (initialisation); KEYFRAMES.md §8.2.
    """
    g = _random_genome(_columns(strict), _rng(random_state), mean_keyframes, std_keyframes,
                       max_keyframes, tolerance)
    return _to_query(g, len(strict))


def stochastic_universal_sampling(fitness, n, *, random_state=None) -> np.ndarray:
    """Select ``n`` individuals with probability proportional to fitness (SUS).

    n equally spaced pointers (spacing ΣF/n, random offset in [0, ΣF/n)) on
    the cumulative fitness; individual i is selected once per pointer in its
    slice, i.e. ⌊n·F_i/ΣF⌋ or ⌈n·F_i/ΣF⌉ times (Baker 1987).  If every
    fitness is 0 all individuals get equal weight (proposed).

    Parameters
    ----------
    fitness : (M,) float, >= 0
    n : int
    random_state : None, int or numpy.random.Generator

    Returns
    -------
    (n,) int64
        Selected indices, ascending (repeats possible).
    """
    f = np.asarray(fitness, dtype=np.float64)
    if f.ndim != 1 or len(f) == 0:
        raise ParameterError(f"fitness must be a non-empty 1-D array, got shape {f.shape}")
    if not np.isfinite(f).all() or (f < 0).any():
        raise ParameterError("fitness must be finite and >= 0")
    return _sus(f, int(n), _rng(random_state))


def _sus(f, n, rng):
    total = f.sum()
    if total <= 0:
        f = np.ones_like(f)
        total = float(len(f))
    step = total / n
    pointers = rng.random() * step + step * np.arange(n)
    idx = np.searchsorted(np.cumsum(f), pointers, side="right")
    return np.minimum(idx, len(f) - 1)


def recombine(a: KeyframeQuery, b: KeyframeQuery, *, random_state=None,
              tolerance=(0.2, 1.0)) -> KeyframeQuery:
    """One offspring of two parents (paper Sect. 6, recombination).

    A random number of keyframes, uniform in 0..K, is drawn from each parent
    (a random subset of that size; if both are empty, one keyframe of a
    random parent); the keyframes are merged by template position (parent
    ``a`` first at equal positions) and identical (position, mask, value)
    duplicates are kept once (proposed); gap bounds are recomputed from the
    positions as in the initialisation (:func:`gap_bounds`).

    Returns
    -------
    KeyframeQuery
    """
    g = _recombine(_genome(a), _genome(b), _rng(random_state), tolerance)
    return _to_query(g, max(a.template_length, b.template_length))


def mutate(query: KeyframeQuery, strict: QuantizedTemplate, loose: QuantizedTemplate, *,
           random_state=None, operation=None, tolerance=(0.2, 1.0),
           gap_step=0.25) -> KeyframeQuery:
    """Apply one random mutation (paper Sect. 6).

    Operations (chosen with the probabilities :data:`MUTATIONS` among those
    applicable to the query):

    * ``add``: a random column of ``strict`` becomes a new keyframe, inserted
      after the keyframes at positions <= its column; the gaps to its
      neighbours get bounds as in :func:`gap_bounds`.
    * ``remove``: a random keyframe is removed (K >= 2); the two gaps around
      an inner keyframe merge into one with summed bounds (proposed).
    * ``specialise``: a random wildcard entry of a random keyframe (with a
      wildcard) gets the value of the δ = 0.05 template ``loose`` at that
      keyframe's column, or a random bit where ``loose`` has a wildcard too.
    * ``generalise``: a random 0/1 entry of a random keyframe becomes a wildcard.
    * ``gap``: d_min or d_max of a random gap moves up or down by a step
      uniform in 1..max(1, ceil(gap_step·Δ)) (Δ = the gap's column distance;
      proposed), clamped to 0 <= d_min <= d_max.

    Parameters
    ----------
    query : KeyframeQuery
    strict, loose : QuantizedTemplate
        δ = 0 and δ = 0.05 quantized templates of T+ (same length).
    random_state : None, int or numpy.random.Generator
    operation : str, optional
        Force one operation (a key of :data:`MUTATIONS`, must be applicable).
    tolerance : (float, float), default (0.2, 1.0)
    gap_step : float, default 0.25

    Returns
    -------
    KeyframeQuery
        A new query (the input is unchanged).

    Raises
    ------
    ParameterError
        An ``operation`` that is unknown or not applicable.
    """
    g = _genome(query)
    if operation is not None and operation not in _applicable(g):
        raise ParameterError(f"operation={operation!r} is not applicable to this query "
                             f"(applicable: {', '.join(_applicable(g))})")
    g = _mutate(g, _columns(strict, loose), _rng(random_state), operation, tolerance, gap_step)
    return _to_query(g, max(query.template_length, len(strict)))


__all__ = ["MUTATIONS", "gap_bounds", "mutate", "random_query", "recombine", "stochastic_universal_sampling"]
