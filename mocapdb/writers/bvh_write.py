"""Write ASF/AMC motions as BVH (the test and benchmark source of BVH files).

:func:`write_bvh` stores an ASF/AMC motion as BVH (``layout="asf"``: ASF bone
names, which :func:`mocapdb.readers.bvh.read_bvh` maps exactly as the ASF
reader; ``layout="cmu"``: the cmuconvert joint names), one joint per ASF bone
with its local rotation ``C·M·C⁻¹`` as Euler angles, so that reading it back
reproduces the ASF joint positions and root rotation.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.bodies.acclaim import AmcMotion
from mocapdb.bodies.acclaim import Skeleton
from mocapdb.bodies.kinematics import local_rotations, node_positions

__all__ = ["write_bvh", "write_bvh_tree", "euler_angles", "CMU_BONE_NAMES"]

#: ASF bone -> joint name in the cmuconvert (cgspeed) CMU BVH files
CMU_BONE_NAMES = {
    "root": "Hips",
    "lhipjoint": "LHipJoint", "lfemur": "LeftUpLeg", "ltibia": "LeftLeg", "lfoot": "LeftFoot",
    "ltoes": "LeftToeBase",
    "rhipjoint": "RHipJoint", "rfemur": "RightUpLeg", "rtibia": "RightLeg", "rfoot": "RightFoot",
    "rtoes": "RightToeBase",
    "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1", "lowerneck": "Neck",
    "upperneck": "Neck1", "head": "Head",
    "lclavicle": "LeftShoulder", "lhumerus": "LeftArm", "lradius": "LeftForeArm",
    "lwrist": "LeftHand", "lhand": "LeftFingerBase", "lfingers": "LeftHandIndex1",
    "lthumb": "LThumb",
    "rclavicle": "RightShoulder", "rhumerus": "RightArm", "rradius": "RightForeArm",
    "rwrist": "RightHand", "rhand": "RightFingerBase", "rfingers": "RightHandIndex1",
    "rthumb": "RThumb",
}

_AXIS = {"x": 0, "y": 1, "z": 2}


def euler_angles(rotations, order: str) -> np.ndarray:
    """Euler angles (radians) of rotation matrices: ``R = R_o0(a0)·R_o1(a1)·R_o2(a2)``.

    Parameters
    ----------
    rotations : ndarray, shape (..., 3, 3)
    order : str
        Three distinct axis letters, e.g. ``"zyx"`` (BVH channel order).

    Returns
    -------
    ndarray, shape (..., 3)
        Angles in the order of ``order``; the middle one in [-pi/2, pi/2].
    """
    o = order.lower()
    if sorted(o) != ["x", "y", "z"]:
        raise ParameterError(f"order={order!r}: expected a permutation of 'xyz'")
    i, j, k = (_AXIS[a] for a in o)
    r = np.asarray(rotations, dtype=np.float64)
    # sign of the permutation (i, j, k): +1 for cyclic (xyz, yzx, zxy)
    s = 1.0 if (j - i) % 3 == 1 else -1.0
    b = np.arctan2(s * r[..., i, k], np.hypot(r[..., i, i], r[..., i, j]))
    a = np.arctan2(-s * r[..., j, k], r[..., k, k])
    c = np.arctan2(-s * r[..., i, j], r[..., i, i])
    return np.stack([a, b, c], axis=-1)


def _fmt(x, precision):
    return format(float(x), f".{precision}g")


def write_bvh(path, skeleton: Skeleton, motion: AmcMotion, *, layout: str = "asf",
              rotation_order="ZYX", rest_frame: bool = False, precision: int = 12) -> Path:
    """Write an ASF/AMC motion as a BVH file.

    One BVH joint per ASF bone (its OFFSET is the parent bone's vector, its
    channels the bone's local rotation ``C·M·C⁻¹``), leaf bones end in an End
    Site with their own vector, the root has 6 channels (position = AMC
    translation + ASF position in toolbox units; rotation = ``O·Rz·Ry·Rx``).
    Reading the file back gives the ASF joint positions and, when the ASF
    orientation O is the identity (all files here), the AMC root rotation.

    Parameters
    ----------
    path : str or Path
    skeleton : Skeleton
    motion : AmcMotion
        Read with ``skeleton``.
    layout : {"asf", "cmu"}, keyword-only
        Joint names: ASF bone names, or the cmuconvert names of
        :data:`CMU_BONE_NAMES` (needs the standard CMU bone set).
    rotation_order : str or dict, keyword-only
        Rotation channel order, e.g. ``"ZYX"`` (default, as cmuconvert) or any
        permutation; a dict maps joint names (BVH names) to orders, others ZYX.
    rest_frame : bool, keyword-only
        Prepend an all-zero frame, as cmuconvert does.
    precision : int, keyword-only
        Significant digits. 12 (default) keeps positions within ~1e-11 of a
        bone length and stays on the reader's exact fast path; 17 round-trips
        float64 exactly but reads ~5x slower (mantissas beyond 2**53 go
        through Python's ``float``).

    Returns
    -------
    Path

    Raises
    ------
    ParameterError
        Unknown layout, a bone without a cmuconvert name, a bad rotation order.
    """
    if layout not in ("asf", "cmu"):
        raise ParameterError(f"layout={layout!r}: expected 'asf' or 'cmu'")
    if layout == "cmu":
        missing = [b.name for b in skeleton.bones if b.name.lower() not in CMU_BONE_NAMES]
        if missing:
            raise ParameterError(f"layout='cmu': bones {missing} have no cmuconvert name; "
                                 "use layout='asf'")
        rename = {b.name: CMU_BONE_NAMES[b.name.lower()] for b in skeleton.bones}
        rename["root"] = CMU_BONE_NAMES["root"]
    else:
        rename = {b.name: b.name for b in skeleton.bones}
        rename["root"] = "root"
    root_rot, local = local_rotations(skeleton, motion)
    positions, _ = node_positions(skeleton, motion)
    bones = skeleton.bones
    index = {b.name: k + 1 for k, b in enumerate(bones)}
    index["root"] = 0
    # a joint sits where its bone starts: its OFFSET is its parent bone's vector; a leaf bone ends in
    # an End Site with its own vector
    offsets = np.zeros((len(bones) + 1, 3))
    for k, b in enumerate(bones):
        if b.parent != "root":
            offsets[k + 1] = skeleton.bone(b.parent).offset
    leaves = {k + 1: b.offset for k, b in enumerate(bones) if not skeleton.children(b.name)}
    rotations = np.concatenate([root_rot[:, None], local], axis=1)
    return write_bvh_tree(path, [rename["root"], *(rename[b.name] for b in bones)],
                          [-1, *(index[b.parent] for b in bones)], offsets, positions[:, 0, :], rotations,
                          motion.fps, end_sites=leaves, rotation_order=rotation_order, rest_frame=rest_frame,
                          precision=precision)


def write_bvh_tree(path, names, parents, offsets, root_positions, rotations, fps, *, end_sites=None,
                   rotation_order="ZYX", rest_frame: bool = False, precision: int = 12) -> Path:
    """Write a skeleton and its motion as a BVH file: the one BVH writer of mocapdb.

    Parameters
    ----------
    path : str or Path
    names : sequence of str
        Joint names; joint 0 is the root.
    parents : sequence of int
        The parent of each joint (-1 for the root); a joint's children are
        written in index order, depth first.
    offsets : array_like, shape (n_joints, 3)
        Each joint's OFFSET: where it sits relative to its parent's origin
        at rest (the root's is written as given).
    root_positions : ndarray, shape (n_frames, 3)
        The root's position channels.
    rotations : ndarray, shape (n_frames, n_joints, 3, 3)
        Each joint's rotation relative to its parent (the root's: global).
    fps : float
    end_sites : dict, optional, keyword-only
        Joint index → the OFFSET of its End Site.
    rotation_order, rest_frame, precision : keyword-only
        As :func:`write_bvh`.

    Returns
    -------
    Path

    Raises
    ------
    ParameterError
        A bad rotation order.
    """
    path = Path(path)
    end_sites = end_sites or {}

    def order_of(joint):
        o = rotation_order.get(joint, "ZYX") if isinstance(rotation_order, dict) else rotation_order
        if sorted(o.lower()) != ["x", "y", "z"]:
            raise ParameterError(f"rotation_order={o!r} (joint {joint!r}): expected a "
                                 "permutation of 'XYZ'")
        return o.upper()

    children = {k: [c for c in range(len(names)) if parents[c] == k] for k in range(len(names))}
    fmt = lambda x: _fmt(x, precision)  # noqa: E731
    lines = ["HIERARCHY"]
    columns = []  # per joint: (n, k) arrays in channel order

    def emit(k, depth):
        ind = "\t" * depth
        name = names[k]
        order = order_of(name)
        rot_names = [f"{a}rotation" for a in order]
        lines.append(f"{ind}{'ROOT' if k == 0 else 'JOINT'} {name}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}\tOFFSET {' '.join(fmt(v) for v in offsets[k])}")
        if k == 0:
            lines.append(f"{ind}\tCHANNELS 6 Xposition Yposition Zposition {' '.join(rot_names)}")
            columns.append(root_positions)
        else:
            lines.append(f"{ind}\tCHANNELS 3 {' '.join(rot_names)}")
        deg = np.degrees(euler_angles(rotations[:, k], order))
        # angles below 1e-10° are rounding noise of the Euler decomposition (a
        # position error of ~1e-12 bone lengths); write them as 0 rather than
        # as 1e-15-style tokens that every reader must parse the slow way
        deg[np.abs(deg) < 1e-10] = 0.0
        columns.append(deg)
        for c in children[k]:
            emit(c, depth + 1)
        if k in end_sites:
            lines.append(f"{ind}\tEnd Site")
            lines.append(f"{ind}\t{{")
            lines.append(f"{ind}\t\tOFFSET {' '.join(fmt(v) for v in end_sites[k])}")
            lines.append(f"{ind}\t}}")
        lines.append(f"{ind}}}")

    emit(0, 0)
    table = np.concatenate(columns, axis=1)
    if rest_frame:
        table = np.concatenate([np.zeros((1, table.shape[1])), table])
    lines.append("MOTION")
    lines.append(f"Frames: {table.shape[0]}")
    lines.append(f"Frame Time: {fmt(1.0 / fps)}")
    body = "\n".join(" ".join(fmt(v) for v in row) for row in table)
    path.write_text("\n".join(lines) + "\n" + body + "\n", encoding="latin-1")
    return path
