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

Public API (the operators are in :mod:`mocapdb.learning.ga_operators`, the runs
and their consensus in :mod:`mocapdb.learning.keyframe_learning`)
----------
evolve_keyframes            one GA run -> :class:`GAResult`
training_index              the index the GA evaluates individuals on
fitness_from_hits, f_beta   precision, recall and Fit_β of document-level hits
fixed_entries               non-wildcard entries of a query (survival tie-break)

Randomness comes only from ``random_state`` (anything
:func:`numpy.random.default_rng` accepts): a run is reproducible from its seed,
and the runs of :func:`learn_keyframe_query` get independent child seeds, so
results do not depend on ``n_jobs``.

Parameters marked "(proposed)" are not fixed by the paper (KEYFRAMES.md §8.2).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.keyframes import Index, build_index
from mocapdb.keyframes import KeyframeQuery, keyframe_hit_documents
from mocapdb.templates import MotionTemplate, learn_template

from mocapdb.learning.ga_operators import _columns, _mutate, _random_genome, _recombine, _rng, _sus, _to_query

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
            raise ParameterError(f"index must be a mocapdb.keyframes.index.Index, got "
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

def _clip_words(clip, where):
    """Words of one clip: an (n,) uint64 array or a (name, words) pair
    (as :func:`mocapdb.learning.class_templates.clips_from_folders` gives)."""
    if isinstance(clip, tuple) and len(clip) == 2 and isinstance(clip[0], str):
        clip = clip[1]
    w = np.asarray(clip)
    if w.ndim != 1 or w.dtype != np.uint64 or w.size == 0:
        raise ParameterError(f"{where} must be a non-empty (n,) uint64 array of packed 30 Hz "
                             f"words (or a (name, words) pair), got dtype {w.dtype} shape "
                             f"{w.shape}; use mocapdb.features.motion_features")
    return w


__all__ = ["GAResult", "GAStatistics", "GA_DEFAULTS", "evolve_keyframes", "f_beta", "fitness_from_hits",
           "fixed_entries", "training_index"]
