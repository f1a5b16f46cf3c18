"""Source frame rates → the 30 Hz feature grid (READERS.md §1).

Templates, keyframes, the index and DTW live at 30 Hz. The toolbox computes
the features at 120 Hz and keeps native frames 0, 4, 8, … (FEATURES.md §1);
that path stays exact. A source at another rate is first resampled to 120 Hz
(:func:`resample_joints`: cubic Hermite interpolation of the joint
trajectories, the root rotation interpolated and re-orthonormalised), then
takes the toolbox path. The alternative — features at the native rate with
the millisecond windows, sampled on the 30 Hz grid — agreed less with the
120 Hz reading of the same recordings (benchmarks/bench_rates.py, RESULTS.md),
so it is kept only as ``method="native"`` for comparison.

The grid is the same either way: 30 Hz frame k is time k/30 s, for every
k with k/30 ≤ (n − 1)/fps, so a 120 Hz take of n frames has ceil(n/4) feature
frames as in the toolbox.
"""
from __future__ import annotations

import math

import numpy as np

from mocapdb._numba import jit
from mocapdb.errors import ParameterError

__all__ = ["FEATURE_RATE", "TOOLBOX_RATE", "RATE_METHODS", "feature_frame_count", "feature_grid",
           "grid_source_frames", "resample_joints", "resampled_count", "check_fps"]

#: rate of the feature words (Hz)
FEATURE_RATE = 30.0
#: the rate the toolbox computes features at (Hz); factor 4 to the words
TOOLBOX_RATE = 120.0
#: how a source at another rate reaches the 30 Hz grid
RATE_METHODS = ("resample", "native")

# grid times are compared with a tolerance: 1/fps is rarely exact in binary
_EPS = 1e-9


def check_fps(fps) -> float:
    """``fps`` as a float if it is a positive finite rate (Hz), else ParameterError."""
    try:
        fps = float(fps)
    except (TypeError, ValueError):
        raise ParameterError(f"fps must be a positive number (Hz), got {fps!r}") from None
    if not (math.isfinite(fps) and fps > 0.0):
        raise ParameterError(f"fps must be a positive number (Hz), got {fps!r}")
    return fps


def feature_frame_count(n_frames: int, fps: float) -> int:
    """Number of 30 Hz feature frames of a take of ``n_frames`` at ``fps``.

    ``floor((n − 1)·30/fps) + 1`` (0 for an empty take): every grid time
    k/30 up to the last source frame. At 120 Hz this is ``ceil(n/4)``.
    """
    fps = check_fps(fps)
    n = int(n_frames)
    if n <= 0:
        return 0
    if fps == TOOLBOX_RATE:
        return (n + 3) // 4
    return int(math.floor((n - 1) * FEATURE_RATE / fps + _EPS)) + 1


def feature_grid(n_frames: int, fps: float) -> np.ndarray:
    """Times (s) of the 30 Hz feature frames of a take: ``k/30``, k = 0 … count − 1."""
    return np.arange(feature_frame_count(n_frames, fps), dtype=np.float64) / FEATURE_RATE


def grid_source_frames(n_frames: int, fps: float) -> np.ndarray:
    """The source frame (0-based) nearest to each 30 Hz grid time.

    At 120 Hz these are frames 0, 4, 8, … exactly; used to show a source
    pose per feature frame (viewer) and by the ``native`` rate method.
    """
    fps = check_fps(fps)
    idx = np.rint(feature_grid(n_frames, fps) * fps).astype(np.int64)
    return np.minimum(idx, max(int(n_frames) - 1, 0))


@jit
def _hermite_kernel(src, fps_in, fps_out, out, first):  # pragma: no cover - compiled
    """Cubic Hermite (Catmull–Rom tangents) resampling of each column of
    ``src`` (n, m) at times j/fps_out, j = first … first + n_out − 1, into
    ``out`` (n_out, m) (a block of a long take's output: the same values as
    the whole's rows). Tangents are central differences (one-sided at the
    ends), so a linear trajectory stays exact and velocities stay continuous."""
    n = src.shape[0]
    m = src.shape[1]
    for jj in range(out.shape[0]):
        j = first + jj
        x = j * fps_in / fps_out
        i = int(math.floor(x + 1e-9))
        if i >= n - 1:
            for c in range(m):
                out[jj, c] = src[n - 1, c]
            continue
        u = x - i
        if u < 0.0:
            u = 0.0
        u2 = u * u
        u3 = u2 * u
        h00 = 2.0 * u3 - 3.0 * u2 + 1.0
        h10 = u3 - 2.0 * u2 + u
        h01 = -2.0 * u3 + 3.0 * u2
        h11 = u3 - u2
        for c in range(m):
            p0 = src[i, c]
            p1 = src[i + 1, c]
            if i > 0:
                m0 = 0.5 * (p1 - src[i - 1, c])
            else:
                m0 = p1 - p0
            if i + 2 < n:
                m1 = 0.5 * (src[i + 2, c] - p0)
            else:
                m1 = p1 - p0
            out[jj, c] = h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1


def resampled_count(n_frames: int, fps: float, target: float = TOOLBOX_RATE) -> int:
    """Frames of a take of ``n_frames`` at ``fps`` resampled to ``target`` Hz (:func:`resample_joints`)."""
    return int(math.floor((n_frames - 1) * target / fps + _EPS)) + 1 if n_frames > 0 else 0


def resample_joints(joints, root_rotation, fps, *, target: float = TOOLBOX_RATE, frames=None):
    """Resample joint trajectories (and the root rotation) to ``target`` Hz.

    Parameters
    ----------
    joints : ndarray, shape (n, 24, 3), float
    root_rotation : ndarray, shape (n, 3, 3), or None
    fps : float
        Source rate (Hz).
    target : float, keyword-only
        Output rate (default 120 Hz, the toolbox's).
    frames : (int, int), optional, keyword-only
        Only the output frames ``a … b − 1`` (a block of a long take), the same
        values as those rows of the whole output.

    Returns
    -------
    joints : ndarray, shape (n_out, 24, 3)
        Frames at times j/target for every j/target ≤ (n − 1)/fps.
    root_rotation : ndarray, shape (n_out, 3, 3), or None
        Interpolated entry-wise, then made orthonormal again (polar
        decomposition via SVD).
    """
    fps = check_fps(fps)
    target = check_fps(target)
    j = np.ascontiguousarray(joints, dtype=np.float64)
    n = j.shape[0]
    if n == 0:
        return j.copy(), None if root_rotation is None else np.asarray(root_rotation, np.float64).copy()
    first, stop = (0, resampled_count(n, fps, target)) if frames is None else map(int, frames)
    n_out = stop - first
    out = np.empty((n_out, j.shape[1] * j.shape[2]))
    _hermite_kernel(j.reshape(n, -1), fps, target, out, first)
    rot = None
    if root_rotation is not None:
        r = np.ascontiguousarray(root_rotation, dtype=np.float64).reshape(n, 9)
        r_out = np.empty((n_out, 9))
        _hermite_kernel(r, fps, target, r_out, first)
        u, _, vt = np.linalg.svd(r_out.reshape(n_out, 3, 3))
        rot = u @ vt
    return out.reshape(n_out, *j.shape[1:]), rot
