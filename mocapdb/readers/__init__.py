"""Readers (DESIGN.md §1, FEATURES.md §2, READERS.md): files → the 24 canonical joints.

ASF/AMC (:mod:`~mocapdb.readers.asf`, :mod:`~mocapdb.readers.amc`, forward
kinematics in :mod:`~mocapdb.readers.kinematics`), BVH
(:mod:`~mocapdb.readers.bvh`) and C3D marker files (:mod:`~mocapdb.readers.c3d`:
points through ezc3d in :mod:`~mocapdb.readers.c3dfile`, marker rules in
:mod:`~mocapdb.readers.c3d_rules`) become a :class:`Motion` (joint positions, root
rotation, rate); :func:`read_motion` dispatches on the file type
(:mod:`~mocapdb.readers.files`), with the options of one :class:`ReaderOptions`
value (:mod:`~mocapdb.readers.options`); :func:`motion_files` walks folders and
zip archives for the files to read (:mod:`~mocapdb.readers.walk`). AMASS
``.npz`` motions are read by :mod:`~mocapdb.readers.amass` over the SMPL tree
of :mod:`~mocapdb.readers.smpl`. Text is scanned by the numba kernels of
:mod:`~mocapdb.readers.textscan`.
"""
from mocapdb.readers.joints import (JOINT_INDEX, JOINT_NAMES, MIRROR_JOINTS)
from mocapdb.readers.motion import (COMMON_RATES, MAX_RATE, Motion, check_finite_motion, check_rate, snap_rate)
from mocapdb.readers.asf import (BONE_DOFS, INCH_TO_TOOLBOX, ROOT_DOFS, Bone, Skeleton, parse_asf, read_asf)
from mocapdb.readers.amc import (DEFAULT_FPS, AmcMotion, parse_amc, read_amc)
from mocapdb.readers.kinematics import (ASF_JOINT_BONES, asf_forward_kinematics, asf_joints, euler_matrix, joint_node_indices, local_rotations, node_positions, orientation_matrix, root_rotation, sincos)
from mocapdb.readers.humanoid import (JointMap, SkeletonTree, map_humanoid)
from mocapdb.readers.bvh import (BvhData, BvhHierarchy, BvhJoint, bvh_joint_map, bvh_node_positions, bvh_to_motion,
                                 joint_map_template, parse_bvh, read_bvh)
from mocapdb.readers.bvh_write import (CMU_BONE_NAMES, euler_angles, write_bvh, write_bvh_tree)
from mocapdb.readers.mapping import (load_mapping)
from mocapdb.readers.c3dfile import (C3dPoints, read_c3d_points)
from mocapdb.readers.c3d import (fit_bone_lengths, read_c3d)
from mocapdb.readers.smpl import (RestSkeleton, generic_rest, smpl_forward_kinematics)
from mocapdb.readers.body_model import (BodyModel, find_body_model, load_body_model)
from mocapdb.readers.amass import (read_amass)
from mocapdb.readers.joints_write import (JOINTS_FORMATS, metres_per_unit, write_joints)
from mocapdb.readers.options import READER_OPTIONS, ReaderOptions
from mocapdb.readers.files import (SUPPORTED_EXTENSIONS, find_skeleton, load_skeleton, read_asf_amc,
                                   read_motion, skeleton_candidates, skeleton_note)
from mocapdb.readers.walk import MOTION_SUFFIXES, companion_kind, motion_files

__all__ = [
    "JOINT_NAMES", "JOINT_INDEX", "MIRROR_JOINTS", "Motion", "Bone", "Skeleton", "read_asf", "parse_asf",
    "INCH_TO_TOOLBOX", "ROOT_DOFS", "BONE_DOFS", "AmcMotion", "read_amc", "parse_amc", "DEFAULT_FPS",
    "ASF_JOINT_BONES", "node_positions", "asf_joints", "asf_forward_kinematics", "root_rotation",
    "euler_matrix", "orientation_matrix", "local_rotations", "joint_node_indices", "sincos", "BvhJoint",
    "BvhHierarchy", "BvhData", "read_bvh", "bvh_joint_map", "joint_map_template", "JointMap", "SkeletonTree",
    "map_humanoid", "snap_rate", "check_rate", "check_finite_motion", "COMMON_RATES", "MAX_RATE", "parse_bvh", "bvh_node_positions", "bvh_to_motion",
    "write_bvh", "write_bvh_tree", "euler_angles", "CMU_BONE_NAMES", "read_motion", "read_asf_amc", "find_skeleton",
    "skeleton_candidates", "skeleton_note", "load_skeleton", "SUPPORTED_EXTENSIONS", "READER_OPTIONS", "load_mapping",
    "C3dPoints", "read_c3d_points", "read_c3d", "fit_bone_lengths", "ReaderOptions", "motion_files",
    "MOTION_SUFFIXES", "read_amass", "RestSkeleton", "generic_rest", "smpl_forward_kinematics", "BodyModel",
    "load_body_model", "find_body_model", "companion_kind", "write_joints", "metres_per_unit", "JOINTS_FORMATS",
]
