"""Query templates: what a query by example matches (paper Sect. 3 templates, used for retrieval).

A query is one stretch of a motion, or several ("more like these"). Its
template is a :class:`~mocapdb.templates.QuantizedTemplate`, the form Δ
matches (paper Sect. 4):

* :func:`clip_template` — the stretch's own words, one column per frame,
  every chosen feature fixed (weights 1): a one-example template;
* :func:`mirror_template` — a template learned from the stretch and its
  left/right mirror image (:func:`mocapdb.features.mirror_words`): features
  in which the two differ become wildcards, so either side matches;
* :func:`examples_template` — a template learned from several stretches by
  the class training of :mod:`mocapdb.learning` (warping and averaging,
  δ-quantization): what the examples share is fixed, the rest is wildcard.

``features`` restricts every template to a feature subset
(:func:`feature_mask`): ``"all"`` 40 features, the toolbox's sets
``"upper"`` (features 1–14: arms and hands) and ``"lower"`` (15–26: legs and
feet), or feature names; the others become wildcards.
"""
from __future__ import annotations

import numpy as np

from mocapdb.annotation.model import DEFAULT_DELTA
from mocapdb.errors import ParameterError
from mocapdb.features import FEATURE_NAMES, FEATURE_SETS, N_FEATURES, mirror_words
from mocapdb.learning import train_model
from mocapdb.templates import QuantizedTemplate, learn_template

#: the named feature subsets of :func:`feature_mask`
FEATURE_CHOICES = ("all", "upper", "lower")

_ALL = (1 << N_FEATURES) - 1


def feature_mask(features="all") -> int:
    """The 40-bit mask of a feature subset.

    Parameters
    ----------
    features : str or sequence of str
        ``"all"``, ``"upper"``, ``"lower"`` (the toolbox's feature sets), or
        feature names (:data:`mocapdb.features.FEATURE_NAMES`) as a sequence
        or one comma-separated string.

    Returns
    -------
    int
        Bit k−1 set for every chosen feature k.

    Raises
    ------
    ParameterError
        An unknown name (with the nearest names), or no feature at all.
    """
    if isinstance(features, str):
        if features in ("all", "upper", "lower"):
            if features == "all":
                return _ALL
            first, n = FEATURE_SETS[features]
            return ((1 << n) - 1) << first
        names = [x.strip() for x in features.split(",") if x.strip()]
    else:
        names = [str(x).strip() for x in features]
    if not names:
        raise ParameterError(f"features must be one of {', '.join(FEATURE_CHOICES)} or feature names, got "
                             f"{features!r}")
    mask = 0
    for name in names:
        if name not in FEATURE_NAMES:
            import difflib

            near = difflib.get_close_matches(name, FEATURE_NAMES, n=3, cutoff=0.5)
            raise ParameterError(f"unknown feature {name!r}" + (f"; did you mean {', '.join(near)}?" if near else
                                                                 f"; features are {', '.join(FEATURE_CHOICES)} or "
                                                                 "names of the feature_flags view"))
        mask |= 1 << FEATURE_NAMES.index(name)
    return mask


def _words(words, what):
    w = np.asarray(words)
    if w.ndim != 1 or w.dtype != np.uint64:
        raise ParameterError(f"{what} must be a 1-D uint64 array of packed 30 Hz words, got dtype {w.dtype} "
                             f"shape {w.shape}")
    if w.size == 0:
        raise ParameterError(f"{what} has no frames")
    return np.ascontiguousarray(w)


def restrict(template: QuantizedTemplate, mask: int) -> QuantizedTemplate:
    """A template with every feature outside ``mask`` made a wildcard."""
    m = np.uint64(mask)
    return QuantizedTemplate(template.mask & m, template.value & m, template.weights)


def clip_template(words, *, features="all") -> QuantizedTemplate:
    """The stretch's own words as a template: a column per frame, weight 1.

    Parameters
    ----------
    words : (n,) uint64
        The query stretch (packed 30 Hz words).
    features : str or sequence of str
        See :func:`feature_mask`.

    Returns
    -------
    QuantizedTemplate
        n columns.
    """
    w = _words(words, "the query")
    m = np.uint64(feature_mask(features))
    return QuantizedTemplate(np.full(w.size, m, np.uint64), w & m, np.ones(w.size))


def mirror_template(words, *, features="all", delta=DEFAULT_DELTA) -> QuantizedTemplate:
    """A template learned from the stretch and its left/right mirror image (δ-quantized).

    Where the stretch is left/right symmetric the template is its words;
    where a feature differs from its mirror feature the column has a
    wildcard (learned value 0.5).
    """
    w = _words(words, "the query")
    mt = learn_template([w, mirror_words(w)])
    return restrict(mt.quantize(delta), feature_mask(features))


def examples_template(examples, *, features="all", delta=DEFAULT_DELTA) -> QuantizedTemplate:
    """A template learned from several example stretches (the class training of :mod:`mocapdb.learning`).

    Parameters
    ----------
    examples : sequence of (n_i,) uint64
        Two or more stretches; their order matters as for
        :func:`mocapdb.learning.train_model` (the template is the first's slot).
    features : str or sequence of str
    delta : float, default 0.05
        Quantization threshold δ (the annotation's).

    Returns
    -------
    QuantizedTemplate
    """
    ex = [_words(w, f"example {k + 1}") for k, w in enumerate(examples)]
    if len(ex) < 2:
        raise ParameterError(f"examples_template needs two or more examples, got {len(ex)}; use clip_template")
    model = train_model({"query": ex}, name="similar", delta=delta)
    return restrict(model.classes[0].quantized, feature_mask(features))


__all__ = ["FEATURE_CHOICES", "feature_mask", "restrict", "clip_template", "mirror_template", "examples_template"]
