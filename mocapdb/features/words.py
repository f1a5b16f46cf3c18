"""Packed feature words: the 40 features of a frame in one uint64 (FEATURES.md §0, §1, §7).

Bit k−1 of a word is feature k (matrix order, :data:`FEATURE_NAMES`).

* :func:`downsample` — native frames on the 30 Hz grid;
* :func:`pack_words` / :func:`unpack_words` — boolean matrix ↔ words;
* :func:`feature_runs` / :func:`segment_runs` — maximal runs of constant word
  (the run-length encoding the inverted index is built from);
* :func:`mirror_words` — left/right swap (§7);
* :func:`reverse_fuzzy_words` — a fuzzy word (mask, value) of the time-reversed motion;
* :func:`as_words` — validate an array of packed words.
"""
import numpy as np

from mocapdb._numba import jit
from mocapdb.errors import ParameterError

#: snake_case names in matrix order; bit k-1 of a packed word is feature k
FEATURE_NAMES = (
    "hand_right_to_front_rel_torso", "hand_left_to_front_rel_torso",
    "hand_right_raised_rel_spine", "hand_left_raised_rel_spine",
    "hand_right_to_top_rel_spine", "hand_left_to_top_rel_spine",
    "elbow_right_bent", "elbow_left_bent",
    "hands_apart_rel_shoulders", "hands_move_together",
    "hand_right_move_apart_rel_root", "hand_left_move_apart_rel_root",
    "hand_right_high_vel", "hand_left_high_vel",
    "foot_right_back_rel_leg_left", "foot_left_back_rel_leg_right",
    "foot_right_raised_rel_y_body_min", "foot_left_raised_rel_y_body_min",
    "feet_apart_rel_hips", "knee_right_bent", "knee_left_bent",
    "foot_crossover", "feet_move_together_rel_hips", "feet_move_apart_rel_hips",
    "foot_right_high_vel", "foot_left_high_vel",
    "humerus_right_abduct_rel_spine", "humerus_left_abduct_rel_spine",
    "femur_right_abduct_rel_spine", "femur_left_abduct_rel_spine",
    "root_behind_feet_left_right_neck", "spine_horizontal_rel_y",
    "hand_right_low_rel_y_body_min", "hand_left_low_rel_y_body_min",
    "shoulders_rotated_right_rel_hip", "shoulders_rotated_left_rel_hip",
    "body_extent_rel_y", "body_extent_extremities_rel_x_z",
    "root_high_vel", "root_high_ang_vel",
)
N_FEATURES = 40
#: features beyond the paper, after the 40 (FEATURES.md §10): bit 40 + k of a word is
#: derived feature k (feature 41: the heading turned, :mod:`mocapdb.features.heading`)
DERIVED_FEATURE_NAMES = ("root_heading_turned",)
#: bits of a packed word that carry features: the 40, then the derived ones
N_BITS = N_FEATURES + len(DERIVED_FEATURE_NAMES)
#: every feature a template or keyframe may name, in bit order
WORD_FEATURE_NAMES = FEATURE_NAMES + DERIVED_FEATURE_NAMES
_DERIVED_MASK = np.uint64(((1 << N_BITS) - 1) ^ ((1 << N_FEATURES) - 1))

#: the toolbox's three feature sets (index per set): name -> (first bit, n bits)
FEATURE_SETS = {"upper": (0, 14), "lower": (14, 12), "mix": (26, 14)}

#: left/right mirror (FEATURES.md §7): mirrored row i = original row MIRROR_FEATURES[i]
MIRROR_FEATURES = tuple(i - 1 for i in (
    2, 1, 4, 3, 6, 5, 8, 7, 9, 10, 12, 11, 14, 13, 16, 15, 18, 17, 19, 21, 20,
    22, 23, 24, 26, 25, 28, 27, 30, 29, 31, 32, 34, 33, 36, 35, 37, 38, 39, 40))
#: the same over every feature bit: a derived feature has no side (the heading turns either way)
MIRROR_BITS = MIRROR_FEATURES + tuple(range(N_FEATURES, N_BITS))

