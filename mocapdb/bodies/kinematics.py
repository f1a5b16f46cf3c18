"""Forward kinematics: ASF skeleton + AMC DOF values -> joint positions.

The toolbox's ASF/AMC kinematics (FEATURES.md §2.2), vectorised over frames in
one numba kernel:

* non-root bone with ASF ``axis`` (ax, ay, az) and AMC angles (rx, ry, rz)
  (missing DOFs = 0): local rotation ``C · M · C⁻¹`` with
  ``C = Rz(az)·Ry(ay)·Rx(ax)``, ``M = Rz(rz)·Ry(ry)·Rx(rx)``;
* global rotation = parent global · local;
* root: global = ``O · Rz(rz)·Ry(ry)·Rx(rx)``, ``O = Rz(o1)·Rx(o2)·Ry(o3)``
  from the ASF ``orientation`` (toolbox ``euler2quat`` default order 'zxy');
  position = AMC translation + ASF ``position`` (both / ``:units length`` · 2.54);
* a bone's node is its distal tip: parent node + global rotation · offset.

The 24 canonical joints are then picked **by bone name**
(:data:`ASF_JOINT_BONES`; lclavicle/rclavicle are the neck point).

The toolbox composes quaternions; we compose 3×3 matrices. Both are exact
rotations, so positions agree with the oracle to ~1e-13. Speed comes from two
things: the kernel carries each bone's frame ``G·C`` so that the per-frame
work per DOF is one elementary rotation of two columns, and sin/cos of all
angles of a take are evaluated up front by a vectorised fdlibm transcription
(:func:`sincos`, within 1 ulp of libm).

References
----------
FEATURES.md §1, §2.1, §2.2; toolbox ``convert2quat.m``,
``forwardKinematicsQuat.m``, ``recursive_forwardKinematicsQuat.m``.
"""
from __future__ import annotations

import math
import weakref

import numpy as np

from mocapdb._numba import jit
from mocapdb.bodies.acclaim import INCH_TO_TOOLBOX, AmcMotion, Skeleton, column_layout
from mocapdb.errors import ParameterError
from mocapdb.bodies.joints import JOINT_NAMES

__all__ = ["ASF_JOINT_BONES", "node_positions", "asf_joints", "asf_forward_kinematics",
           "root_rotation", "euler_matrix", "orientation_matrix", "local_rotations",
           "joint_node_indices", "sincos"]

#: canonical joint -> the ASF bone whose distal tip it is ("root" = the root
#: node). FEATURES.md §2.2 table; lclavicle/rclavicle = neck = tip of thorax.
ASF_JOINT_BONES = {
    "root": "root",
    "lhip": "lhipjoint", "lknee": "lfemur", "lankle": "ltibia", "ltoes": "ltoes",
    "rhip": "rhipjoint", "rknee": "rfemur", "rankle": "rtibia", "rtoes": "rtoes",
    "belly": "lowerback", "chest": "upperback", "neck": "thorax", "head": "upperneck",
    "headtop": "head",
    "lclavicle": "thorax", "lshoulder": "lclavicle", "lelbow": "lhumerus",
    "lwrist": "lwrist", "lfingers": "lfingers",
    "rclavicle": "thorax", "rshoulder": "rclavicle", "relbow": "rhumerus",
    "rwrist": "rwrist", "rfingers": "rfingers",
}

_DEG = math.pi / 180.0


def _angle_factor(unit: str) -> float:
    # toolbox convert2quat.m: conversion_factor = pi/180 for 'deg', 1 for 'rad'
    return _DEG if unit == "deg" else 1.0


# ----------------------------------------------------------------------------
# small rotation helpers (NumPy, vectorised; used outside the hot kernel)

