"""Slow, obviously-correct references for mocapdb.features (FEATURES.md §3–§6).

Written from the spec text, frame by frame, with plain NumPy/Python and
none of the library's code: ``np.pad(mode="symmetric")`` for P3, one small
function per primitive, one function per feature returning its lenient and
strict test, and the toolbox's edge rule (§5) for the hysteresis.
"""
import math

import numpy as np

from mocapdb.bodies.joints import JOINT_INDEX

J = JOINT_INDEX


# --------------------------------------------------------------------------
# §3 body-scale units (frame 0)

def body_units(joints):
    p = joints[0]

    def dist(a, b):
        return float(np.linalg.norm(p[J[a]] - p[J[b]]))

    return {
        "hum_R": dist("relbow", "rshoulder"),
        "hum_L": dist("lshoulder", "lelbow"),
        "chest_len": dist("chest", "neck"),
        "shoulder_w": dist("rshoulder", "lshoulder"),
        "hip_w": dist("rhip", "lhip"),
        "body_len": sum(dist(a, b) for a, b in (
            ("rankle", "rknee"), ("rknee", "rhip"), ("root", "belly"),
            ("belly", "chest"), ("chest", "neck"), ("neck", "head"),
            ("head", "headtop"))),
    }


# --------------------------------------------------------------------------
# §4 primitives (one frame unless stated)

def unit(x):
    return x / np.linalg.norm(x)


def angle_deg(u, v):
    c = float(np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v)))
    return math.degrees(math.acos(min(1.0, max(-1.0, c)))) if c == c else math.nan


def p1_plane_distance(p, p1, p2, p3, q):
    nrm = unit(np.cross(p[J[p1]] - p[J[p3]], p[J[p2]] - p[J[p3]]))
    return float(nrm @ (p[J[q]] - p[J[p3]]))


def p1_plane_normal(p, p1, p2, p3):
    return unit(np.cross(p[J[p1]] - p[J[p3]], p[J[p2]] - p[J[p3]]))


def p2_normal_distance(p, p1, p2, p3, q):
    return float(unit(p[J[p2]] - p[J[p1]]) @ (p[J[q]] - p[J[p3]]))


def window_frames(win_ms, fps):
    return max(1, math.ceil(win_ms / 1000 * fps))


def p3_smoothed_velocity(x, win_ms, fps):
    """P3 on a whole (n, 3) trajectory: (n, 3) smoothed velocity per second."""
    n = len(x)
    w = window_frames(win_ms, fps)
    v = np.diff(x, axis=0)
    v = np.vstack([v, v[-1:]])                                  # step 1
    if n < w:
        v = np.pad(v, ((0, w - n), (0, 0)), mode="symmetric")   # step 2
    pw = math.ceil(w / 2)
    u = np.pad(v, ((pw, pw), (0, 0)), mode="symmetric")         # step 3
    # vs[t] = mean of v[t+1-pw .. t+w-pw]  =  u[t+1 .. t+w]
    vs = np.array([u[t + 1:t + 1 + w].mean(axis=0) for t in range(n)])
    return vs * fps                                             # step 4


def p6_joint_angle(p, a, b, c):
    return angle_deg(p[J[a]] - p[J[c]], p[J[b]] - p[J[c]])


def p7_segment_angle(p, p1, p2, p3, p4):
    return angle_deg(p[J[p1]] - p[J[p2]], p[J[p3]] - p[J[p4]])


def p8_angle_to_vector(p, p1, p2, v):
    return angle_deg(unit(p[J[p2]] - p[J[p1]]), np.asarray(v, float))


def p9_y_min(p, exclude=()):
    return min(p[J[j], 1] for j in J if j not in exclude)


def p9_y_max(p):
    return max(p[J[j], 1] for j in J)


# --------------------------------------------------------------------------
# §5 hysteresis, the toolbox's edge rule

def edge_rule(f1, f2):
    """features_combine_robust as described in FEATURES.md §5 (0-based frames)."""
    f1 = [bool(x) for x in f1]
    f2 = [bool(x) for x in f2]
    n = len(f1)
    rises = [t for t in range(n) if f2[t] and (t == 0 or not f2[t - 1])]
    descents = [t for t in range(1, n) if f1[t - 1] and not f1[t]] + [n]
    out = np.zeros(n, dtype=bool)
    last_descent = -1
    for r in rises:
        if r <= last_descent:
            continue
        d = min(x for x in descents if x >= r)
        if d == r:
            continue
        out[r:d] = True
        last_descent = d
    return out


def state_machine(f1, f2):
    """The §5 state machine, literally."""
    state, out = 0, []
    for a, b in zip(f1, f2):
        if state == 0 and b:
            state = 1
        elif state == 1 and not a:
            state = 0
        out.append(bool(state))
    return np.array(out, dtype=bool)


# --------------------------------------------------------------------------
# §6 the 40 features: lenient and strict test per frame

