"""Acclaim skeletons whose bones are not CMU-named, read through the humanoid mapper.

An ASF bone carries its rotation at its start and ends at its tip, where
its children start — as a BVH joint and the offset to its child. The
skeleton becomes a tree of points (the root and every bone's tip, rest
positions from the bones' directions and lengths) that
:func:`mocapdb.bodies.humanoid.map_humanoid` reads like a BVH skeleton.

A tip is named after its bone, translated where the bone's name says the
segment rather than the joint at its end: the tip of a thigh (``LeftUpLeg``,
``lfemur``) is the knee, of a shin the ankle, of an upper arm the elbow, of
a forearm the wrist, of a foot the toes, of a hand the fingers, of the head
the head top. Bones named after the joint at their tip (``LeftKnee``,
``LeftWrist``, as PyAsfAmc writes them) keep their names.
"""
from __future__ import annotations

import numpy as np

from mocapdb.bodies.humanoid import (LIMB_WORDS, JointMap, SkeletonTree, hip_axis_is_x, humanoid_problem,
                                     map_humanoid, name_side, normalized_name)
from mocapdb.bodies.joints import JOINT_INDEX

__all__ = ["asf_tree", "asf_joint_map", "asf_humanoid_joints"]

#: a segment's name → the joint at its tip
_TIP_OF = {**{w: "knee" for w in LIMB_WORDS["thigh"] - {"hip"}},
           **{w: "ankle" for w in LIMB_WORDS["knee"] - {"knee"}},
           **{w: "elbow" for w in LIMB_WORDS["upper arm"] - {"shoulder"}},
           **{w: "wrist" for w in LIMB_WORDS["elbow"] - {"elbow"}},
           "foot": "toe", "hand": "fingers", "head": "headtop", "clavicle": "shoulder"}
_SIDE_WORD = {"l": "Left", "r": "Right"}


def _tip_name(bone: str) -> str:
    word = _TIP_OF.get(normalized_name(bone))
    if word is None:
        return bone
    side = name_side(bone)
    return f"{_SIDE_WORD[side]} {word}" if side else word


def asf_tree(skeleton) -> SkeletonTree:
    """The skeleton as points: the root (0), then each bone's tip (k + 1), in the rest pose."""
    bones = skeleton.bones
    index = {b.name.lower(): k + 1 for k, b in enumerate(bones)}
    parent = np.array([-1] + [0 if b.parent.lower() == "root" else index[b.parent.lower()] for b in bones],
                      dtype=np.int64)
    rest = np.zeros((len(bones) + 1, 3))
    rest[0] = skeleton.root_position
    for k in skeleton.topological_order():
        rest[k + 1] = rest[parent[k + 1]] + bones[k].offset
    names = ("root",) + tuple(_tip_name(b.name) for b in bones)
    return SkeletonTree(names, parent, rest, np.ones(len(bones) + 1, dtype=bool))


def asf_joint_map(skeleton) -> JointMap:
    """The 24 canonical joints as weighted sums of the skeleton's nodes (root, bone tips).

    Raises
    ------
    MappingError
        Not a humanoid the mapper can read.
    """
    return map_humanoid(asf_tree(skeleton))


def asf_humanoid_joints(skeleton, nodes: np.ndarray, root_rotation: np.ndarray):
    """The canonical joints of a take from its node positions, and whether it is a human.

    Parameters
    ----------
    skeleton : Skeleton
    nodes : ndarray, shape (n_frames, n_bones + 1, 3)
        :func:`mocapdb.bodies.kinematics.node_positions`.
    root_rotation : ndarray, shape (n_frames, 3, 3)

    Returns
    -------
    joints : ndarray, shape (n_frames, 24, 3)
    root_rotation : ndarray or None
        The AMC root rotation when its x axis is the hip axis (the CMU
        convention feature #40 relies on), else None (#40 then uses the hip axis).
    jm : JointMap
    problem : tuple or None
        ``(what, why)``: why the body is not a human (:func:`~mocapdb.bodies.humanoid.humanoid_problem`).
    """
    jm = asf_joint_map(skeleton)
    joints = np.einsum("jp,fpc->fjc", jm.weights, nodes)
    hips = joints[:, JOINT_INDEX["lhip"]] - joints[:, JOINT_INDEX["rhip"]]
    asf_axes = hip_axis_is_x(np.einsum("fji,fj->i", root_rotation, hips) / max(len(hips), 1))
    problem = humanoid_problem(joints, jm.weights @ asf_tree(skeleton).rest)
    return joints, root_rotation if asf_axes else None, jm, problem
