"""Keyframe queries a new actor keeps: generalised, and kept only where they held for unseen actors.

Preselection is a hard filter: a class whose query misses a new actor's
motion cannot annotate it (paper Sect. 5). The GA (paper Sect. 6) sees only
its training actors, so :func:`learn_robust_queries` adds two steps:

1. **Generalise** each learned query (:func:`lab.generalisation.generalise_query`):
   turn fixed keyframe entries into wildcards as long as the training
   fitness stays (dropping keyframes or widening gaps is not done: on
   joined documents it lets chains form almost anywhere).
2. **Leave one group out** (actor, subject): for every group g, the GA
   learns the classes on the other groups' clips (fewer runs), the result
   is generalised the same way and searched on g's clips. A class's
   *held-out recall* pools these over its groups (and the *coverage*: the
   share of a held-out clip's frames inside the preselected segments, the
   search's hits widened by the annotation margins). The query learned on all
   clips is kept only if its held-out recall reaches ``min_recall`` and its
   coverage ``min_coverage``; a
   class with clips of one group only cannot be checked and gets none.
   A class without a query is matched on whole documents — the reference
   mode's recall for that class.

T− of a class leaves out the clips of its own label's other classes
(:func:`mocapdb.learning.keyframe_learning.learn_keyframe_queries` with ``labels``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.keyframes import annot_margins, build_index, keyframe_search
from mocapdb.learning.genetic import training_index
from lab.generalisation import generalise_query
from mocapdb.learning.keyframe_learning import learn_keyframe_queries
from mocapdb.templates import learn_template

__all__ = ["RobustQuery", "learn_robust_queries", "generalise_queries"]


@dataclass(frozen=True, eq=False)
class RobustQuery:
    """The keyframe query of a class after :func:`learn_robust_queries`.

    Attributes
    ----------
    query : KeyframeQuery or None
        None: the class is matched on whole documents.
    learned : KeyframeQuery
        The generalised query learned on all clips (kept or not).
    held_out_hits, held_out_clips : int
        Held-out clips the inner queries found, of how many.
    held_out_coverage : float
        Mean share of a held-out clip's frames inside the preselected
        segments (the search's hits widened by the annotation margins).
    fitness, precision, recall : float
        Training fitness of the GA's consensus (before generalising).
    statistics : tuple of GAStatistics
        Per-generation statistics of the final runs (paper Fig. 5).
    """

    query: object
    learned: object
    held_out_hits: int
    held_out_clips: int
    held_out_coverage: float
    fitness: float
    precision: float
    recall: float
    statistics: tuple = ()

    @property
    def held_out_recall(self):
        return self.held_out_hits / self.held_out_clips if self.held_out_clips else float("nan")


def _words(clips):
    return {c: [np.asarray(getattr(x, "words", x), dtype=np.uint64) for x in v] for c, v in clips.items()}


def generalise_queries(queries, clips_by_class, *, labels=None, beta=2.0):
    """:func:`generalise_query` (wildcards only) of each class's query on the training clips.

    Parameters
    ----------
    queries : mapping str -> KeyframeQuery
    clips_by_class : mapping str -> sequence of words (or Clip)
    labels : mapping str -> str, optional
        As in :func:`learn_keyframe_queries`: sibling classes are not T−.
    """
    words = _words(clips_by_class)
    names = list(words)
    flat = [w for c in names for w in words[c]]
    ids = np.array([k for k, c in enumerate(names) for _ in words[c]], dtype=np.int64)
    index = training_index(flat)
    cache, out = {}, {}
    for c, q in queries.items():
        relevant = ids == names.index(c)
        docs = None
        if labels is not None:
            sib = np.array([labels.get(n, n) == labels.get(c, c) for n in names])[ids]
            docs = ~sib | relevant
        out[c], _ = generalise_query(q, index, relevant, docs, beta=beta, kinds=("wildcard",), cache=cache)
    return out


def learn_robust_queries(clips, *, classes=None, labels=None, templates=None, runs=20, inner_runs=3,
                         generations=100, inner_generations=50, min_recall=0.9, min_coverage=0.0, random_state=0,
                         n_jobs=None, template_cache=None, progress=None):
    """Generalised GA queries, kept where they held for unseen groups (module docstring).

    Parameters
    ----------
    clips : mapping str -> sequence of Clip
        Training clips per class, each with its ``group``.
    classes : sequence of str, optional
        Classes to learn (default all); every class's clips are T− of the others.
    labels : mapping str -> str, optional
        Class → label (sibling classes are not T−).
    templates : mapping str -> MotionTemplate, optional
        Templates of the final run (default learned from the clips).
    runs, generations : int
        GA runs and generations of the final queries (paper: 100 generations).
    inner_runs, inner_generations : int
        The same for the leave-one-group-out queries.
    min_recall : float, default 0.9
        Held-out recall a query needs to be kept.
    min_coverage : float, default 0.0
        Mean share of held-out clips' frames its preselection must keep.
    random_state : int, default 0
    n_jobs : int, optional
        GA worker processes.
    template_cache : dict, optional
        Inner templates keyed by class and clip names.
    progress : callable, optional
        ``progress(what)`` after each GA batch.

    Returns
    -------
    dict of str to RobustQuery
    """
    if not 0 <= min_recall <= 1:
        raise ParameterError(f"min_recall={min_recall!r}; use a number in [0, 1]")
    names = list(clips)
    classes = names if classes is None else list(classes)
    groups = sorted({x.group for v in clips.values() for x in v})
    cache = {} if template_cache is None else template_cache
    hits = {c: [0, 0, 0.0] for c in classes}
    for g in groups:
        inner = {c: [x for x in v if x.group != g] for c, v in clips.items()}
        inner = {c: v for c, v in inner.items() if v}
        test = {c: [x for x in clips[c] if x.group == g] for c in classes}
        todo = [c for c in classes if test[c] and c in inner]
        if not todo:
            continue
        tmpl = {}
        for c in todo:
            key = (c, tuple(x.name for x in inner[c]))
            if key not in cache:
                cache[key] = learn_template([x.words for x in inner[c]])
            tmpl[c] = cache[key]
        learned = learn_keyframe_queries(_words(inner), classes=todo, runs=inner_runs, templates=tmpl,
                                         random_state=random_state, n_jobs=n_jobs, labels=labels,
                                         generations=inner_generations)
        queries = generalise_queries({c: learned[c].query for c in todo}, inner, labels=labels)
        for c in todo:
            held = [x.words for x in test[c]]
            h, cov = _held_out(queries[c], held)
            hits[c][0] += h
            hits[c][1] += len(held)
            hits[c][2] += cov
        if progress is not None:
            progress(f"held out {g}")
    final = learn_keyframe_queries(_words(clips), classes=classes, runs=runs, templates=templates,
                                   random_state=random_state, n_jobs=n_jobs, labels=labels,
                                   generations=generations)
    general = generalise_queries({c: final[c].query for c in classes}, clips, labels=labels)
    if progress is not None:
        progress("all groups")
    out = {}
    for c in classes:
        h, n, cov = hits[c]
        cov = cov / n if n else float("nan")
        keep = n > 0 and h >= min_recall * n and cov >= min_coverage
        lq = final[c]
        out[c] = RobustQuery(general[c] if keep else None, general[c], h, n, cov, lq.fitness, lq.precision,
                             lq.recall, tuple(r.statistics for r in lq.runs))
    return out


def _held_out(query, clips):
    """(clips hit, summed share of each clip's frames in the preselected segments) of held-out clips."""
    index = build_index(clips, feature_sets=("full",))
    left, right = annot_margins(query)
    segs = keyframe_search(index, query, extend_left=left, extend_right=right)
    covered = np.zeros(len(clips))
    for d, a, b in zip(segs.doc.tolist(), segs.start.tolist(), segs.end.tolist()):
        covered[d] += b - a + 1  # segments of one document do not overlap (KEYFRAMES.md §5)
    share = covered / np.array([len(w) for w in clips], dtype=np.float64)
    return int((covered > 0).sum()), float(np.minimum(share, 1.0).sum())