#: time reversal (:func:`reverse_fuzzy_words`): features that say a body part moves in a
#: direction (forward, upward, together, away from the root); played backwards it moves
#: the opposite way, which no feature says -- except feet moving together <-> apart
DIRECTION_FEATURES = tuple(i - 1 for i in (1, 2, 5, 6, 10, 11, 12))
#: pairs of features that swap under time reversal (feet move together / apart)
REVERSE_SWAP = ((22, 23),)

#: the toolbox keeps every 4th native frame (120 Hz -> 30 Hz), whatever the rate
DOWNSAMPLING_FACTOR = 4

#: parts of a word a run can be restricted to: a toolbox feature set, or all 40 bits
SET_BITS = {**FEATURE_SETS, "full": (0, N_FEATURES)}

_I32_MAX = 2**31 - 1

def _as_bool_matrix(x, name):
    """Validate a boolean (or 0/1 integer) matrix; returns a C-contiguous bool array."""
    a = np.asarray(x)
    if a.ndim != 2:
        raise ParameterError(
            f"{name} must be a 2-D (n_frames, n_features) array, got shape {a.shape}")
    if a.dtype != np.bool_:
        if a.size and ((a != 0) & (a != 1)).any():
            raise ParameterError(
                f"{name} must hold booleans or 0/1 values; got dtype {a.dtype} with "
                "other values; pass a bool array")
        a = a != 0
    return np.ascontiguousarray(a)


def as_words(words):
    """Validate packed words: a C-contiguous 1-D uint64 array (non-negative integers are converted)."""
    w = np.asarray(words)
    if w.ndim != 1:
        raise ParameterError(f"words must be a 1-D array of packed words, got shape {w.shape}")
    if w.dtype != np.uint64:
        if w.size and not np.issubdtype(w.dtype, np.integer):
            raise ParameterError(f"words must be uint64 packed words, got dtype {w.dtype}")
        if w.size and (w < 0).any():
            raise ParameterError("words must be non-negative (uint64 packed words)")
        w = w.astype(np.uint64)
    return np.ascontiguousarray(w)




@jit
def _count_runs_kernel(words, doc_offset, shift, mask, out_count):  # pragma: no cover
    """Number of maximal runs of constant ``(word >> shift) & mask`` per document."""
    for d in range(len(doc_offset) - 1):
        lo = doc_offset[d]
        hi = doc_offset[d + 1]
        if hi <= lo:
            out_count[d] = 0
            continue
        n = 1
        prev = (words[lo] >> shift) & mask
        for t in range(lo + 1, hi):
            w = (words[t] >> shift) & mask
            if w != prev:
                n += 1
                prev = w
        out_count[d] = n


@jit
def _fill_runs_kernel(words, doc_offset, shift, mask, seg_offset,
                      out_start, out_len, out_word):  # pragma: no cover
    """Write the runs counted by :func:`_count_runs_kernel` (runs_find_constant.m)."""
    for d in range(len(doc_offset) - 1):
        lo = doc_offset[d]
        hi = doc_offset[d + 1]
        if hi <= lo:
            continue
        s = seg_offset[d]
        prev = (words[lo] >> shift) & mask
        start = lo
        for t in range(lo + 1, hi + 1):
            w = prev
            if t < hi:
                w = (words[t] >> shift) & mask
            if t == hi or w != prev:
                out_start[s] = start - lo
                out_len[s] = t - start
                out_word[s] = prev
                s += 1
                start = t
                prev = w



def as_doc_lengths(doc_lengths, n_frames=None):
    """Validate frames per document: (n_docs,) int64 in 0..2^31-1, summing to ``n_frames`` if given."""
    lengths = np.asarray(doc_lengths)
    if lengths.ndim != 1 or lengths.dtype.kind not in "iu":
        raise ParameterError("doc_lengths must be a 1-D integer array (frames per document)")
    lengths = lengths.astype(np.int64)
    if lengths.size and (lengths.min() < 0 or lengths.max() > _I32_MAX):
        raise ParameterError(f"doc_lengths must be in 0..{_I32_MAX}")
    if n_frames is not None and int(lengths.sum()) != n_frames:
        raise ParameterError(f"doc_lengths sum to {int(lengths.sum())} but words has "
                             f"{n_frames} frames")
    return lengths


