"""Forward kinematics of a BVH hierarchy, and the gather of the 24 canonical joints from its points.

:func:`bvh_node_positions` gives every joint's origin and End Site per frame, a frame at a time; the BVH
reader (:mod:`~mocapdb.readers.bvh`) runs FK and the gather in one kernel call per block of motion lines
(:func:`_bvh_joints_kernel`, issue 35), 64 frames side by side, so a take's points of every joint are never
written out. The hierarchy's arrays come from ``BvhHierarchy.arrays()`` (built once per hierarchy).
"""
from __future__ import annotations

import math

import numpy as np

from mocapdb._numba import jit
from mocapdb.bodies.kinematics import rotate_lanes, rotate_columns

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


#: frames a call of :func:`_bvh_joints_kernel` holds side by side (a block's matrices, nj × 9 × 64 doubles, and
#: points stay in the processor's cache between FK and the gather)
_FK_BLOCK = 64
#: a block's lanes are rounded up to this many (whole vectors; the lanes past the frames are ignored)
_FK_LANE_GROUP = 8


@jit
def _bvh_joints_kernel(values, parent, offset, ch_start, ch_count, ch_kind, ch_axis, end_site, has_end, needed,
                       rot_joint, point, end_of, weight, joints, rotations):  # pragma: no cover - compiled
    """FK and the gather of the 24 canonical joints in one call (issue 35) into ``joints`` (n, 24, 3) and
    ``rotations`` (n, 3, 3): :func:`_bvh_fk_kernel` then the weighted sum of each canonical joint's points (``point``, ``weight``;
    a point ≥ n_joints is the End Site of joint ``end_of[point − n_joints]``), :data:`_FK_BLOCK` frames at
    a time with the frames of a block side by side, one lane each (the loops over lanes are vector
    instructions, as the ASF kinematics' :func:`~mocapdb.bodies.kinematics._asf_motion_kernel`). Each lane
    takes the operations of the frame-by-frame kernels in their order, so the result is theirs bit for bit
    (tests/test_bvh.py); only sine and cosine stay a libm call per angle, skipped for an angle of 0 (cos ±0 = 1
    and sin ±0 = ±0 exactly: a rig converted from ASF writes 0 for each missing degree of freedom, a fifth of
    a CMU conversion's angles). The gather reads only points of weight ≠ 0, which ``needed`` (closed under
    parents) makes FK write."""
    n = values.shape[0]
    nj = parent.shape[0]
    deg = math.pi / 180.0
    h = np.empty((nj, 3, 3, _FK_BLOCK))
    org = np.empty((nj, 3, _FK_BLOCK))
    end = np.empty((nj, 3, _FK_BLOCK))
    t = np.empty((3, _FK_BLOCK))
    cs = np.ones(_FK_BLOCK)    # lanes past a block's frames rotate by 0: no stale or subnormal values
    sn = np.zeros(_FK_BLOCK)
    acc = np.empty(_FK_BLOCK)
    for a in range(0, n, _FK_BLOCK):
        m = min(_FK_BLOCK, n - a)
        w = min(_FK_BLOCK, (m + _FK_LANE_GROUP - 1) // _FK_LANE_GROUP * _FK_LANE_GROUP)   # lanes computed
        for f in range(m, w):   # a short last block: its lanes past the frames rotate by 0 (channels write < m)
            cs[f] = 1.0
            sn[f] = 0.0
        for j in range(nj):
            if not needed[j]:
                continue
            p = parent[j]
            hj = h[j]
            for i in range(3):
                for k in range(3):
                    if p >= 0:
                        hp = h[p, i, k]
                        for f in range(w):
                            hj[i, k, f] = hp[f]
                    else:
                        e = 1.0 if i == k else 0.0
                        for f in range(w):
                            hj[i, k, f] = e
                o = offset[j, i]
                for f in range(w):
                    t[i, f] = o
            s0 = ch_start[j]
            for c in range(ch_count[j]):
                col = s0 + c
                ax = ch_axis[col]
                if ch_kind[col] == 0:
                    ta = t[ax]
                    if p >= 0:
                        for f in range(m):
                            ta[f] = values[a + f, col]  # replaces the OFFSET coordinate
                    else:
                        for f in range(m):
                            ta[f] += values[a + f, col]
                else:
                    for f in range(m):
                        v = values[a + f, col] * deg
                        if v == 0.0:
                            cs[f] = 1.0
                            sn[f] = v
                        else:
                            cs[f] = math.cos(v)
                            sn[f] = math.sin(v)
                    rotate_lanes(h, j, ax, cs, sn, w)
            for i in range(3):
                oj = org[j, i]
                if p >= 0:
                    op, hp0, hp1, hp2 = org[p, i], h[p, i, 0], h[p, i, 1], h[p, i, 2]
                    t0, t1, t2 = t[0], t[1], t[2]
                    for f in range(w):
                        oj[f] = op[f] + (hp0[f] * t0[f] + hp1[f] * t1[f] + hp2[f] * t2[f])
                else:
                    ti = t[i]
                    for f in range(w):
                        oj[f] = ti[f]
            if has_end[j]:
                e0, e1, e2 = end_site[j, 0], end_site[j, 1], end_site[j, 2]
                for i in range(3):
                    ej, oj, hj0, hj1, hj2 = end[j, i], org[j, i], hj[i, 0], hj[i, 1], hj[i, 2]
                    for f in range(w):
                        ej[f] = oj[f] + (hj0[f] * e0 + hj1[f] * e1 + hj2[f] * e2)
            if j == rot_joint:
                for f in range(m):
                    for i in range(3):
                        for k in range(3):
                            rotations[a + f, i, k] = hj[i, k, f]
        for q in range(point.shape[0]):
            for c in range(3):
                for f in range(w):
                    acc[f] = 0.0
                for k in range(point.shape[1]):
                    wt = weight[q, k]
                    if wt == 0.0:
                        continue
                    pt = point[q, k]
                    src = org[pt, c] if pt < nj else end[end_of[pt - nj], c]
                    for f in range(w):
                        acc[f] += wt * src[f]
                for f in range(m):
                    joints[a + f, q, c] = acc[f]
