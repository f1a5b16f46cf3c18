"""Gaps in a recording: short ones filled, lost markers rebuilt from their rigid segment, long ones cut.

Shared by the C3D reader (missing marker samples) and the BVH reader (lost
tracking: ``NaN``/``inf`` or absurd channel values):

* :func:`fill_short` interpolates runs of missing samples up to the gap
  limit (0.25 s) linearly over time, holding the ends of the take;
* :func:`rigid_fill` rebuilds a marker over a longer gap from three or more
  markers of its rigid segment (e.g. LASI from RASI, LPSI and RPSI): the
  marker's position in the segment's frame is learnt on the nearest frames
  where all of them are present (least-squares rigid fit, Kabsch), and the
  segment's pose in each gap frame carries it back;
* :func:`longest_part` keeps the longest stretch without an unrecoverable
  gap, or refuses the take when little is left (:data:`MIN_PART_S`,
  :data:`MIN_PART_FRACTION`). One file stays one motion: a database user
  finds each take once, under its file name, and re-ingest stays a no-op;
  the notes say which frames of the file the motion holds.

References
----------
W. Kabsch: A solution for the best rotation to relate two sets of vectors,
Acta Cryst. A32 (1976) 922–923.
"""
from __future__ import annotations

import math

import numpy as np

from mocapdb.errors import ParseError

__all__ = ["MAX_GAP_S", "MIN_PART_S", "MIN_PART_FRACTION", "runs", "long_gaps", "max_gap_frames", "fill_short",
           "rigid_fill", "longest_part", "frames_text"]

#: longest gap (seconds) filled by interpolation
MAX_GAP_S = 0.25
#: a take is refused when its longest stretch without an unrecoverable gap is shorter than
#: this (seconds) …
MIN_PART_S = 1.0
#: … or holds less than this fraction of the take's frames
MIN_PART_FRACTION = 0.1
#: reference frames on each side of a gap for a rigid fill
_REFERENCE_FRAMES = 20
#: a marker whose position in its segment's frame spreads more than this fraction of the
#: segment's radius over the reference frames is not rigid with it: no fill
_RIGID_TOLERANCE = 0.25


def max_gap_frames(rate: float) -> int:
    """The longest gap (frames) filled by interpolation at ``rate`` Hz."""
    return int(math.floor(MAX_GAP_S * rate + 1e-9))


