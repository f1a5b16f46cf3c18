"""A model from every kind of class source: learned, mirrored, reversed and designed classes.

The paper's authors assembled each of their 15 classes from fine classes
("subclasses", one template each), some of them mirrored copies
(``…Mirrored``). :func:`build_model` does the same from a :class:`Recipe`:

* **learned** classes: a motion template per class from its training
  :class:`Clip` s (:func:`mocapdb.templates.learn_template`), δ-quantized;
* **mirrored** classes: the left/right mirror image of a learned class
  (FEATURES.md §7; ``kickRFront1Reps`` from ``kickLFront1Reps``): the
  template's rows and the keyframe query's bits permuted;
* **reversed** classes: a learned class played backwards, usually under
  another label (``standUpLieFloor`` from ``lieDownFloor``): quantized
  columns in reverse order, features by
  :func:`mocapdb.features.reverse_fuzzy_words`;
* **designed** classes: hand-written class definitions
  (:mod:`mocapdb.learning.class_definitions`, paper Sect. 8);
* **copies**: a learned class's template under a query of its own (a
  keyframe definition with ``template``: ``depositFloorRBothHands`` is
  ``depositFloorR``'s template found where both hands reach the floor, as a
  box is lifted), beside the learned class and its query.

Keyframe queries (:func:`build_model`'s ``keyframes``): learned classes by the
genetic algorithm (paper Sect. 6), with T− = the clips of every other learned
class and of the mirror images, unless a keyframe definition (a
``[[keyframes]]`` table) designs the class's query by hand; a mirrored or
reversed class takes its source's query mirrored or reversed; a designed
class its definition's.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from importlib import resources

from mocapdb.annotation.labels import class_labels
from mocapdb.annotation.model import DEFAULT_DELTA, DEFAULT_TAU, ClassModel, Model
from mocapdb.errors import ParameterError
from mocapdb.features import mirror_words
from mocapdb.learning.class_definitions import apply_keyframe_definitions, compile_definition, read_definitions
from mocapdb.templates import learn_template

__all__ = ["Clip", "Recipe", "PAPER_LABELS", "build_model", "mirror_class", "reverse_class", "clip_words",
           "recipe_clips", "recipe_copies", "default_recipe", "DEFAULT_MIRRORS", "DEFAULT_REVERSALS", "DEFINITIONS_DIR",
           "DEFAULT_CONCURRENT", "OTHERS"]

#: the shipped default model's mirrored classes (learned class -> mirror image):
#: one-sided motions whose other side the data lacks (RESULTS.md, issue 11)
DEFAULT_MIRRORS = {"kickLFront1Reps": "kickRFront1Reps", "sneak2StepsLStart": "sneak2StepsRStart",
                   "jogLeftCircle4StepsRstart": "jogRightCircle4StepsLstart",
                   "elbowToKnee1RepsLelbowStart": "elbowToKnee1RepsRelbowStart"}
#: the shipped default model's reversed classes: lying down played backwards is standing up
DEFAULT_REVERSALS = {"lieDownFloor": ("standUpLieFloor", "standUp")}
#: the shipped class definitions (hand-designed classes), ``mocapdb/shipped_models/classes/*.toml``
DEFINITIONS_DIR = "classes"

#: the class of training clips that show motions of no class (the authors' ``others``):
#: no template is learned from them; τ learning keeps every class from claiming them
OTHERS = "others"
#: the shipped default model's concurrent labels: a walker who turns is still walking
DEFAULT_CONCURRENT = ("turn",)
#: the paper's 15 labels (Table 1), in its order (Δarg ties go to the earlier label)
PAPER_LABELS = ("neutral", "tpose", "move", "turn", "sitLieDown", "standUp", "hopOneLeg", "jump", "kick",
                "punch", "rotateArms", "throwR", "grabDepR", "cartwheel", "exercise")


@dataclass(frozen=True, eq=False)
class Clip:
    """A training clip: packed 30 Hz words, with where it comes from.

    Attributes
    ----------
    name : str
    words : (n,) uint64
    group : str
        Who performed it (HDM05 actor, CMU subject): leave-one-group-out
        inside training and evaluation folds use it.
    document : str
        The recording it was cut from (its own name for a cut clip).
    """

    name: str
    words: np.ndarray
    group: str = ""
    document: str = ""


@dataclass(frozen=True)
class Recipe:
    """How a model is made (module docstring).

    Attributes
    ----------
    labels : mapping of str to str
        Learned class → label. Only classes with clips are learned.
    mirrors : mapping of str to str
        Learned class → name of its mirror-image class (same label).
    reversals : mapping of str to (str, str)
        Learned class → (name, label) of its time-reversed class.
    definitions : tuple of ClassDefinition
        Designed classes.
    keyframes : tuple of KeyframeDefinition
        Hand-designed keyframe queries of learned classes (they replace a
        learned query; mirrored and reversed classes take them mirrored /
        reversed), and of copies (a definition with ``template``).
    label_order : tuple of str
        Label order of the model (Δarg ties); labels not in it follow in
        order of appearance.
    delta, tau : float
        δ of the learned templates; τ of learned, mirrored and reversed classes.
    concurrent_labels : tuple of str
        Labels annotated beside the others (``Model.concurrent_labels``);
        those without a class in the model are left out.
    """

    labels: Mapping = field(default_factory=dict)
    mirrors: Mapping = field(default_factory=dict)
    reversals: Mapping = field(default_factory=dict)
    definitions: tuple = ()
    keyframes: tuple = ()
    label_order: tuple = PAPER_LABELS
    delta: float = DEFAULT_DELTA
    tau: float = DEFAULT_TAU
    concurrent_labels: tuple = ()


def clip_words(clips):
    """The words of a sequence of clips (:class:`Clip`, ``(name, words)`` pairs or arrays)."""
    out = []
    for c in clips:
        if isinstance(c, Clip):
            out.append(c.words)
        elif isinstance(c, tuple):
            out.append(c[-1])
        else:
            out.append(c)
    return [np.asarray(w, dtype=np.uint64) for w in out]


def mirror_class(c: ClassModel, name: str, label: str | None = None) -> ClassModel:
    """The left/right mirror image of a class (template, quantized template, keyframe query)."""
    return ClassModel(name, c.label if label is None else label,
                      template=None if c.template is None else c.template.mirrored(),
                      quantized=c.quantized.mirrored(), delta=c.delta, tau=c.tau,
                      keyframe_query=None if c.keyframe_query is None else c.keyframe_query.mirrored())


def reverse_class(c: ClassModel, name: str, label: str) -> ClassModel:
    """A class played backwards (quantized template and keyframe query; no real-valued template)."""
    return ClassModel(name, label, quantized=c.quantized.reversed(), delta=c.delta, tau=c.tau,
                      keyframe_query=None if c.keyframe_query is None else c.keyframe_query.reversed())


def _check(recipe, clips):
    if not isinstance(recipe, Recipe):
        raise ParameterError(f"recipe must be a lab.recipe.Recipe, got {type(recipe).__name__}")
    for what, keys in (("mirrors", recipe.mirrors), ("reversals", recipe.reversals),
                       ("keyframes", [k.template or k.cls for k in recipe.keyframes])):
        unknown = sorted(set(keys) - set(recipe.labels))
        if unknown:
            raise ParameterError(f"recipe.{what} names classes {unknown} that recipe.labels does not learn")
    taken = sorted(set(recipe_copies(recipe)) & set(recipe.labels))
    if taken:
        raise ParameterError(f"recipe.keyframes copies a template to {taken}, which recipe.labels learns")


def recipe_copies(recipe) -> dict:
    """Copy → the learned class whose template it takes (keyframe definitions with ``template``)."""
    return {k.cls: k.template for k in recipe.keyframes if k.template}


def recipe_clips(clips, recipe):
    """Training clips of every class with clips, mirror images included (for T− of the GA).

    Returns
    -------
    dict of str to list of Clip
        Learned classes (in ``recipe.labels`` order) and their mirrors
        (clips mirrored by :func:`mocapdb.features.mirror_words`).
    """
    out = {c: list(clips[c]) for c in recipe.labels if clips.get(c)}
    for c, m in recipe.mirrors.items():
        if c in out:
            out[m] = [Clip(x.name + "~mirror", mirror_words(x.words), x.group, x.document) for x in out[c]]
    return out


def build_model(clips, recipe, *, name, keyframes=None, cache=None):
    """A model from training clips and a recipe (module docstring).

    Parameters
    ----------
    clips : mapping of str to sequence of Clip
        Learned class → its clips in a deterministic order (classes without
        clips are left out, with their mirrors and reversals; classes the
        recipe does not name are ignored).
    recipe : Recipe
    name : str
    keyframes : callable, optional
        ``keyframes(model, clips)`` → ``{class: KeyframeQuery}`` for learned
        classes, given the model of learned classes and
        :func:`recipe_clips`; e.g. :func:`mocapdb.learning.keyframe_learning.learn_keyframe_queries`
        wrapped. Default: learned, mirrored and reversed classes get no query
        (designed classes keep their definitions').
    cache : dict, optional
        Learned templates kept across calls, keyed by class and clip names
        (evaluation folds share most of their clips).

    Returns
    -------
    Model
        Classes grouped by label in ``recipe.label_order``; within a label:
        learned, mirrored, reversed, copies, designed, each in recipe order.
    """
    _check(recipe, clips)
    learned = []
    for c, lab in recipe.labels.items():
        cl = clips.get(c)
        if not cl:
            continue
        key = (c, tuple(x.name if isinstance(x, Clip) else None for x in cl))
        mt = cache.get(key) if cache is not None and None not in key[1] else None
        if mt is None:
            mt = learn_template(clip_words(cl))
            if cache is not None and None not in key[1]:
                cache[key] = mt
        learned.append(ClassModel(c, lab, template=mt, delta=recipe.delta, tau=recipe.tau))
    if keyframes is not None and learned:
        queries = keyframes(Model(name, tuple(learned)), recipe_clips(clips, recipe))
        learned = [dataclasses.replace(c, keyframe_query=queries.get(c.name, c.keyframe_query)) for c in learned]
    learned, copies = (list(x) for x in apply_keyframe_definitions(learned, recipe.keyframes))
    by_name = {c.name: c for c in learned}
    derived = [mirror_class(by_name[c], m) for c, m in recipe.mirrors.items() if c in by_name]
    derived += [reverse_class(by_name[c], n, lab) for c, (n, lab) in recipe.reversals.items() if c in by_name]
    derived += copies
    designed = [compile_definition(d) for d in recipe.definitions]
    classes = learned + derived + designed
    names = [c.name for c in classes]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ParameterError(f"class names {dup} occur twice in the recipe; rename the mirrored, reversed or "
                             "designed classes")
    order = list(recipe.label_order) + [c.label for c in classes if c.label not in recipe.label_order]
    order = list(dict.fromkeys(order))
    rank = {lab: k for k, lab in enumerate(order)}
    classes.sort(key=lambda c: rank[c.label])  # stable: keeps the source order within a label
    used = {c.label for c in classes}
    return Model(name, tuple(classes), labels=tuple(lab for lab in order if lab in used),
                 concurrent_labels=tuple(lab for lab in recipe.concurrent_labels if lab in used))


def default_recipe(definitions=None) -> Recipe:
    """The recipe of the shipped default model.

    Learned classes and labels from the shipped ``default`` mapping
    (``mocapdb/shipped_models/default_labels.csv``), :data:`DEFAULT_MIRRORS`,
    :data:`DEFAULT_REVERSALS`, and the class and keyframe definitions
    shipped in ``mocapdb/shipped_models/classes/`` (or ``definitions``: files or
    folders).
    """
    if definitions is None:
        with resources.as_file(resources.files("mocapdb.shipped_models").joinpath(DEFINITIONS_DIR)) as d:
            defs, keyframes = read_definitions(d)
    else:
        defs, keyframes = read_definitions(definitions)
    return Recipe(labels=class_labels("default"), mirrors=dict(DEFAULT_MIRRORS), reversals=dict(DEFAULT_REVERSALS),
                  definitions=tuple(defs), keyframes=tuple(keyframes), concurrent_labels=DEFAULT_CONCURRENT)
