"""Genetic learning of keyframe queries (paper Sect. 6, KEYFRAMES.md §8.2).

An individual is a :class:`~mocapdb.keyframes.KeyframeQuery` of 40-bit
keyframes (``feature_sets=None``).  Its fitness is the weighted F-measure
Fit_β of the *documents* (training clips) in which the keyframe search finds
at least one hit, on T = T+ ∪ T− (positive clips of the class and clips of all
other classes).  The loop follows the paper: an initial population from
columns of the δ = 0 quantized motion template of T+; per generation r parents
by stochastic universal sampling, one offspring per pair of parents
(recombination), one mutation per offspring, and survival of the M fittest of
population ∪ offspring.  Runs differ a lot, so a class is learned with several
independent runs and a consensus pick among their results.

Public API
----------
evolve_keyframes            one GA run -> :class:`GAResult`
learn_keyframe_query        several runs for one class + consensus -> :class:`LearnedQuery`
learn_keyframe_queries      every class of a training set (one shared index)
training_index              the index the GA evaluates individuals on
random_query, gap_bounds    initialisation (one individual, gap bounds from positions)
stochastic_universal_sampling, recombine, mutate    the genetic operators
fitness_from_hits, f_beta   precision, recall and Fit_β of document-level hits
consensus_scores, consensus_pick                     the pick among run results
fixed_entries               non-wildcard entries of a query (survival tie-break)
average_statistics          per-generation statistics averaged over runs (Fig. 5)

Randomness comes only from ``random_state`` (anything
:func:`numpy.random.default_rng` accepts): a run is reproducible from its seed,
and the runs of :func:`learn_keyframe_query` get independent child seeds, so
results do not depend on ``n_jobs``.

Parameters marked "(proposed)" are not fixed by the paper (KEYFRAMES.md §8.2).
"""
from __future__ import annotations

import bisect
import math
import os
import time
import multiprocessing
import zlib
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.features import N_FEATURES
from mocapdb.index import Index, build_index
from mocapdb.keyframes import UNBOUNDED, KeyframeQuery, keyframe_hit_documents
from mocapdb.templates import MotionTemplate, QuantizedTemplate, learn_template

__all__ = [
    "GAResult", "GAStatistics", "LearnedQuery", "MUTATIONS", "average_statistics",
    "GA_DEFAULTS", "consensus_pick", "consensus_scores", "evolve_keyframes", "f_beta",
    "fitness_from_hits", "fixed_entries", "gap_bounds", "learn_keyframe_queries", "learn_keyframe_query", "mutate", "random_query",
    "recombine", "stochastic_universal_sampling", "training_index",
]

_ALL40 = (1 << N_FEATURES) - 1

#: mutation operations and their probabilities: the paper's three kinds
#: (add/remove a keyframe; specialise/generalise an entry; change a gap
#: bound) equally likely, each kind's two directions equally likely (proposed)
MUTATIONS = {"add": 1 / 6, "remove": 1 / 6, "specialise": 1 / 6, "generalise": 1 / 6,
             "gap": 1 / 3}

#: defaults of :func:`evolve_keyframes` (the paper's, or proposed where noted there)
GA_DEFAULTS = {"population_size": 50, "n_parents": 5, "generations": 100, "beta": 2.0,
               "mean_keyframes": 3.0, "std_keyframes": 1.0, "max_keyframes": 8,
               "tolerance": (0.2, 1.0), "gap_step": 0.25, "ties": "fewest_fixed"}


# --------------------------------------------------------------------------
# results


@dataclass(frozen=True, eq=False)
class GAStatistics:
    """Per-generation statistics of a GA run, index g = generation (0 = initial).

    Attributes
    ----------
    mean_precision, mean_recall, mean_fitness : (G+1,) float64
        Averages over the population Π^g (paper Fig. 5).
    best_fitness, best_precision, best_recall : (G+1,) float64
        The fittest individual of Π^g.
    mean_keyframes : (G+1,) float64
        Average number of keyframes of the individuals.
    """

    mean_precision: np.ndarray
    mean_recall: np.ndarray
    mean_fitness: np.ndarray
    best_fitness: np.ndarray
    best_precision: np.ndarray
    best_recall: np.ndarray
    mean_keyframes: np.ndarray

    @property
    def generations(self) -> int:
        return len(self.mean_fitness) - 1


