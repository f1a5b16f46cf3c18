"""Keyframe queries and the keyframe-chain search (Baak, Müller & Seidel 2008).

A keyframe query (V, d) is a sequence of K keyframes -- fuzzy feature words,
each a pair ``(mask, value)`` of 40-bit words: a frame with word w matches iff
``w & mask == value`` (mask bit 0 = wildcard) -- and K-1 gap bounds
``d_min[g] <= t_{g+1} - t_g <= d_max[g]`` (30 Hz frames).  The search returns
the document segments that contain an admissible chain of matching frames,
extended by margins and merged, exactly as the toolbox's ``C_KeyframeSearch``
(KEYFRAMES.md §3-5).

Public API
----------
KeyframeQuery                          the query (+ ``from_stiffness``, ``from_toolbox``)
keyframe_mask_value                    a 0/1/0.5 keyframe vector -> (mask, value)
keyframe_search                        one query -> segments (and raw hits)
keyframe_search_batch                  many queries on one index -> segments per query
keyframe_hit_documents                 many queries -> (n_queries, n_docs) "has a hit" (GA fitness)
keyframe_intervals, keyframe_postings  the per-keyframe intermediate results (§3)
annot_margins                          extension margins used by annotation (TEMPLATES.md §10)
intervals_from_runs, chain_search      the search on matching runs from SQL
choose_keyframes_equally_distributed   the toolbox's heuristic chooser (§8.1)

The numba kernels live in :mod:`mocapdb.keyframe_kernels`.  Frames, template
positions and documents are 0-based, segment ends inclusive.
``d_max = +inf`` is stored as :data:`UNBOUNDED`.
"""
from __future__ import annotations

import math
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.features import FEATURE_SETS, N_FEATURES
from mocapdb.index import SET_PARTS, Index, Segments, fuzzy_postings
from mocapdb.keyframe_kernels import (_AUTO, _chain_batch_kernel, _hit_documents_kernel,
                                      _keyframe_intervals_kernel, _runs_intervals_kernel,
                                      _search_kernel)

#: d_max value meaning "+inf" (large enough never to bind, small enough that
#: frame + UNBOUNDED and frame - UNBOUNDED cannot overflow int64)
UNBOUNDED = 1 << 62
#: the toolbox's keyframeIndex order {'AK_upper', 'AK_lower', 'AK_mix_avr'}
TOOLBOX_SETS = ("upper", "lower", "mix")

_ALL40 = (1 << N_FEATURES) - 1


# --------------------------------------------------------------------------
# the query


def _set_bits(name) -> int:
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
            if int(mask[k]) & ~_set_bits(s):
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
# planning: keyframes -> single-part sub-keyframes


def _check_layout(layout):
    if layout not in (None, "sets", "full"):
        raise ParameterError(f"layout={layout!r}; use None (auto), 'sets' (the toolbox's per-set "
                             "indexes) or 'full' (the 40-bit index)")


def _keyframe_subs(index: Index, mask: int, value: int, feature_set, layout):
    """Sub-keyframes ``((part id, local mask, local value), ...)`` answering one keyframe.

    None (auto): a keyframe within one feature set uses that set's part when
    the index has it, otherwise the 40-bit part; a keyframe spanning several
    sets uses the 40-bit part when present, else one sub-keyframe per set
    (their intervals are intersected).  'sets'/'full' force a layout.
    """
    sets = [name for name in SET_PARTS if mask & _set_bits(name)]
    if feature_set is not None and not sets:
        sets = [feature_set]
    has_sets = all(name in index.parts for name in sets)
    if layout == "full" or (layout is None and "full" in index.parts
                            and (len(sets) > 1 or not has_sets)):
        return ((index.part_id("full"), mask, value),)
    if not sets:  # all wildcards: every frame matches, any part will do
        return ((0, 0, 0),)
    subs = []
    for name in sets:
        first, n = FEATURE_SETS[name]
        full = (1 << n) - 1
        subs.append((index.part_id(name), (mask >> first) & full, (value >> first) & full))
    return tuple(subs)