def segment_runs(words, doc_lengths, *, feature_set="full"):
    """Maximal runs of constant word in many documents (runs_find_constant.m).

    Parameters
    ----------
    words : (n_frames,) uint64
        Packed words of all documents, concatenated.
    doc_lengths : (n_docs,) int
        Frames per document (zero allowed).
    feature_set : {'upper', 'lower', 'mix', 'full'}, default 'full'
        Restrict the word to this set's bits, shifted so feature 1 of the set
        is bit 0 (KEYFRAMES.md §1.2), or keep all 40 bits.

    Returns
    -------
    start, length : (n_segs,) int64
        First frame (0-based, within its document) and length of each run.
    word : (n_segs,) uint64
        The (restricted) word of the run.
    seg_offset : (n_docs + 1,) int64
        Runs of document d are ``seg_offset[d]:seg_offset[d+1]``.
    """
    words = as_words(words)
    lengths = as_doc_lengths(doc_lengths, len(words))
    if feature_set not in SET_BITS:
        raise ParameterError(f"feature_set={feature_set!r}; allowed: {', '.join(SET_BITS)}")
    first, nbits = SET_BITS[feature_set]
    shift, mask = np.uint64(first), np.uint64((1 << nbits) - 1)
    doc_offset = np.zeros(len(lengths) + 1, np.int64)
    np.cumsum(lengths, out=doc_offset[1:])
    count = np.empty(len(lengths), np.int64)
    _count_runs_kernel(words, doc_offset, shift, mask, count)
    seg_offset = np.zeros(len(lengths) + 1, np.int64)
    np.cumsum(count, out=seg_offset[1:])
    n = int(seg_offset[-1])
    start = np.empty(n, np.int64)
    length = np.empty(n, np.int64)
    word = np.empty(n, np.uint64)
    _fill_runs_kernel(words, doc_offset, shift, mask, seg_offset, start, length, word)
    return start, length, word, seg_offset



def downsample(features, factor=DOWNSAMPLING_FACTOR):
    """Keep frames 0, factor, 2·factor, … (120 Hz → 30 Hz for factor 4).

    Parameters
    ----------
    features : array_like, shape (n_frames, ...)
        Boolean feature matrix or packed words at the native rate.
    factor : int, optional
        The toolbox's fixed factor 4, whatever the native rate.

    Returns
    -------
    ndarray, shape (ceil(n_frames/factor), ...), contiguous copy

    References
    ----------
    FEATURES.md §1 (Downsampling).
    """
    if isinstance(factor, bool) or not isinstance(factor, (int, np.integer)) or factor < 1:
        raise ParameterError(f"factor must be a positive integer, got {factor!r}; default 4")
    a = np.asarray(features)
    if a.ndim < 1:
        raise ParameterError("features must have a frame axis (at least 1-D)")
    return np.ascontiguousarray(a[::factor])


def pack_words(features):
    """Pack a boolean feature matrix into one uint64 word per frame.

    Bit k−1 of a word is feature (column) k.

    Parameters
    ----------
    features : array_like, shape (n_frames, n_features), bool (or 0/1)
        ``n_features`` ≤ 64.

    Returns
    -------
    ndarray, shape (n_frames,), uint64

    Raises
    ------
    ParameterError
        If the array is not 2-D, has more than 64 columns or non-0/1 values.

    References
    ----------
    FEATURES.md §7 (word / bit order).
    """
    f = _as_bool_matrix(features, "features")
    n, k = f.shape
    if k > 64:
        raise ParameterError(f"features must have at most 64 columns to fit a uint64, got {k}")
    buf = np.zeros((n, 8), dtype=np.uint8)
    if k:
        packed = np.packbits(f, axis=1, bitorder="little")
        buf[:, :packed.shape[1]] = packed
    return buf.view("<u8").reshape(n).astype(np.uint64)


