"""The generic rest skeleton: CMU subject 86's proportions on the SMPL tree, read from the shipped
``mocapdb/sample/86.asf``.

AMASS takes read without the user's body model are placed on it (READERS.md §9). It sits in
``readers``, not beside the SMPL tree in ``bodies.smpl``, because it reads a file (an ASF) and
bodies import no format.
"""
from __future__ import annotations

import threading
from importlib import resources

import numpy as np

from mocapdb.bodies.smpl import BODY_JOINTS, END_POINTS, RestSkeleton, asf_rest_tips
from mocapdb.readers.asf import read_asf

__all__ = ["generic_rest", "GENERIC_SOURCE"]

#: the skeleton whose proportions the generic rest skeleton takes (ships with mocapdb)
GENERIC_SOURCE = "86.asf"

#: SMPL body joint → the CMU ASF point it sits at in the generic rest skeleton: a bone's tip, or
#: ``root``. The SMPL joint is where the ASF bone whose rotation it takes starts (the pelvis's
#: child spine1 at the root, where ASF's lowerback starts; neck and collars at the thorax's tip).
_GENERIC_AT = {
    "pelvis": "root", "left_hip": "lhipjoint", "right_hip": "rhipjoint", "spine1": "root",
    "left_knee": "lfemur", "right_knee": "rfemur", "spine2": "lowerback", "left_ankle": "ltibia",
    "right_ankle": "rtibia", "spine3": "upperback", "left_foot": "lfoot", "right_foot": "rfoot",
    "neck": "thorax", "left_collar": "thorax", "right_collar": "thorax", "head": "upperneck",
    "left_shoulder": "lclavicle", "right_shoulder": "rclavicle", "left_elbow": "lhumerus",
    "right_elbow": "rhumerus", "left_wrist": "lwrist", "right_wrist": "rwrist",
}
_GENERIC_ENDS = {"ltoes": "ltoes", "rtoes": "rtoes", "headtop": "head", "lfingers": "lfingers",
                 "rfingers": "rfingers"}
#: the ASF bones whose rest direction is SMPL's straight down instead (thighs and shins: the CMU
#: rest pose spreads the legs by 20°, SMPL's rest pose stands on straight legs)
_VERTICAL = ("lfemur", "ltibia", "rfemur", "rtibia")

_GENERIC: list = []
_GENERIC_LOCK = threading.Lock()


def generic_rest() -> RestSkeleton:
    """The generic rest skeleton: CMU subject 86's proportions on the SMPL tree (cached).

    Each SMPL body joint sits where the ASF bone whose motion it carries
    starts (:data:`_GENERIC_AT`); the end points are the tips of the ASF toes,
    head and finger bones. The rest pose is SMPL's: the ASF rest pose is a
    T-pose too, but with the legs spread by 20°, so thighs and shins keep
    their lengths and point straight down. Computed from
    ``mocapdb/sample/86.asf`` (the skeleton that ships with the sample take).
    """
    with _GENERIC_LOCK:
        if not _GENERIC:
            path = resources.files("mocapdb") / "sample" / GENERIC_SOURCE
            with resources.as_file(path) as p:
                skel = read_asf(p)
            tips = asf_rest_tips(skel, vertical=_VERTICAL)
            joints = np.array([tips[_GENERIC_AT[name]] for name in BODY_JOINTS])
            ends = np.array([tips[_GENERIC_ENDS[name]] for name, _ in END_POINTS])
            _GENERIC.append(RestSkeleton(joints, ends, "the generic rest skeleton shipped with mocapdb "
                                                       "(CMU subject 86's proportions on the SMPL tree)"))
        return _GENERIC[0]