def _plan(index: Index, queries, layout):
    """Distinct keyframes of the queries and the flat arrays the kernels take."""
    _check_layout(layout)
    kf_id = {}
    q_kf = []
    q_kf_offset = [0]
    for query in queries:
        if not isinstance(query, KeyframeQuery):
            raise ParameterError(f"expected a KeyframeQuery, got {type(query).__name__}")
        for k in range(query.n_keyframes):
            subs = _keyframe_subs(index, int(query.mask[k]), int(query.value[k]),
                                  query.feature_sets[k], layout)
            q_kf.append(kf_id.setdefault(subs, len(kf_id)))
        q_kf_offset.append(len(q_kf))
    keys = list(kf_id)  # insertion order = keyframe id
    d_min = np.concatenate([q.d_min for q in queries]) if queries else np.empty(0, np.int64)
    d_max = np.concatenate([q.d_max for q in queries]) if queries else np.empty(0, np.int64)
    return keys, np.array(q_kf, np.int64), np.array(q_kf_offset, np.int64), d_min, d_max


def _sub_arrays(keys):
    sub_part, sub_mask, sub_value, kf_sub_offset = [], [], [], [0]
    for subs in keys:
        for p, m, v in subs:
            sub_part.append(p)
            sub_mask.append(m)
            sub_value.append(v)
        kf_sub_offset.append(len(sub_part))
    return (np.array(sub_part, np.int64), np.array(sub_mask, np.uint64),
            np.array(sub_value, np.uint64), np.array(kf_sub_offset, np.int64))


def _intervals(index: Index, keys, cache=None):
    """Intervals of the distinct keyframes ``keys``: (doc, start, end, kf_offset).

    With a ``cache`` dict, keyframes computed by earlier calls on the same
    index are reused and new ones are added.
    """
    if cache is None:
        return _keyframe_intervals_kernel(*index.kernel_arrays(), *_sub_arrays(keys),
                                          0, index.n_docs)
    missing = [k for k in keys if k not in cache]
    if missing:
        doc, start, end, off = _keyframe_intervals_kernel(*index.kernel_arrays(),
                                                          *_sub_arrays(missing), 0, index.n_docs)
        for i, key in enumerate(missing):
            a, b = off[i], off[i + 1]
            cache[key] = (doc[a:b].copy(), start[a:b].copy(), end[a:b].copy())
    parts = [cache[k] for k in keys]
    off = np.zeros(len(keys) + 1, np.int64)
    np.cumsum([len(x[0]) for x in parts], out=off[1:])
    return (*(np.concatenate([x[i] for x in parts]) for i in range(3)), off)


#: below this many frames a search runs on the calling thread (the hand-off to
#: a thread costs more than it saves on small indexes)
PARALLEL_MIN_FRAMES = 1 << 19
_POOL = None
_POOL_LOCK = threading.Lock()


def _pool():
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=os.cpu_count() or 1,
                                       thread_name_prefix="mocapdb-keyframes")
        return _POOL


def _shards(index: Index, n_threads):
    """Document ranges of about equal frame counts, one per thread."""
    if n_threads is None:
        n_threads = (os.cpu_count() or 1) if index.n_frames >= PARALLEL_MIN_FRAMES else 1
    if isinstance(n_threads, bool) or not isinstance(n_threads, (int, np.integer)) or n_threads < 1:
        raise ParameterError(f"n_threads={n_threads!r}; use None (auto) or a positive int")
    if n_threads == 1 or index.n_docs < 2:
        return [(0, index.n_docs)]
    cum = np.cumsum(index.doc_lengths)
    cuts = np.searchsorted(cum, cum[-1] * np.arange(1, n_threads) / n_threads)
    bounds = np.unique(np.concatenate([[0], np.minimum(cuts + 1, index.n_docs), [index.n_docs]]))
    return list(zip(bounds[:-1].tolist(), bounds[1:].tolist()))


