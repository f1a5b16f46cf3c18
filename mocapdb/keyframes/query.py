"""Keyframe queries (Baak, Müller & Seidel 2008; KEYFRAMES.md §2, §5, §8.1).

A keyframe query (V, d) is a sequence of K keyframes -- fuzzy feature words,
each a pair ``(mask, value)`` of 40-bit words: a frame with word w matches iff
``w & mask == value`` (mask bit 0 = wildcard) -- and K-1 gap bounds
``d_min[g] <= t_{g+1} - t_g <= d_max[g]`` (30 Hz frames).  The search over an
index lives in :mod:`mocapdb.keyframes.search`.

Public API
----------
KeyframeQuery                          the query (+ ``from_stiffness``, ``from_toolbox``)
keyframe_mask_value                    a 0/1/0.5 keyframe vector -> (mask, value)
stiffness_bounds                       gap bounds from template distances
annot_margins                          extension margins used by annotation (TEMPLATES.md §10)
choose_keyframes_equally_distributed   the toolbox's heuristic chooser (§8.1)

Template positions are 0-based. An unbounded ``d_max`` is :data:`UNBOUNDED` in
memory (``+inf`` is accepted) and NULL in the database.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.features import FEATURE_SETS, N_FEATURES, mirror_words, reverse_fuzzy_words

#: d_max value meaning "+inf" (large enough never to bind, small enough that
#: frame + UNBOUNDED and frame - UNBOUNDED cannot overflow int64)
UNBOUNDED = 1 << 62
#: the toolbox's keyframeIndex order {'AK_upper', 'AK_lower', 'AK_mix_avr'}
TOOLBOX_SETS = ("upper", "lower", "mix")

_ALL40 = (1 << N_FEATURES) - 1

# --------------------------------------------------------------------------
# the query


def set_bits(name) -> int:
    """The 40-bit mask of a toolbox feature set's bits (``'upper'``, ``'lower'``, ``'mix'``)."""
    first, n = FEATURE_SETS[name]
    return ((1 << n) - 1) << first


def keyframe_mask_value(vector, *, feature_set=None) -> tuple[int, int]:
    """Convert a keyframe vector with entries 0, 1, 0.5 (wildcard) to ``(mask, value)``.

    Parameters
    ----------
    vector : (n,) array_like of {0, 0.5, 1}
        Over one feature set (n = its size, entry i = feature i+1 of the set)
        when ``feature_set`` is given, else over all 40 features.
    feature_set : {'upper', 'lower', 'mix'}, optional

    Returns
    -------
    mask, value : int
        40-bit words (bit k-1 = feature k of the full word).

    Raises
    ------
    ParameterError
        Entries other than 0, 0.5, 1 or a length not matching the set
        (as checkKeyframes.m).
    """
    if feature_set is not None and feature_set not in FEATURE_SETS:
        raise ParameterError(f"feature_set={feature_set!r}; allowed: "
                             f"{', '.join(FEATURE_SETS)} or None")
    v = np.asarray(vector, dtype=np.float64).ravel()
    first, n = FEATURE_SETS[feature_set] if feature_set is not None else (0, N_FEATURES)
    if len(v) != n:
        where = f"feature set {feature_set!r}" if feature_set else "the full word"
        raise ParameterError(f"keyframe vector has {len(v)} entries; {where} needs {n}")
    bad = ~((v == 0) | (v == 0.5) | (v == 1))
    if bad.any():
        raise ParameterError(f"keyframe vector entry {int(np.argmax(bad))} is {v[bad][0]!r}; "
                             "entries must be 0, 1 or 0.5 (wildcard)")
    mask = value = 0
    for i, x in enumerate(v):
        if x != 0.5:
            mask |= 1 << (first + i)
            if x == 1:
                value |= 1 << (first + i)
    return mask, value


