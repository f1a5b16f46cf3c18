"""Retrieval quality: query by example on labelled documents, scored per class.

The measure (issue 21, the usual ones of ranked retrieval): a query is one
labelled clip of one actor; the archive searched is the documents of the
*other* actors (the leave-one-actor-out documents of
:mod:`lab.documents`), so the query never saw them. A result
is relevant when the truth segment it overlaps most is of the query's class,
covers at least half of the result, and no better-ranked result found it
already (a segment counts once). Per query, with n the number of true
segments of the class in the archive:

* **R-precision** — the fraction of relevant results among the first n;
* **precision at 1, 5, 10** — among the first 1, 5, 10 (missing results
  count as irrelevant).

Per class the means over its queries. Variants (:data:`VARIANTS`), each with
or without keyframe preselection:

* ``clip`` — the clip's own words as the template (the default method);
* ``unweighted`` — the same, every feature counting the same (the paper's
  local cost c^Q instead of the information weights);
* ``mirror`` — a template learned from the clip and its mirror image;
* ``keyframes`` — fuzzy keyframes only: three keyframes taken from the clip,
  the chain hits widened by the annotation margins, ranked by how far their
  span is from the keyframes' span in the clip.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from mocapdb.errors import ParameterError
from lab.documents import DocumentSet
from mocapdb.keyframes import build_index, keyframe_search
from mocapdb.features import unpack_words
from mocapdb.retrieval import (CELL_BUDGET, RESULT_DTYPE, TAU_FACTOR, archive_sample, chance_cost, clip_template,
                               feature_frequencies, mirror_template, search_documents, template_query)
from mocapdb.retrieval.keyframes import column_paths, pick_keyframes

#: the retrieval variants compared (module docstring)
VARIANTS = ("clip", "unweighted", "mirror", "keyframes")
#: the ranks precision is reported at
PRECISION_AT = (1, 5, 10)


@dataclass(frozen=True)
class QueryResult:
    """One query of :func:`loao_retrieval`: its clip, the relevant count, and per result its
    relevance and its cost relative to the query's chance level (NaN for ``keyframes``)."""

    document: str
    start: int
    end: int
    label: str
    group: str
    n_relevant: int
    relevant: tuple
    cost_by_chance: tuple = ()


@dataclass(frozen=True)
class ClassScores:
    """Means over the queries of one class."""

    label: str
    n_queries: int
    n_relevant: float
    r_precision: float
    precision_at: dict


def relevance(results, truth, label, names) -> list:
    """Relevant or not, for ranked results (module docstring).

    Parameters
    ----------
    results : ndarray of RESULT_DTYPE
        ``doc`` indexes ``names``.
    truth : ndarray of LABEL_DTYPE
        Truth segments (30 Hz, 0-based inclusive) of the documents.
    label : str
    names : sequence of str

    Returns
    -------
    list of bool
    """
    found = set()
    out = []
    for r in results:
        doc = names[int(r["doc"])]
        rows = np.flatnonzero(truth["document"] == doc)
        ok = False
        if rows.size:
            t = truth[rows]
            overlap = np.minimum(t["end"], r["end"]) - np.maximum(t["start"], r["start"]) + 1
            k = int(np.argmax(overlap))
            key = (doc, int(rows[k]))
            ok = (str(t["label"][k]) == label and overlap[k] >= 0.5 * (r["end"] - r["start"] + 1)
                  and key not in found)
            if ok:
                found.add(key)
        out.append(bool(ok))
    return out


def r_precision(relevant, n) -> float:
    """Relevant fraction of the first ``n`` results (missing ones irrelevant)."""
    return float(np.sum(list(relevant)[:n])) / n if n else float("nan")


def precision_at(relevant, k) -> float:
    """Relevant fraction of the first ``k`` results (missing ones irrelevant)."""
    return float(np.sum(list(relevant)[:k])) / k


def _keyframes_only(words, lengths, index, template, sample, limit):
    """The ``keyframes`` variant: chain hits of three keyframes, widened, ranked by span."""
    paths, value = column_paths(template, sample)
    kq = pick_keyframes(paths, value, len(template), n_keyframes=3, frequency=0.1)
    if kq is None:
        return np.empty(0, RESULT_DTYPE)
    _, hits = keyframe_search(index, kq, return_hits=True)
    span = max(1, int(kq.positions[-1] - kq.positions[0]))
    left, right = kq.positions[0], len(template) - 1 - kq.positions[-1]
    out = np.empty(len(hits), RESULT_DTYPE)
    out["doc"] = hits.doc
    out["start"] = np.maximum(hits.start - left, 0)
    out["end"] = np.minimum(hits.end + right, lengths[hits.doc] - 1)
    out["cost"] = np.abs(np.log((hits.end - hits.start + 1) / (span + 1)))
    out = out[np.lexsort((out["start"], out["doc"], out["cost"]))]
    kept = []
    for r in out:  # non-overlapping, best first
        if all(k["doc"] != r["doc"] or k["end"] < r["start"] or r["end"] < k["start"] for k in kept):
            kept.append(r)
        if len(kept) == limit:
            break
    return np.array(kept, RESULT_DTYPE)