def _search(index: Index, queries, ext_l, ext_r, want_hits, layout, n_threads, cache=None,
            strategy=_AUTO):
    """Segments (and hits) per query: lists of (n, 3) int64 row arrays."""
    keys, q_kf, q_kf_offset, d_min, d_max = _plan(index, queries, layout)
    n_q = len(queries)
    if cache is not None:
        iv = _intervals(index, keys, cache)
        segs, seg_q, hits, hit_q = _chain_batch_kernel(*iv, q_kf, q_kf_offset, d_min, d_max,
                                                       index.doc_lengths, ext_l, ext_r,
                                                       bool(want_hits))
        return ([segs[seg_q[i]:seg_q[i + 1]] for i in range(n_q)],
                [hits[hit_q[i]:hit_q[i + 1]] for i in range(n_q)])
    args = (*index.kernel_arrays(), *_sub_arrays(keys), q_kf, q_kf_offset, d_min, d_max,
            index.doc_lengths, ext_l, ext_r, 1 if want_hits else 0)
    no_hit_docs = np.zeros((0, 0), np.bool_)
    shards = _shards(index, n_threads)
    if len(shards) == 1:
        parts = [_search_kernel(*args, *shards[0], strategy, no_hit_docs)]
    else:  # documents are independent and the kernel releases the GIL
        parts = list(_pool().map(lambda sh: _search_kernel(*args, *sh, strategy, no_hit_docs),
                                 shards))
    if len(parts) == 1:
        s, s_q, h, h_q = parts[0]
        return ([s[s_q[i]:s_q[i + 1]] for i in range(n_q)],
                [h[h_q[i]:h_q[i + 1]] for i in range(n_q)])
    segs = [np.concatenate([s[s_q[i]:s_q[i + 1]] for s, s_q, _, _ in parts]) for i in range(n_q)]
    hits = [np.concatenate([h[h_q[i]:h_q[i + 1]] for _, _, h, h_q in parts]) for i in range(n_q)]
    return segs, hits


def _margins(x, n_q, name):
    a = np.asarray(x)
    if a.ndim == 0:
        a = np.full(n_q, a)
    if a.shape != (n_q,):
        raise ParameterError(f"{name} must be an int or one int per query ({n_q}), "
                             f"got shape {a.shape}")
    if a.dtype.kind not in "iu" and not (a == np.floor(a)).all():
        raise ParameterError(f"{name}={a.tolist()} must be whole frame counts")
    a = a.astype(np.int64)
    if (a < 0).any():
        raise ParameterError(f"{name}={a.tolist()} must be >= 0")
    return a


def _to_segments(rows):
    return Segments(rows[:, 0].copy(), rows[:, 1].copy(), rows[:, 2].copy())


# --------------------------------------------------------------------------
# public search API


def keyframe_intervals(index: Index, query: KeyframeQuery, *, layout=None) -> list:
    """Per-keyframe frame intervals B[k] (KEYFRAMES.md §3).

    Returns
    -------
    list of K :class:`~mocapdb.index.Segments`
        Keyframe k's maximal runs of matching frames ``(doc, start, end)``,
        sorted by (doc, start).  The same for every layout.
    """
    keys, q_kf, _, _, _ = _plan(index, [query], layout)
    doc, s, e, off = _intervals(index, keys)
    return [Segments(doc[off[i]:off[i + 1]], s[off[i]:off[i + 1]], e[off[i]:off[i + 1]])
            for i in q_kf]


def keyframe_postings(index: Index, query: KeyframeQuery, *, layout=None) -> list:
    """Per keyframe the matching index words and the union of their posting lists (§3).

    Every keyframe must be answered by one index part (restricted to one
    feature set, or the 40-bit part).

    Returns
    -------
    list of K :class:`~mocapdb.index.Postings`
    """
    _check_layout(layout)
    out = []
    for k in range(query.n_keyframes):
        subs = _keyframe_subs(index, int(query.mask[k]), int(query.value[k]),
                              query.feature_sets[k], layout)
        if len(subs) != 1:
            raise ParameterError(f"keyframe {k} spans several feature sets; its posting lists "
                                 "live in different per-set indexes (use a 'full' index)")
        p, m, v = subs[0]
        out.append(fuzzy_postings(index, index.parts[p], m, v))
    return out


