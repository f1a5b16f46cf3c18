"""The 24 canonical joints every reader produces (FEATURES.md §2.1).

Order is the toolbox name-map order used by the oracle position files;
``lclavicle``/``rclavicle`` are the neck point for ASF/AMC skeletons.
"""

JOINT_NAMES = (
    "root", "lhip", "lknee", "lankle", "ltoes",
    "rhip", "rknee", "rankle", "rtoes",
    "belly", "chest", "neck", "head", "headtop",
    "lclavicle", "lshoulder", "lelbow", "lwrist", "lfingers",
    "rclavicle", "rshoulder", "relbow", "rwrist", "rfingers",
)

#: joint name -> column in a ``(n_frames, 24, 3)`` joint array
JOINT_INDEX = {name: i for i, name in enumerate(JOINT_NAMES)}

#: left/right swap of the canonical joints (used by mirror tests and flipped templates)
MIRROR_JOINTS = tuple(
    JOINT_INDEX[n[0].translate(str.maketrans("lr", "rl")) + n[1:]]
    if n[0] in "lr" and n != "root" else i
    for i, n in enumerate(JOINT_NAMES)
)

__all__ = ["JOINT_NAMES", "JOINT_INDEX", "MIRROR_JOINTS"]