@dataclass(frozen=True, eq=False)
class GAResult:
    """Outcome of one GA run (:func:`evolve_keyframes`).

    Attributes
    ----------
    query : KeyframeQuery
        The fittest individual of the last population.
    fitness, precision, recall : float
        Its Fit_β, P and R on the training set.
    statistics : GAStatistics
    population : tuple of KeyframeQuery
        The last population, by decreasing fitness (``population[0] is query``).
    population_fitness, population_precision, population_recall : (M,) float64
    n_evaluations : int
        Keyframe searches on the training set (M + G·r(r-1)/2).
    seconds : float
        Wall time of the run.
    """

    query: KeyframeQuery
    fitness: float
    precision: float
    recall: float
    statistics: GAStatistics
    population: tuple
    population_fitness: np.ndarray
    population_precision: np.ndarray
    population_recall: np.ndarray
    n_evaluations: int
    seconds: float


@dataclass(frozen=True, eq=False)
class LearnedQuery:
    """The consensus of several GA runs for one class (:func:`learn_keyframe_query`).

    Attributes
    ----------
    query : KeyframeQuery
        The picked run's result.
    fitness, precision, recall : float
        Of ``query`` on the training set.
    best_run : int
        Which run was picked.
    consensus : (runs,) float64
        :func:`consensus_scores` of the run results.
    runs : tuple of GAResult
    """

    query: KeyframeQuery
    fitness: float
    precision: float
    recall: float
    best_run: int
    consensus: np.ndarray
    runs: tuple


# --------------------------------------------------------------------------
# fitness


def f_beta(precision, recall, *, beta=2.0):
    """Weighted F-measure Fit_β = (1+β²)·P·R / (β²·P + R), 0 where P = R = 0.

    Parameters
    ----------
    precision, recall : float or array_like
    beta : float, default 2.0
        The paper's choice: recall weighs more than precision.

    Returns
    -------
    float64 array (or scalar) of the broadcast shape.

    References
    ----------
    Paper Sect. 6; KEYFRAMES.md §8.2.
    """
    p = np.asarray(precision, dtype=np.float64)
    r = np.asarray(recall, dtype=np.float64)
    b2 = float(beta) ** 2
    den = b2 * p + r
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.where(den > 0, (1.0 + b2) * p * r / np.where(den > 0, den, 1.0), 0.0)
    return f if f.ndim else float(f)


def fitness_from_hits(hits, relevant, *, documents=None, beta=2.0):
    """Precision, recall and Fit_β of document-level hits.

    Parameters
    ----------
    hits : (n_queries, n_docs) bool
        Document d is retrieved by query q (:func:`keyframe_hit_documents`).
    relevant : (n_docs,) bool
        The documents of T+.
    documents : (n_docs,) bool, optional
        The documents of T = T+ ∪ T−; hits elsewhere are ignored.  Default:
        every document.
    beta : float, default 2.0

    Returns
    -------
    precision, recall, fitness : (n_queries,) float64
        P = |H ∩ T+| / |H|, R = |H ∩ T+| / |T+|; P = 0 and Fit = 0 when H is
        empty (the paper leaves this case open).
    """
    hits = np.asarray(hits, dtype=bool)
    relevant = np.asarray(relevant, dtype=bool)
    if documents is not None:
        hits = hits[:, np.asarray(documents, dtype=bool)]
        relevant = relevant[np.asarray(documents, dtype=bool)]
    n_rel = int(relevant.sum())
    if n_rel == 0:
        raise ParameterError("relevant marks no document; T+ must hold at least one clip")
    tp = hits[:, relevant].sum(axis=1).astype(np.float64)
    n_hit = hits.sum(axis=1).astype(np.float64)
    precision = np.divide(tp, n_hit, out=np.zeros_like(tp), where=n_hit > 0)
    recall = tp / n_rel
    return precision, recall, f_beta(precision, recall, beta=beta)


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