def keyframe_search(index: Index, query: KeyframeQuery, *, extend_left=0, extend_right=0,
                    return_hits=False, layout=None, n_threads=None):
    """Segments of the documents that contain the keyframe chain (KEYFRAMES.md §5).

    Parameters
    ----------
    index : Index
    query : KeyframeQuery
    extend_left, extend_right : int, default 0
        Margins added to every hit before merging (annotation uses
        :func:`annot_margins`).
    return_hits : bool, default False
        Also return the raw hits (before extension and merging) in the
        toolbox's order (duplicates included).
    layout : {None, 'sets', 'full'}
        Which index parts answer the keyframes.  None: a keyframe within one
        feature set uses that set's index (the toolbox), a keyframe spanning
        several sets the 40-bit index if built, else the intersection of its
        per-set parts.  'sets'/'full' force one layout.  All give identical
        results.
    n_threads : int, optional
        Split the documents into this many ranges searched in parallel
        (default: every core for indexes of at least
        :data:`PARALLEL_MIN_FRAMES` frames, else 1).

    Returns
    -------
    segments : Segments
        ``(doc, start, end)``, 0-based inclusive, sorted by (doc, start),
        overlapping extended hits merged.
    hits : Segments
        Only with ``return_hits``: ``(doc, hit_start, hit_end)``.

    Notes
    -----
    With K = 1 (not defined by the toolbox) every interval of the keyframe is
    a hit.  A document is searched only if every keyframe matches in it; so
    the keyframes' posting lists first filter the documents (from the fewest
    postings up) and intervals are computed only in the documents left --
    the result is the same as with every keyframe's full intervals.

    References
    ----------
    KEYFRAMES.md §3-5; toolbox keyframeSearchEfficient.m, C_KeyframeSearch.c.
    """
    el = _margins(extend_left, 1, "extend_left")
    er = _margins(extend_right, 1, "extend_right")
    segs, hits = _search(index, [query], el, er, return_hits, layout, n_threads)
    if return_hits:
        return _to_segments(segs[0]), _to_segments(hits[0])
    return _to_segments(segs[0])


def keyframe_search_batch(index: Index, queries, *, extend_left=0, extend_right=0,
                          layout=None, n_threads=None, cache=None) -> list:
    """:func:`keyframe_search` for many queries on one index.

    Each query is searched with its own document filter (as
    :func:`keyframe_search`).  ``extend_left``/``extend_right`` are ints or
    one int per query.  ``cache``: a dict owned by the caller, used with this
    index (and layout) only and by one thread at a time, that keeps every
    keyframe's full intervals across calls, so keyframes shared between
    queries (frequent in a GA population) are matched once (the search then
    runs on the calling thread, without the document filter).

    Returns
    -------
    list of Segments, one per query.
    """
    queries = list(queries)
    el = _margins(extend_left, len(queries), "extend_left")
    er = _margins(extend_right, len(queries), "extend_right")
    if not queries:
        return []
    segs, _ = _search(index, queries, el, er, False, layout, n_threads, cache)
    return [_to_segments(x) for x in segs]


def keyframe_hit_documents(index: Index, queries, *, layout=None, cache=None) -> np.ndarray:
    """Which documents each query hits (the GA fitness, KEYFRAMES.md §8.2).

    Document d is hit iff :func:`keyframe_search` returns a segment in it;
    the search of a document stops at its first hit.  Runs on the calling
    thread (and releases the GIL): parallelise over independent GA runs.

    Parameters
    ----------
    index : Index
    queries : sequence of KeyframeQuery
    layout : {None, 'sets', 'full'}
        As in :func:`keyframe_search`.
    cache : dict, optional
        As in :func:`keyframe_search_batch`; a GA keeps one per training
        index (offspring mostly reuse their parents' keyframes).

    Returns
    -------
    (n_queries, n_docs) bool
    """
    queries = list(queries)
    out = np.zeros((len(queries), index.n_docs), np.bool_)
    if not queries:
        return out
    keys, q_kf, q_kf_offset, d_min, d_max = _plan(index, queries, layout)
    if cache is None:  # each query's intervals only where all its keyframes match
        zeros = np.zeros(len(queries), np.int64)
        _search_kernel(*index.kernel_arrays(), *_sub_arrays(keys), q_kf, q_kf_offset, d_min,
                       d_max, index.doc_lengths, zeros, zeros, 2, 0, index.n_docs, _AUTO, out)
        return out
    iv = _intervals(index, keys, cache)
    _hit_documents_kernel(*iv, q_kf, q_kf_offset, d_min, d_max, index.doc_lengths, out)
    return out


