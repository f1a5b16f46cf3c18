"""Readers (DESIGN.md §1, FEATURES.md §2, READERS.md): files → the 24 canonical joints.

The formats and the walk over files. ASF/AMC (:mod:`~mocapdb.readers.asf`, :mod:`~mocapdb.readers.amc`),
BVH (:mod:`~mocapdb.readers.bvh`) and C3D marker files (:mod:`~mocapdb.readers.c3d`: points through ezc3d
in :mod:`~mocapdb.readers.c3dfile`, marker rules in :mod:`~mocapdb.readers.c3d_rules`) become a
:class:`~mocapdb.bodies.Motion` (joint positions, root rotation, rate) through the forward kinematics and
humanoid mapping of :mod:`mocapdb.bodies`; :func:`read_motion` dispatches on the file type
(:mod:`~mocapdb.readers.files`), with the options of one :class:`ReaderOptions` value
(:mod:`~mocapdb.readers.options`); :func:`motion_files` walks folders and zip archives for the files to
read (:mod:`~mocapdb.readers.walk`). AMASS ``.npz`` motions are read by :mod:`~mocapdb.readers.amass`
over the SMPL tree of :mod:`mocapdb.bodies.smpl`, with the user's body model
(:mod:`~mocapdb.readers.body_model`) or the generic one (:mod:`~mocapdb.readers.generic_body`). Text is
scanned by the numba kernels of :mod:`~mocapdb.readers.textscan`.
"""
from mocapdb.readers.asf import parse_asf, read_asf
from mocapdb.readers.amc import parse_amc, read_amc
from mocapdb.readers.bvh import (BvhData, BvhHierarchy, BvhJoint, bvh_joint_map, bvh_to_motion, joint_map_template,
                                 parse_bvh, read_bvh)
from mocapdb.readers.bvh_kinematics import bvh_node_positions
from mocapdb.readers.mapping import load_mapping
from mocapdb.readers.c3dfile import C3dPoints, read_c3d_points
from mocapdb.readers.c3d import fit_bone_lengths, read_c3d
from mocapdb.readers.generic_body import generic_rest
from mocapdb.readers.body_model import BodyModel, find_body_model, load_body_model
from mocapdb.readers.amass import read_amass
from mocapdb.readers.options import READER_OPTIONS, ReaderOptions
from mocapdb.readers.files import (SUPPORTED_EXTENSIONS, find_skeleton, load_skeleton, read_asf_amc,
                                   read_motion, skeleton_candidates, skeleton_note)
from mocapdb.readers.walk import MOTION_SUFFIXES, companion_kind, motion_files

__all__ = [
    "read_asf", "parse_asf", "read_amc", "parse_amc", "BvhJoint", "BvhHierarchy", "BvhData", "read_bvh",
    "bvh_joint_map", "joint_map_template", "parse_bvh", "bvh_node_positions", "bvh_to_motion", "read_motion",
    "read_asf_amc", "find_skeleton", "skeleton_candidates", "skeleton_note", "load_skeleton", "SUPPORTED_EXTENSIONS",
    "READER_OPTIONS", "load_mapping", "C3dPoints", "read_c3d_points", "read_c3d", "fit_bone_lengths",
    "ReaderOptions", "motion_files", "MOTION_SUFFIXES", "read_amass", "generic_rest", "BodyModel",
    "load_body_model", "find_body_model", "companion_kind",
]