# --------------------------------------------------------------------------
# one run


def training_index(clips) -> Index:
    """The GA's training index: one document per clip, the 40-bit part only.

    Parameters
    ----------
    clips : sequence of (n_i,) uint64
        Packed 30 Hz feature words; document ids = positions.

    Returns
    -------
    Index
        ``feature_sets=('full',)``: GA keyframes span all feature sets, which
        the 40-bit part answers with one posting-list scan per keyframe.
    """
    return build_index(list(clips), feature_sets=("full",))


def _check_ga_params(population_size, n_parents, generations, beta, mean_keyframes,
                     std_keyframes, max_keyframes, tolerance, gap_step, ties):
    def posint(name, v, lo):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise ParameterError(f"{name}={v!r}; use an integer >= {lo}")
    posint("population_size", population_size, 1)
    posint("n_parents", n_parents, 2)
    posint("generations", generations, 0)
    posint("max_keyframes", max_keyframes, 1)
    for name, v in (("beta", beta), ("std_keyframes", std_keyframes), ("gap_step", gap_step),
                    ("mean_keyframes", mean_keyframes)):
        if not isinstance(v, (int, float, np.floating)) or not math.isfinite(v) or v < 0:
            raise ParameterError(f"{name}={v!r}; use a finite number >= 0")
    if ties not in ("fewest_fixed", "offspring"):
        raise ParameterError(f"ties={ties!r}; use 'fewest_fixed' or 'offspring'")
    try:
        lo, hi = (float(x) for x in tolerance)
    except (TypeError, ValueError):
        raise ParameterError(f"tolerance={tolerance!r}; use a pair (lo, hi)") from None
    if not 0 <= lo <= hi <= 1e6:
        raise ParameterError(f"tolerance={tolerance!r}; need 0 <= lo <= hi")
    return (lo, hi)


def _templates(template):
    if not isinstance(template, MotionTemplate):
        raise ParameterError(f"template must be a MotionTemplate (learn_template of T+), got "
                             f"{type(template).__name__}")
    return template.quantize(0.0), template.quantize(0.05)


def _doc_ids(x, n_docs, name):
    a = np.asarray(x)
    if a.ndim != 1 or (a.size and a.dtype.kind not in "iu"):
        raise ParameterError(f"with index=, {name} must be a 1-D int array of document ids")
    a = a.astype(np.int64)
    if a.size and (a.min() < 0 or a.max() >= n_docs):
        raise ParameterError(f"{name} has document ids outside 0..{n_docs - 1}")
    return a


def _training_set(positive, negative, template, index):
    """(index, relevant, documents, template) for one class."""
    if index is None:
        positive = [_clip_words(c, f"positive[{k}]") for k, c in enumerate(positive)]
        negative = [_clip_words(c, f"negative[{k}]") for k, c in enumerate(negative)]
        if not positive:
            raise ParameterError("positive holds no clip; T+ needs at least one")
        index = training_index(positive + negative)
        pos_ids = np.arange(len(positive))
        neg_ids = np.arange(len(positive), len(positive) + len(negative))
        if template is None:
            template = learn_template(positive)
    else:
        if not isinstance(index, Index):
            raise ParameterError(f"index must be a mocapdb.index.Index, got "
                                 f"{type(index).__name__}")
        if template is None:
            raise ParameterError("with index=, pass template= too (the index does not keep "
                                 "the clips to learn it from)")
        pos_ids = _doc_ids(positive, index.n_docs, "positive")
        neg_ids = _doc_ids(negative, index.n_docs, "negative")
        if pos_ids.size == 0:
            raise ParameterError("positive holds no document; T+ needs at least one")
        if np.intersect1d(pos_ids, neg_ids).size:
            raise ParameterError("positive and negative share documents; T+ and T- must be "
                                 "disjoint")
    relevant = np.zeros(index.n_docs, bool)
    relevant[pos_ids] = True
    documents = relevant.copy()
    documents[neg_ids] = True
    return index, relevant, documents, template


