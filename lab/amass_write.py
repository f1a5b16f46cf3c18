"""Write ASF/AMC takes as AMASS-format ``.npz`` files (the test and benchmark source of AMASS files).

AMASS's licence forbids redistributing its files, so mocapdb's tests and
benchmarks write their own: a real take's rotations re-expressed on the
SMPL tree. :func:`write_amass` takes the global rotation of each ASF bone
from the forward kinematics of the take and gives each SMPL joint the
rotation of the bone it carries (:data:`SMPL_BONES`), turned so that the
rest skeleton's bone direction goes where the ASF bone's rest direction
goes; a joint's local rotation is its parent's global rotation inverted
times its own, written as axis-angle in an ``.npz`` laid out as AMASS
publishes SMPL-H (``poses`` n × 156, ``mocap_framerate``), SMPL-X (n × 165,
``mocap_frame_rate``) or SMPL (n × 72). Read back with the same rest
skeleton, the file gives the take's joints again (READERS.md §9).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.bodies.acclaim import AmcMotion
from mocapdb.bodies.acclaim import Skeleton
from mocapdb.bodies.humanoid import Z_UP_TO_Y_UP
from mocapdb.bodies.kinematics import local_rotations, node_positions
from mocapdb.bodies.smpl import (BODY_JOINTS, BODY_PARENTS, FAMILIES, RestSkeleton, align_rotations, asf_rest_tips,
                                 rotation_vectors)
from mocapdb.readers.generic_body import generic_rest

__all__ = ["write_amass", "SMPL_BONES", "asf_globals"]

_CM = 0.01
#: SMPL body joint → (the ASF bone whose global rotation it takes, the ASF points its child segment
#: runs between at rest: from, to). The neck carries two ASF bones (lowerneck, upperneck): it takes
#: the rotation that turns their rest chord onto their chord in the frame.
SMPL_BONES = {
    "pelvis": ("root", None),
    "left_hip": ("lfemur", ("lhipjoint", "lfemur")), "right_hip": ("rfemur", ("rhipjoint", "rfemur")),
    "spine1": ("lowerback", ("root", "lowerback")),
    "left_knee": ("ltibia", ("lfemur", "ltibia")), "right_knee": ("rtibia", ("rfemur", "rtibia")),
    "spine2": ("upperback", ("lowerback", "upperback")),
    "left_ankle": ("lfoot", ("ltibia", "lfoot")), "right_ankle": ("rfoot", ("rtibia", "rfoot")),
    "spine3": ("thorax", ("upperback", "thorax")),
    "left_foot": ("ltoes", ("lfoot", "ltoes")), "right_foot": ("rtoes", ("rfoot", "rtoes")),
    "neck": ("lowerneck", ("thorax", "upperneck")),
    "left_collar": ("lclavicle", ("thorax", "lclavicle")), "right_collar": ("rclavicle", ("thorax", "rclavicle")),
    "head": ("head", ("upperneck", "head")),
    "left_shoulder": ("lhumerus", ("lclavicle", "lhumerus")),
    "right_shoulder": ("rhumerus", ("rclavicle", "rhumerus")),
    "left_elbow": ("lwrist", ("lhumerus", "lwrist")), "right_elbow": ("rwrist", ("rhumerus", "rwrist")),
    "left_wrist": ("lhand", ("lwrist", "lfingers")), "right_wrist": ("rhand", ("rwrist", "rfingers")),
}
#: the segment of the rest skeleton each SMPL joint's rotation is aligned by: its child (or end point)
_REST_SEGMENT = {"left_foot": ("end", 0), "right_foot": ("end", 1), "head": ("end", 2),
                 "left_wrist": ("end", 3), "right_wrist": ("end", 4)}
_FIRST_CHILD = {BODY_JOINTS[p]: BODY_JOINTS[j] for j, p in reversed(list(enumerate(BODY_PARENTS))) if p >= 0}
_RATE_KEY = {"smpl": "mocap_framerate", "smplh": "mocap_framerate", "smplx": "mocap_frame_rate"}


def asf_globals(skeleton: Skeleton, motion: AmcMotion) -> dict:
    """The global rotation of the root and of every ASF bone per frame: name → (n, 3, 3)."""
    root, local = local_rotations(skeleton, motion)
    glob = {"root": root}
    for k in skeleton.topological_order():
        b = skeleton.bones[k]
        glob[b.name] = glob[b.parent] @ local[:, k]
    return glob


def write_amass(path, skeleton: Skeleton, motion: AmcMotion, *, family: str = "smplh",
                rest: RestSkeleton | None = None, gender="female", betas=None, rate_key=None) -> Path:
    """Write an ASF/AMC take (CMU bone names) as an AMASS-format ``.npz``.

    Parameters
    ----------
    path : str or Path
    skeleton : Skeleton
        With the CMU/HDM05 bone names.
    motion : AmcMotion
    family : {"smplh", "smplx", "smpl"}, keyword-only
        The layout: ``poses`` n × 156, 165 or 72.
    rest : RestSkeleton, optional, keyword-only
        The rest skeleton the file is to be read with (default: the generic
        one); ``trans`` puts its pelvis on the ASF root.
    gender : str or bytes, keyword-only
        Written as given (AMASS writes bytes or text).
    betas : array_like, optional, keyword-only
        Default 16 zeros.
    rate_key : str, optional, keyword-only
        Default AMASS's: ``mocap_framerate`` (SMPL-H, SMPL), ``mocap_frame_rate`` (SMPL-X).

    Returns
    -------
    Path
    """
    if family not in FAMILIES:
        raise ParameterError(f"family={family!r}: expected one of {', '.join(FAMILIES)}")
    rest = generic_rest() if rest is None else rest
    names = {b.name.lower(): b.name for b in skeleton.bones}
    names["root"] = "root"
    tips = asf_rest_tips(skeleton)
    glob = asf_globals(skeleton, motion)
    positions, _ = node_positions(skeleton, motion)
    n = motion.n_frames
    # the world: ASF is Y up, AMASS Z up
    to_z = Z_UP_TO_Y_UP.T
    smpl_glob = np.empty((n, len(BODY_JOINTS), 3, 3))
    for j, joint in enumerate(BODY_JOINTS):
        bone, seg = SMPL_BONES[joint]
        g = glob[names[bone]]
        if seg is not None:
            kind = _REST_SEGMENT.get(joint)
            child = rest.ends[kind[1]] if kind else rest.joints[BODY_JOINTS.index(_FIRST_CHILD[joint])]
            asf_from, asf_to = (tips[names[s]] for s in seg)
            g = g @ align_rotations(child - rest.joints[j], asf_to - asf_from)[0]
        if joint == "neck":
            # two ASF bones: turn the rest chord onto the frame's chord after the lower bone's rotation
            idx = {b.name: k + 1 for k, b in enumerate(skeleton.bones)}
            chord = positions[:, idx[names["upperneck"]]] - positions[:, idx[names["thorax"]]]
            rest_chord = g @ (rest.joints[BODY_JOINTS.index("head")] - rest.joints[j])
            g = align_rotations(rest_chord, chord) @ g
        smpl_glob[:, j] = to_z @ g
    local = np.empty_like(smpl_glob)
    local[:, 0] = smpl_glob[:, 0]
    for j in range(1, len(BODY_JOINTS)):
        local[:, j] = np.swapaxes(smpl_glob[:, BODY_PARENTS[j]], 1, 2) @ smpl_glob[:, j]
    poses = np.zeros((n, FAMILIES[family][1]))
    poses[:, :66] = rotation_vectors(local).reshape(n, 66)
    trans = positions[:, 0] * _CM @ to_z.T - rest.joints[0]
    out = Path(path)
    np.savez(out, poses=poses, trans=trans, betas=np.zeros(16) if betas is None else np.asarray(betas, float),
             gender=np.array(gender), **{rate_key or _RATE_KEY[family]: np.array(float(motion.fps))})
    return out