def intervals_from_runs(keyframe, doc, start, length):
    """Frame intervals of keyframes from their matching runs (KEYFRAMES.md §3 re-segmentation).

    Parameters
    ----------
    keyframe, doc, start, length : (n,) int
        Runs of constant word that match keyframe ``keyframe`` (any order;
        already sorted by (keyframe, doc, start) is detected and costs no
        sort): document, first frame (0-based) and number of frames — e.g.
        the rows of a postings table filtered by ``word & mask = value``.

    Returns
    -------
    keyframe, doc, start, end : (m,) int64
        Maximal intervals (adjacent runs merged), sorted by (keyframe, doc, start).
    """
    k, d, s, n = (np.ascontiguousarray(x, dtype=np.int64) for x in (keyframe, doc, start, length))
    if not (len(k) == len(d) == len(s) == len(n)):
        raise ParameterError(f"keyframe, doc, start, length have lengths {len(k)}, {len(d)}, "
                             f"{len(s)}, {len(n)}; they must be equal")
    order = np.empty(0, np.int64)
    n_docs = n_groups = 0
    if len(k):
        n_docs = int(d.max()) + 1
        n_groups = (int(k.max()) + 1) * n_docs
        if k.min() < 0 or d.min() < 0 or n_groups > 4 * len(k) + (1 << 20):
            order = np.lexsort((s, d, k))  # too many (keyframe, doc) groups to count
    return _runs_intervals_kernel(k, d, s, n, n_docs, n_groups, order)


def chain_search(intervals, query: KeyframeQuery, doc_lengths, *, extend_left=0, extend_right=0):
    """The chain search (§5) on given per-keyframe intervals instead of an index.

    Parameters
    ----------
    intervals : tuple (keyframe, doc, start, end) of (m,) int
        As returned by :func:`intervals_from_runs`: keyframe k's maximal
        matching intervals, sorted by (keyframe, doc, start), 0-based inclusive.
    query : KeyframeQuery
        Gap bounds (its masks are not used: ``intervals`` already answer them).
    doc_lengths : (n_docs,) int
        Frames per document (segments are clipped to them).
    extend_left, extend_right : int

    Returns
    -------
    Segments
        As :func:`keyframe_search` on an index whose keyframes give these intervals.
    """
    kf, doc, start, end = (np.ascontiguousarray(x, dtype=np.int64) for x in intervals)
    K = query.n_keyframes
    if len(kf) and (kf.min() < 0 or kf.max() >= K):
        raise ParameterError(f"interval keyframe numbers must be in 0..{K - 1}")
    kf_offset = np.searchsorted(kf, np.arange(K + 1)).astype(np.int64)
    el = _margins(extend_left, 1, "extend_left")
    er = _margins(extend_right, 1, "extend_right")
    segs, _, _, _ = _chain_batch_kernel(doc, start, end, kf_offset, np.arange(K, dtype=np.int64),
                                        np.array([0, K], np.int64), query.d_min, query.d_max,
                                        np.asarray(doc_lengths, dtype=np.int64), el, er, False)
    return _to_segments(segs)


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
    bits = _set_bits(feature_set) if feature_set is not None else _ALL40
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


__all__ = ["PARALLEL_MIN_FRAMES", "UNBOUNDED", "TOOLBOX_SETS", "KeyframeQuery", "annot_margins",
           "chain_search", "intervals_from_runs",
           "choose_keyframes_equally_distributed", "keyframe_hit_documents",
           "keyframe_intervals", "keyframe_mask_value", "keyframe_postings", "keyframe_search",
           "keyframe_search_batch", "stiffness_bounds"]