def evolve_keyframes(positive, negative, *, template=None, index=None, population_size=50,
                     n_parents=5, generations=100, beta=2.0, mean_keyframes=3.0,
                     std_keyframes=1.0, max_keyframes=8, tolerance=(0.2, 1.0), gap_step=0.25,
                     ties="fewest_fixed", random_state=None, cache=None) -> GAResult:
    """Learn one keyframe query with one GA run (paper Sect. 6).

    Parameters
    ----------
    positive, negative : sequence of (n_i,) uint64, or (n,) int with ``index``
        T+ and T−: packed 30 Hz words of the training clips (or (name,
        words) pairs), one document each.  With ``index``: document ids of
        that index (documents in neither are ignored).
    template : MotionTemplate, optional
        The motion template of T+ (default: :func:`learn_template` of
        ``positive``; required with ``index``).  Its δ = 0 quantization seeds
        the population and the ``add`` mutation, its δ = 0.05 quantization
        the ``specialise`` mutation.
    index : Index, optional
        A prebuilt index (e.g. :func:`training_index` of all clips, shared by
        every class and run).  Default: built from ``positive + negative``.
    population_size : int, default 50
        M.
    n_parents : int, default 5
        r parents per generation; r(r-1)/2 offspring.
    generations : int, default 100
        G.
    beta : float, default 2.0
        Fit_β.
    mean_keyframes, std_keyframes, max_keyframes, tolerance
        Initialisation, see :func:`random_query`.
    gap_step : float, default 0.25
        Gap mutation step, see :func:`mutate`.
    ties : {'fewest_fixed', 'offspring'}, default 'fewest_fixed'
        Order of equally fit individuals in survival (and the result =
        first of the last population).  'fewest_fixed': fewer fixed
        (non-wildcard) keyframe entries first, then offspring; 'offspring':
        offspring first.  (proposed; the paper leaves ties open.  Ties are
        frequent -- on HDM05 most runs reach Fit = 1 early -- and then decide
        the result: on leave-one-actor-out hdm05_cut the held-out recall of
        the learned queries is 0.89 with 'fewest_fixed' and 0.70 with
        'offspring', whose neutral drift bloats queries to ~8 keyframes;
        benchmarks/bench_ga.py --ties.)
    random_state : None, int or numpy.random.Generator
    cache : dict, optional
        Keyframe intervals kept across searches (:func:`keyframe_hit_documents`);
        one per index, used by one thread at a time.  Default: a fresh dict
        for this run (offspring reuse their parents' keyframes: ~15% faster
        runs on hdm05_cut than without a cache).

    Returns
    -------
    GAResult

    Raises
    ------
    ParameterError
        Bad parameters, an empty T+, overlapping T+ and T−.

    References
    ----------
    Paper Sect. 6 and 7 (Fig. 5); KEYFRAMES.md §8.2.
    """
    tolerance = _check_ga_params(population_size, n_parents, generations, beta,
                                 mean_keyframes, std_keyframes, max_keyframes, tolerance,
                                 gap_step, ties)
    index, relevant, documents, template = _training_set(positive, negative, template, index)
    strict, loose = _templates(template)
    return _evolve(index, relevant, documents, strict, loose, _rng(random_state),
                   {} if cache is None else cache, population_size=population_size,
                   n_parents=n_parents, generations=generations, beta=beta,
                   mean_keyframes=mean_keyframes, std_keyframes=std_keyframes,
                   max_keyframes=max_keyframes, tolerance=tolerance, gap_step=gap_step,
                   ties=ties)