def feature_tests(joints, root_rotation, fps, *, root_ang_vel_thresholds=(50.0, 100.0),
                  to_front_anchor="lhip"):
    """(f1, f2), each (n, 40) bool, straight from the §6 text.

    ``to_front_anchor`` replaces the anchor of the hand velocities of #1/#2
    (d/dt(wrist − lhip); the plane normal stays neck/rhip/lhip): the mirror
    image of #1 is #2 measured relative to rhip (the mirror test uses it).
    """
    n = len(joints)
    u = body_units(joints)
    hum_r, hum_l = u["hum_R"], u["hum_L"]
    f1 = np.zeros((n, 40), dtype=bool)
    f2 = np.zeros((n, 40), dtype=bool)

    def traj(q, p3=None):
        x = joints[:, J[q]]
        return x if p3 is None else x - joints[:, J[p3]]

    vel = {
        "rfront": p3_smoothed_velocity(traj("rwrist", to_front_anchor), 250, fps),
        "lfront": p3_smoothed_velocity(traj("lwrist", to_front_anchor), 250, fps),
        "rtop": p3_smoothed_velocity(traj("rwrist", "neck"), 250, fps),
        "ltop": p3_smoothed_velocity(traj("lwrist", "neck"), 250, fps),
        "hands": p3_smoothed_velocity(traj("lwrist", "rwrist"), 100, fps),
        "rroot": p3_smoothed_velocity(traj("root", "rwrist"), 0, fps),
        "lroot": p3_smoothed_velocity(traj("root", "lwrist"), 0, fps),
        "rfingers": p3_smoothed_velocity(traj("rfingers"), 100, fps),
        "lfingers": p3_smoothed_velocity(traj("lfingers"), 100, fps),
        "lankle_rhip": p3_smoothed_velocity(traj("lankle", "rhip"), 100, fps),
        "rankle_rhip": p3_smoothed_velocity(traj("rankle", "rhip"), 100, fps),
        "rtoes": p3_smoothed_velocity(traj("rtoes"), 100, fps),
        "rankle": p3_smoothed_velocity(traj("rankle"), 100, fps),
        "ltoes": p3_smoothed_velocity(traj("ltoes"), 100, fps),
        "lankle": p3_smoothed_velocity(traj("lankle"), 100, fps),
        "root": p3_smoothed_velocity(traj("root"), 0, fps),
    }

    def speed(key, t):
        return float(np.linalg.norm(vel[key][t]))

    # #40 quantity over the whole motion
    if root_rotation is not None:
        axis = np.asarray(root_rotation)[:, :, 0]
    else:
        axis = joints[:, J["lhip"]] - joints[:, J["rhip"]]
    yaw = np.zeros(n)
    for t in range(n - 1):
        yaw[t] = angle_deg(axis[t + 1, [0, 2]], axis[t, [0, 2]]) * fps

    def both(k, lenient, strict):
        f1[t, k - 1] = lenient
        f2[t, k - 1] = strict

    for t in range(n):
        p = joints[t]
        # 1, 2
        nrm = p1_plane_normal(p, "neck", "rhip", "lhip")
        for k, key in ((1, "rfront"), (2, "lfront")):
            x = float(nrm @ vel[key][t])
            both(k, 1.3 * hum_l < x, 1.8 * hum_l < x)
        # 3, 4
        for k, w in ((3, "rwrist"), (4, "lwrist")):
            d = p2_normal_distance(p, "chest", "neck", "neck", w)
            both(k, d + 0 * u["chest_len"] >= 0, d - 0.2 * u["chest_len"] >= 0)
        # 5, 6
        for k, key in ((5, "rtop"), (6, "ltop")):
            x = float(unit(p[J["neck"]] - p[J["chest"]]) @ vel[key][t])
            both(k, 1.3 * hum_l < x, 1.8 * hum_l < x)
        # 7, 8
        for k, side in ((7, "r"), (8, "l")):
            a = p6_joint_angle(p, side + "shoulder", side + "wrist", side + "elbow")
            both(k, 0 <= a <= 120, 0 <= a <= 110)
        # 9
        d = abs(p2_normal_distance(p, "lshoulder", "rshoulder", "lwrist", "rwrist"))
        both(9, d >= 2.0 * u["shoulder_w"], d >= 2.5 * u["shoulder_w"])
        # 10
        x = float(unit(p[J["rwrist"]] - p[J["lwrist"]]) @ vel["hands"][t])
        both(10, x >= 1.2 * hum_r, x >= 1.4 * hum_r)
        # 11, 12
        for k, w, key in ((11, "rwrist", "rroot"), (12, "lwrist", "lroot")):
            x = float(unit(p[J["root"]] - p[J[w]]) @ vel[key][t])
            both(k, x >= 1.2 * hum_r, x >= 1.4 * hum_r)
        # 13, 14
        for k, key in ((13, "rfingers"), (14, "lfingers")):
            s = speed(key, t)
            both(k, s >= 2.0 * hum_r, s >= 2.5 * hum_r)
        # 15, 16
        d = p1_plane_distance(p, "root", "lhip", "lankle", "rankle")
        both(15, d >= 0, d >= 0.375 * hum_r)
        d = p1_plane_distance(p, "root", "rankle", "rhip", "lankle")
        both(16, d >= 0, d >= 0.375 * hum_r)
        # 17, 18
        for k, toe in ((17, "rtoes"), (18, "ltoes")):
            h = p[J[toe], 1] - p9_y_min(p)
            both(k, h - 1.0 * hum_r >= 0, h - 1.2 * hum_r >= 0)
        # 19
        d = abs(p2_normal_distance(p, "lhip", "rhip", "lankle", "rankle"))
        both(19, d >= 1.8 * hum_r, d >= 2.1 * hum_r)
        # 20, 21
        for k, side in ((20, "r"), (21, "l")):
            a = p6_joint_angle(p, side + "hip", side + "ankle", side + "knee")
            both(k, 0 <= a <= 120, 0 <= a <= 110)
        # 22
        dl = p2_normal_distance(p, "lhip", "rhip", "lhip", "lankle")
        dr = p2_normal_distance(p, "lhip", "rhip", "lhip", "rankle")
        both(22, dr - dl <= 0, dr - dl <= -0.125 * u["hip_w"])
        # 23, 24
        hip = unit(p[J["rhip"]] - p[J["lhip"]])
        vl = float(hip @ vel["lankle_rhip"][t])
        vr = float(hip @ vel["rankle_rhip"][t])
        both(23, vl - vr >= 1.3 * hum_r, vl - vr >= 1.5 * hum_r)
        both(24, vr - vl >= 1.3 * hum_r, vr - vl >= 1.5 * hum_r)
        # 25, 26
        for k, toe, ank in ((25, "rtoes", "rankle"), (26, "ltoes", "lankle")):
            st, sa = speed(toe, t), speed(ank, t)
            both(k, st >= 2.0 * hum_r and sa >= 2.0 * hum_r,
                 st >= 2.5 * hum_r and sa >= 2.5 * hum_r)
        # 27, 28
        for k, side in ((27, "r"), (28, "l")):
            a = p7_segment_angle(p, "neck", "root", side + "elbow", side + "shoulder")
            both(k, a < 155, a < 150)
        # 29, 30
        for k, side in ((29, "r"), (30, "l")):
            a = p7_segment_angle(p, "neck", "root", side + "hip", side + "knee")
            both(k, a > 45, a > 50)
        # 31
        d = p1_plane_distance(p, "lankle", "neck", "rankle", "root")
        both(31, d < -0.35 * hum_r, d < -0.5 * hum_r)
        # 32
        a = p8_angle_to_vector(p, "root", "neck", (0, 1, 0))
        both(32, 60 <= a <= 120, 70 <= a <= 110)
        # 33, 34
        for k, side in ((33, "r"), (34, "l")):
            m = p9_y_min(p, exclude=(side + "fingers", side + "wrist"))
            y = p[J[side + "fingers"], 1]
            both(k, y < m + 1.4 * hum_r, y < m + 1.2 * hum_r)
        # 35, 36
        x = (p1_plane_distance(p, "rhip", "lhip", "neck", "lshoulder")
             - p1_plane_distance(p, "rhip", "lhip", "neck", "rshoulder"))
        both(35, x > 0.35 * hum_l, x > 0.40 * hum_l)
        both(36, x < -0.35 * hum_l, x < -0.40 * hum_l)
        # 37
        e = p9_y_max(p) - p9_y_min(p)
        both(37, e <= 0.9 * u["body_len"], e <= 0.8 * u["body_len"])
        # 38
        pts = [p[J[j]][[0, 2]] for j in ("lankle", "rankle", "lwrist", "rwrist",
                                         "headtop", "root")]
        diam = max(float(np.linalg.norm(a - b)) for i, a in enumerate(pts)
                   for b in pts[i + 1:])
        both(38, diam >= 3.0 * hum_r, diam >= 3.25 * hum_r)
        # 39
        s = speed("root", t)
        both(39, s >= 2.0 * hum_r, s >= 2.3 * hum_r)
        # 40
        th1, th2 = root_ang_vel_thresholds
        both(40, yaw[t] >= th1, yaw[t] >= th2)
    return f1, f2


def relational_features(joints, root_rotation, fps, **kwargs):
    """The 40 robust features, (n, 40) bool; all zero for fewer than 2 frames."""
    joints = np.asarray(joints, dtype=float)
    n = len(joints)
    if n < 2:
        return np.zeros((n, 40), dtype=bool)
    f1, f2 = feature_tests(joints, root_rotation, fps, **kwargs)
    return np.stack([edge_rule(f1[:, k], f2[:, k]) for k in range(40)], axis=1)


# --------------------------------------------------------------------------
# packing references

def pack_words(features):
    return np.array([sum(1 << k for k in range(row.size) if row[k]) for row in features],
                    dtype=np.uint64)


def feature_runs(words):
    starts, lengths, values = [], [], []
    for t, w in enumerate(words):
        if t == 0 or w != words[t - 1]:
            starts.append(t)
            lengths.append(0)
            values.append(w)
        lengths[-1] += 1
    return starts, lengths, values