def runs(mask: np.ndarray) -> list:
    """``(start, stop)`` of each run of True in a 1-d bool array (stop exclusive)."""
    edges = np.diff(np.concatenate(([0], np.asarray(mask, dtype=np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def long_gaps(valid: np.ndarray, max_gap: int) -> list:
    """Runs of missing samples longer than ``max_gap`` frames."""
    return [(a, b) for a, b in runs(~valid) if b - a > max_gap]


def frames_text(a: int, b: int, rate: float) -> str:
    """``frames a+1–b (s s)`` for the 0-based half-open run ``[a, b)``."""
    return f"frames {a + 1}–{b} ({(b - a) / rate:.2f} s)"


def fill_short(values: np.ndarray, valid: np.ndarray) -> int:
    """Fill the missing samples of a trajectory in place, linearly over time (ends held).

    Parameters
    ----------
    values : ndarray, shape (n_frames, k)
    valid : ndarray, shape (n_frames,), bool
        At least one True.

    Returns
    -------
    int
        Samples filled.
    """
    missing = ~valid
    k = int(missing.sum())
    if k:
        t = np.flatnonzero(valid)
        where = np.flatnonzero(missing)
        for axis in range(values.shape[1]):
            values[missing, axis] = np.interp(where, t, values[valid, axis])
    return k


def _kabsch(template: np.ndarray, points: np.ndarray):
    """Rotations and centroids taking ``template`` (k, 3) onto each frame of ``points`` (n, k, 3).

    Returns ``(R (n, 3, 3), c (n, 3))`` with ``points ≈ c + R (template − mean(template))``.
    """
    p = template - template.mean(axis=0)
    c = points.mean(axis=1)
    q = points - c[:, None, :]
    h = np.einsum("ki,nkj->nij", p, q)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.einsum("nji,nkj->nik", vt, u)))   # det(V Uᵀ): no reflection
    fix = np.ones((len(d), 3))
    fix[:, 2] = d
    r = np.einsum("nji,nj,nkj->nik", vt, fix, u)   # V diag(1, 1, d) Uᵀ
    return r, c


def rigid_fill(xyz: np.ndarray, valid: np.ndarray, target: int, donors, gap) -> tuple:
    """Rebuild point ``target`` over the frames ``gap = (a, b)`` from the ``donors`` of its segment.

    Frames are grouped by which donors they have; a group with at least
    three donors is filled from the up to 20 nearest frames on each side
    where the target and those donors are all present. Nothing is filled
    where the target does not move rigidly with the donors there.

    Parameters
    ----------
    xyz : ndarray, shape (n_frames, n_points, 3)
        Modified in place.
    valid : ndarray, shape (n_frames, n_points), bool
        Modified in place (filled samples become valid).
    target : int
    donors : sequence of int
    gap : (int, int)

    Returns
    -------
    (int, tuple of int)
        Frames filled, and the donors used.
    """
    a, b = gap
    donors = np.asarray(list(donors), dtype=np.int64)
    if len(donors) < 3:
        return 0, ()
    have = valid[a:b][:, donors]
    filled, used = 0, set()
    patterns, inverse = np.unique(have, axis=0, return_inverse=True)
    for k, pattern in enumerate(patterns):
        if pattern.sum() < 3:
            continue
        group = donors[pattern]
        frames = a + np.flatnonzero(inverse.ravel() == k)
        ok = valid[:, target] & valid[:, group].all(axis=1)
        ref = np.flatnonzero(ok)
        if len(ref) < 3:
            continue
        before, after = ref[ref < a][-_REFERENCE_FRAMES:], ref[ref >= b][:_REFERENCE_FRAMES]
        ref = np.concatenate([before, after])
        if len(ref) < 3:
            continue
        template = xyz[ref[0], group]
        radius = float(np.sqrt(np.mean(np.sum((template - template.mean(axis=0)) ** 2, axis=1))))
        if not radius > 0:
            continue
        r_ref, c_ref = _kabsch(template, xyz[ref][:, group])
        local = np.einsum("nji,nj->ni", r_ref, xyz[ref, target] - c_ref)   # Rᵀ (p − c)
        spread = float(np.sqrt(np.mean(np.sum((local - local.mean(axis=0)) ** 2, axis=1))))
        if spread > _RIGID_TOLERANCE * radius:
            continue
        r_gap, c_gap = _kabsch(template, xyz[frames][:, group])
        xyz[frames, target] = c_gap + np.einsum("nij,j->ni", r_gap, np.median(local, axis=0))
        valid[frames, target] = True
        filled += len(frames)
        used.update(group.tolist())
    return filled, tuple(sorted(used))


def longest_part(bad: np.ndarray, rate: float, path, why: str) -> tuple:
    """The longest run of frames without a ``bad`` frame, or a ParseError when little is left.

    Parameters
    ----------
    bad : ndarray, shape (n_frames,), bool
        Frames of unrecoverable gaps.
    rate : float
    path : for messages
    why : str
        What made the bad frames (for the message and the note).

    Returns
    -------
    (int, int, str or None)
        ``start, stop`` (0-based, stop exclusive) and a note (None when nothing is cut).
    """
    n = len(bad)
    if not bad.any():
        return 0, n, None
    good = runs(~bad)
    if not good:
        raise ParseError(path, None, f"{why}; no frame is left")
    a, b = max(good, key=lambda r: (r[1] - r[0], -r[0]))
    if (b - a) / rate < MIN_PART_S or (b - a) < MIN_PART_FRACTION * n:
        raise ParseError(path, None, f"{why}; the longest stretch without it, {frames_text(a, b, rate)}, is "
                         f"too little of the {n} frames to keep (at least {MIN_PART_S:g} s and "
                         f"{MIN_PART_FRACTION:.0%} of the take)")
    dropped = n - (b - a)
    return a, b, (f"kept frames {a + 1}–{b} of {n}, the longest stretch without an unrecoverable gap "
                  f"({dropped} frames cut: {why})")