def fixed_entries(query: KeyframeQuery) -> int:
    """Number of non-wildcard entries of all keyframes (the GA's tie-break)."""
    return sum(int(m).bit_count() for m in query.mask.tolist())


def _survivors(fitness, fixed, n, ties):
    """Indices of the ``n`` survivors: by decreasing fitness, ties by ``ties``
    (``'fewest_fixed'``: fewer fixed entries first), then earlier position."""
    if ties == "fewest_fixed":
        return np.lexsort((np.arange(len(fitness)), fixed, -fitness))[:n]
    return np.argsort(-fitness, kind="stable")[:n]


def _evolve(index, relevant, documents, strict, loose, rng, cache, *, population_size,
            n_parents, generations, beta, mean_keyframes, std_keyframes, max_keyframes,
            tolerance, gap_step, ties) -> GAResult:
    """The GA loop on validated inputs."""
    t0 = time.perf_counter()
    cols = _columns(strict, loose)
    L = cols.length
    rel_t = relevant[documents]  # the search runs on the index, the score on T only

    def evaluate(genomes):
        queries = [_to_query(g, L) for g in genomes]
        hits = keyframe_hit_documents(index, queries, cache=cache)[:, documents]
        return (queries, *fitness_from_hits(hits, rel_t, beta=beta),
                np.array([sum(m.bit_count() for m in g.mask) for g in genomes]))

    M = population_size
    genomes = [_random_genome(cols, rng, mean_keyframes, std_keyframes, max_keyframes,
                              tolerance) for _ in range(M)]
    pop, P, R, F, X = evaluate(genomes)
    order = _survivors(F, X, M, ties)
    genomes, pop = [genomes[i] for i in order], [pop[i] for i in order]
    P, R, F, X = P[order], R[order], F[order], X[order]
    n_eval = M
    stats = [[] for _ in range(7)]

    def record():
        for s, x in zip(stats, (P.mean(), R.mean(), F.mean(), F[0], P[0], R[0],
                                np.mean([len(g.pos) for g in genomes]))):
            s.append(float(x))

    record()
    pairs = [(i, j) for i in range(n_parents) for j in range(i + 1, n_parents)]
    for _ in range(generations):
        parents = _sus(F, n_parents, rng)
        kids = [_mutate(_recombine(genomes[parents[i]], genomes[parents[j]], rng, tolerance),
                        cols, rng, None, tolerance, gap_step)
                for i, j in pairs]
        kq, Pk, Rk, Fk, Xk = evaluate(kids)
        n_eval += len(kids)
        # survival of the M fittest (ties: see evolve_keyframes' `ties`);
        # offspring come first, so they win remaining ties
        order = _survivors(np.concatenate([Fk, F]), np.concatenate([Xk, X]), M, ties)
        genomes = [(kids[i] if i < len(kids) else genomes[i - len(kids)]) for i in order]
        pop = [(kq[i] if i < len(kids) else pop[i - len(kids)]) for i in order]
        P = np.concatenate([Pk, P])[order]
        R = np.concatenate([Rk, R])[order]
        F = np.concatenate([Fk, F])[order]
        X = np.concatenate([Xk, X])[order]
        record()
    statistics = GAStatistics(*(np.array(s) for s in stats))
    return GAResult(pop[0], float(F[0]), float(P[0]), float(R[0]), statistics, tuple(pop),
                    F, P, R, n_eval, time.perf_counter() - t0)


# --------------------------------------------------------------------------
# several runs and consensus


