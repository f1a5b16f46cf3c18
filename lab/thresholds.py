"""A hit threshold τ per class, learned on the training clips by leave-one-group-out.

The toolbox uses τ = 0.13 for every class (0.06 for standing and T-pose,
TEMPLATES.md §9.1). How well a template matches a new actor's motion, and how
readily it matches other motions, differs from class to class; a τ per class
can follow it. :func:`learn_taus` measures both the way annotation meets
them — on actors the templates did not see:

1. For every group g of the training clips (HDM05 actor, CMU subject) the
   model is built without g's clips (:func:`lab.recipe.build_model`,
   templates only) and every class's Δ is computed on each of g's clips (a
   document each; mirror images for mirrored classes): the clip's cost
   ``m[c, d]`` = min Δ_c over the clip.
2. Clip d of class e *counts for* class c at threshold τ if ``m[c, d] ≤ τ``
   and no class of d's own label matches d better — the frames would carry
   c's label in the annotation. For c's own clips that is a true positive,
   for clips of other labels a false positive.
3. τ_c maximises F1 of those counts over a grid; a designed class (no clips
   of its own) takes the largest τ up to its definition's whose false
   positives stay at most ``max_false_rate`` of the other clips (so does a
   reversed class, and a learned class whose clips all come from one group:
   no template of it exists without that group).

4. **Still poses.** The training clips are class motions only, but a real
   recording also holds stretches where nobody does anything in particular
   (standing, looking around: the authors' ``others``). A template that
   matches a motionless pose would label them. So every clip also gives
   *still clips*: a pose of it (at 1/4, 1/2 and 3/4 of the clip) held for
   2 s, its velocity features off (:func:`still_clips`). A class whose
   template moves (:func:`is_static` is false) takes no τ at which it claims
   more than ``max_still_rate`` of the held-out actors' still clips.

5. **Keyframes** (``keyframes=True``): a learned class with a designed
   keyframe query (a keyframe definition) is matched only where its
   preselection lets annotation match it, so a clip its keyframes miss is
   no claim — a strict query (the kick's stretched leg) buys the class the
   τ its template alone could not afford. Only a *specific* query earns
   that: one that holds in at most ``max_keyframe_rate`` of the other
   labels' training clips (:func:`specific_queries`; a chain by its most
   specific keyframe). A query that also holds in other motions (the
   throw's ball held up: jumping jacks, knee raises) only filters; the
   class keeps the τ of its template alone, because the clips it is
   measured on are short and a long recording of those motions gives the
   template the chances the clips do not.

6. **Motions of no class.** Clips of :data:`lab.recipe.OTHERS`
   (waving, raising a hand: motions a user's archive holds that none of
   the classes are) are held out with their group like every clip, and a
   class that claims one counts a false positive, as for another label's
   clip: the τ that tells the classes apart also keeps them silent there.
   They are whole recordings, so (with ``keyframes``) every class with a
   query meets them through its preselection, as annotation does: a class
   whose keyframes never hold in a wave need not give up τ for it.

7. **Copies** (a learned class's template under a query of its own,
   :func:`lab.recipe.recipe_copies`) have no clips of their own: the
   false-claim rule, and never more than their template's class learned —
   the same template, found in more places.

8. **Caps.** A keyframe definition's ``tau`` caps its class and the class's
   mirror image (:class:`mocapdb.learning.class_definitions.KeyframeDefinition`):
   steps 5 and 6 meet motions through the query, which annotation without
   keyframes does not, and a query that shuts motions of no class out would
   otherwise raise τ for that mode too.

Designed classes therefore never take more than their author gave them, and
learned ones get the τ at which unseen actors' clips are told apart best.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from mocapdb.annotation.model import Model
from mocapdb.annotation.preselection import preselection_for
from mocapdb.errors import ParameterError
from mocapdb.features import FEATURE_NAMES
from mocapdb.keyframes import KeyframeQuery
from lab.recipe import OTHERS, build_model, recipe_clips, recipe_copies
from mocapdb.templates import ANNOTATION_STEPS, mt_distance_slices

__all__ = ["TAU_GRID", "VELOCITY_FEATURES", "clip_costs", "learn_taus", "with_taus", "still_clips", "is_static",
           "specific_queries"]

#: the τ values tried (the paper's Fig. 8 sweep: 0.05 … 0.25)
TAU_GRID = tuple(np.round(np.arange(0.04, 0.2501, 0.01), 2).tolist())


#: features that need motion (velocities, FEATURES.md §6): all off when the body is still
VELOCITY_FEATURES = tuple(FEATURE_NAMES.index(n) + 1 for n in (
    "hand_right_to_front_rel_torso", "hand_left_to_front_rel_torso", "hand_right_to_top_rel_spine",
    "hand_left_to_top_rel_spine", "hands_move_together", "hand_right_move_apart_rel_root",
    "hand_left_move_apart_rel_root", "hand_right_high_vel", "hand_left_high_vel", "feet_move_together_rel_hips",
    "feet_move_apart_rel_hips", "foot_right_high_vel", "foot_left_high_vel", "root_high_vel",
    "root_high_ang_vel"))
_VELOCITY_MASK = np.uint64(sum(1 << (f - 1) for f in VELOCITY_FEATURES))
#: how a still clip is made: poses at these fractions of a clip, held this many 30 Hz frames
STILL_AT = (0.25, 0.5, 0.75)
STILL_FRAMES = 60


def still_clips(words) -> list:
    """Motionless stretches made from a clip: a few of its poses, each held 2 s with the velocity features off."""
    w = np.asarray(words, dtype=np.uint64)
    if w.size == 0:
        return []
    return [np.full(STILL_FRAMES, w[min(int(w.size * f), w.size - 1)] & ~_VELOCITY_MASK, dtype=np.uint64)
            for f in STILL_AT]


def is_static(cls) -> bool:
    """True for a class of a motionless pose (neutral, T-pose): no velocity feature is
    on in any column of its template (its quantized template where no real one exists)."""
    idx = np.array(VELOCITY_FEATURES) - 1
    if cls.template is not None:
        return bool((np.asarray(cls.template.real)[:, idx] < 0.5).all())
    q = cls.quantized
    return not bool((q.value & _VELOCITY_MASK).any())


def clip_costs(model: Model, clips, *, preselect=()) -> np.ndarray:
    """``m[c, d]``: the smallest Δ of class c's template on clip d (+inf if none ends).

    Parameters
    ----------
    model : Model
    clips : sequence of (n_d,) uint64
    preselect : collection of str, default ()
        Classes (with keyframe queries) matched only where their keyframe
        preselection lets annotation match them
        (:func:`mocapdb.annotation.preselection.preselection_for`): a clip
        their keyframes miss costs +inf, as in annotation with keyframes.

    Returns
    -------
    (n_classes, n_clips) float64
    """
    words = [np.asarray(w, dtype=np.uint64) for w in clips]
    if not words:
        return np.zeros((len(model.classes), 0))
    flat = np.concatenate(words)
    lengths = np.array([w.size for w in words], dtype=np.int64)
    bounds = np.concatenate(([0], np.cumsum(lengths))).astype(np.int64)
    n_cls, n_doc = len(model.classes), len(words)
    preselect = set(preselect)
    unknown = sorted(preselect - set(model.class_names))
    if unknown:
        raise ParameterError(f"preselect names classes {unknown} the model does not have")
    pre = preselection_for(flat, lengths, model, True) if preselect else None
    tc, ta, tb = [], [], []
    for k in range(n_cls):
        sl = None if pre is None or model.classes[k].name not in preselect else pre[k]
        if sl is None:                                   # whole clips
            tc.append(np.full(n_doc, k))
            ta.append(bounds[:-1])
            tb.append(bounds[1:])
        else:
            sl = np.asarray(sl, dtype=np.int64).reshape(-1, 2)
            tc.append(np.full(len(sl), k))
            ta.append(sl[:, 0])
            tb.append(sl[:, 1] + 1)
    tc, ta, tb = (np.concatenate(x).astype(np.int64) for x in (tc, ta, tb))
    delta, offsets, _ = mt_distance_slices(flat, [c.quantized for c in model.classes], tc, ta, tb,
                                           steps=ANNOTATION_STEPS, rule="toolbox", return_starts=True)
    out = np.full((n_cls, n_doc), np.inf)
    doc = np.searchsorted(bounds, ta, side="right") - 1
    for q in range(tc.size):
        seg = delta[offsets[q]:offsets[q + 1]]
        if seg.size:
            out[tc[q], doc[q]] = min(out[tc[q], doc[q]], seg.min())
    return out


def _keyframe_alone(query, k):
    """Keyframe k of a query as a query of its own (same template position and length)."""
    none = np.zeros(0, np.int64)
    return KeyframeQuery(query.mask[k:k + 1], query.value[k:k + 1], query.positions[k:k + 1], none, none,
                         query.template_length)


def specific_queries(model: Model, clips, *, max_rate=0.02) -> dict:
    """How often each learned class's keyframe query holds in other labels' clips, and whether it is specific.

    A chain of keyframes is judged by its most specific keyframe alone: on
    short clips a chain that spans the template rarely fits into another
    motion's clip, but in a recording the next motion supplies its later
    keyframes; a chain can never hold in more places than each of its
    keyframes.

    Parameters
    ----------
    model : Model
    clips : mapping of str to sequence of Clip
        Clips per class name (:func:`lab.recipe.recipe_clips`);
        a name the model does not have is its own label.
    max_rate : float, default 0.02
        A query is specific if one of its keyframes holds in at most this
        share of the clips of other labels.

    Returns
    -------
    dict of str to (float, bool)
        Class → (share of other labels' clips its most specific keyframe
        holds in, specific), for the classes with a template and a keyframe
        query.
    """
    ks = [k for k, c in enumerate(model.classes) if c.template is not None and c.keyframe_query is not None]
    owners = [name for name, v in clips.items() for _ in v]
    words = [np.asarray(x.words, dtype=np.uint64) for v in clips.values() for x in v]
    if not ks or not words:
        return {}
    lengths = np.array([w.size for w in words], dtype=np.int64)
    bounds = np.concatenate(([0], np.cumsum(lengths)))
    flat = np.concatenate(words)
    label_of = {c.name: c.label for c in model.classes}
    owner_label = np.array([label_of.get(n, n) for n in owners], dtype=object)
    rates = {k: [] for k in ks}
    for j in range(max(model.classes[k].keyframe_query.n_keyframes for k in ks)):
        alone = {model.classes[k].name: _keyframe_alone(model.classes[k].keyframe_query, j)
                 for k in ks if j < model.classes[k].keyframe_query.n_keyframes}
        pre = preselection_for(flat, lengths, model.with_keyframe_queries(alone), True)
        for k in ks:
            if model.classes[k].name not in alone:
                continue
            neg = owner_label != model.classes[k].label
            held = np.zeros(len(owners), dtype=bool)
            sl = np.asarray(pre[k], dtype=np.int64).reshape(-1, 2)
            held[np.searchsorted(bounds, sl[:, 0], side="right") - 1] = True
            rates[k].append(float(held[neg].mean()) if neg.any() else 0.0)
    out = {}
    for k in ks:
        rate = min(rates[k])
        out[model.classes[k].name] = (rate, rate <= max_rate)
    return out


def _f_beta(tp, fn, fp, beta):
    b2 = beta * beta
    den = (1 + b2) * tp + b2 * fn + fp
    return np.where(den > 0, (1 + b2) * tp / np.maximum(den, 1e-300), 0.0)


def learn_taus(clips, recipe, *, grid=TAU_GRID, max_false_rate=0.02, beta=1.0, max_still_rate=0.05, cache=None,
               keyframes=False, max_keyframe_rate=0.02):
    """τ per class of the model a recipe builds from ``clips`` (module docstring).

    Parameters
    ----------
    clips : mapping of str to sequence of Clip
        The training clips (with groups), as for :func:`build_model`.
    recipe : Recipe
    grid : sequence of float
        Candidate τ values.
    max_false_rate : float, default 0.02
        Designed classes: the largest share of other clips they may claim.
    beta : float, default 1.0
        Learned classes maximise F_β of the clip counts (β < 1 weighs
        precision more).
    max_still_rate : float or None, default 0.05
        A class that moves claims at most this share of the held-out still
        clips (step 4 of the module docstring); None: no still clips.
    cache : dict, optional
        Templates kept across builds (:func:`build_model`).
    keyframes : bool, default False
        Measure learned classes with a keyframe query (a keyframe
        definition's; GA queries are not part of these models) through
        their preselection, as annotation with keyframes meets them
        (:func:`clip_costs`). Designed classes keep the false-claim rule on
        whole clips: nothing but their author vouches for their queries.
    max_keyframe_rate : float, default 0.02
        With ``keyframes``: only a query that holds in at most this share
        of other labels' clips is specific enough (:func:`specific_queries`).

    Returns
    -------
    dict of str to float
        Class → τ for every class of the model (learned, mirrored, reversed,
        designed).
    """
    grid = np.asarray(sorted(float(t) for t in grid))
    if grid.size == 0 or (grid < 0).any():
        raise ParameterError("grid must hold non-negative τ values")
    every = recipe_clips(clips, recipe)
    negatives = list(clips.get(OTHERS, ()))
    groups = sorted({x.group for v in every.values() for x in v} | {x.group for x in negatives})
    if len(groups) < 2:
        raise ParameterError(f"learning τ needs clips of at least two groups (actors), got {groups}")
    full = build_model(clips, recipe, name="taus", cache=cache)
    names = full.class_names
    through = ([c for c, (_, ok) in specific_queries(full, every, max_rate=max_keyframe_rate).items() if ok]
               if keyframes else [])
    label_of = {c.name: c.label for c in full.classes}
    costs, owner, still_costs = [], [], []
    for g in groups:
        rest = {c: [x for x in v if x.group != g] for c, v in clips.items()}
        model = build_model(rest, recipe, name=f"without_{g}", cache=cache)
        held = [(c, x) for c, v in every.items() for x in v if x.group == g]
        negs = [x for x in negatives if x.group == g]
        if not held and not negs:
            continue
        stills = [s for _, x in held for s in still_clips(x.words)] if max_still_rate is not None else []
        m = clip_costs(model, [x.words for _, x in held] + stills,
                       preselect=[c for c in through if c in model.class_names])
        if negs:
            # motions of no class (step 6) are whole recordings, met as annotation with keyframes
            # meets them: a class claims one only where its keyframes let it
            queried = [c.name for c in model.classes if keyframes and c.keyframe_query is not None]
            m = np.hstack([m[:, :len(held)], clip_costs(model, [x.words for x in negs], preselect=queried),
                           m[:, len(held):]])
            held += [(OTHERS, x) for x in negs]
        row = {c: k for k, c in enumerate(model.class_names)}
        full_m = np.full((len(names), m.shape[1]), np.inf)
        for k, c in enumerate(names):
            if c in row:
                full_m[k] = m[row[c]]
        costs.append(full_m[:, :len(held)])
        still_costs.append(full_m[:, len(held):])
        owner += [c for c, _ in held]
    m = np.concatenate(costs, axis=1)
    still = np.concatenate(still_costs, axis=1)
    owner = np.array(owner, dtype=object)
    own_label = np.array([label_of.get(c, c) for c in owner], dtype=object)
    # the best cost of each clip among the classes of its own label
    own_best = np.full(m.shape[1], np.inf)
    for k, c in enumerate(names):
        mine = own_label == label_of[c]
        own_best[mine] = np.minimum(own_best[mine], m[k, mine])
    out = {}
    for k, c in enumerate(full.classes):
        if still.shape[1] and not is_static(c):
            # the largest τ claiming few still poses caps the class (step 4)
            claimed = (still[k][:, None] <= grid[None, :]).mean(axis=0)
            ok = grid[claimed <= max_still_rate]
            cap = float(ok.max()) if ok.size else float(grid.min())
        else:
            cap = float(grid.max())
        out[c.name] = min(_class_tau(k, c, m, owner, own_label, own_best, grid, beta, max_false_rate), cap)
    for copy, source in recipe_copies(recipe).items():   # step 7
        if copy in out and source in out:
            out[copy] = min(out[copy], out[source])
    for k in recipe.keyframes:                           # step 8
        if k.tau is not None:
            for c in (k.cls, recipe.mirrors.get(k.cls)):
                if c in out:
                    out[c] = min(out[c], k.tau)
    return out


def _class_tau(k, c, m, owner, own_label, own_best, grid, beta, max_false_rate) -> float:
    """Steps 2–3 for class k: F_β-best τ on its held-out clips, or the false-claim rule."""
    pos = owner == c.name
    neg = own_label != c.label
    claims = m[k][:, None] <= grid[None, :]                     # (n_clips, n_grid)
    fp = (claims[neg] & (m[k, neg] < own_best[neg])[:, None]).sum(axis=0)
    if pos.any() and np.isfinite(m[k, pos]).any():
        tp = claims[pos].sum(axis=0)
        f = _f_beta(tp, pos.sum() - tp, fp, beta)
        return float(grid[int(np.flatnonzero(f == f.max())[-1])])  # ties: the larger τ
    # no held-out clips of its own (designed, reversed, one group): its own τ at most, few false claims
    allowed = grid[(fp <= max_false_rate * max(1, neg.sum())) & (grid <= c.tau + 1e-12)]
    # none allowed: the grid's smallest, never above the definition's own τ (a design below the grid, whose
    # exact match is what tells it from its neighbours, keeps it)
    return float(allowed.max()) if allowed.size else min(float(grid.min()), float(c.tau))


def with_taus(model: Model, taus) -> Model:
    """A copy of ``model`` whose classes take τ from ``taus`` (class → τ; others keep theirs)."""
    return dataclasses.replace(model, classes=tuple(
        dataclasses.replace(c, tau=float(taus[c.name])) if c.name in taus else c for c in model.classes))
