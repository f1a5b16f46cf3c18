"""Slow, obviously-correct references for the readers' kernels.

Each function follows the spec text literally, one frame at a time, with
Python floats and NumPy 3×3 matrices, and shares no code with the kernels it
checks (only the parsed Skeleton / hierarchy objects).
"""
import math

import numpy as np

from mocapdb.bodies.joints import JOINT_NAMES


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


def naive_axis_angle(v):
    """Rotation matrix of an axis-angle vector: a rotation by |v| about v/|v| as the product of
    elementary rotations (the axis turned onto z, rotated about z, turned back)."""
    theta = math.sqrt(sum(float(x) ** 2 for x in v))
    if theta == 0.0:
        return np.eye(3)
    k = np.asarray(v, dtype=float) / theta
    # turn k onto +z: about z by -atan2(ky, kx), then about y by -acos(kz)
    az, el = math.atan2(k[1], k[0]), math.acos(max(-1.0, min(1.0, k[2])))
    to_z = rot("y", -el) @ rot("z", -az)
    return to_z.T @ rot("z", theta) @ to_z


def naive_smpl_fk(rest_joints, rest_ends, pose, trans):
    """READERS.md §9 per frame: SMPL forward kinematics and the canonical joints written from the
    spec text (22 body joints, five end points on the feet, the head and the wrists).

    Returns (joints (n, 24, 3), pelvis rotation (n, 3, 3)).
    """
    parents = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19]
    ends_on = [10, 11, 15, 20, 21]
    body = {"root": 0, "lhip": 1, "lknee": 4, "lankle": 7, "rhip": 2, "rknee": 5, "rankle": 8, "neck": 12,
            "head": 15, "lclavicle": 12, "rclavicle": 12, "lshoulder": 16, "lelbow": 18, "lwrist": 20,
            "rshoulder": 17, "relbow": 19, "rwrist": 21}
    ends = {"ltoes": 0, "rtoes": 1, "headtop": 2, "lfingers": 3, "rfingers": 4}
    spine = [0, 3, 6, 9, 12]
    lengths = [float(np.linalg.norm(rest_joints[b] - rest_joints[a])) for a, b in zip(spine, spine[1:])]
    n = len(pose)
    out = np.zeros((n, 24, 3))
    pelvis = np.zeros((n, 3, 3))
    for f in range(n):
        G, P = [None] * 22, [None] * 22
        for j in range(22):
            R = naive_axis_angle(pose[f][j])
            if parents[j] < 0:
                G[j], P[j] = R, rest_joints[j] + trans[f]
            else:
                p = parents[j]
                G[j] = G[p] @ R
                P[j] = P[p] + G[p] @ (rest_joints[j] - rest_joints[p])
        E = [P[j] + G[j] @ (rest_ends[k] - rest_joints[j]) for k, j in enumerate(ends_on)]
        pelvis[f] = G[0]
        for i, name in enumerate(JOINT_NAMES):
            if name in body:
                out[f, i] = P[body[name]]
            elif name in ends:
                out[f, i] = E[ends[name]]
            else:   # belly, chest: 1/3 and 2/3 of the rest spine's length, between the joints around it
                at = (1.0 if name == "belly" else 2.0) / 3.0 * sum(lengths)
                walked = 0.0
                for s, length in enumerate(lengths):
                    if walked + length >= at or s == len(lengths) - 1:
                        u = (at - walked) / length if length else 0.0
                        out[f, i] = (1 - u) * P[spine[s]] + u * P[spine[s + 1]]
                        break
                    walked += length
    return out, pelvis
