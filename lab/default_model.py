"""The whole training of a model like the shipped ``default``: classes, keyframe queries, τ, segment filters.

:func:`train_recipe` runs, on training clips with groups (actors, subjects):

1. **classes** — :func:`lab.recipe.build_model`: learned,
   mirrored, reversed and designed classes;
2. **keyframe queries** — a keyframe definition's for the learned classes
   it names; with ``keyframes=True`` (off by default) the other learned
   classes get :func:`lab.robust_queries.learn_robust_queries`
   (GA, generalised, kept only if they found every held-out group's clip,
   ``min_recall = 1``, and kept 95 % of their frames in the preselection,
   ``min_coverage = 0.95``); mirrored and reversed classes take their
   source's query mirrored / reversed; designed classes their definition's;
3. **τ per class** — :func:`lab.thresholds.learn_taus`
   (leave-one-group-out on the clips);
4. **minimum segment length** — :func:`half_median_template` per label.

Each step is switchable; the development evaluation
(:mod:`lab.development`, ``benchmarks/eval_quality.py``)
reports each beside the reference mode.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from mocapdb.annotation.model import Model
from lab.recipe import build_model, recipe_copies
from lab.robust_queries import learn_robust_queries
from lab.thresholds import learn_taus, with_taus

__all__ = ["TrainedModel", "train_recipe", "half_median_template", "TAU_GRID_DEFAULT"]

#: τ tried per class: never above the paper's 0.13 (a higher τ bought held-out
#: recall on clips but cost precision on documents in the development runs)
TAU_GRID_DEFAULT = tuple(np.round(np.arange(0.02, 0.1301, 0.01), 2).tolist())


@dataclass(frozen=True, eq=False)
class TrainedModel:
    """Result of :func:`train_recipe`.

    Attributes
    ----------
    model : Model
    queries : dict of str to RobustQuery
        Learned classes' keyframe statistics (empty without keyframes).
    query_source : dict of str to str
        Class → where its keyframe query (or its absence) comes from.
    """

    model: Model
    queries: dict
    query_source: dict


def half_median_template(model: Model, designed=(), copies=()) -> Model:
    """``min_frames`` of every class: half the median *learned* template length of its label.

    A full match of a template of K columns covers at least K/2 frames (the
    DTW steps shrink it at most twice); a run of the label shorter than half
    its typical (median) template is a leftover between other labels.
    Typical means measured: only learned (and mirrored, reversed) templates
    count, whose length is the mean duration of their training clips. A
    designed class's template length is a choice of its author (phases long
    enough to tell it from its neighbours), not a duration seen: counted, two
    new side-step designs moved ``move``'s minimum in every fold (RESULTS.md,
    issue 32). A design counts by the shortest duration it states (its
    ``min_frames``, the phases' shortest durations summed): the label's
    minimum never falls below its designs' shortest, so a label whose learned
    classes are short (``move`` without HDM05's sneaks and circle jogs: 14
    frames) keeps the 24 its designs require, and a new design states a
    duration at least that long or lowers it knowingly. A label of designed
    classes only keeps half the median of their templates (they are all it
    has). A class with a longer minimum of its own keeps it.

    Parameters
    ----------
    model : Model
    designed : collection of str, optional
        Names of the designed classes (default none: every template is learned).
    copies : collection of str, optional
        Names of copies of a learned class (its template under another query): the template counts once,
        as its learned class.
    """
    lengths, designs, floor = {}, {}, {}
    for c in model.classes:
        k = len(c.quantized.expand())
        if c.name in copies:
            continue
        if c.name in designed:
            designs.setdefault(c.label, []).append(k)
            floor[c.label] = min(floor.get(c.label, c.min_frames), c.min_frames)
        else:
            lengths.setdefault(c.label, []).append(k)
    need = {lab: max(int(math.ceil(float(np.median(lengths.get(lab) or designs[lab])) / 2)), floor.get(lab, 0))
            for lab in model.labels}
    return dataclasses.replace(model, classes=tuple(dataclasses.replace(c, min_frames=max(c.min_frames, need[c.label]))
                                                    for c in model.classes))


def train_recipe(clips, recipe, *, name, keyframes=False, runs=20, generations=100, inner_runs=3,
                 inner_generations=50, min_recall=1.0, min_coverage=0.95, learn_tau=True, tau_grid=TAU_GRID_DEFAULT,
                 max_false_rate=0.0, max_still_rate=0.05, tau_keyframes=True, min_length=True, margin=0.0, seed=0,
                 n_jobs=None, cache=None, progress=None) -> TrainedModel:
    """Train a model from clips and a recipe (module docstring).

    Parameters
    ----------
    clips : mapping of str to sequence of Clip
        Training clips per learned class, with groups.
    recipe : Recipe
    name : str
    keyframes : bool, default False
        Learn keyframe queries by the GA for learned classes without a
        keyframe definition (step 2). Off by default: on the development
        evaluation the robust GA queries cost held-out actors more than they
        gave (RESULTS.md, issue 11: loao F1 0.874 → 0.86); designed
        queries (class and keyframe definitions) are always attached.
    runs, generations, inner_runs, inner_generations, min_recall, min_coverage
        See :func:`lab.robust_queries.learn_robust_queries`.
    learn_tau : bool, default True
        τ per class by :func:`lab.thresholds.learn_taus`
        (else the recipe's τ and the definitions').
    tau_grid : sequence of float
    max_false_rate : float, default 0.0
        Designed (and reversed) classes may claim no held-out clip of another label.
    max_still_rate : float or None, default 0.05
        A moving class claims at most this share of still poses (None: off);
        see :func:`lab.thresholds.learn_taus`.
    tau_keyframes : bool, default True
        τ of learned classes with a specific keyframe definition (one whose
        most specific keyframe holds in at most 2 % of other labels' clips,
        :func:`lab.thresholds.specific_queries`) measured
        through their preselection (the default annotation mode uses
        keyframes); other queries only filter, and designed classes keep
        the whole-clip rule.
    min_length : bool, default True
        ``min_frames`` by :func:`half_median_template`.
    margin : float, default 0.0
        The model's margin (:mod:`mocapdb.annotation.postprocess`).
    seed : int, default 0
    n_jobs : int, optional
        GA worker processes.
    cache : dict, optional
        Templates kept across calls.
    progress : callable, optional
        ``progress(what)`` after each step.

    Returns
    -------
    TrainedModel
    """
    cache = {} if cache is None else cache
    robust = {}
    designed = {k.cls for k in recipe.keyframes}

    def learn(model, recipe_clips):
        # a class whose keyframes are designed by hand needs no GA
        robust.update(learn_robust_queries(
            recipe_clips, classes=[c for c in model.class_names if c not in designed],
            labels={c.name: c.label for c in model.classes},
            templates={c.name: c.template for c in model.classes}, runs=runs, generations=generations,
            inner_runs=inner_runs, inner_generations=inner_generations, min_recall=min_recall,
            min_coverage=min_coverage, random_state=seed, n_jobs=n_jobs, template_cache=cache, progress=progress))
        return {c: r.query for c, r in robust.items()}

    model = build_model(clips, recipe, name=name, keyframes=learn if keyframes else None, cache=cache)
    if progress is not None:
        progress("classes")
    if learn_tau:
        model = with_taus(model, learn_taus(clips, recipe, grid=tau_grid, max_false_rate=max_false_rate,
                                            max_still_rate=max_still_rate, cache=cache, keyframes=tau_keyframes))
        if progress is not None:
            progress("tau")
    if min_length:
        model = half_median_template(model, {d.name for d in recipe.definitions}, recipe_copies(recipe))
    model = dataclasses.replace(model, margin=float(margin))
    source = {}
    mirrored = {m: c for c, m in recipe.mirrors.items()}
    reversed_ = {n: c for c, (n, _) in recipe.reversals.items()}
    copies = recipe_copies(recipe)
    for c in model.classes:
        if c.name in copies:
            source[c.name] = f"keyframe definition on {copies[c.name]}'s template"
        elif c.name in designed:
            source[c.name] = "keyframe definition"
        elif c.name in robust:
            r = robust[c.name]
            held = (f"held-out recall {r.held_out_hits}/{r.held_out_clips}, "
                    f"coverage {r.held_out_coverage:.2f}")
            if r.query is not None:
                source[c.name] = f"ga, generalised ({held})"
            elif r.held_out_clips == 0:
                source[c.name] = "none: clips of one group only, no held-out check"
            else:
                source[c.name] = f"none: failed the held-out check ({held})"
        elif c.name in mirrored:
            source[c.name] = f"mirror of {mirrored[c.name]}'s"
        elif c.name in reversed_:
            source[c.name] = f"reverse of {reversed_[c.name]}'s"
        else:
            source[c.name] = "class definition" if c.keyframe_query is not None else "none"
    return TrainedModel(model, robust, source)
