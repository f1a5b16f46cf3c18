"""Motion templates (paper Sect. 3, TEMPLATES.md §1, §8): real-valued and quantized.

A :class:`MotionTemplate` is an ``(L, 40)`` matrix of values in [0, 1] with
column weights (learned by :func:`mocapdb.templates.learn_template`); its
δ-quantization (:func:`quantize`) is a :class:`QuantizedTemplate` of
``(mask, value)`` word pairs (mask bit 0 = wildcard) that the Δ kernels of
:mod:`mocapdb.templates.distance` match against packed feature words.
"""
from dataclasses import dataclass, field

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.features import MIRROR_FEATURES, N_BITS, N_FEATURES, mirror_words, pack_words, reverse_fuzzy_words, unpack_words

# ---------------------------------------------------------------------------
# helpers


def _matlab_round(x):
    """Round halves away from zero (Matlab/Octave ``round``) for float arrays."""
    x = np.asarray(x, dtype=np.float64)
    a = np.abs(x)
    fl = np.floor(a)
    r = fl + (a - fl >= 0.5)
    return np.copysign(r, x)


def _as_sequence(x, name):
    """A clip / template as a C-contiguous ``(L, 40)`` float64 matrix."""
    a = np.asarray(x)
    if a.ndim == 1:
        if a.dtype != np.uint64 and not (a.size == 0 or np.issubdtype(a.dtype, np.integer)):
            raise ParameterError(
                f"{name} must be an (n, 40) feature matrix or (n,) uint64 packed words, "
                f"got a 1-D array of dtype {a.dtype}")
        a = unpack_words(a)
    if a.ndim != 2 or a.shape[1] != N_FEATURES:
        raise ParameterError(
            f"{name} must have shape (n_frames, {N_FEATURES}), got {a.shape}; "
            "pass frames first (transpose a 40 x n toolbox matrix)")
    if a.shape[0] == 0:
        raise ParameterError(f"{name} has no frames; drop empty clips")
    a = np.ascontiguousarray(a, dtype=np.float64)
    if not np.isfinite(a).all() or (a < 0).any() or (a > 1).any():
        raise ParameterError(f"{name} must hold values in [0, 1] (booleans or averages)")
    return a


def _as_weights(w, n, name):
    if w is None:
        return np.ones(n)
    a = np.ascontiguousarray(w, dtype=np.float64)
    if a.shape != (n,):
        raise ParameterError(f"{name} must have shape ({n},), got {a.shape}")
    if not np.isfinite(a).all() or (a <= 0).any():
        raise ParameterError(f"{name} must hold positive finite weights")
    return a

def _expand_counts(weights):
    reps = np.maximum(1.0, _matlab_round(weights))
    return reps.astype(np.int64), weights / reps


# ---------------------------------------------------------------------------
# data containers


@dataclass(frozen=True, eq=False)
class QuantizedTemplate:
    """A quantized motion template on packed words (TEMPLATES.md §8, §9).

    Attributes
    ----------
    mask : ndarray, shape (K,), uint64
        Bit k−1 set where feature k of the column is not a wildcard.
    value : ndarray, shape (K,), uint64
        Bit k−1 set where feature k of the column is 1 (always within ``mask``).
    weights : ndarray, shape (K,), float64
        Column weights (≈ frames represented), unchanged by quantization.
    """

    mask: np.ndarray
    value: np.ndarray
    weights: np.ndarray

    def __post_init__(self):
        mask = np.ascontiguousarray(self.mask, dtype=np.uint64)
        value = np.ascontiguousarray(self.value, dtype=np.uint64)
        weights = np.ascontiguousarray(self.weights, dtype=np.float64)
        if mask.ndim != 1 or value.shape != mask.shape or weights.shape != mask.shape:
            raise ParameterError(
                "mask, value and weights must be 1-D arrays of the same length, got "
                f"{mask.shape}, {value.shape}, {weights.shape}")
        if mask.size == 0:
            raise ParameterError("a quantized template needs at least one column")
        if (value & ~mask).any():
            raise ParameterError("value has bits outside mask; value must be a subset of mask")
        if (mask >> np.uint64(N_BITS)).any():
            raise ParameterError(f"mask has bits above feature {N_BITS} (the 40 and the derived ones, FEATURES.md §10)")
        if not np.isfinite(weights).all() or (weights <= 0).any():
            raise ParameterError("weights must be positive and finite")
        object.__setattr__(self, "mask", mask)
        object.__setattr__(self, "value", value)
        object.__setattr__(self, "weights", weights)

    def __len__(self):
        return self.mask.shape[0]

    @classmethod
    def from_dense(cls, matrix, weights):
        """Build from a ``(K, 40)`` matrix of 0 / 1 / 0.5 (wildcard) entries."""
        q = np.asarray(matrix, dtype=np.float64)
        if q.ndim != 2 or q.shape[1] != N_FEATURES:
            raise ParameterError(f"matrix must have shape (K, {N_FEATURES}), got {q.shape}")
        if not np.isin(q, (0.0, 0.5, 1.0)).all():
            raise ParameterError("matrix must hold only 0, 1 and 0.5 (wildcard)")
        return cls(pack_words(q != 0.5), pack_words(q == 1.0), weights)

    def dense(self):
        """The template as a ``(K, 40)`` float64 matrix of 0 / 1 / 0.5 (wildcard)."""
        m = unpack_words(self.mask)
        v = unpack_words(self.value)
        return np.where(m, v.astype(np.float64), 0.5)

    def expand(self):
        """expandWeightedVectorSequence (§6.1, §9): repeat columns by rounded weight.

        Returns a new template; for balanced templates (weights < 1.5) it is
        equal to ``self``.
        """
        reps, w = _expand_counts(self.weights)
        return QuantizedTemplate(np.repeat(self.mask, reps), np.repeat(self.value, reps),
                                 np.repeat(w, reps))

    def mirrored(self):
        """The template of the left/right mirrored motion (FEATURES.md §7)."""
        return QuantizedTemplate(mirror_words(self.mask), mirror_words(self.value), self.weights)

    def reversed(self):
        """The template of the motion played backwards: columns in reverse order,
        features by :func:`mocapdb.features.reverse_fuzzy_words`."""
        m, v = reverse_fuzzy_words(self.mask[::-1], self.value[::-1])
        return QuantizedTemplate(m, v, self.weights[::-1].copy())

    @property
    def wildcard_fraction(self):
        """Fraction of wildcard entries (of K × 40)."""
        return 1.0 - unpack_words(self.mask).mean()


