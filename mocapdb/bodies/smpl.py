"""The SMPL family's kinematic tree, its forward kinematics and the 24 canonical joints on it.

SMPL, SMPL-H and SMPL-X share the 22 joints of the body (pelvis, legs,
spine, neck, head, arms to the wrists); SMPL adds a hand joint per side,
SMPL-H 15 finger joints per hand, SMPL-X a jaw, two eyes and the fingers. A
pose is one axis-angle rotation per joint, each in its parent's frame, the
pelvis's in the world's; the pelvis sits at its rest position plus the
translation. Only the 22 body joints move the canonical joints, so only
they are computed (:func:`smpl_forward_kinematics`, a numba kernel over frames).

A rest skeleton (:class:`RestSkeleton`) holds the 22 rest joints and five
**end points** — the toe tips, the head top and the finger points — each
carried rigidly by its joint (as a BVH End Site): SMPL has no joint there,
and the features need them (FEATURES.md §6, #17, #18, #37). It comes from
the user's body model (:mod:`~mocapdb.readers.body_model`) or is the generic
one shipped with mocapdb (:func:`mocapdb.readers.generic_body.generic_rest`):
the proportions of the CMU subject 86 skeleton that ships with the sample
recordings (``mocapdb/sample/86.asf``) laid onto the SMPL tree
(:func:`asf_rest_tips` here; the file is read in ``readers``, as bodies
import no format). No number comes from an SMPL model file (their licence
forbids it).

The canonical joints (FEATURES.md §2.1) on the tree, as the humanoid mapper
places them on any skeleton (READERS.md §2): the pelvis is the root; hips,
knees, ankles, shoulders, elbows and wrists are the joints of those names;
the toes, head top and fingers are the end points; the neck is SMPL's neck
joint (the base of the neck), and the clavicles are the neck point as in
ASF data; belly and chest lie at 1/3 and 2/3 of the spine's rest length from
the pelvis to the neck.

References
----------
READERS.md §9; FEATURES.md §2.1; M. Loper et al., SMPL: A Skinned
Multi-Person Linear Model, SIGGRAPH Asia 2015 (the kinematic tree and the
pose parameters).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from mocapdb._numba import jit
from mocapdb.errors import ParameterError
from mocapdb.bodies.joints import JOINT_INDEX, JOINT_NAMES
from mocapdb.bodies.kinematics import orientation_matrix, sincos

__all__ = ["BODY_JOINTS", "BODY_PARENTS", "FAMILIES", "END_POINTS", "RestSkeleton",
           "canonical_weights", "smpl_forward_kinematics", "axis_angle_matrices", "rotation_vectors", "align_rotations",
           "asf_rest_tips"]

#: the 22 joints every SMPL-family body has, in the order of the pose parameters
BODY_JOINTS = ("pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2", "left_ankle",
               "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar", "right_collar", "head",
               "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist")
#: the parent of each body joint (-1: the pelvis, the root)
BODY_PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)

#: family → (its name, the width of ``poses``, the joints of its body model, the body model joint of
#: the left and the right finger point: SMPL's hand joint, the middle finger's first joint of SMPL-H/X)
FAMILIES = {
    "smpl": ("SMPL", 72, 24, (22, 23)),
    "smplh": ("SMPL-H", 156, 52, (25, 40)),
    "smplx": ("SMPL-X", 165, 55, (28, 43)),
}

#: the end points of a rest skeleton and the body joint that carries each
END_POINTS = (("ltoes", 10), ("rtoes", 11), ("headtop", 15), ("lfingers", 20), ("rfingers", 21))

_J = {name: k for k, name in enumerate(BODY_JOINTS)}
_N_BODY = len(BODY_JOINTS)
#: canonical joint → the body joint it is (the end points, belly and chest are placed apart)
_CANONICAL_JOINT = {
    "root": "pelvis", "lhip": "left_hip", "lknee": "left_knee", "lankle": "left_ankle",
    "rhip": "right_hip", "rknee": "right_knee", "rankle": "right_ankle",
    "neck": "neck", "head": "head", "lclavicle": "neck", "rclavicle": "neck",
    "lshoulder": "left_shoulder", "lelbow": "left_elbow", "lwrist": "left_wrist",
    "rshoulder": "right_shoulder", "relbow": "right_elbow", "rwrist": "right_wrist",
}
_SPINE = ("pelvis", "spine1", "spine2", "spine3", "neck")


@dataclass(frozen=True)
class RestSkeleton:
    """The rest pose of an SMPL-family body: where its joints are with every rotation zero.

    Attributes
    ----------
    joints : ndarray, shape (22, 3), float64
        The body joints (:data:`BODY_JOINTS`) in metres, in the body's own
        frame (Y up, facing +Z, the body's left at +X).
    ends : ndarray, shape (5, 3), float64
        The end points (:data:`END_POINTS`) at rest, same frame.
    source : str
        Where it comes from, for the motion's note.
    """

    joints: np.ndarray
    ends: np.ndarray
    source: str

    @functools.cached_property
    def kernel_arrays(self) -> tuple:
        """What forward kinematics needs of this skeleton, computed once: the pelvis at rest, each
        joint's offset from its parent, the parents, the end points' offsets and joints, and the
        canonical joints as (point, weight) pairs (:func:`canonical_weights`)."""
        parents = np.array(BODY_PARENTS, dtype=np.int64)
        offsets = np.ascontiguousarray(self.joints - self.joints[np.maximum(parents, 0)])
        end_joints = np.array([j for _, j in END_POINTS], dtype=np.int64)
        end_offsets = np.ascontiguousarray(self.ends - self.joints[end_joints])
        w = canonical_weights(self)
        width = int((w != 0).sum(axis=1).max())
        point = np.zeros((len(JOINT_NAMES), width), dtype=np.int64)
        weight = np.zeros((len(JOINT_NAMES), width))
        for k in range(len(JOINT_NAMES)):
            nz = np.flatnonzero(w[k])
            point[k, :len(nz)] = nz
            weight[k, :len(nz)] = w[k, nz]
        return (np.ascontiguousarray(self.joints[0], dtype=np.float64), offsets, parents, end_offsets, end_joints,
                point, weight)


# ----------------------------------------------------------------------------
# rest positions of an ASF skeleton's bone tips

_CM = 0.01  # the ASF reader's lengths are centimetres (READERS.md §5)

def asf_rest_tips(skeleton, *, vertical=()) -> dict:
    """The rest position of every bone tip of an ASF skeleton (root at the origin), in metres.

    Bone vectors are turned by the root's ``orientation`` as forward
    kinematics turns them at zero angles (FEATURES.md §2.2); bones named in
    ``vertical`` point straight down (−Y) with their own length instead.

    Returns
    -------
    dict
        Bone name (and ``"root"``) → (3,) float64.
    """
    orient = orientation_matrix(skeleton)
    tips = {"root": np.zeros(3)}
    for k in skeleton.topological_order():
        b = skeleton.bones[k]
        offset = np.array([0.0, -b.length, 0.0]) if b.name in vertical else orient @ np.asarray(b.offset, float)
        tips[b.name] = tips[b.parent] + offset * _CM
    return tips


# ----------------------------------------------------------------------------
# rotations

def axis_angle_matrices(rotvec) -> np.ndarray:
    """Rotation matrices of axis-angle vectors (Rodrigues' formula), vectorised.

    Parameters
    ----------
    rotvec : array_like, shape (..., 3)
        Axis times angle in radians.

    Returns
    -------
    ndarray, shape (..., 3, 3), float64
    """
    r = np.asarray(rotvec, dtype=np.float64)
    theta = np.sqrt(np.einsum("...i,...i->...", r, r))
    safe = np.where(theta > 0.0, theta, 1.0)
    k = r / safe[..., None]
    s = np.sin(theta)[..., None, None]
    c1 = (1.0 - np.cos(theta))[..., None, None]
    kx, ky, kz = k[..., 0], k[..., 1], k[..., 2]
    zero = np.zeros_like(kx)
    skew = np.stack([np.stack([zero, -kz, ky], -1), np.stack([kz, zero, -kx], -1),
                     np.stack([-ky, kx, zero], -1)], -2)
    return np.eye(3) + s * skew + c1 * (skew @ skew)


def rotation_vectors(matrices) -> np.ndarray:
    """Axis-angle vectors of rotation matrices (the inverse of :func:`axis_angle_matrices`).

    Through the unit quaternion (Shepperd's choice of the largest component,
    stable at every angle up to π).

    Parameters
    ----------
    matrices : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 3), float64
        Angles in [0, π].
    """
    m = np.asarray(matrices, dtype=np.float64)
    tr = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    cand = np.stack([tr, m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]], -1)
    pick = np.argmax(cand, axis=-1)
    q = np.empty(m.shape[:-2] + (4,))
    # w largest
    t = np.sqrt(np.maximum(1.0 + tr, 1e-300)) * 2.0
    qw = np.stack([0.25 * t, (m[..., 2, 1] - m[..., 1, 2]) / t, (m[..., 0, 2] - m[..., 2, 0]) / t,
                   (m[..., 1, 0] - m[..., 0, 1]) / t], -1)
    t = np.sqrt(np.maximum(1.0 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2], 1e-300)) * 2.0
    qx = np.stack([(m[..., 2, 1] - m[..., 1, 2]) / t, 0.25 * t, (m[..., 0, 1] + m[..., 1, 0]) / t,
                   (m[..., 0, 2] + m[..., 2, 0]) / t], -1)
    t = np.sqrt(np.maximum(1.0 + m[..., 1, 1] - m[..., 0, 0] - m[..., 2, 2], 1e-300)) * 2.0
    qy = np.stack([(m[..., 0, 2] - m[..., 2, 0]) / t, (m[..., 0, 1] + m[..., 1, 0]) / t, 0.25 * t,
                   (m[..., 1, 2] + m[..., 2, 1]) / t], -1)
    t = np.sqrt(np.maximum(1.0 + m[..., 2, 2] - m[..., 0, 0] - m[..., 1, 1], 1e-300)) * 2.0
    qz = np.stack([(m[..., 1, 0] - m[..., 0, 1]) / t, (m[..., 0, 2] + m[..., 2, 0]) / t,
                   (m[..., 1, 2] + m[..., 2, 1]) / t, 0.25 * t], -1)
    for k, cand_q in enumerate((qw, qx, qy, qz)):
        q[pick == k] = cand_q[pick == k]
    q = np.where(q[..., :1] < 0.0, -q, q)   # w ≥ 0: the angle in [0, π]
    v = q[..., 1:]
    sin_half = np.sqrt(np.einsum("...i,...i->...", v, v))
    angle = 2.0 * np.arctan2(sin_half, q[..., 0])
    scale = np.where(sin_half > 1e-12, angle / np.where(sin_half > 1e-12, sin_half, 1.0), 2.0)
    return v * scale[..., None]


def align_rotations(a, b) -> np.ndarray:
    """The smallest rotations turning directions ``a`` onto directions ``b``, row by row.

    Parameters
    ----------
    a, b : array_like, shape (n, 3)

    Returns
    -------
    ndarray, shape (n, 3, 3), float64
        The identity where either has no length; half a turn about an axis
        perpendicular to ``a`` where they are opposite.
    """
    a = np.asarray(a, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 3)
    na = np.linalg.norm(a, axis=1, keepdims=True)
    nb = np.linalg.norm(b, axis=1, keepdims=True)
    u = a / np.where(na > 0, na, 1.0)
    w = b / np.where(nb > 0, nb, 1.0)
    v = np.cross(u, w)
    c = np.einsum("ni,ni->n", u, w)
    k = np.zeros((len(a), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 0] = -v[:, 2], v[:, 1], v[:, 2]
    k[:, 1, 2], k[:, 2, 0], k[:, 2, 1] = -v[:, 0], -v[:, 1], v[:, 0]
    opposite = c < -1.0 + 1e-9
    out = np.eye(3) + k + (k @ k) / np.where(opposite, 1.0, 1.0 + c)[:, None, None]
    if opposite.any():
        p = np.cross(u[opposite], np.where(np.abs(u[opposite, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
        p /= np.linalg.norm(p, axis=1, keepdims=True)
        out[opposite] = 2.0 * np.einsum("ni,nj->nij", p, p) - np.eye(3)
    still = (nb[:, 0] == 0.0) | (na[:, 0] == 0.0)
    out[still] = np.eye(3)
    return out


# ----------------------------------------------------------------------------
# kinematics

def canonical_weights(rest: RestSkeleton) -> np.ndarray:
    """The canonical joints as weights over the body joints and end points, shape (24, 27).

    Row ``JOINT_INDEX[j]`` gives joint j as a weighted sum of the 22 body
    joints followed by the 5 end points: one 1 for a joint or end point,
    two weights on the spine for belly and chest (1/3 and 2/3 of the rest
    polyline pelvis → spine1 → spine2 → spine3 → neck, as the humanoid mapper
    places them, READERS.md §2).
    """
    w = np.zeros((len(JOINT_NAMES), _N_BODY + len(END_POINTS)))
    for j, body in _CANONICAL_JOINT.items():
        w[JOINT_INDEX[j], _J[body]] = 1.0
    for k, (name, _) in enumerate(END_POINTS):
        w[JOINT_INDEX[name], _N_BODY + k] = 1.0
    chain = [_J[n] for n in _SPINE]
    pts = rest.joints[chain]
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    total = float(seg.sum())
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    for name, frac in (("belly", 1.0 / 3.0), ("chest", 2.0 / 3.0)):
        at = frac * total
        i = int(np.clip(np.searchsorted(cum, at, side="right") - 1, 0, len(seg) - 1))
        u = 0.0 if seg[i] == 0.0 else (at - cum[i]) / seg[i]
        w[JOINT_INDEX[name], chain[i]] += 1.0 - u
        w[JOINT_INDEX[name], chain[i + 1]] += u
    return w


@jit
def _angles_kernel(pose, theta):  # pragma: no cover - compiled
    """``theta[f, j]`` = |pose[f, j]|, the rotation angle of an axis-angle vector."""
    for f in range(pose.shape[0]):
        for j in range(pose.shape[1]):
            theta[f, j] = math.sqrt(pose[f, j, 0] ** 2 + pose[f, j, 1] ** 2 + pose[f, j, 2] ** 2)


@jit
def _smpl_fk_kernel(pose, theta, sin, cos, trans, root_rest, offsets, parents, end_offsets, end_joints, point,
                    weight, joints, pelvis):  # pragma: no cover - compiled
    """Forward kinematics of every frame, one frame at a time.

    ``pose`` (n, 22, 3) axis-angle, ``theta`` (n, 22) its angles, ``sin`` and
    ``cos`` theirs (computed vectorised beforehand); ``trans`` (n, 3);
    ``root_rest`` (3,) the pelvis at rest; ``offsets`` (22, 3) each joint's
    rest position minus its parent's; ``parents`` (22,); ``end_offsets``
    (5, 3) each end point minus its joint at rest, ``end_joints`` (5,);
    ``point``, ``weight`` (24, k) each canonical joint's points (joints, then
    end points) and their weights. Writes ``joints[f]`` (24, 3) and
    ``pelvis[f]`` (3, 3), the pelvis's global rotation.
    """
    n = pose.shape[0]
    nb = offsets.shape[0]
    ne = end_offsets.shape[0]
    g = np.empty((nb, 3, 3))
    pts = np.empty((nb + ne, 3))
    for f in range(n):
        for j in range(nb):
            # Rodrigues: R = I + sin θ K + (1 − cos θ) K², K the cross-product matrix of the unit axis
            x, y, z = pose[f, j, 0], pose[f, j, 1], pose[f, j, 2]
            t = theta[f, j]
            if t > 0.0:
                x /= t
                y /= t
                z /= t
            s = sin[f, j]
            c1 = 1.0 - cos[f, j]
            r00 = 1.0 - c1 * (y * y + z * z)
            r11 = 1.0 - c1 * (x * x + z * z)
            r22 = 1.0 - c1 * (x * x + y * y)
            r01 = c1 * x * y - s * z
            r10 = c1 * x * y + s * z
            r02 = c1 * x * z + s * y
            r20 = c1 * x * z - s * y
            r12 = c1 * y * z - s * x
            r21 = c1 * y * z + s * x
            p = parents[j]
            if p < 0:
                for a in range(3):
                    pts[j, a] = root_rest[a] + trans[f, a]
                g[j, 0, 0], g[j, 0, 1], g[j, 0, 2] = r00, r01, r02
                g[j, 1, 0], g[j, 1, 1], g[j, 1, 2] = r10, r11, r12
                g[j, 2, 0], g[j, 2, 1], g[j, 2, 2] = r20, r21, r22
                for a in range(3):
                    for b in range(3):
                        pelvis[f, a, b] = g[j, a, b]
            else:
                o0, o1, o2 = offsets[j, 0], offsets[j, 1], offsets[j, 2]
                for a in range(3):
                    p0, p1, p2 = g[p, a, 0], g[p, a, 1], g[p, a, 2]
                    pts[j, a] = pts[p, a] + p0 * o0 + p1 * o1 + p2 * o2
                    g[j, a, 0] = p0 * r00 + p1 * r10 + p2 * r20
                    g[j, a, 1] = p0 * r01 + p1 * r11 + p2 * r21
                    g[j, a, 2] = p0 * r02 + p1 * r12 + p2 * r22
        for e in range(ne):
            j = end_joints[e]
            o0, o1, o2 = end_offsets[e, 0], end_offsets[e, 1], end_offsets[e, 2]
            for a in range(3):
                pts[nb + e, a] = pts[j, a] + g[j, a, 0] * o0 + g[j, a, 1] * o1 + g[j, a, 2] * o2
        for k in range(point.shape[0]):
            for a in range(3):
                acc = 0.0
                for q in range(point.shape[1]):
                    acc += weight[k, q] * pts[point[k, q], a]
                joints[f, k, a] = acc


def smpl_forward_kinematics(rest: RestSkeleton, body_pose, trans):
    """The 24 canonical joints and the pelvis's rotation of every frame.

    Parameters
    ----------
    rest : RestSkeleton
    body_pose : ndarray, shape (n_frames, 22, 3)
        Axis-angle rotations of the 22 body joints (the first 66 columns of
        ``poses``); the pelvis's in the world's frame, the others in their
        parent's.
    trans : ndarray, shape (n_frames, 3)
        The translation: the pelvis is at its rest position plus ``trans``.

    Returns
    -------
    joints : ndarray, shape (n_frames, 24, 3), float64
        In :data:`~mocapdb.bodies.joints.JOINT_NAMES` order, the file's frame.
    pelvis : ndarray, shape (n_frames, 3, 3), float64
        The pelvis's global rotation.
    """
    pose = np.ascontiguousarray(body_pose, dtype=np.float64).reshape(-1, _N_BODY, 3)
    trans = np.ascontiguousarray(trans, dtype=np.float64).reshape(-1, 3)
    if pose.shape[0] != trans.shape[0]:
        raise ParameterError(f"body_pose has {pose.shape[0]} frames, trans {trans.shape[0]}")
    n = pose.shape[0]
    joints = np.empty((n, len(JOINT_NAMES), 3))
    pelvis = np.empty((n, 3, 3))
    theta = np.empty((n, _N_BODY))
    _angles_kernel(pose, theta)
    sin, cos = sincos(theta)
    _smpl_fk_kernel(pose, theta, sin, cos, trans, *rest.kernel_arrays, joints, pelvis)
    return joints, pelvis
