"""Slow, obviously-correct references for the readers' kernels.

Each function follows the spec text literally, one frame at a time, with
Python floats and NumPy 3×3 matrices, and shares no code with the kernels it
checks (only the parsed Skeleton / hierarchy objects).
"""
import math

import numpy as np

from mocapdb.readers.joints import JOINT_NAMES


def rot(axis, a):
    c, s = math.cos(a), math.sin(a)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]], dtype=float)
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], dtype=float)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], dtype=float)


def naive_amc_values(data: bytes, skeleton):
    """Parse AMC bytes line by line with ``float``: {bone: [[values per frame]]}.

    Bone names are matched case-insensitively; returns (frames list of dicts, fps, unit).
    """
    frames = []
    fps, unit = 120.0, None
    names = {b.name.lower(): b.name for b in skeleton.bones}
    names["root"] = "root"
    for raw in data.decode("latin-1").split("\n"):
        tok = raw.split()
        if not tok or tok[0].startswith("#"):
            continue
        if tok[0].startswith(":"):
            key = tok[0][1:].upper()
            if key == "DEGREES":
                unit = "deg"
            elif key == "RADIANS":
                unit = "rad"
            elif key == "SAMPLES-PER-SECOND":
                fps = float(tok[1])
            continue
        if tok[0].isdigit():
            frames.append({})
            continue
        frames[-1][names[tok[0].lower()]] = [float(t) for t in tok[1:]]
    return frames, fps, unit


def naive_asf_fk(skeleton, frames, *, angle_unit=None):
    """FEATURES.md §2.2, per frame: returns (joints (n,24,3), nodes (n,nb+1,3), root_rot (n,3,3)).

    ``frames``: list of {bone: values} as from :func:`naive_amc_values`.
    """
    deg = (angle_unit or skeleton.angle_unit) == "deg"
    k = math.pi / 180.0 if deg else 1.0
    ka = math.pi / 180.0 if skeleton.angle_unit == "deg" else 1.0
    L = skeleton.length_unit
    o = skeleton.root_orientation * ka
    O = rot("z", o[0]) @ rot("x", o[1]) @ rot("y", o[2])
    bones = skeleton.bones
    node_of = {"root": 0}
    for i, b in enumerate(bones):
        node_of[b.name] = i + 1
    jn = []
    for j in JOINT_NAMES:
        bone = {"lhip": "lhipjoint", "rhip": "rhipjoint", "lknee": "lfemur", "rknee": "rfemur",
                "lankle": "ltibia", "rankle": "rtibia", "belly": "lowerback",
                "chest": "upperback", "neck": "thorax", "lclavicle": "thorax",
                "rclavicle": "thorax", "head": "upperneck", "headtop": "head",
                "lshoulder": "lclavicle", "rshoulder": "rclavicle", "lelbow": "lhumerus",
                "relbow": "rhumerus"}.get(j, j)
        jn.append(node_of[bone])
    n = len(frames)
    nodes = np.zeros((n, len(bones) + 1, 3))
    rr = np.zeros((n, 3, 3))
    for f, fr in enumerate(frames):
        vals = dict(zip(skeleton.root_order, fr.get("root", [0.0] * len(skeleton.root_order))))
        t = np.array([vals.get(d, 0.0) for d in ("tx", "ty", "tz")])
        R = (rot("z", vals.get("rz", 0.0) * k) @ rot("y", vals.get("ry", 0.0) * k)
             @ rot("x", vals.get("rx", 0.0) * k))
        rr[f] = R
        G = {"root": O @ R}
        P = {"root": t / L * 2.54 + skeleton.root_position}

        def place(name):
            if name in G:
                return
            b = skeleton.bone(name)
            place(b.parent)
            v = dict(zip(b.dof, fr.get(b.name, [0.0] * len(b.dof))))
            ax = b.axis * ka
            C = rot("z", ax[2]) @ rot("y", ax[1]) @ rot("x", ax[0])
            M = (rot("z", v.get("rz", 0.0) * k) @ rot("y", v.get("ry", 0.0) * k)
                 @ rot("x", v.get("rx", 0.0) * k))
            G[name] = G[b.parent] @ (C @ M @ np.linalg.inv(C))
            d = b.direction
            nd = np.linalg.norm(d)
            offset = d / nd * b.length if nd > 0 else np.zeros(3)
            P[name] = P[b.parent] + G[name] @ offset

        for b in bones:
            place(b.name)
        nodes[f, 0] = P["root"]
        for i, b in enumerate(bones):
            nodes[f, i + 1] = P[b.name]
    return nodes[:, jn], nodes, rr


def naive_bvh_fk(hierarchy, values):
    """BVH forward kinematics per frame: (origins (n,nj,3), end sites (n,nj,3) NaN if none,
    global rotations (n,nj,3,3))."""
    joints = hierarchy.joints
    n = values.shape[0]
    nj = len(joints)
    origins = np.zeros((n, nj, 3))
    ends = np.full((n, nj, 3), np.nan)
    glob = np.zeros((n, nj, 3, 3))
    for f in range(n):
        for j, jt in enumerate(joints):
            local = np.eye(3)
            t = np.array(jt.offset, dtype=float)
            for c, name in enumerate(jt.channels):
                v = values[f, jt.channel_start + c]
                axis = name[0].lower()
                if name.endswith("position"):
                    # the root's position channels add to its OFFSET, a non-root
                    # joint's replace it (READERS.md §2)
                    if jt.parent >= 0:
                        t["xyz".index(axis)] = v
                    else:
                        t["xyz".index(axis)] += v
                else:
                    local = local @ rot(axis, math.radians(v))
            pg = glob[f, jt.parent] if jt.parent >= 0 else np.eye(3)
            po = origins[f, jt.parent] if jt.parent >= 0 else np.zeros(3)
            origins[f, j] = po + pg @ t
            glob[f, j] = pg @ local
            if jt.end_site is not None:
                ends[f, j] = origins[f, j] + glob[f, j] @ jt.end_site
    return origins, ends, glob
