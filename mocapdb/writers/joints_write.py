"""The 24 canonical joints of a motion out to other tools: NumPy ``.npz``, CSV, BVH.

What every reader produces (FEATURES.md §2.1) is what fairmotion, Blender,
aitviewer or a notebook want of a take: the joints at the recording's own
rate, in metres, Y up, in :data:`~mocapdb.bodies.joints.JOINT_NAMES` order.

* **npz**: ``joints`` (frames × 24 × 3), ``fps``, ``joint_names``;
* **csv**: one row per frame: ``frame`` (1-based), ``time`` (s), then
  ``<joint>_x``, ``<joint>_y``, ``<joint>_z`` per joint;
* **bvh**: a skeleton of the canonical joints (:data:`BVH_JOINTS`), one BVH
  joint per segment between two of them, named after the CMU ASF bones the
  segment spans, so that mocapdb reads it back exactly by those names
  (READERS.md §2). Each segment has its median length over the take and
  turns, frame by frame, the least that takes it from its parent's frame onto
  the segment's direction; the root carries the root rotation (or, where the
  source has none, the frame of the hip axis and the spine), so feature #40
  reads back as it was.

Lengths come out in metres: ASF/AMC and C3D joints carry their unit
(centimetres, or the toolbox's ``mm × -POINT:SCALE``), AMASS joints are
metres; BVH files declare none, so the BVH reader decides it from the legs
and the bone names (:mod:`mocapdb.bodies.units`: metres, centimetres,
millimetres, inches or CMU's 1/0.45 inch), unless the user gives it. The npz
says which source unit was converted and why (``source_unit``,
``metres_per_source_unit``); a CSV or BVH has no place for a note that
every reader skips (Blender's wants ``HIERARCHY`` first, a ``#`` line is a
row to ``csv.DictReader``), so ``export-joints`` says it per file and in the
``units.json`` of a folder it writes.

References
----------
docs/USER_GUIDE.md "Joints out"; READERS.md §2, §9; FEATURES.md §2.1.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.writers.bvh_write import write_bvh_tree
from mocapdb.bodies.joints import JOINT_INDEX, JOINT_NAMES
from mocapdb.bodies.motion import Motion
from mocapdb.bodies.smpl import align_rotations
from mocapdb.bodies.units import metres_per_unit

__all__ = ["JOINTS_FORMATS", "BVH_JOINTS", "metres_per_unit", "write_joints", "canonical_bvh_rotations"]

#: file formats of :func:`write_joints`
JOINTS_FORMATS = ("npz", "csv", "bvh")

#: the exported BVH skeleton: (joint name, parent index, the canonical joint it sits at, the canonical
#: joint its segment ends at). Named after the CMU ASF bones the segments span (``lwrist``: the forearm,
#: radius and wrist bones; ``lfingers``: the hand), so a BVH reader finds the ASF points by name.
BVH_JOINTS = (
    ("root", -1, "root", None),
    ("lhipjoint", 0, "root", "lhip"), ("lfemur", 1, "lhip", "lknee"), ("ltibia", 2, "lknee", "lankle"),
    ("ltoes", 3, "lankle", "ltoes"),
    ("rhipjoint", 0, "root", "rhip"), ("rfemur", 5, "rhip", "rknee"), ("rtibia", 6, "rknee", "rankle"),
    ("rtoes", 7, "rankle", "rtoes"),
    ("lowerback", 0, "root", "belly"), ("upperback", 9, "belly", "chest"), ("thorax", 10, "chest", "neck"),
    ("upperneck", 11, "neck", "head"), ("head", 12, "head", "headtop"),
    ("lclavicle", 11, "neck", "lshoulder"), ("lhumerus", 14, "lshoulder", "lelbow"),
    ("lwrist", 15, "lelbow", "lwrist"), ("lfingers", 16, "lwrist", "lfingers"),
    ("rclavicle", 11, "neck", "rshoulder"), ("rhumerus", 18, "rshoulder", "relbow"),
    ("rwrist", 19, "relbow", "rwrist"), ("rfingers", 20, "rwrist", "rfingers"),
)

def _hip_frame(joints):
    """Per frame a rotation whose x axis is the hip axis (lhip − rhip) and y the spine orthogonal to it:
    the ASF root convention, for sources without a root rotation."""
    x = joints[:, JOINT_INDEX["lhip"]] - joints[:, JOINT_INDEX["rhip"]]
    up = joints[:, JOINT_INDEX["neck"]] - joints[:, JOINT_INDEX["root"]]
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    y = up - np.einsum("ni,ni->n", up, x)[:, None] * x
    y = y / np.linalg.norm(y, axis=1, keepdims=True)
    return np.stack([x, y, np.cross(x, y)], axis=2)


def canonical_bvh_rotations(joints, root_rotation=None):
    """The exported BVH skeleton's rest offsets and each frame's rotations.

    Parameters
    ----------
    joints : ndarray, shape (n_frames, 24, 3)
    root_rotation : ndarray, shape (n_frames, 3, 3), optional
        The source's root rotation; default the hip-axis frame.

    Returns
    -------
    segments : ndarray, shape (22, 3)
        Each BVH joint's segment at rest (the root's is zero), in the root's
        frame: its median direction there, its median length.
    local : ndarray, shape (n_frames, 22, 3, 3)
        Each joint's rotation relative to its parent (the root's: global).
    """
    n = joints.shape[0]
    root = _hip_frame(joints) if root_rotation is None else np.asarray(root_rotation, dtype=np.float64)
    nj = len(BVH_JOINTS)
    segments = np.zeros((nj, 3))
    glob = np.empty((n, nj, 3, 3))
    local = np.empty((n, nj, 3, 3))
    glob[:, 0] = local[:, 0] = root
    for k, (_, parent, start, tip) in enumerate(BVH_JOINTS[1:], start=1):
        cur = joints[:, JOINT_INDEX[tip]] - joints[:, JOINT_INDEX[start]]
        in_root = np.einsum("nji,nj->ni", root, cur)   # Rᵀ · segment
        length = float(np.median(np.linalg.norm(cur, axis=1)))
        direction = np.median(in_root, axis=0)
        norm = float(np.linalg.norm(direction))
        segments[k] = direction / norm * length if norm > 0 else 0.0
        before = glob[:, parent] @ segments[k]
        glob[:, k] = align_rotations(before, cur) @ glob[:, parent]
        local[:, k] = np.swapaxes(glob[:, parent], 1, 2) @ glob[:, k]
    return segments, local


def _write_bvh(path, joints, fps, root_rotation):
    segments, local = canonical_bvh_rotations(joints, root_rotation)
    names = [name for name, *_ in BVH_JOINTS]
    parents = [parent for _, parent, *_ in BVH_JOINTS]
    # a joint sits at the end of its parent's segment; a joint no other joint continues ends in an End Site
    offsets = np.array([segments[p] if p > 0 else np.zeros(3) for p in parents])
    leaves = {k: segments[k] for k in range(1, len(names)) if k not in parents}
    return write_bvh_tree(path, names, parents, offsets, joints[:, JOINT_INDEX["root"]], local, fps,
                          end_sites=leaves)


def write_joints(path, motion: Motion, *, format: str, unit=None, scale=None) -> str:
    """Write a motion's canonical joints, in metres at its own rate, as ``npz``, ``csv`` or ``bvh``.

    Parameters
    ----------
    path : str or Path
    motion : Motion
    format : {"npz", "csv", "bvh"}, keyword-only
    unit, scale : optional, keyword-only
        A BVH source's unit or metres per unit, overriding the reader's
        decision (:func:`mocapdb.bodies.units.metres_per_unit`).

    Returns
    -------
    str
        The source unit converted from and how it was known.

    Raises
    ------
    ParameterError
        An unknown format, unit or a bad scale.
    """
    if format not in JOINTS_FORMATS:
        raise ParameterError(f"format must be one of {', '.join(JOINTS_FORMATS)}, got {format!r}")
    path = Path(path)
    factor, how = metres_per_unit(motion, unit=unit, scale=scale)
    joints = np.ascontiguousarray(motion.joints * factor)
    fps = float(motion.fps)
    if format == "npz":
        with path.open("wb") as fh:   # np.savez would add .npz to another suffix
            np.savez(fh, joints=joints, fps=np.float64(fps), joint_names=np.array(JOINT_NAMES),
                     source_unit=np.array(how), metres_per_source_unit=np.float64(factor))
    elif format == "csv":
        n = joints.shape[0]
        header = ["frame", "time"] + [f"{j}_{a}" for j in JOINT_NAMES for a in "xyz"]
        table = np.column_stack([np.arange(1, n + 1), np.arange(n) / fps, joints.reshape(n, -1)])
        fmt = ["%d", "%.9g"] + ["%.9g"] * (joints.shape[1] * 3)
        np.savetxt(path, table, fmt=fmt, delimiter=",", header=",".join(header), comments="")
    else:
        _write_bvh(path, joints, fps, motion.root_rotation)
    return how
