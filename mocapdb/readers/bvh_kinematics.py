"""Forward kinematics of a BVH hierarchy, and the gather of the 24 canonical joints from its points.

:func:`bvh_node_positions` gives every joint's origin and End Site per frame; the BVH reader
(:mod:`~mocapdb.readers.bvh`) runs FK and the gather in one kernel call per block of motion lines
(:func:`_bvh_joints_kernel`, issue 35), so a take's points of every joint are never written out. The
hierarchy's arrays come from ``BvhHierarchy.arrays()`` (built once per hierarchy).
"""
from __future__ import annotations

import math

import numpy as np

from mocapdb._numba import jit
from mocapdb.bodies.kinematics import rotate_columns

__all__ = ["bvh_node_positions"]


@jit
def _bvh_fk_kernel(values, parent, offset, ch_start, ch_count, ch_kind, ch_axis,
                   end_site, has_end, needed, origins, ends, rotations, rot_joint):  # pragma: no cover
    """Joint origins (n, nj, 3), End Sites (n, nj, 3) and the global rotation of
    joint ``rot_joint`` (n, 3, 3) for every frame; see the module docstring.
    Sine and cosine are taken here, of rotation channels only (no temporaries);
    joints not ``needed`` (nor below a needed one) are skipped."""
    n = values.shape[0]
    nj = parent.shape[0]
    h = np.empty((nj, 3, 3))
    t = np.empty(3)
    deg = math.pi / 180.0
    for f in range(n):
        for j in range(nj):
            if not needed[j]:
                continue
            p = parent[j]
            for i in range(3):
                for k in range(3):
                    h[j, i, k] = h[p, i, k] if p >= 0 else (1.0 if i == k else 0.0)
                t[i] = offset[j, i]
            s0 = ch_start[j]
            for c in range(ch_count[j]):
                col = s0 + c
                if ch_kind[col] == 0:
                    if p >= 0:
                        t[ch_axis[col]] = values[f, col]  # replaces the OFFSET coordinate
                    else:
                        t[ch_axis[col]] += values[f, col]
                else:
                    a = values[f, col] * deg
                    rotate_columns(h, j, ch_axis[col], math.cos(a), math.sin(a))
            for i in range(3):
                if p >= 0:
                    origins[f, j, i] = origins[f, p, i] + (h[p, i, 0] * t[0] + h[p, i, 1] * t[1]
                                                           + h[p, i, 2] * t[2])
                else:
                    origins[f, j, i] = t[i]
            if has_end[j]:
                for i in range(3):
                    ends[f, j, i] = origins[f, j, i] + (h[j, i, 0] * end_site[j, 0]
                                                        + h[j, i, 1] * end_site[j, 1]
                                                        + h[j, i, 2] * end_site[j, 2])
            if j == rot_joint:
                for i in range(3):
                    for k in range(3):
                        rotations[f, i, k] = h[j, i, k]


def bvh_node_positions(data, *, rotation_joint: int = 0, needed=None):
    """Forward kinematics of a parsed BVH file.

    ``needed`` (bool per joint, closed under parents) limits the work to those
    joints; the others' origins and End Sites are left undefined.

    Returns
    -------
    origins : ndarray, shape (n_frames, n_joints, 3)
    end_sites : ndarray, shape (n_frames, n_joints, 3)
        NaN for joints without an End Site.
    rotation : ndarray, shape (n_frames, 3, 3)
        Global rotation of joint ``rotation_joint`` (default: the root).
    """
    hier = data.hierarchy
    nj = len(hier.joints)
    parent, offset, ch_start, ch_count, kinds, axes, has_end, end_site = hier.arrays()
    values = np.ascontiguousarray(data.values, dtype=np.float64)
    n = values.shape[0]
    origins = np.empty((n, nj, 3))
    ends = np.full((n, nj, 3), np.nan)
    rot = np.empty((n, 3, 3))
    if needed is None:
        needed = np.ones(nj, dtype=np.bool_)
    _bvh_fk_kernel(values, parent, offset, ch_start, ch_count, kinds, axes, end_site,
                   has_end, needed, origins, ends, rot, rotation_joint)
    return origins, ends, rot


@jit
def _combine_kernel(origins, ends, point, end_of, weight, out):  # pragma: no cover - compiled
    """out[f, j] = Σ_k weight[j, k] · P(point[j, k]); a point below n_joints is a joint
    origin, above it the End Site of joint end_of[point - n_joints]."""
    nj = origins.shape[1]
    for f in range(origins.shape[0]):
        for j in range(point.shape[0]):
            for c in range(3):
                out[f, j, c] = 0.0
            for k in range(point.shape[1]):
                w = weight[j, k]
                if w == 0.0:
                    continue
                p = point[j, k]
                for c in range(3):
                    if p < nj:
                        out[f, j, c] += w * origins[f, p, c]
                    else:
                        out[f, j, c] += w * ends[f, end_of[p - nj], c]


#: frames of FK points a call of :func:`_bvh_joints_kernel` holds at a time (the points of a 64-frame block
#: stay in the processor's cache between FK and the gather)
_FK_BLOCK = 64


@jit
def _bvh_joints_kernel(values, parent, offset, ch_start, ch_count, ch_kind, ch_axis, end_site, has_end, needed,
                       rot_joint, point, end_of, weight, joints, rotations):  # pragma: no cover - compiled
    """FK and the gather of the 24 canonical joints in one call (issue 35): :func:`_bvh_fk_kernel` and
    :func:`_combine_kernel` a block of :data:`_FK_BLOCK` frames at a time into ``joints`` (n, 24, 3) and
    ``rotations`` (n, 3, 3). The block's FK points need no NaN fill: the gather reads only points of
    weight ≠ 0, which ``needed`` (closed under parents) makes FK write."""
    n = values.shape[0]
    nj = parent.shape[0]
    origins = np.empty((_FK_BLOCK, nj, 3))
    ends = np.empty((_FK_BLOCK, nj, 3))
    for a in range(0, n, _FK_BLOCK):
        b = min(n, a + _FK_BLOCK)
        _bvh_fk_kernel(values[a:b], parent, offset, ch_start, ch_count, ch_kind, ch_axis, end_site, has_end,
                       needed, origins[:b - a], ends[:b - a], rotations[a:b], rot_joint)
        _combine_kernel(origins[:b - a], ends[:b - a], point, end_of, weight, joints[a:b])