@dataclass(frozen=True, eq=False)
class MotionTemplate:
    """A real-valued (weighted) motion template learned from example clips (§7).

    Attributes
    ----------
    real : ndarray, shape (K, 40), float64
        Entries in [0, 1]: fraction of the (warped) training clips with the
        feature on at that template column.
    weights : ndarray, shape (K,), float64
        Average number of original frames each column stands for.
    iterations : int
        Learning iterations performed (0 if not learned here).
    error_max, error_mean, error_std : ndarray, shape (iterations,), float64
        Per-iteration statistics of the normalised alignment costs (§7).
    n_clips : int
        Number of training clips (0 if not learned here).
    """

    real: np.ndarray
    weights: np.ndarray
    iterations: int = 0
    error_max: np.ndarray = field(default_factory=lambda: np.zeros(0))
    error_mean: np.ndarray = field(default_factory=lambda: np.zeros(0))
    error_std: np.ndarray = field(default_factory=lambda: np.zeros(0))
    n_clips: int = 0

    def __post_init__(self):
        real = _as_sequence(self.real, "real")
        object.__setattr__(self, "real", real)
        object.__setattr__(self, "weights", _as_weights(self.weights, real.shape[0], "weights"))
        for name in ("error_max", "error_mean", "error_std"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=np.float64))

    def __len__(self):
        return self.real.shape[0]

    def mirrored(self):
        """The template of the left/right mirrored clips (FEATURES.md §7): rows permuted.

        Equal to :func:`~mocapdb.templates.learn_template` of the mirrored
        clips up to the order of floating-point sums (equal bit for bit on 10
        of the 11 HDM05 classes; the quantized templates agree on all).
        """
        return MotionTemplate(self.real[:, list(MIRROR_FEATURES)], self.weights, self.iterations, self.error_max,
                              self.error_mean, self.error_std, self.n_clips)

    def quantize(self, delta=0.05):
        """Quantize to a wildcard template (§8, ``motionTemplateBool.m``).

        Parameters
        ----------
        delta : float, default 0.05
            Entries ≤ δ become 0, entries ≥ 1 − δ become 1, the rest wildcards
            (the annotation scripts use δ = 0.05; the paper's keyframe learning δ = 0).

        Returns
        -------
        QuantizedTemplate
        """
        return quantize(self.real, self.weights, delta=delta)


# ---------------------------------------------------------------------------
# public algorithm steps


def quantize(real, weights, *, delta=0.05):
    """Quantize a real template (§8): ≤ δ → 0, ≥ 1 − δ → 1, otherwise wildcard.

    Parameters
    ----------
    real : array_like, shape (K, 40), float
    weights : array_like, shape (K,), float
    delta : float, default 0.05

    Returns
    -------
    QuantizedTemplate

    Raises
    ------
    ParameterError
        If ``delta`` is not in [0, 0.5).

    References
    ----------
    TEMPLATES.md §8; paper Sect. 3.
    """
    if not isinstance(delta, (int, float, np.floating)) or not 0.0 <= float(delta) < 0.5:
        raise ParameterError(f"delta must be a number in [0, 0.5), got {delta!r}")
    x = _as_sequence(real, "real")
    w = _as_weights(weights, x.shape[0], "weights")
    lo = float(delta)
    hi = 1.0 - lo
    # the toolbox's order of assignment: wildcards first, then 0, then 1
    q = x.copy()
    q[(q > lo) & (q < hi)] = 0.5
    q[q <= lo] = 0.0
    q[q >= hi] = 1.0
    return QuantizedTemplate.from_dense(q, w)


__all__ = ["MotionTemplate", "QuantizedTemplate", "quantize"]