def _axis_matrix(axis: str, a):
    a = np.asarray(a, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    if axis == "x":
        m = [[o, z, z], [z, c, -s], [z, s, c]]
    elif axis == "y":
        m = [[c, z, s], [z, o, z], [-s, z, c]]
    else:
        m = [[c, -s, z], [s, c, z], [z, z, o]]
    return np.moveaxis(np.array(m), (0, 1), (-2, -1))


def euler_matrix(angles, order: str):
    """Rotation ``R_order[0](a0) · R_order[1](a1) · R_order[2](a2)`` (radians).

    Parameters
    ----------
    angles : array_like, shape (..., len(order))
        One angle per letter of ``order``, in that order.
    order : str
        Axis letters, e.g. ``"zyx"`` for ``Rz·Ry·Rx`` (the leftmost factor is
        applied last to a column vector).

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    angles = np.asarray(angles, dtype=np.float64)
    out = None
    for k, ax in enumerate(order.lower()):
        m = _axis_matrix(ax, angles[..., k])
        out = m if out is None else out @ m
    return out


def orientation_matrix(skeleton: Skeleton) -> np.ndarray:
    """The ASF root orientation ``O = Rz(o1)·Rx(o2)·Ry(o3)``, shape (3, 3).

    The numbers are taken in file order with the toolbox's ``euler2quat``
    default order 'zxy' (FEATURES.md §2.2), not Acclaim's reading.
    """
    o = skeleton.root_orientation
    if skeleton.angle_unit == "deg":
        o = o * math.pi / 180.0  # readRootASF.m: rootRotationalOffsetEuler*pi/180
    return euler_matrix(o, "zxy")


def _axis_rotations(skeleton: Skeleton) -> np.ndarray:
    """``C = Rz(az)·Ry(ay)·Rx(ax)`` of every bone, shape (n_bones, 3, 3)."""
    # convert2quat.m: axis * conversion_factor (the ASF's own angle unit)
    ax = np.array([b.axis for b in skeleton.bones], dtype=np.float64).reshape(-1, 3)
    ax = ax * _angle_factor(skeleton.angle_unit)
    return np.ascontiguousarray(euler_matrix(ax[:, ::-1], "zyx"))


# ----------------------------------------------------------------------------
# the kernel

# fdlibm (k_sin.c, k_cos.c, e_rem_pio2.c) polynomial coefficients and the
# two-step Cody-Waite reduction by pi/2
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11
_INVPIO2 = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e+00   # first 33 bits of pi/2
_PIO2_2 = 6.07710050630396597660e-11   # next 33 bits
_PIO2_2T = 2.02226624879595063154e-21  # pi/2 - (_PIO2_1 + _PIO2_2)
_TOINT = 6755399441055744.0  # 1.5 * 2**52: adding and subtracting it rounds to an integer
_SINCOS_RANGE = 1.0e5  # the two-step reduction is exact far beyond this (|n| < 2**20)


@jit
def _sincos_kernel(x, s, c):  # pragma: no cover - numba
    """``s = sin(x)``, ``c = cos(x)`` elementwise over flat arrays, within 1 ulp.

    The angles of a take are ~2 million sin/cos pairs per 30 k frames; libm
    costs ~17 ns a pair, this branch-free fdlibm transcription ~2 ns because
    LLVM vectorises it. |x| beyond 1e5 rad falls back to libm.
    """
    n = x.shape[0]
    for i in range(n):
        xi = x[i]
        fn = (xi * _INVPIO2 + _TOINT) - _TOINT
        q = np.int64(fn)
        r = xi - fn * _PIO2_1
        w = fn * _PIO2_2
        t = r
        r = t - w
        w = fn * _PIO2_2T - ((t - r) - w)
        y0 = r - w
        y1 = (r - y0) - w
        z = y0 * y0
        v = z * y0
        rs = _S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))
        ks = y0 - ((z * (0.5 * y1 - v * rs) - y1) - v * _S1)
        rc = z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
        hz = 0.5 * z
        ww = 1.0 - hz
        kc = ww + (((1.0 - ww) - hz) + (z * rc - y0 * y1))
        odd = (q & 1) != 0
        sv = kc if odd else ks
        cv = ks if odd else kc
        if (q & 2) != 0:
            sv = -sv
        if ((q + 1) & 2) != 0:
            cv = -cv
        s[i] = sv
        c[i] = cv
    for i in range(n):
        if not abs(x[i]) < _SINCOS_RANGE:
            s[i] = math.sin(x[i])
            c[i] = math.cos(x[i])


def sincos(x):
    """``(sin(x), cos(x))`` of a float64 array (any shape), within 1 ulp of libm."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    s = np.empty_like(x)
    c = np.empty_like(x)
    _sincos_kernel(x.reshape(-1), s.reshape(-1), c.reshape(-1))
    return s, c


@jit
def _mixed_columns(axis):  # pragma: no cover - numba
    """The two columns ``(i, j)`` (cyclic) that a rotation about ``axis`` (0=x, 1=y, 2=z) mixes."""
    if axis == 0:
        return 1, 2
    if axis == 1:
        return 2, 0
    return 0, 1


@jit
def rotate_columns(h, k, axis, c, s):  # pragma: no cover - numba
    """h[k] = h[k] · R_axis(θ) with c = cos θ, s = sin θ (axis 0=x, 1=y, 2=z).

    Right-multiplying by an elementary rotation only mixes two columns.
    """
    i, j = _mixed_columns(axis)
    # R_axis has R[i,i] = c, R[j,i] = s, R[i,j] = -s, R[j,j] = c for (i, j) cyclic
    for r in range(3):
        a = h[k, r, i]
        b = h[k, r, j]
        h[k, r, i] = c * a + s * b
        h[k, r, j] = c * b - s * a


# ----------------------------------------------------------------------------
# public API

class _Layout:
    """Constant arrays of the kernel for one skeleton (and its AMC column layout)."""

    def __init__(self, skeleton: Skeleton):
        bones = skeleton.bones
        nb = len(bones)
        idx = skeleton.bone_index
        self.parent = np.array([0 if b.parent == "root" else idx[b.parent] + 1 for b in bones],
                               dtype=np.int64)
        axis_c = _axis_rotations(skeleton)
        c_parent = np.concatenate([np.eye(3)[None], axis_c])[self.parent]
        self.dmat = np.ascontiguousarray(np.swapaxes(c_parent, 1, 2) @ axis_c)
        # parent and child share the axis (ltibia under lfemur, ...): skip the
        # product, which would give the identity only up to rounding
        self.dident = np.all(c_parent == axis_c, axis=(1, 2))
        offset = np.array([b.offset for b in bones], dtype=np.float64).reshape(nb, 3)
        self.offp = np.ascontiguousarray(np.einsum("bji,bj->bi", axis_c, offset))
        self.order = skeleton.topological_order()
        self.orient = np.ascontiguousarray(orientation_matrix(skeleton))
        _, _, _, self.columns, self.dof_names = column_layout(skeleton)
        self.cols = self.motion_columns(skeleton, self)

    @staticmethod
    def motion_columns(skeleton: Skeleton, motion):
        """(rot_cols (nb, 3) of rz ry rx, root_cols (3,) of rz ry rx, trans_cols [tx ty tz])."""
        def col(bone, d):
            names = motion.dof_names.get(bone, ())
            return motion.columns[bone].start + names.index(d) if d in names else -1

        nb = len(skeleton.bones)
        rot = np.array([[col(b.name, d) for d in ("rz", "ry", "rx")] for b in skeleton.bones],
                       dtype=np.int64).reshape(nb, 3)
        root = np.array([col("root", d) for d in ("rz", "ry", "rx")], dtype=np.int64)
        return rot, root, [col("root", d) for d in ("tx", "ty", "tz")]

    def columns_for(self, skeleton: Skeleton, motion: AmcMotion):
        if motion.columns == self.columns and motion.dof_names == self.dof_names:
            return self.cols
        return self.motion_columns(skeleton, motion)


# skeletons are immutable: cache their kernel arrays (per call they cost more
# than the kinematics of a short clip); entries die with the skeleton
_LAYOUTS: dict = {}


def _layout(skeleton: Skeleton) -> _Layout:
    key = id(skeleton)
    hit = _LAYOUTS.get(key)
    if hit is not None and hit[0]() is skeleton:
        return hit[1]
    lay = _Layout(skeleton)
    _LAYOUTS[key] = (weakref.ref(skeleton, lambda _ref, k=key: _LAYOUTS.pop(k, None)), lay)
    return lay


def _check(skeleton: Skeleton, motion: AmcMotion):
    names = _layout(skeleton).columns
    extra = [n for n in motion.columns if n not in names]
    if extra:
        raise ParameterError(f"motion: bones {extra} are not in skeleton {skeleton.name!r}; "
                             "read the AMC with the same skeleton")


#: frames per block of forward kinematics, the lanes of :func:`_asf_motion_kernel`: each bone's frame and
#: node are held for a block's frames side by side (a block's matrices, 31 × 9 × 64 doubles, stay in the
#: processor's cache)
_FK_BLOCK = 64
#: a block's lanes are rounded up to this many (whole vectors; the lanes past the frames are ignored)
_FK_LANE_GROUP = 8


@jit
def rotate_lanes(h, k, axis, c, s, m):  # pragma: no cover - numba
    """:func:`rotate_columns` of matrix ``k`` of ``h`` (nodes, 3, 3, lanes) in each of the first ``m`` lanes,
    ``c``/``s`` the lanes' cosine and sine: the same products and sums, a lane per frame."""
    i, j = _mixed_columns(axis)
    h0i, h0j = h[k, 0, i], h[k, 0, j]
    h1i, h1j = h[k, 1, i], h[k, 1, j]
    h2i, h2j = h[k, 2, i], h[k, 2, j]
    for f in range(m):
        cf, sf = c[f], s[f]
        a, b = h0i[f], h0j[f]
        h0i[f] = cf * a + sf * b
        h0j[f] = cf * b - sf * a
        a, b = h1i[f], h1j[f]
        h1i[f] = cf * a + sf * b
        h1j[f] = cf * b - sf * a
        a, b = h2i[f], h2j[f]
        h2i[f] = cf * a + sf * b
        h2j[f] = cf * b - sf * a


@jit
def _asf_motion_kernel(values, factor, trans_cols, length_unit, root_position, root_cols, orient, order, parent,
                       dmat, dident, offp, rot_cols, joint_nodes, joints, root_rot):  # pragma: no cover - numba
    """A take's forward kinematics in one call (issue 35), :data:`_FK_BLOCK` frames at a time, the frames of a
    block side by side (one lane each: the loops over lanes are vector instructions).

    Per block: the AMC values (n, ncols) in the motion's angle unit times ``factor`` (convert2quat.m: angle ·
    conversion factor), their sine and cosine (:func:`_sincos_kernel`), the root position ``(t / length_unit)
    · 2.54 + root_position`` (readAMC.m / readASF.m; ``trans_cols`` −1: t = 0), then each bone's frame
    ``H_b = G_b · C_b`` (global rotation times its axis rotation): ``H_b = H_parent · (C_parentᵀ · C_b) ·
    Rz·Ry·Rx`` and ``node_b = node_parent + H_b · (C_bᵀ · offset_b)``, which equals the toolbox's ``G_b =
    G_parent · C_b·M_b·C_bᵀ`` but needs no per-frame ``C``/``C⁻¹`` products when parent and child share an
    axis. Each lane takes the operations of the frame-by-frame kinematics in their order (bit for bit:
    tests/test_asf_amc.py ``frame_by_frame_asf_fk``).

    ``root_cols`` (3,) columns of the root rz, ry, rx (−1 = absent); ``orient`` (3, 3) = O; ``order`` bones
    parents-first; ``parent`` (nb,) parent node (0 = root, k+1 = bone k); ``dmat`` (nb, 3, 3) =
    C_parentᵀ·C_b, ``dident`` (nb,) true when that is the identity; ``offp`` (nb, 3) = C_bᵀ·offset_b;
    ``rot_cols`` (nb, 3) columns of rz, ry, rx. Writes ``joints[f, j]`` = node ``joint_nodes[j]`` and
    ``root_rot[f]`` = Rz·Ry·Rx of the root."""
    n, ncols = values.shape
    nb = order.shape[0]
    nj = joint_nodes.shape[0]
    ang = np.zeros(ncols * _FK_BLOCK)
    sin = np.empty(ncols * _FK_BLOCK)
    cos = np.empty(ncols * _FK_BLOCK)
    h = np.empty((nb + 1, 3, 3, _FK_BLOCK))
    node = np.zeros((nb + 1, 3, _FK_BLOCK))
    rr = np.empty((1, 3, 3, _FK_BLOCK))
    for a in range(0, n, _FK_BLOCK):
        m = min(_FK_BLOCK, n - a)
        w = min(_FK_BLOCK, (m + _FK_LANE_GROUP - 1) // _FK_LANE_GROUP * _FK_LANE_GROUP)   # lanes computed
        av = ang[:ncols * w].reshape((ncols, w))
        for f in range(m):
            for k in range(ncols):
                av[k, f] = values[a + f, k] * factor
        for k in range(3):
            c = trans_cols[k]
            for f in range(m):
                t = values[a + f, c] if c >= 0 else 0.0
                node[0, k, f] = (t / length_unit) * INCH_TO_TOOLBOX + root_position[k]
        _sincos_kernel(ang[:ncols * w], sin[:ncols * w], cos[:ncols * w])
        sv = sin[:ncols * w].reshape((ncols, w))
        cv = cos[:ncols * w].reshape((ncols, w))
        # ---- root: R = Rz·Ry·Rx, H_0 = O · R
        for i in range(3):
            for j in range(3):
                e = 1.0 if i == j else 0.0
                o = orient[i, j]
                for f in range(w):
                    rr[0, i, j, f] = e
                    h[0, i, j, f] = o
        for q in range(3):
            c = root_cols[q]
            if c >= 0:
                rotate_lanes(rr, 0, 2 - q, cv[c], sv[c], w)
                rotate_lanes(h, 0, 2 - q, cv[c], sv[c], w)
        # ---- bones, parents first
        for q in range(nb):
            b = order[q]
            p = parent[b]
            k = b + 1
            hp, hk = h[p], h[k]
            if dident[b]:
                for i in range(3):
                    for j in range(3):
                        for f in range(w):
                            hk[i, j, f] = hp[i, j, f]
            else:
                d00, d01, d02 = dmat[b, 0, 0], dmat[b, 0, 1], dmat[b, 0, 2]
                d10, d11, d12 = dmat[b, 1, 0], dmat[b, 1, 1], dmat[b, 1, 2]
                d20, d21, d22 = dmat[b, 2, 0], dmat[b, 2, 1], dmat[b, 2, 2]
                for f in range(w):
                    for i in range(3):
                        p0, p1, p2 = hp[i, 0, f], hp[i, 1, f], hp[i, 2, f]
                        hk[i, 0, f] = p0 * d00 + p1 * d10 + p2 * d20
                        hk[i, 1, f] = p0 * d01 + p1 * d11 + p2 * d21
                        hk[i, 2, f] = p0 * d02 + p1 * d12 + p2 * d22
            for ax in range(3):  # z, y, x: M = Rz·Ry·Rx
                c = rot_cols[b, ax]
                if c >= 0:
                    rotate_lanes(h, k, 2 - ax, cv[c], sv[c], w)
            o0, o1, o2 = offp[b, 0], offp[b, 1], offp[b, 2]
            np_, nk = node[p], node[k]
            for f in range(w):
                for i in range(3):
                    nk[i, f] = np_[i, f] + (hk[i, 0, f] * o0 + hk[i, 1, f] * o1 + hk[i, 2, f] * o2)
        for f in range(m):
            for j in range(nj):
                for i in range(3):
                    joints[a + f, j, i] = node[joint_nodes[j], i, f]
            for i in range(3):
                for j in range(3):
                    root_rot[a + f, i, j] = rr[0, i, j, f]


def _run(skeleton: Skeleton, motion: AmcMotion, joint_nodes: np.ndarray):
    _check(skeleton, motion)
    lay = _layout(skeleton)
    rot_cols, root_cols, trans_cols = lay.columns_for(skeleton, motion)
    n = motion.n_frames
    joints = np.empty((n, joint_nodes.shape[0], 3))
    rot = np.empty((n, 3, 3))
    # AMC angles are in the motion's unit (the ASF unit unless the AMC says otherwise)
    _asf_motion_kernel(np.ascontiguousarray(motion.values, dtype=np.float64), _angle_factor(motion.angle_unit),
                       np.asarray(trans_cols, dtype=np.int64), float(skeleton.length_unit),
                       np.asarray(skeleton.root_position, dtype=np.float64), root_cols, lay.orient, lay.order,
                       lay.parent, lay.dmat, lay.dident, lay.offp, rot_cols, joint_nodes, joints, rot)
    return joints, rot


def node_positions(skeleton: Skeleton, motion: AmcMotion):
    """Positions of every skeleton node for every frame.

    Parameters
    ----------
    skeleton : Skeleton
    motion : AmcMotion
        Read with the same skeleton (:func:`mocapdb.readers.amc.read_amc`).

    Returns
    -------
    positions : ndarray, shape (n_frames, n_bones + 1, 3), float64
        Node 0 = root, node k+1 = tip of the k-th bone (file order), toolbox
        units, Y up.
    root_rotation : ndarray, shape (n_frames, 3, 3), float64
        AMC root ``Rz(rz)·Ry(ry)·Rx(rx)`` without the ASF orientation
        (feature #40 reads its x axis).

    References
    ----------
    FEATURES.md §2.2.
    """
    return _run(skeleton, motion, np.arange(len(skeleton.bones) + 1, dtype=np.int64))


def joint_node_indices(skeleton: Skeleton) -> np.ndarray:
    """Node index (0 = root, k+1 = bone k) of each canonical joint, shape (24,).

    Raises
    ------
    ParameterError
        The skeleton lacks a bone the canonical joints need (names listed).
    """
    cached = skeleton.__dict__.get("_joint_nodes")
    if cached is not None:   # a skeleton is immutable: its takes share the answer (callers never write it;
        return cached        # writable, so that the kernels see the type node_positions gives them)
    idx = {b.name.lower(): k + 1 for k, b in enumerate(skeleton.bones)}
    idx["root"] = 0
    missing = sorted({ASF_JOINT_BONES[j] for j in JOINT_NAMES} - set(idx))
    if missing:
        raise ParameterError(f"skeleton {skeleton.name!r} ({skeleton.path}) lacks the bones "
                             f"{', '.join(missing)} needed for the 24 canonical joints")
    nodes = np.array([idx[ASF_JOINT_BONES[j]] for j in JOINT_NAMES], dtype=np.int64)
    object.__setattr__(skeleton, "_joint_nodes", nodes)   # a frozen dataclass: a private memo
    return nodes


def asf_forward_kinematics(skeleton: Skeleton, motion: AmcMotion):
    """The 24 canonical joints and the root rotation of an ASF/AMC motion.

    Returns
    -------
    joints : ndarray, shape (n_frames, 24, 3), float64
        In :data:`mocapdb.bodies.joints.JOINT_NAMES` order.
    root_rotation : ndarray, shape (n_frames, 3, 3), float64

    Raises
    ------
    ParameterError
        The skeleton lacks bones needed for the canonical joints.

    References
    ----------
    FEATURES.md §2.1, §2.2.
    """
    return _run(skeleton, motion, joint_node_indices(skeleton))


def asf_joints(skeleton: Skeleton, motion: AmcMotion) -> np.ndarray:
    """The 24 canonical joints only; see :func:`asf_forward_kinematics`."""
    return asf_forward_kinematics(skeleton, motion)[0]


def root_rotation(skeleton: Skeleton, motion: AmcMotion) -> np.ndarray:
    """AMC root rotation ``Rz·Ry·Rx`` (no ASF orientation), shape (n_frames, 3, 3)."""
    return node_positions(skeleton, motion)[1]


def local_rotations(skeleton: Skeleton, motion: AmcMotion):
    """Per-bone local rotations ``C·M·C⁻¹`` and the root's ``O·Rz·Ry·Rx`` (NumPy).

    Used by the BVH writer (which stores one local rotation per joint), not
    by the hot path.

    Returns
    -------
    root : ndarray, shape (n_frames, 3, 3)
        Global root rotation including the ASF orientation.
    local : ndarray, shape (n_frames, n_bones, 3, 3)
        In ASF bone file order.
    """
    n = motion.n_frames
    fac = _angle_factor(motion.angle_unit)

    def col(bone, d):
        c = motion.column(bone, d)
        return motion.values[:, c] * fac if c >= 0 else np.zeros(n)

    m = euler_matrix(np.stack([col("root", "rz"), col("root", "ry"), col("root", "rx")], -1), "zyx")
    root = orientation_matrix(skeleton) @ m
    local = np.empty((n, len(skeleton.bones), 3, 3))
    axis_c = _axis_rotations(skeleton)
    for k, b in enumerate(skeleton.bones):
        if not b.dof:
            local[:, k] = np.eye(3)  # C·I·C⁻¹, exactly (no rounding noise)
            continue
        c = axis_c[k]
        mb = euler_matrix(np.stack([col(b.name, "rz"), col(b.name, "ry"), col(b.name, "rx")], -1),
                          "zyx")
        local[:, k] = c @ mb @ c.T
    return root, local