def _gap_array(x, name, k):
    a = np.asarray(x, dtype=np.float64).ravel()
    if len(a) != k:
        raise ParameterError(f"{name} has {len(a)} entries; a query with {k + 1} keyframes "
                             f"needs {k}")
    if np.isnan(a).any():
        raise ParameterError(f"{name} contains NaN; use inf for an unbounded gap")
    if (a < 0).any():
        raise ParameterError(f"{name}={a.tolist()} has negative entries; gap bounds are "
                             ">= 0 frames")
    if (np.isfinite(a) & (a != np.floor(a))).any():
        raise ParameterError(f"{name}={a.tolist()} must be whole frame counts")
    return np.where(a >= UNBOUNDED, UNBOUNDED, np.minimum(a, UNBOUNDED)).astype(np.int64)


@dataclass(frozen=True, eq=False)
class KeyframeQuery:
    """A keyframe query (V, d) over packed 40-bit feature words.

    Parameters
    ----------
    mask, value : (K,) uint64
        Keyframe k matches word w iff ``w & mask[k] == value[k]``.
    positions : (K,) int
        Template columns (0-based, non-decreasing) the keyframes were taken
        from; used for :func:`annot_margins` and :meth:`from_stiffness`.
    d_min, d_max : (K-1,) int
        Admissible distance between the frames matched to keyframes g and g+1;
        ``d_max`` may be ``inf`` (stored as :data:`UNBOUNDED`).
    template_length : int
        Length L of the motion template (>= positions[-1] + 1).
    feature_sets : tuple of (str or None), optional
        Per keyframe the feature set it is restricted to (its mask must lie
        within the set's bits); None = any bits of the 40-bit word.

    Raises
    ------
    ParameterError
        Inconsistent lengths, value bits outside the mask, mask bits outside
        the keyframe's set or above bit 39, decreasing positions, negative or
        crossed gap bounds.
    """

    mask: np.ndarray
    value: np.ndarray
    positions: np.ndarray
    d_min: np.ndarray
    d_max: np.ndarray
    template_length: int
    feature_sets: tuple = None

    def __post_init__(self):
        mask = np.atleast_1d(np.asarray(self.mask)).astype(np.uint64)
        value = np.atleast_1d(np.asarray(self.value)).astype(np.uint64)
        pos = np.atleast_1d(np.asarray(self.positions))
        K = len(mask)
        if K < 1 or mask.ndim != 1:
            raise ParameterError("a keyframe query needs at least one keyframe "
                                 "(mask of shape (K,))")
        if len(value) != K or len(pos) != K:
            raise ParameterError(f"mask, value, positions have lengths {K}, {len(value)}, "
                                 f"{len(pos)}; "
                                 "they must be equal")
        if (mask & ~np.uint64(_ALL40)).any():
            raise ParameterError("mask has bits above bit 39; keyframes are 40-bit feature words")
        if (value & ~mask).any():
            k = int(np.argmax(value & ~mask))
            raise ParameterError(f"value[{k}]={int(value[k]):#x} has bits outside mask[{k}]="
                                 f"{int(mask[k]):#x}; clear them (wildcard bits carry no value)")
        if pos.dtype.kind == "f" and (pos != np.floor(pos)).any():
            raise ParameterError(f"positions={pos.tolist()} must be whole template columns")
        pos = pos.astype(np.int64)
        if (pos < 0).any() or (np.diff(pos) < 0).any():
            raise ParameterError(f"positions={pos.tolist()} must be >= 0 and non-decreasing "
                                 "(Keyframe Positions are not ascending)")
        L = int(self.template_length)
        if L != self.template_length or L < int(pos[-1]) + 1:
            raise ParameterError(f"template_length={self.template_length!r} must be an integer "
                                 f">= last position + 1 = {int(pos[-1]) + 1}")
        sets = self.feature_sets
        sets = (None,) * K if sets is None else tuple(sets)
        if len(sets) != K:
            raise ParameterError(f"feature_sets has {len(sets)} entries for {K} keyframes")
        for k, s in enumerate(sets):
            if s is None:
                continue
            if s not in FEATURE_SETS:
                raise ParameterError(f"feature_sets[{k}]={s!r}; allowed: "
                                     f"{', '.join(FEATURE_SETS)} or None")
            if int(mask[k]) & ~set_bits(s):
                raise ParameterError(f"keyframe {k} is restricted to {s!r} but its mask "
                                     f"{int(mask[k]):#x} has bits outside that set")
        d_min = _gap_array(self.d_min, "d_min", K - 1)
        d_max = _gap_array(self.d_max, "d_max", K - 1)
        if (d_max < d_min).any():
            g = int(np.argmax(d_max < d_min))
            raise ParameterError(f"gap {g}: d_max={self.d_max[g]!r} < d_min={self.d_min[g]!r}; "
                                 "need d_min <= d_max")
        for name, val in (("mask", mask), ("value", value), ("positions", pos),
                          ("d_min", d_min), ("d_max", d_max), ("template_length", L),
                          ("feature_sets", sets)):
            object.__setattr__(self, name, val)
        for a in (mask, value, pos, d_min, d_max):
            a.flags.writeable = False

    @property
    def n_keyframes(self) -> int:
        return len(self.mask)

    def mirrored(self) -> "KeyframeQuery":
        """The query of the left/right mirrored motion (FEATURES.md §7; 40-bit keyframes)."""
        return KeyframeQuery(mirror_words(self.mask), mirror_words(self.value), self.positions, self.d_min,
                             self.d_max, self.template_length, self.feature_sets)

    def reversed(self) -> "KeyframeQuery":
        """The query of the motion played backwards: keyframes and gaps in reverse order,
        positions ``L - 1 - p``, features by :func:`mocapdb.features.reverse_fuzzy_words`."""
        m, v = reverse_fuzzy_words(self.mask[::-1], self.value[::-1])
        return KeyframeQuery(m, v, self.template_length - 1 - self.positions[::-1], self.d_min[::-1],
                             self.d_max[::-1], self.template_length, self.feature_sets[::-1])

    def to_vectors(self) -> np.ndarray:
        """``(K, 40) float64`` keyframe vectors with 0, 1 and 0.5 (wildcard)."""
        bits = np.arange(N_FEATURES, dtype=np.uint64)
        m = (self.mask[:, None] >> bits) & np.uint64(1)
        v = (self.value[:, None] >> bits) & np.uint64(1)
        return np.where(m == 1, v.astype(np.float64), 0.5)

    @classmethod
    def from_stiffness(cls, mask, value, positions, stiffness, *, template_length,
                       feature_sets=None) -> "KeyframeQuery":
        """Gap bounds from keyframe distances and stiffness (KEYFRAMES.md §4).

        For gap g with distance δ = positions[g+1] - positions[g] and
        stiffness s: ``d_min = ceil(s·δ)``, ``d_max = floor((1/s)·δ)`` in IEEE
        doubles as keyframeSearchEfficient.m computes them; NaN (δ = 0, s = 0)
        becomes +inf, s = 0 gives [0, +inf], s = 1 gives [δ, δ].

        Parameters
        ----------
        mask, value, positions
            As :class:`KeyframeQuery`.
        stiffness : float or (K-1,) array_like
            In [0, 1]; a scalar applies to every gap.
        template_length : int
        feature_sets : tuple, optional

        Raises
        ------
        ParameterError
            Stiffness outside [0, 1] or of the wrong length (checkKeyframes.m),
            decreasing positions, or d_max < d_min.
        """
        pos = np.atleast_1d(np.asarray(positions))
        if (np.diff(pos) < 0).any():
            raise ParameterError(f"positions={pos.tolist()} are not ascending")
        n_gaps = max(len(pos) - 1, 0)
        s = np.asarray(stiffness, dtype=np.float64)
        if s.ndim == 0:
            s = np.full(n_gaps, float(s))
        s = s.ravel()
        if len(s) != n_gaps:
            raise ParameterError(f"stiffness has {len(s)} entries; {len(pos)} keyframes need "
                                 f"{n_gaps} "
                                 "(Stiffness dimension doesn't match)")
        if np.isnan(s).any() or (s < 0).any() or (s > 1).any():
            raise ParameterError(f"stiffness={s.tolist()} out of range; each must be in [0, 1]")
        d_min, d_max = stiffness_bounds(np.diff(pos).astype(np.float64), s)
        return cls(mask, value, pos, d_min, d_max, template_length, feature_sets)

    @classmethod
    def from_toolbox(cls, vectors, set_index, positions, stiffness, *, template_length,
                     pad_short_mix=False) -> "KeyframeQuery":
        """A hand-made toolbox query (manualKeyframesForAnnotation_AVR.m form).

        Parameters
        ----------
        vectors : sequence of (n_s,) array_like of {0, 0.5, 1}
            Keyframe k over the feature set ``set_index[k]``.
        set_index : (K,) int
            Toolbox ``keyframeIndex``: 1 = upper, 2 = lower, 3 = mix.
        positions : (K,) int
            Toolbox ``keyframePositions`` (1-based template columns).
        stiffness : float or (K-1,)
        template_length : int
        pad_short_mix : bool, default False
            Pad 13-entry vectors of the 14-bit mix set with a wildcard for
            feature 40 (the stale 39-feature cases of the toolbox file,
            KEYFRAMES.md §2, proposed); the toolbox itself rejects them.

        Raises
        ------
        ParameterError
            As checkKeyframes.m.
        """
        set_index = np.atleast_1d(np.asarray(set_index)).astype(np.int64)
        if len(vectors) != len(set_index):
            raise ParameterError(f"{len(vectors)} vectors but {len(set_index)} set indices")
        if ((set_index < 1) | (set_index > 3)).any():
            raise ParameterError(f"set_index={set_index.tolist()}; toolbox indices are 1 (upper), "
                                 "2 (lower), 3 (mix)")
        sets = tuple(TOOLBOX_SETS[i - 1] for i in set_index)
        masks, values = [], []
        for k, (vec, s) in enumerate(zip(vectors, sets)):
            vec = np.asarray(vec, dtype=np.float64).ravel()
            if pad_short_mix and s == "mix" and len(vec) == FEATURE_SETS["mix"][1] - 1:
                vec = np.append(vec, 0.5)
            try:
                m, v = keyframe_mask_value(vec, feature_set=s)
            except ParameterError as e:
                raise ParameterError(f"keyframe {k + 1}: {e}") from None
            masks.append(m)
            values.append(v)
        pos = np.atleast_1d(np.asarray(positions)).astype(np.int64) - 1
        return cls.from_stiffness(np.array(masks, np.uint64), np.array(values, np.uint64), pos,
                                  stiffness, template_length=template_length, feature_sets=sets)