def consensus_scores(queries) -> np.ndarray:
    """How often the keyframes of each run result occur in the other results.

    A result *contains* a keyframe iff one of its keyframes has the same
    40-bit ``(mask, value)`` word (positions and gaps are ignored: the same
    pose counts wherever it sits).  Score of result i = the mean, over its
    keyframes, of the number of other results that contain the keyframe
    (mean, not sum, so that long queries are not favoured; proposed form of
    the paper's "keyframes that most frequently occur in the solutions").

    Parameters
    ----------
    queries : sequence of KeyframeQuery

    Returns
    -------
    (n,) float64
    """
    sets = [set(zip(q.mask.tolist(), q.value.tolist())) for q in queries]
    count = {}
    for s in sets:
        for kf in s:
            count[kf] = count.get(kf, 0) + 1
    scores = np.zeros(len(queries))
    for i, q in enumerate(queries):
        kfs = list(zip(q.mask.tolist(), q.value.tolist()))
        # count[kf] includes result i itself once
        scores[i] = np.mean([count[kf] - 1 for kf in kfs])
    return scores


def consensus_pick(queries, fitness) -> int:
    """Index of the run result to keep: highest :func:`consensus_scores`,
    ties -> higher fitness, then the earlier run.

    The consensus outranks fitness (KEYFRAMES.md §8.2, proposed), so a
    slightly less fit result whose keyframes recur can win.  On
    leave-one-actor-out hdm05_cut (10 runs per class) the pick's held-out
    Fit_2 (0.869) was that of the average run (0.871) and of the fittest run
    (0.875) within noise.

    Parameters
    ----------
    queries : sequence of KeyframeQuery
    fitness : (n,) float

    Returns
    -------
    int
    """
    queries = list(queries)
    if not queries:
        raise ParameterError("consensus_pick needs at least one run result")
    fitness = np.asarray(fitness, dtype=np.float64)
    if fitness.shape != (len(queries),):
        raise ParameterError(f"fitness must have one entry per query ({len(queries)}), got "
                             f"shape {fitness.shape}")
    scores = consensus_scores(queries)
    return int(np.lexsort((np.arange(len(queries)), -fitness, -scores))[0])


def _n_jobs(n_jobs):
    if n_jobs is None:
        return os.cpu_count() or 1
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, (int, np.integer)) or n_jobs < 1:
        raise ParameterError(f"n_jobs={n_jobs!r}; use None (all cores) or a positive int")
    return int(n_jobs)


def _check_runs(runs):
    if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) or runs < 1:
        raise ParameterError(f"runs={runs!r}; use a positive integer")
    return int(runs)


def _ga_params(ga_params):
    unknown = set(ga_params) - set(GA_DEFAULTS)
    if unknown:
        raise ParameterError(f"unknown GA parameter(s) {', '.join(sorted(unknown))}; allowed: "
                             f"{', '.join(GA_DEFAULTS)}")
    p = {**GA_DEFAULTS, **ga_params}
    p["tolerance"] = _check_ga_params(**p)
    return p


def _learned(results) -> LearnedQuery:
    results = tuple(results)
    fit = np.array([r.fitness for r in results])
    best = consensus_pick([r.query for r in results], fit)
    r = results[best]
    return LearnedQuery(r.query, r.fitness, r.precision, r.recall, best,
                        consensus_scores([x.query for x in results]), results)


#: the shared data of the worker processes (set once per worker by _worker_init)
_WORKER = {}


def _worker_init(index, documents, setups, params):
    _WORKER.update(index=index, documents=documents, setups=setups, params=params)


def _worker_run(key, rng):
    w = _WORKER
    relevant, strict, loose = w["setups"][key]
    return _evolve(w["index"], relevant, w["documents"], strict, loose, rng, {}, **w["params"])


def _run_all(index, documents, setups, params, tasks, n_jobs, on_done):
    """Run GA tasks ``(key, run, rng)``; ``on_done(key, run, result)`` on this thread.

    ``setups[key] = (relevant, strict, loose)``.  Parallel runs use worker
    processes, not threads: most of a run's time is Python (operators,
    query validation, search planning) holding the GIL, so threads do not
    scale (benchmarks/bench_ga.py measures both).  The index and templates go
    to each worker once; 'spawn' workers start clean (no threads inherited
    from numba's parallel kernels), at ~1 s each.
    """
    n = min(_n_jobs(n_jobs), len(tasks))
    if n <= 1:
        for key, i, rng in tasks:
            relevant, strict, loose = setups[key]
            on_done(key, i, _evolve(index, relevant, documents, strict, loose, rng, {},
                                    **params))
        return
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_worker_init,
                             initargs=(index, documents, setups, params)) as pool:
        futures = {pool.submit(_worker_run, key, rng): (key, i) for key, i, rng in tasks}
        for fut in as_completed(futures):
            on_done(*futures[fut], fut.result())