def loao_retrieval(docs: DocumentSet, *, variant="clip", keyframes=None, budget=CELL_BUDGET, features="all", tau=None,
                   groups=None, labels=None, query_frames=None, progress=None) -> list:
    """Query with every labelled clip of every actor over the other actors' documents.

    Parameters
    ----------
    docs : DocumentSet
        Leave-one-actor-out documents of several actors, truth with the
        classes as labels (``loao_documents(…, class_labels={})``).
    variant : {"clip", "mirror", "keyframes"}
    keyframes : bool, optional
        Preselect with the query's keyframes (``clip``, ``mirror``): None as
        far as ``budget`` needs, True always (at least the most lenient level), False never.
    budget : int
        Δ cells a query may rank (:func:`mocapdb.retrieval.preselect`);
        scale it to the archive to see the preselection a larger archive gets.
    features : str
        Feature subset of the template.
    tau : float, optional
        Hit threshold (default: the method's).
    groups : callable, optional
        Document name → actor; default the ``loao_<actor>_<k>`` names.
    labels : sequence of str, optional
        Only query clips of these labels (default all).
    query_frames : int, optional
        Query with at most this many frames from the middle of each clip
        (long labelled stretches; default the whole clip).
    progress : callable, optional
        ``progress(n_done, n_total)``.

    Returns
    -------
    list of QueryResult
    """
    if variant not in VARIANTS:
        raise ParameterError(f"variant must be one of {', '.join(VARIANTS)}, got {variant!r}")
    group_of = groups or (lambda name: name.split("_")[1])
    names = list(docs.names)
    doc_group = np.array([group_of(n) for n in names])
    bounds = np.concatenate(([0], np.cumsum(docs.doc_lengths))).astype(np.int64)
    queries = docs.truth if labels is None else docs.truth[np.isin(docs.truth["label"], list(labels))]
    archives = {}
    out = []
    for k, q in enumerate(queries):
        d = names.index(str(q["document"]))
        g = doc_group[d]
        if g not in archives:
            keep = np.flatnonzero(doc_group != g)
            words = np.concatenate([docs.words[bounds[i]:bounds[i + 1]] for i in keep])
            lengths = docs.doc_lengths[keep]
            archives[g] = (keep, words, lengths, build_index(words, doc_lengths=lengths, feature_sets=("full",)),
                           archive_sample(words, lengths))
        keep, words, lengths, index, sample = archives[g]
        clip = docs.words[bounds[d] + q["start"]:bounds[d] + q["end"] + 1]
        if query_frames is not None and clip.size > query_frames:
            clip = clip[(clip.size - query_frames) // 2:][:query_frames]
        kept = [names[i] for i in keep]
        truth = docs.truth[np.isin(docs.truth["document"], kept)]
        n = int(np.sum(truth["label"] == q["label"]))
        limit = max(n, max(PRECISION_AT))
        chance = np.nan
        if variant == "keyframes":
            results = _keyframes_only(words, lengths, index, clip_template(clip, features=features), sample, limit)
        else:
            template = (mirror_template(clip, features=features) if variant == "mirror"
                        else clip_template(clip, features=features))
            query = template_query(template, sample, tau=tau, keyframes=keyframes is not False)
            if variant == "unweighted":
                equal = np.where(unpack_words(template.mask), 1.0, 0.0)
                chance = chance_cost(template, feature_frequencies(sample), equal)
                query = replace(query, weights=equal, chance=chance,
                                tau=TAU_FACTOR * chance if tau is None else query.tau)
            chance = query.chance
            results = search_documents(words, lengths, query, limit=limit, index=index, budget=budget,
                                       force=bool(keyframes))
        out.append(QueryResult(str(q["document"]), int(q["start"]), int(q["end"]), str(q["label"]), str(g), n,
                               tuple(relevance(results, truth, str(q["label"]), kept)),
                               tuple((results["cost"] / chance).tolist())))
        if progress is not None:
            progress(k + 1, len(queries))
    return out


def class_scores(results) -> list:
    """Per class (label order of first appearance) the mean R-precision and precisions at 1, 5, 10."""
    by = {}
    for r in results:
        by.setdefault(r.label, []).append(r)
    out = []
    for label, rs in by.items():
        out.append(ClassScores(label, len(rs), float(np.mean([r.n_relevant for r in rs])),
                               float(np.mean([r_precision(r.relevant, r.n_relevant) for r in rs])),
                               {k: float(np.mean([precision_at(r.relevant, k) for r in rs])) for k in PRECISION_AT}))
    return out


__all__ = ["VARIANTS", "PRECISION_AT", "QueryResult", "ClassScores", "relevance", "r_precision", "precision_at",
           "loao_retrieval", "class_scores"]