def unpack_words(words, n_features=N_FEATURES):
    """Inverse of :func:`pack_words`: bit k−1 of each word becomes column k−1.

    Parameters
    ----------
    words : array_like, shape (n_frames,), uint64
    n_features : int, optional
        Number of low bits to unpack (≤ 64); higher bits are ignored.

    Returns
    -------
    ndarray, shape (n_frames, n_features), bool
    """
    if (isinstance(n_features, bool) or not isinstance(n_features, (int, np.integer))
            or not 0 <= n_features <= 64):
        raise ParameterError(f"n_features must be an integer in 0..64, got {n_features!r}")
    w = as_words(words)
    n = w.shape[0]
    bytes_ = w.astype("<u8").view(np.uint8).reshape(n, 8)
    bits = np.unpackbits(bytes_, axis=1, count=int(n_features), bitorder="little")
    return bits.astype(np.bool_)


def feature_runs(words):
    """Maximal runs of identical consecutive words.

    Parameters
    ----------
    words : array_like, shape (n_frames,), uint64

    Returns
    -------
    starts : ndarray, shape (n_runs,), int64
        0-based first frame of each run.
    lengths : ndarray, shape (n_runs,), int64
    values : ndarray, shape (n_runs,), uint64
        The word of each run; ``np.repeat(values, lengths)`` gives ``words``.

    References
    ----------
    FEATURES.md §1 (run-length encoding); KEYFRAMES.md (inverted index).
    """
    w = as_words(words)
    starts, lengths, values, _ = segment_runs(w, [w.shape[0]], feature_set="full")
    return starts, lengths, values


def mirror_words(words):
    """Swap left and right in packed feature words.

    Mirrored feature i is original feature ``MIRROR_FEATURES[i]`` (FEATURES.md
    §7): the word of a left/right mirrored motion. Derived features (bit 40
    on, FEATURES.md §10) have no side and are kept.

    Parameters
    ----------
    words : array_like, shape (n_frames,), uint64

    Returns
    -------
    ndarray, shape (n_frames,), uint64
    """
    w = as_words(words)
    # derived features (bit 40 on) have no side: they keep their bits
    return pack_words(unpack_words(w)[:, list(MIRROR_FEATURES)]) | (w & _DERIVED_MASK)



def reverse_fuzzy_words(mask, value):
    """Fuzzy words ``(mask, value)`` (bit set in mask = feature fixed) of the motion played backwards.

    Poses and speeds read the same backwards; a motion in a direction becomes
    the opposite motion. For the direction features
    (:data:`DIRECTION_FEATURES`: hand to the front / to the top, hands move
    together, hand moves away from the root) "on" becomes "off" (moving the
    other way is not moving this way) and "off" becomes a wildcard (the
    other way is unknown); feet moving together and apart swap
    (:data:`REVERSE_SWAP`). Word order is not touched: reverse the sequence
    yourself.

    Parameters
    ----------
    mask, value : array_like, shape (n,), uint64

    Returns
    -------
    mask, value : ndarray, shape (n,), uint64
    """
    m = np.array(mask, dtype=np.uint64, copy=True)
    v = np.array(value, dtype=np.uint64, copy=True)
    for f in DIRECTION_FEATURES:
        b = np.uint64(1 << f)
        was_on = (m & b).astype(bool) & (v & b).astype(bool)
        m = np.where(was_on, m, m & ~b)      # fixed 0 -> wildcard; fixed 1 stays fixed ...
        v = v & ~b                           # ... and becomes 0
    for a, c in REVERSE_SWAP:
        ba, bc = np.uint64(1 << a), np.uint64(1 << c)
        for x in (m, v):
            on_a, on_c = (x & ba) != 0, (x & bc) != 0
            x &= ~(ba | bc)
            x |= np.where(on_a, bc, np.uint64(0)) | np.where(on_c, ba, np.uint64(0))
    return m, v


__all__ = [
    "FEATURE_NAMES", "N_FEATURES", "DERIVED_FEATURE_NAMES", "N_BITS", "WORD_FEATURE_NAMES", "MIRROR_BITS",
    "FEATURE_SETS", "SET_BITS", "MIRROR_FEATURES", "DOWNSAMPLING_FACTOR",
    "downsample", "pack_words", "unpack_words", "feature_runs", "segment_runs", "mirror_words", "as_words",
    "reverse_fuzzy_words", "DIRECTION_FEATURES", "REVERSE_SWAP",
    "as_doc_lengths",
]
