"""Bodies (FEATURES.md §2, READERS.md §2, §9): skeletons and poses as plain arrays → the 24 canonical joints.

What every format shares once its file is read, below ``readers`` so that it imports no format: the
canonical joints (:mod:`~mocapdb.bodies.joints`), the :class:`Motion` they form
(:mod:`~mocapdb.bodies.motion`), the Acclaim skeleton and its DOF values (:mod:`~mocapdb.bodies.acclaim`)
and their forward kinematics (:mod:`~mocapdb.bodies.kinematics`), any humanoid skeleton mapped onto the
canonical joints (:mod:`~mocapdb.bodies.humanoid`, ASF skeletons in :mod:`~mocapdb.bodies.asf_humanoid`),
the SMPL tree and its forward kinematics (:mod:`~mocapdb.bodies.smpl`) and the length unit of a
motion's joints (:mod:`~mocapdb.bodies.units`).
"""
from mocapdb.bodies.joints import JOINT_INDEX, JOINT_NAMES, MIRROR_JOINTS
from mocapdb.bodies.motion import COMMON_RATES, MAX_RATE, Motion, check_finite_motion, check_rate, snap_rate
from mocapdb.bodies.acclaim import (BONE_DOFS, DEFAULT_FPS, INCH_TO_TOOLBOX, ROOT_DOFS, AmcMotion, Bone, Skeleton,
                                    column_layout)
from mocapdb.bodies.kinematics import (ASF_JOINT_BONES, asf_forward_kinematics, asf_joints, euler_matrix,
                                       joint_node_indices, local_rotations, node_positions, orientation_matrix,
                                       root_rotation, sincos)
from mocapdb.bodies.humanoid import JointMap, SkeletonTree, map_humanoid
from mocapdb.bodies.smpl import RestSkeleton, smpl_forward_kinematics
from mocapdb.bodies.units import metres_per_unit

__all__ = [
    "JOINT_NAMES", "JOINT_INDEX", "MIRROR_JOINTS", "Motion", "snap_rate", "check_rate", "check_finite_motion",
    "COMMON_RATES", "MAX_RATE", "Bone", "Skeleton", "AmcMotion", "column_layout", "INCH_TO_TOOLBOX", "ROOT_DOFS",
    "BONE_DOFS", "DEFAULT_FPS", "ASF_JOINT_BONES", "node_positions", "asf_joints", "asf_forward_kinematics",
    "root_rotation", "euler_matrix", "orientation_matrix", "local_rotations", "joint_node_indices", "sincos",
    "JointMap", "SkeletonTree", "map_humanoid", "RestSkeleton", "smpl_forward_kinematics", "metres_per_unit",
]