def learn_keyframe_query(positive, negative, *, runs=20, random_state=0, n_jobs=None,
                         template=None, index=None, progress=None, **ga_params) -> LearnedQuery:
    """Learn a class's keyframe query: several independent GA runs + consensus.

    Parameters
    ----------
    positive, negative, template, index
        As :func:`evolve_keyframes`.
    runs : int, default 20
        Independent runs (paper: 100-500; proposed default 20).
    random_state : None, int or numpy.random.Generator, default 0
        Run i uses the i-th child seed (``default_rng(random_state).spawn``),
        so results do not depend on ``n_jobs``.
    n_jobs : int, optional
        Worker processes running the runs (default: every core; 1 = in this
        process).  With more than one, call from an importable main module
        (``if __name__ == "__main__":``), as multiprocessing's 'spawn' needs.
    progress : callable, optional
        ``progress(run, runs_done, runs)`` after each finished run.
    **ga_params
        Any GA parameter of :func:`evolve_keyframes` (``population_size``,
        ``n_parents``, ``generations``, ``beta``, ``mean_keyframes``,
        ``std_keyframes``, ``max_keyframes``, ``tolerance``, ``gap_step``,
        ``ties``).

    Returns
    -------
    LearnedQuery

    References
    ----------
    Paper Sect. 6 (last paragraph); KEYFRAMES.md §8.2 (consensus, proposed).
    """
    runs = _check_runs(runs)
    params = _ga_params(ga_params)
    index, relevant, documents, template = _training_set(positive, negative, template, index)
    strict, loose = _templates(template)
    seeds = _rng(random_state).spawn(runs)
    results = [None] * runs
    done = [0]

    def on_done(key, i, res):
        results[i] = res
        done[0] += 1
        if progress is not None:
            progress(i, done[0], runs)

    _run_all(index, documents, {0: (relevant, strict, loose)}, params,
             [(0, i, s) for i, s in enumerate(seeds)], n_jobs, on_done)
    return _learned(results)


def _clip_words(clip, where):
    """Words of one clip: an (n,) uint64 array or a (name, words) pair
    (as :func:`mocapdb.training.clips_from_folders` gives)."""
    if isinstance(clip, tuple) and len(clip) == 2 and isinstance(clip[0], str):
        clip = clip[1]
    w = np.asarray(clip)
    if w.ndim != 1 or w.dtype != np.uint64 or w.size == 0:
        raise ParameterError(f"{where} must be a non-empty (n,) uint64 array of packed 30 Hz "
                             f"words (or a (name, words) pair), got dtype {w.dtype} shape "
                             f"{w.shape}; use mocapdb.features.motion_features")
    return w


def _class_seed(random_state, name):
    """Per-class seed sequence: independent of which other classes are learned."""
    if isinstance(random_state, np.random.Generator):
        random_state = int(random_state.integers(2**63))
    if random_state is None:
        random_state = np.random.SeedSequence().entropy
    if isinstance(random_state, bool) or not isinstance(random_state, (int, np.integer)):
        raise ParameterError(f"random_state={random_state!r}; use None, an int or a Generator")
    return np.random.SeedSequence([int(random_state), zlib.crc32(name.encode())])