def stiffness_bounds(distances, stiffness):
    """``(d_min, d_max)`` int64 arrays from gap distances and stiffness (KEYFRAMES.md §4).

    ``d_min = ceil(s·δ)``, ``d_max = floor((1/s)·δ)``, NaN -> +inf
    (:data:`UNBOUNDED`).  Raises ParameterError if some d_max < d_min.
    """
    delta = np.asarray(distances, dtype=np.float64)
    s = np.asarray(stiffness, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        lo = np.ceil(s * delta)
        hi = np.floor((1.0 / s) * delta)
    lo = np.where(np.isnan(lo), np.inf, lo)
    hi = np.where(np.isnan(hi), np.inf, hi)
    if (hi - lo < 0).any():
        g = int(np.argmax(hi - lo < 0))
        raise ParameterError(f"gap {g}: distance {delta[g]} with stiffness {s[g]} gives "
                             f"d_max={hi[g]} < d_min={lo[g]}")
    if np.isinf(lo).any():  # cannot happen for stiffness in [0, 1]; keep the query valid
        raise ParameterError("a gap got d_min = inf; check distances and stiffness")
    lo = lo.astype(np.int64)
    hi = np.where(np.isinf(hi) | (hi >= UNBOUNDED), UNBOUNDED, np.minimum(hi, UNBOUNDED))
    hi = hi.astype(np.int64)
    return lo, hi


def annot_margins(query: KeyframeQuery) -> tuple[int, int]:
    """Extension margins of the annotation scripts: ``(2·(pos_1 - 1), 2·(L - pos_K))``.

    With 0-based positions p: ``(2·p_1, 2·(L - 1 - p_K))``, so a segment can
    hold a template match stretched up to 2x (TEMPLATES.md §10, KEYFRAMES.md §5).
    """
    p = query.positions
    return 2 * int(p[0]), 2 * (query.template_length - 1 - int(p[-1]))


# --------------------------------------------------------------------------
# heuristic keyframe chooser (§8.1)


def choose_keyframes_equally_distributed(mask, value, *, n_keyframes=3, stiffness=0.5,
                                         feature_set=None) -> KeyframeQuery:
    """keyframesChooseLeastGrayValuesEquallyDistributed.m on a quantized template.

    Ignore floor(0.1·L) columns at each end; split the remaining L' columns
    into ``n_keyframes`` sections of floor(L'/K) columns, one column skipped
    between sections, the last section running to the end; in each section
    take the first column with the fewest wildcards.

    Parameters
    ----------
    mask, value : (L,) uint64
        Quantized template columns (mask bit 0 = wildcard), e.g.
        ``QuantizedTemplate.mask``/``.value``; L = template length.
    n_keyframes : int, default 3
        The toolbox's ``par.keyframesNumMax`` (3 = the paper's mean number of
        keyframes).
    stiffness : float or (K-1,), default 0.5
        Gap stiffness for :meth:`KeyframeQuery.from_stiffness` (proposed: the
        value most hand-made queries use; 0.5 admits time warps of 0.5x-2x).
    feature_set : {'upper', 'lower', 'mix'}, optional
        Restrict the keyframes (and the wildcard count) to one set, as the
        toolbox's single-set use; default all 40 features.

    Returns
    -------
    KeyframeQuery
        Positions = chosen columns (0-based), template_length = L.

    Raises
    ------
    ParameterError
        Template too short for ``n_keyframes`` sections (the toolbox fails
        with an index error there).
    """
    mask = np.atleast_1d(np.asarray(mask)).astype(np.uint64)
    value = np.atleast_1d(np.asarray(value)).astype(np.uint64)
    if mask.ndim != 1 or mask.shape != value.shape or len(mask) == 0:
        raise ParameterError(f"mask and value must be (L,) uint64 of equal length, "
                             f"got {mask.shape}, {value.shape}")
    K = int(n_keyframes)
    if K != n_keyframes or K < 1:
        raise ParameterError(f"n_keyframes={n_keyframes!r} must be a positive integer")
    if feature_set is not None and feature_set not in FEATURE_SETS:
        raise ParameterError(f"feature_set={feature_set!r}; allowed: "
                             f"{', '.join(FEATURE_SETS)} or None")
    bits = set_bits(feature_set) if feature_set is not None else _ALL40
    L = len(mask)
    m = mask & np.uint64(bits)
    v = value & m
    n_bits = bin(bits).count("1")
    wild = n_bits - np.array([bin(int(x)).count("1") for x in m], np.int64)
    ignored = math.floor(L * 0.1)
    inner = wild[ignored:L - ignored]
    n = len(inner)
    sec = n // K
    last_start = (K - 1) * (sec + 1)
    if sec < 1 or last_start >= n:
        raise ParameterError(f"template of length {L} ({n} columns after ignoring {ignored} "
                             "at each end) "
                             f"is too short for n_keyframes={K}; use fewer keyframes")
    pos = []
    c = 0
    for _ in range(K - 1):
        pos.append(c + int(np.argmin(inner[c:c + sec])) + ignored)  # argmin: first minimum
        c += sec + 1
    pos.append(c + int(np.argmin(inner[c:])) + ignored)
    pos = np.array(pos, np.int64)
    sets = None if feature_set is None else (feature_set,) * K
    return KeyframeQuery.from_stiffness(m[pos], v[pos], pos, stiffness, template_length=L,
                                        feature_sets=sets)


__all__ = ["UNBOUNDED", "TOOLBOX_SETS", "KeyframeQuery", "set_bits", "annot_margins", "choose_keyframes_equally_distributed",
           "keyframe_mask_value", "stiffness_bounds"]
