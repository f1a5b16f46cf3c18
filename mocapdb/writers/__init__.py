"""Writers: the canonical joints and ASF/AMC takes out as files (``export-joints``, BVH).

:mod:`~mocapdb.writers.bvh_write` writes a BVH of an ASF/AMC take or of any joint tree;
:mod:`~mocapdb.writers.joints_write` writes a motion's canonical joints as npz, CSV or BVH, in metres.
They take the plain data of :mod:`mocapdb.bodies` and import no reader.
"""
from mocapdb.writers.bvh_write import CMU_BONE_NAMES, euler_angles, write_bvh, write_bvh_tree
from mocapdb.writers.joints_write import JOINTS_FORMATS, write_joints

__all__ = ["write_bvh", "write_bvh_tree", "euler_angles", "CMU_BONE_NAMES", "write_joints", "JOINTS_FORMATS"]