def learn_keyframe_queries(clips_by_class, *, classes=None, runs=20, templates=None,
                           random_state=0, n_jobs=None, progress=None,
                           **ga_params) -> dict:
    """Learn the keyframe queries of several classes of one training set.

    One :func:`training_index` over every clip of every class serves all
    classes and runs; for class C, T+ = its clips and T− = the clips of all
    other classes (paper Sect. 7).  All (class, run) pairs share one pool of
    worker processes.

    Parameters
    ----------
    clips_by_class : mapping str -> sequence of (n_i,) uint64 or of (name, words)
        Training clips per class (e.g. ``mocapdb.training.clips_from_folders``).
    classes : sequence of str, optional
        Classes to learn (default: all); T− always holds every other class.
    runs : int, default 20
    templates : mapping str -> MotionTemplate, optional
        Motion templates per class (default: learned from the clips).
    random_state : None, int or numpy.random.Generator, default 0
        Class C's runs use the children of ``SeedSequence([seed, crc32(C)])``:
        a class's result does not depend on which other classes are learned.
    n_jobs : int, optional
        Worker processes, see :func:`learn_keyframe_query`.
    progress : callable, optional
        ``progress(class_name, runs_done, runs)`` after each finished run.
    **ga_params
        GA parameters, see :func:`learn_keyframe_query`.

    Returns
    -------
    dict str -> LearnedQuery
        In the order of ``classes``.

    Raises
    ------
    ParameterError
        Unknown classes, a class without clips, bad parameters.
    """
    runs = _check_runs(runs)
    params = _ga_params(ga_params)
    names = list(clips_by_class)
    classes = names if classes is None else list(classes)
    missing = [c for c in classes if c not in clips_by_class]
    if missing:
        raise ParameterError(f"classes {missing} are not in clips_by_class "
                             f"(has {', '.join(names)})")
    words, labels = [], []
    for ci, name in enumerate(names):
        cl = [_clip_words(c, f"clips_by_class[{name!r}][{k}]")
              for k, c in enumerate(clips_by_class[name])]
        if not cl and name in classes:
            raise ParameterError(f"class {name!r} has no clips")
        words += cl
        labels += [ci] * len(cl)
    labels = np.array(labels, np.int64)
    index = training_index(words)
    everything = np.ones(index.n_docs, bool)
    setup = {}
    for name in classes:
        ci = names.index(name)
        tmpl = templates.get(name) if templates is not None else None
        if tmpl is None:
            tmpl = learn_template([w for w, lab in zip(words, labels) if lab == ci])
        setup[name] = (labels == ci, *_templates(tmpl))
    results = {name: [None] * runs for name in classes}
    done = {name: 0 for name in classes}
    tasks = [(name, i, np.random.default_rng(s)) for name in classes
             for i, s in enumerate(_class_seed(random_state, name).spawn(runs))]

    def on_done(name, i, res):
        results[name][i] = res
        done[name] += 1
        if progress is not None:
            progress(name, done[name], runs)

    _run_all(index, everything, setup, params, tasks, n_jobs, on_done)
    return {name: _learned(results[name]) for name in classes}


def average_statistics(results) -> GAStatistics:
    """Per-generation statistics averaged over GA runs (and classes): paper Fig. 5.

    Parameters
    ----------
    results : iterable of GAResult, LearnedQuery or GAStatistics
        A LearnedQuery contributes all its runs; all must have the same
        number of generations.

    Returns
    -------
    GAStatistics
    """
    stats = []
    for r in results:
        if isinstance(r, LearnedQuery):
            stats += [x.statistics for x in r.runs]
        elif isinstance(r, GAResult):
            stats.append(r.statistics)
        elif isinstance(r, GAStatistics):
            stats.append(r)
        else:
            raise ParameterError(f"expected GAResult, LearnedQuery or GAStatistics, got "
                                 f"{type(r).__name__}")
    if not stats:
        raise ParameterError("average_statistics needs at least one result")
    if len({s.generations for s in stats}) != 1:
        raise ParameterError("results have different numbers of generations")
    fields = GAStatistics.__dataclass_fields__
    return GAStatistics(**{f: np.mean([getattr(s, f) for s in stats], axis=0) for f in fields})
