"""Learning one keyframe query per class: several GA runs and their consensus (paper Sect. 6).

:func:`learn_keyframe_query` runs :func:`mocapdb.learning.genetic.evolve_keyframes`
with independent child seeds (in worker processes) and picks the run result
whose keyframes the other runs agree on most (:func:`consensus_pick`);
:func:`learn_keyframe_queries` does so for every class of a training set on
one shared index. :func:`average_statistics` averages the runs' per-generation
statistics (paper Fig. 5).
"""
from __future__ import annotations

import os
import multiprocessing
import zlib
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.keyframes import KeyframeQuery
from mocapdb.templates import learn_template

from mocapdb.learning.ga_operators import _rng
from mocapdb.learning.genetic import (GA_DEFAULTS, GAResult, GAStatistics, _check_ga_params, _clip_words, _evolve,
                                      _templates, _training_set, training_index)

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


def _setup(setups, key, documents):
    """(relevant, documents, strict, loose) of a task: a setup may carry its own documents."""
    relevant, strict, loose, *own = setups[key]
    return relevant, (own[0] if own else documents), strict, loose


def _worker_run(key, rng):
    w = _WORKER
    relevant, documents, strict, loose = _setup(w["setups"], key, w["documents"])
    return _evolve(w["index"], relevant, documents, strict, loose, rng, {}, **w["params"])


def _run_all(index, documents, setups, params, tasks, n_jobs, on_done):
    """Run GA tasks ``(key, run, rng)``; ``on_done(key, run, result)`` on this thread.

    ``setups[key] = (relevant, strict, loose[, documents])``.  Parallel runs use worker
    processes, not threads: most of a run's time is Python (operators,
    query validation, search planning) holding the GIL, so threads do not
    scale (benchmarks/bench_ga.py measures both).  The index and templates go
    to each worker once; 'spawn' workers start clean (no threads inherited
    from numba's parallel kernels), at ~1 s each.
    """
    n = min(_n_jobs(n_jobs), len(tasks))
    if n <= 1:
        for key, i, rng in tasks:
            relevant, docs, strict, loose = _setup(setups, key, documents)
            on_done(key, i, _evolve(index, relevant, docs, strict, loose, rng, {}, **params))
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
                           random_state=0, n_jobs=None, progress=None, labels=None,
                           **ga_params) -> dict:
    """Learn the keyframe queries of several classes of one training set.

    One :func:`training_index` over every clip of every class serves all
    classes and runs; for class C, T+ = its clips and T− = the clips of all
    other classes (paper Sect. 7).  All (class, run) pairs share one pool of
    worker processes.

    Parameters
    ----------
    clips_by_class : mapping str -> sequence of (n_i,) uint64 or of (name, words)
        Training clips per class (e.g. ``mocapdb.learning.class_templates.clips_from_folders``).
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
    labels : mapping str -> str, optional
        Class → coarse label. Then T− of class C leaves out the clips of the
        other classes of C's label (paper Sect. 7: T− is the clips of the
        other classes Table 1 annotates; a hit on a sibling subclass is no
        error of the label). Default: every other class is T−.
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
    label_of = None if labels is None else dict(labels)
    words, class_ids = [], []
    for ci, name in enumerate(names):
        cl = [_clip_words(c, f"clips_by_class[{name!r}][{k}]")
              for k, c in enumerate(clips_by_class[name])]
        if not cl and name in classes:
            raise ParameterError(f"class {name!r} has no clips")
        words += cl
        class_ids += [ci] * len(cl)
    class_ids = np.array(class_ids, np.int64)
    index = training_index(words)
    everything = np.ones(index.n_docs, bool)
    setup = {}
    for name in classes:
        ci = names.index(name)
        tmpl = templates.get(name) if templates is not None else None
        if tmpl is None:
            tmpl = learn_template([w for w, k in zip(words, class_ids) if k == ci])
        docs = everything
        if label_of is not None:
            sibling = np.array([label_of.get(n, n) == label_of.get(name, name) for n in names])[class_ids]
            docs = ~sibling | (class_ids == ci)
        setup[name] = (class_ids == ci, *_templates(tmpl), docs)
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


__all__ = ["LearnedQuery", "average_statistics", "consensus_pick", "consensus_scores", "learn_keyframe_queries",
           "learn_keyframe_query"]
