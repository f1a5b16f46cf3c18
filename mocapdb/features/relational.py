"""The 40 boolean relational features of Müller & Röder (2006) + root angular velocity.

Everything in this module follows FEATURES.md (matrix order §0, body units
§3, primitives §4, hysteresis §5, per-feature definitions §6) and reproduces
the toolbox's ``*_robust`` feature functions bit for bit.

Pipeline of one motion (:func:`~mocapdb.features.pipeline.motion_features`):

1. :func:`relational_features` — (n, 40) bool at the native rate: body units
   from frame 0, smoothed velocities (one kernel), the lenient and strict
   test of every feature (one kernel per feature set: upper, lower, mix; the
   kernels are split to keep a cold numba compile short), the root yaw rate
   (#40), then :func:`hysteresis`;
2. :func:`downsample` — native frames 0, 4, 8, … (120 Hz → 30 Hz);
3. :func:`pack_words` — one uint64 per frame, bit k−1 = feature k.

:func:`~mocapdb.features.pipeline.motion_features` runs steps 1–3 and
feature 41's hysteresis as one kernel call per take, calling the kernels
here (issue 35).

Steps 2 and 3 and everything else on words live in :mod:`mocapdb.features.words`.
"""
import functools
import math

import numpy as np

from mocapdb._numba import jit
from mocapdb.errors import ParameterError
from mocapdb.features.rates import check_fps
from mocapdb.features.heading import HEADING_THRESHOLDS, HEADING_WINDOW_S, heading_change
from mocapdb.features.words import N_FEATURES, _as_bool_matrix
from mocapdb.bodies import JOINT_INDEX


#: the lenient/strict thresholds (θ1, θ2) of FEATURES.md §6, matrix order; the
#: test each pair enters is written next to the feature in the kernels below.
#: Units: hum_L/hum_R per second for velocities, body-scale units for
#: distances, degrees for angles (#32: the range [θ, 180 − θ]), deg/s for #40.
FEATURE_THRESHOLDS = (
    (1.3, 1.8), (1.3, 1.8),        # 1, 2   hum_L/s < vel (250 ms)
    (0.0, 0.2), (0.0, 0.2),        # 3, 4   d - θ·chest_len >= 0
    (1.3, 1.8), (1.3, 1.8),        # 5, 6   hum_L/s < vel (250 ms)
    (120.0, 110.0), (120.0, 110.0),  # 7, 8  0 <= angle <= θ
    (2.0, 2.5),                    # 9      |d| >= θ·shoulder_w
    (1.2, 1.4),                    # 10     vel >= θ·hum_R (100 ms)
    (1.2, 1.4), (1.2, 1.4),        # 11, 12 vel >= θ·hum_R (no smoothing)
    (2.0, 2.5), (2.0, 2.5),        # 13, 14 speed >= θ·hum_R (100 ms)
    (0.0, 0.375), (0.0, 0.375),    # 15, 16 d >= θ·hum_R
    (1.0, 1.2), (1.0, 1.2),        # 17, 18 y - ymin - θ·hum_R >= 0
    (1.8, 2.1),                    # 19     |d| >= θ·hum_R
    (120.0, 110.0), (120.0, 110.0),  # 20, 21 0 <= angle <= θ
    (0.0, 0.125),                  # 22     x <= -θ·hip_w
    (1.3, 1.5), (1.3, 1.5),        # 23, 24 ±(vL - vR) >= θ·hum_R (100 ms)
    (2.0, 2.5), (2.0, 2.5),        # 25, 26 both speeds >= θ·hum_R (100 ms)
    (155.0, 150.0), (155.0, 150.0),  # 27, 28 angle < θ
    (45.0, 50.0), (45.0, 50.0),    # 29, 30 angle > θ
    (0.35, 0.5),                   # 31     d < -θ·hum_R
    (60.0, 70.0),                  # 32     θ <= angle <= 180 - θ
    (1.4, 1.2), (1.4, 1.2),        # 33, 34 y < ymin' + θ·hum_R
    (0.35, 0.40), (0.35, 0.40),    # 35, 36 ±x > θ·hum_L
    (0.9, 0.8),                    # 37     yextent <= θ·body_len
    (3.0, 3.25),                   # 38     xz diameter >= θ·hum_R
    (2.0, 2.3),                    # 39     speed >= θ·hum_R (no smoothing)
    (50.0, 100.0),                 # 40     yaw rate >= θ deg/s
)

#: smoothing windows of the velocity features in ms (FEATURES.md §6; 0 = none)
SMOOTHING_MS = {"to_front": 250, "to_top": 250, "hands_together": 100,
                "move_apart_root": 0, "hand_speed": 100, "feet_sideways": 100,
                "foot_speed": 100, "root_speed": 0}

#: the alternative #40 thresholds of tools_intern/features/ (FEATURES.md §6)
ROOT_ANG_VEL_THRESHOLDS_ALT = (100.0, 110.0)

# joint indices as int64 constants: a kernel passing a Python int constant to a
# compiled helper gets one specialisation of the helper per distinct value
# (numba types it as a literal), which multiplied the cold compile time
_ROOT = np.int64(JOINT_INDEX["root"])
_LHIP = np.int64(JOINT_INDEX["lhip"])
_LKNEE = np.int64(JOINT_INDEX["lknee"])
_LANKLE = np.int64(JOINT_INDEX["lankle"])
_LTOES = np.int64(JOINT_INDEX["ltoes"])
_RHIP = np.int64(JOINT_INDEX["rhip"])
_RKNEE = np.int64(JOINT_INDEX["rknee"])
_RANKLE = np.int64(JOINT_INDEX["rankle"])
_RTOES = np.int64(JOINT_INDEX["rtoes"])
_BELLY = np.int64(JOINT_INDEX["belly"])
_CHEST = np.int64(JOINT_INDEX["chest"])
_NECK = np.int64(JOINT_INDEX["neck"])
_HEAD = np.int64(JOINT_INDEX["head"])
_HEADTOP = np.int64(JOINT_INDEX["headtop"])
_LSHOULDER = np.int64(JOINT_INDEX["lshoulder"])
_LELBOW = np.int64(JOINT_INDEX["lelbow"])
_LWRIST = np.int64(JOINT_INDEX["lwrist"])
_LFINGERS = np.int64(JOINT_INDEX["lfingers"])
_RSHOULDER = np.int64(JOINT_INDEX["rshoulder"])
_RELBOW = np.int64(JOINT_INDEX["relbow"])
_RWRIST = np.int64(JOINT_INDEX["rwrist"])
_RFINGERS = np.int64(JOINT_INDEX["rfingers"])

#: the smoothed velocity trajectories (P3) the features read: rows of
#: (q, p, window key) meaning d/dt (P_q - P_p), p = -1 for a plain joint.
#: The order fixes the rows of the velocity array the kernels index.
_VELOCITY_TRAJECTORIES = (
    (_RWRIST, _LHIP, "to_front"),          # 0   #1
    (_LWRIST, _LHIP, "to_front"),          # 1   #2
    (_RWRIST, _NECK, "to_top"),            # 2   #5
    (_LWRIST, _NECK, "to_top"),            # 3   #6
    (_LWRIST, _RWRIST, "hands_together"),  # 4   #10
    (_ROOT, _RWRIST, "move_apart_root"),   # 5   #11
    (_ROOT, _LWRIST, "move_apart_root"),   # 6   #12
    (_RFINGERS, -1, "hand_speed"),         # 7   #13
    (_LFINGERS, -1, "hand_speed"),         # 8   #14
    (_LANKLE, _RHIP, "feet_sideways"),     # 9   #23, #24
    (_RANKLE, _RHIP, "feet_sideways"),     # 10  #23, #24
    (_RTOES, -1, "foot_speed"),            # 11  #25
    (_RANKLE, -1, "foot_speed"),           # 12  #25
    (_LTOES, -1, "foot_speed"),            # 13  #26
    (_LANKLE, -1, "foot_speed"),           # 14  #26
    (_ROOT, -1, "root_speed"),             # 15  #39
)
_VEL_Q = np.array([q for q, _, _ in _VELOCITY_TRAJECTORIES], dtype=np.int64)
_VEL_P = np.array([p for _, p, _ in _VELOCITY_TRAJECTORIES], dtype=np.int64)
_VEL_MS = tuple(SMOOTHING_MS[key] for _, _, key in _VELOCITY_TRAJECTORIES)

# body-scale units (§3), indices into the units vector
_HUM_R, _HUM_L, _CHEST_LEN, _SHOULDER_W, _HIP_W, _BODY_LEN = range(6)

#: the six points of #38's floor-plane diameter
_EXTREMITIES = (_LANKLE, _RANKLE, _LWRIST, _RWRIST, _HEADTOP, _ROOT)

#: degrees are computed as acos(c)*180/pi, the toolbox's order of operations
_HALF_TURN_DEG = 180.0


# ---------------------------------------------------------------------------
# small geometric helpers (compiled into the kernels that call them)

@jit
def _sub(joints, t, a, b):  # pragma: no cover - compiled
    return (joints[t, a, 0] - joints[t, b, 0],
            joints[t, a, 1] - joints[t, b, 1],
            joints[t, a, 2] - joints[t, b, 2])


@jit
def _dot(u, v):  # pragma: no cover - compiled
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@jit
def _norm(u):  # pragma: no cover - compiled
    return math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])


@jit
def _unit(u):  # pragma: no cover - compiled
    # division by the norm, as the toolbox's n./repmat(sqrt(sum(n.^2)),3,1);
    # a zero vector gives NaN and every comparison with it is false (§4)
    s = _norm(u)
    return (u[0] / s, u[1] / s, u[2] / s)


@jit
def _cross(u, v):  # pragma: no cover - compiled
    return (u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0])


@jit
def _acos_deg(c):  # pragma: no cover - compiled
    # real(acos(c)): rounding beyond ±1 gives 0° / 180°; NaN stays NaN
    if c > 1.0:
        c = 1.0
    elif c < -1.0:
        c = -1.0
    return math.acos(c) * _HALF_TURN_DEG / math.pi


@jit
def _plane_normal(joints, t, p1, p2, p3):  # pragma: no cover - compiled
    """P1 normal: unit((P_p1 - P_p3) × (P_p2 - P_p3))."""
    return _unit(_cross(_sub(joints, t, p1, p3), _sub(joints, t, p2, p3)))


@jit
def _joint_angle(joints, t, a, b, c):  # pragma: no cover - compiled
    """P6: angle at c between a and b, degrees."""
    return _acos_deg(_dot(_unit(_sub(joints, t, a, c)), _unit(_sub(joints, t, b, c))))


@jit
def _segment_angle(joints, t, p1, p2, p3, p4):  # pragma: no cover - compiled
    """P7: angle between P_p1 - P_p2 and P_p3 - P_p4, degrees."""
    s1 = _sub(joints, t, p1, p2)
    s2 = _sub(joints, t, p3, p4)
    return _acos_deg(_dot(s1, s2) / (_norm(s1) * _norm(s2)))


@jit
def _vel(vel, k, t, fps):  # pragma: no cover - compiled
    # velRel: the averaged velocity is scaled by SR before the projection
    return (vel[k, t, 0] * fps, vel[k, t, 1] * fps, vel[k, t, 2] * fps)


@jit
def _speed(vel, k, t, fps):  # pragma: no cover - compiled
    # velPoint: the norm of the averaged velocity, then scaled by SR
    return math.sqrt(vel[k, t, 0] * vel[k, t, 0] + vel[k, t, 1] * vel[k, t, 1]
                     + vel[k, t, 2] * vel[k, t, 2]) * fps


@jit
def _y_min(joints, t, skip1, skip2):  # pragma: no cover - compiled
    """P9: lowest Y over the 24 joints, without joints skip1/skip2 (-1: none)."""
    m = math.inf
    for j in range(joints.shape[1]):
        if j != skip1 and j != skip2 and joints[t, j, 1] < m:
            m = joints[t, j, 1]
    return m


# ---------------------------------------------------------------------------
# kernels

@jit
def _body_units_kernel(joints, units):  # pragma: no cover - compiled
    """Body-scale units of FEATURES.md §3 from frame 0 into ``units`` (6,)."""
    units[_HUM_R] = _norm(_sub(joints, np.int64(0), _RELBOW, _RSHOULDER))
    units[_HUM_L] = _norm(_sub(joints, np.int64(0), _LSHOULDER, _LELBOW))
    units[_CHEST_LEN] = _norm(_sub(joints, np.int64(0), _CHEST, _NECK))
    units[_SHOULDER_W] = _norm(_sub(joints, np.int64(0), _RSHOULDER, _LSHOULDER))
    units[_HIP_W] = _norm(_sub(joints, np.int64(0), _RHIP, _LHIP))
    units[_BODY_LEN] = (_norm(_sub(joints, np.int64(0), _RANKLE, _RKNEE))
                        + _norm(_sub(joints, np.int64(0), _RKNEE, _RHIP))
                        + _norm(_sub(joints, np.int64(0), _ROOT, _BELLY))
                        + _norm(_sub(joints, np.int64(0), _BELLY, _CHEST))
                        + _norm(_sub(joints, np.int64(0), _CHEST, _NECK))
                        + _norm(_sub(joints, np.int64(0), _NECK, _HEAD))
                        + _norm(_sub(joints, np.int64(0), _HEAD, _HEADTOP)))


@jit
def _symmetric_index(k, m):  # pragma: no cover - compiled
    """Index into a length-m signal extended by numpy/Matlab 'symmetric' padding."""
    k = k % (2 * m)
    return k if k < m else 2 * m - 1 - k


@jit
def _smoothed_velocity_kernel(joints, q, p, windows, out):  # pragma: no cover
    """P3 steps 1–3 (FEATURES.md §4) for every trajectory d/dt(P_q[k] - P_p[k]).

    ``out[k, t, c]`` is the box-averaged forward difference per frame (not yet
    multiplied by the sampling rate). Each output is summed oldest sample
    first, each sample times 1/w, the order of the toolbox's ``conv``.

    A trajectory's three coordinates are taken in one pass over the joints (the joints of a take
    are read once per trajectory, not once per coordinate: they do not fit the processor's first
    cache), its difference of frames t + 1 and t as the difference of the two frames' values (the
    same subtractions), and the box sums run over every output at once, a window offset at a time,
    into a contiguous array (vector instructions; each output's additions in the same order) —
    1.15× the kernel's speed before (issue 35).
    """
    n = joints.shape[0]
    wmax = 1
    for k in range(windows.shape[0]):
        wmax = max(wmax, windows[k])
    d = np.empty((3, n))
    v = np.empty(max(n, wmax))
    u = np.empty(max(n, wmax) + 2 * ((wmax + 1) // 2))
    acc = np.empty(n)
    for k in range(q.shape[0]):
        w = windows[k]
        m = max(n, w)
        half = (w + 1) // 2  # ceil(w/2)
        inv_w = 1.0 / w
        qk = q[k]
        pk = p[k]
        # 1. the trajectory, each frame's three coordinates together
        if pk >= 0:
            for t in range(n):
                for c in range(3):
                    d[c, t] = joints[t, qk, c] - joints[t, pk, c]
        else:
            for t in range(n):
                for c in range(3):
                    d[c, t] = joints[t, qk, c]
        for c in range(3):
            # its forward difference, last value duplicated
            dc = d[c]
            for t in range(n - 1):
                v[t] = dc[t + 1] - dc[t]
            v[n - 1] = v[n - 2]
            # 2. files shorter than the window: extend at the end
            for t in range(n, m):
                v[t] = v[_symmetric_index(t, n)]
            # 3. pad ceil(w/2) on both sides, centred box average (the middle copied straight: an
            #    integer division per sample for the padding's index was a third of the kernel)
            for i in range(half):
                u[i] = v[_symmetric_index(i - half, m)]
            for i in range(m):
                u[half + i] = v[i]
            for i in range(m + half, m + 2 * half):
                u[i] = v[_symmetric_index(i - half, m)]
            for t in range(n):
                acc[t] = 0.0
            for j in range(w):
                uj = u[1 + j:1 + j + n]
                for t in range(n):
                    acc[t] = uj[t] * inv_w + acc[t]
            for t in range(n):
                out[k, t, c] = acc[t]


@jit
def _upper_kernel(joints, vel, units, thr, fps, f1, f2):  # pragma: no cover
    """Lenient/strict tests of features 1–14 (FEATURES.md §6, upper body)."""
    hum_r = units[_HUM_R]
    hum_l = units[_HUM_L]
    for t in range(joints.shape[0]):
        # 1, 2: hand moves forward (P4, plane neck/rhip/lhip, 250 ms)
        nrm = _plane_normal(joints, t, _NECK, _RHIP, _LHIP)
        for col, k in ((0, 0), (1, 1)):
            x = _dot(nrm, _vel(vel, k, t, fps))
            f1[t, col] = thr[col, 0] * hum_l < x
            f2[t, col] = thr[col, 1] * hum_l < x
        # 3, 4: hand above the neck (P2, normal chest -> neck)
        nrm = _unit(_sub(joints, t, _NECK, _CHEST))
        for col, j in ((2, _RWRIST), (3, _LWRIST)):
            d = _dot(nrm, _sub(joints, t, j, _NECK))
            f1[t, col] = d - thr[col, 0] * units[_CHEST_LEN] >= 0.0
            f2[t, col] = d - thr[col, 1] * units[_CHEST_LEN] >= 0.0
        # 5, 6: hand moves upward along the spine (P5, 250 ms)
        for col, k in ((4, 2), (5, 3)):
            x = _dot(nrm, _vel(vel, k, t, fps))
            f1[t, col] = thr[col, 0] * hum_l < x
            f2[t, col] = thr[col, 1] * hum_l < x
        # 7, 8: elbow bent (P6)
        for col, s, e, w in ((6, _RSHOULDER, _RELBOW, _RWRIST),
                             (7, _LSHOULDER, _LELBOW, _LWRIST)):
            a = _joint_angle(joints, t, s, w, e)
            f1[t, col] = 0.0 <= a and a <= thr[col, 0]
            f2[t, col] = 0.0 <= a and a <= thr[col, 1]
        # 9: hands apart along the shoulder line (P2)
        nrm = _unit(_sub(joints, t, _RSHOULDER, _LSHOULDER))
        d = abs(_dot(nrm, _sub(joints, t, _RWRIST, _LWRIST)))
        f1[t, 8] = d >= thr[8, 0] * units[_SHOULDER_W]
        f2[t, 8] = d >= thr[8, 1] * units[_SHOULDER_W]
        # 10: hands move together (P5, normal lwrist -> rwrist, 100 ms)
        nrm = _unit(_sub(joints, t, _RWRIST, _LWRIST))
        x = _dot(nrm, _vel(vel, np.int64(4), t, fps))
        f1[t, 9] = x >= thr[9, 0] * hum_r
        f2[t, 9] = x >= thr[9, 1] * hum_r
        # 11, 12: hand moves away from the root (P5, no smoothing)
        for col, k, j in ((10, 5, _RWRIST), (11, 6, _LWRIST)):
            nrm = _unit(_sub(joints, t, _ROOT, j))
            x = _dot(nrm, _vel(vel, k, t, fps))
            f1[t, col] = x >= thr[col, 0] * hum_r
            f2[t, col] = x >= thr[col, 1] * hum_r
        # 13, 14: hand fast (P3 speed of the finger tips, 100 ms)
        for col, k in ((12, 7), (13, 8)):
            s = _speed(vel, k, t, fps)
            f1[t, col] = s >= thr[col, 0] * hum_r
            f2[t, col] = s >= thr[col, 1] * hum_r


@jit
def _lower_kernel(joints, vel, units, thr, fps, f1, f2):  # pragma: no cover
    """Lenient/strict tests of features 15–26 (FEATURES.md §6, lower body)."""
    hum_r = units[_HUM_R]
    for t in range(joints.shape[0]):
        # 15: right foot behind the left leg (P1, plane root/lhip/lankle)
        d = _dot(_plane_normal(joints, t, _ROOT, _LHIP, _LANKLE),
                 _sub(joints, t, _RANKLE, _LANKLE))
        f1[t, 14] = d >= thr[14, 0] * hum_r
        f2[t, 14] = d >= thr[14, 1] * hum_r
        # 16: left foot behind the right leg (P1, plane root/rankle/rhip)
        d = _dot(_plane_normal(joints, t, _ROOT, _RANKLE, _RHIP),
                 _sub(joints, t, _LANKLE, _RHIP))
        f1[t, 15] = d >= thr[15, 0] * hum_r
        f2[t, 15] = d >= thr[15, 1] * hum_r
        # 17, 18: foot raised above the lowest body point (P9)
        ymin = _y_min(joints, t, np.int64(-1), np.int64(-1))
        for col, j in ((16, _RTOES), (17, _LTOES)):
            f1[t, col] = joints[t, j, 1] - ymin - thr[col, 0] * hum_r >= 0.0
            f2[t, col] = joints[t, j, 1] - ymin - thr[col, 1] * hum_r >= 0.0
        # 19: feet apart along the hip line (P2)
        hip_axis = _unit(_sub(joints, t, _RHIP, _LHIP))
        d = abs(_dot(hip_axis, _sub(joints, t, _RANKLE, _LANKLE)))
        f1[t, 18] = d >= thr[18, 0] * hum_r
        f2[t, 18] = d >= thr[18, 1] * hum_r
        # 20, 21: knee bent (P6)
        for col, h, kn, a in ((19, _RHIP, _RKNEE, _RANKLE),
                              (20, _LHIP, _LKNEE, _LANKLE)):
            ang = _joint_angle(joints, t, h, a, kn)
            f1[t, col] = 0.0 <= ang and ang <= thr[col, 0]
            f2[t, col] = 0.0 <= ang and ang <= thr[col, 1]
        # 22: feet crossed over (two P2 distances along the hip axis)
        x = (_dot(hip_axis, _sub(joints, t, _RANKLE, _LHIP))
             - _dot(hip_axis, _sub(joints, t, _LANKLE, _LHIP)))
        f1[t, 21] = x <= -thr[21, 0] * units[_HIP_W]
        f2[t, 21] = x <= -thr[21, 1] * units[_HIP_W]
        # 23, 24: feet move together / apart along the hip axis (P5, 100 ms)
        vl = _dot(hip_axis, _vel(vel, np.int64(9), t, fps))
        vr = _dot(hip_axis, _vel(vel, np.int64(10), t, fps))
        f1[t, 22] = vl - vr >= thr[22, 0] * hum_r
        f2[t, 22] = vl - vr >= thr[22, 1] * hum_r
        f1[t, 23] = vr - vl >= thr[23, 0] * hum_r
        f2[t, 23] = vr - vl >= thr[23, 1] * hum_r
        # 25, 26: foot fast — toes and ankle both (P3 speeds, 100 ms)
        for col, kt, ka in ((24, 11, 12), (25, 13, 14)):
            st = _speed(vel, kt, t, fps)
            sa = _speed(vel, ka, t, fps)
            f1[t, col] = st >= thr[col, 0] * hum_r and sa >= thr[col, 0] * hum_r
            f2[t, col] = st >= thr[col, 1] * hum_r and sa >= thr[col, 1] * hum_r


@jit
def _mix_kernel(joints, vel, units, thr, fps, f1, f2):  # pragma: no cover
    """Lenient/strict tests of features 27–39 (FEATURES.md §6, mixed)."""
    hum_r = units[_HUM_R]
    hum_l = units[_HUM_L]
    for t in range(joints.shape[0]):
        # 27, 28: upper arm abducted (P7 spine vs humerus)
        for col, e, s in ((26, _RELBOW, _RSHOULDER), (27, _LELBOW, _LSHOULDER)):
            a = _segment_angle(joints, t, _NECK, _ROOT, e, s)
            f1[t, col] = a < thr[col, 0]
            f2[t, col] = a < thr[col, 1]
        # 29, 30: thigh lifted (P7 spine vs femur)
        for col, h, kn in ((28, _RHIP, _RKNEE), (29, _LHIP, _LKNEE)):
            a = _segment_angle(joints, t, _NECK, _ROOT, h, kn)
            f1[t, col] = a > thr[col, 0]
            f2[t, col] = a > thr[col, 1]
        # 31: root behind the plane lankle/neck/rankle (P1)
        d = _dot(_plane_normal(joints, t, _LANKLE, _NECK, _RANKLE),
                 _sub(joints, t, _ROOT, _RANKLE))
        f1[t, 30] = d < -thr[30, 0] * hum_r
        f2[t, 30] = d < -thr[30, 1] * hum_r
        # 32: spine horizontal (P8: unit(neck - root) vs (0, 1, 0))
        a = _acos_deg(_unit(_sub(joints, t, _NECK, _ROOT))[1])
        f1[t, 31] = thr[31, 0] <= a and a <= _HALF_TURN_DEG - thr[31, 0]
        f2[t, 31] = thr[31, 1] <= a and a <= _HALF_TURN_DEG - thr[31, 1]
        # 33, 34: hand low, relative to the lowest other joint (P9)
        for col, fi, wr in ((32, _RFINGERS, _RWRIST), (33, _LFINGERS, _LWRIST)):
            m = _y_min(joints, t, fi, wr)
            f1[t, col] = joints[t, fi, 1] < m + thr[col, 0] * hum_r
            f2[t, col] = joints[t, fi, 1] < m + thr[col, 1] * hum_r
        # 35, 36: shoulders twisted w.r.t. the hips (P1, plane rhip/lhip/neck)
        nrm = _plane_normal(joints, t, _RHIP, _LHIP, _NECK)
        x = (_dot(nrm, _sub(joints, t, _LSHOULDER, _NECK))
             - _dot(nrm, _sub(joints, t, _RSHOULDER, _NECK)))
        f1[t, 34] = x > thr[34, 0] * hum_l
        f2[t, 34] = x > thr[34, 1] * hum_l
        f1[t, 35] = x < -thr[35, 0] * hum_l
        f2[t, 35] = x < -thr[35, 1] * hum_l
        # 37: body compact in height (P9 max - min)
        ymax = -math.inf
        for j in range(joints.shape[1]):
            if joints[t, j, 1] > ymax:
                ymax = joints[t, j, 1]
        e = ymax - _y_min(joints, t, np.int64(-1), np.int64(-1))
        f1[t, 36] = e <= thr[36, 0] * units[_BODY_LEN]
        f2[t, 36] = e <= thr[36, 1] * units[_BODY_LEN]
        # 38: extremities far apart in the floor plane (xz diameter of 6 points)
        d2 = 0.0
        for a_ in range(6):
            ja = _EXTREMITIES[a_]
            for b_ in range(a_ + 1, 6):
                jb = _EXTREMITIES[b_]
                dx = joints[t, ja, 0] - joints[t, jb, 0]
                dz = joints[t, ja, 2] - joints[t, jb, 2]
                s = dx * dx + dz * dz
                if s > d2:
                    d2 = s
        diam = math.sqrt(d2)
        f1[t, 37] = diam >= thr[37, 0] * hum_r
        f2[t, 37] = diam >= thr[37, 1] * hum_r
        # 39: root fast (P3 speed, no smoothing)
        s = _speed(vel, np.int64(15), t, fps)
        f1[t, 38] = s >= thr[38, 0] * hum_r
        f2[t, 38] = s >= thr[38, 1] * hum_r


@jit
def _yaw_rate_kernel(axis_x, axis_z, fps, out):  # pragma: no cover - compiled
    """#40 quantity: angle (deg) between consecutive floor-plane directions × SR.

    ``out[t]`` compares frames t+1 and t; ``out[n-1] = 0`` (FEATURES.md §6).
    """
    n = axis_x.shape[0]
    frame_time = 1.0 / fps
    for t in range(n - 1):
        ux, uz = axis_x[t + 1], axis_z[t + 1]
        vx, vz = axis_x[t], axis_z[t]
        c = (ux * vx + uz * vz) / (math.sqrt(ux * ux + uz * uz)
                                   * math.sqrt(vx * vx + vz * vz))
        out[t] = _acos_deg(c) / frame_time
    if n > 0:
        out[n - 1] = 0.0


@jit
def _hysteresis_kernel(f1, f2, out, states):  # pragma: no cover - compiled
    """§5 state machine per column: on when f2 holds, off when f1 fails. ``states`` (k,) bool is
    each column's state before the first row (False at a take's start), and after the last row on
    return: a long take's blocks run one after another."""
    n, k = f1.shape
    for j in range(k):
        state = states[j]
        for t in range(n):
            if state:
                state = f1[t, j]
            else:
                state = f2[t, j]
            out[t, j] = state
        states[j] = state


# ---------------------------------------------------------------------------
# public API

_THRESHOLDS = np.array(FEATURE_THRESHOLDS, dtype=np.float64)



def hysteresis(lenient, strict):
    """Combine a lenient and a strict test into one robust feature.

    The state machine of FEATURES.md §5: a feature switches on in the frame
    where the strict test holds and stays on until the lenient test fails. It
    equals the toolbox's edge rule (``features_combine_robust.m``) whenever
    ``strict`` implies ``lenient``, which holds for all 40 features.

    Parameters
    ----------
    lenient, strict : array_like, shape (n_frames, n_features) or (n_frames,), bool
        Per-frame results of the tests with θ1 and θ2 (native rate).

    Returns
    -------
    ndarray, same shape, bool

    Raises
    ------
    ParameterError
        If the shapes differ or the arrays are not boolean.

    References
    ----------
    FEATURES.md §5.
    """
    one_d = np.ndim(lenient) == 1
    f1 = _as_bool_matrix(np.asarray(lenient)[:, None] if one_d else lenient, "lenient")
    f2 = _as_bool_matrix(np.asarray(strict)[:, None] if np.ndim(strict) == 1 else strict,
                         "strict")
    if f1.shape != f2.shape:
        raise ParameterError(
            f"lenient and strict must have the same shape, got {f1.shape} and {f2.shape}")
    out = np.empty(f1.shape, dtype=np.bool_)
    _hysteresis_kernel(f1, f2, out, np.zeros(f1.shape[1], dtype=np.bool_))
    return out[:, 0] if one_d else out


def _check_threshold_pair(pair):
    try:
        lo, hi = (float(v) for v in pair)
    except (TypeError, ValueError):
        raise ParameterError(
            f"root_ang_vel_thresholds must be two numbers (lenient, strict) in deg/s, "
            f"got {pair!r}; the toolbox default is (50.0, 100.0)") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 <= lo <= hi):
        raise ParameterError(
            f"root_ang_vel_thresholds must satisfy 0 <= lenient <= strict (finite), got "
            f"{pair!r}; the toolbox default is (50.0, 100.0), the alternative "
            f"{ROOT_ANG_VEL_THRESHOLDS_ALT}")
    return lo, hi


def smoothing_window(win_ms, fps):
    """Frames of a ``win_ms`` smoothing window at ``fps``: ``max(1, ceil(ms/1000·fps))``.

    Computed in the toolbox's order of operations (``win_ms/1000*SR``), so a
    100 ms window is 12 frames at 120 Hz. References: FEATURES.md §1, §4 (P3).
    """
    return max(1, math.ceil(win_ms / 1000 * fps))


def relational_features(joints, root_rotation, fps, *,
                        root_ang_vel_thresholds=(50.0, 100.0)):
    """The 40 boolean relational features of a motion, per native frame.

    Body-scale units come from frame 0 (§3); velocities are P3 box averages
    over ``ceil(ms/1000·fps)`` frames with symmetric padding (§4); each
    feature's lenient and strict tests (§6) are combined by the hysteresis of
    §5 at the native rate. Downsample afterwards (:func:`downsample`).

    Parameters
    ----------
    joints : array_like, shape (n_frames, 24, 3), float
        Joint positions in :data:`mocapdb.bodies.joints.JOINT_NAMES` order, Y up, any
        length unit (all features are unit-free).
    root_rotation : array_like, shape (n_frames, 3, 3), float, or None
        Root rotation per frame (AMC ``Rz·Ry·Rx``, without the ASF root
        orientation). Feature 40 reads the floor-plane part of its x axis.
        None: feature 40 uses the hip axis ``lhip − rhip`` instead (the
        position-only variant proposed in FEATURES.md §2.4.8/§6; equal to the
        toolbox on all AMC oracle clips, but not guaranteed in general).
    fps : float
        Native sampling rate in Hz (velocities are per second, windows in ms).
    root_ang_vel_thresholds : (float, float), optional
        Lenient/strict yaw-rate thresholds of feature 40 in deg/s. The default
        is the toolbox's ``andreas_index`` version; the other toolbox version
        is :data:`ROOT_ANG_VEL_THRESHOLDS_ALT`.

    Returns
    -------
    ndarray, shape (n_frames, 40), bool
        Column k−1 is feature k (matrix order of FEATURES.md §0). A motion of
        fewer than 2 frames gives all-zero features (§7: the toolbox errors).

    Raises
    ------
    ParameterError
        On a wrong shape, a non-positive ``fps`` or invalid thresholds.

    References
    ----------
    FEATURES.md §3–§6; Müller & Röder, SCA 2006; Müller, Baak & Seidel, SCA 2009.
    """
    j, r, fps, ang_thr = _checked_input(joints, root_rotation, fps, root_ang_vel_thresholds)
    n = j.shape[0]
    out = np.zeros((n, N_FEATURES), dtype=np.bool_)
    if n < 2:
        return out
    f1, f2 = feature_tests(j, r, fps, body_units(j), root_ang_vel_thresholds=ang_thr)
    _hysteresis_kernel(f1, f2, out, np.zeros(N_FEATURES, dtype=np.bool_))
    return out


def _checked_input(joints, root_rotation, fps, root_ang_vel_thresholds):
    """The features' input checked once: ``(joints (n, 24, 3) float64 contiguous, root_rotation (n, 3, 3) or
    None, fps, (lenient, strict) yaw-rate thresholds)``; a clear :class:`ParameterError` otherwise."""
    j = np.asarray(joints)
    if j.ndim != 3 or j.shape[1:] != (24, 3):
        raise ParameterError(
            f"joints must have shape (n_frames, 24, 3) in JOINT_NAMES order, got {j.shape}")
    if not np.issubdtype(j.dtype, np.number):
        raise ParameterError(f"joints must be numeric, got dtype {j.dtype}")
    j = np.ascontiguousarray(j, dtype=np.float64)
    r = None
    if root_rotation is not None:
        r = np.asarray(root_rotation)
        if r.shape != (j.shape[0], 3, 3):
            raise ParameterError(
                f"root_rotation must have shape ({j.shape[0]}, 3, 3) to match joints, got "
                f"{r.shape}; pass None for position-only data")
    return j, r, check_fps(fps), _check_threshold_pair(root_ang_vel_thresholds)


@functools.lru_cache(maxsize=16)
def _windows(fps: float) -> np.ndarray:
    """The smoothing window (frames) of each velocity trajectory at ``fps`` (read-only: shared)."""
    out = np.array([smoothing_window(ms, fps) for ms in _VEL_MS], dtype=np.int64)
    out.flags.writeable = False
    return out


@functools.lru_cache(maxsize=16)
def _thresholds(root_ang_vel_thresholds: tuple) -> np.ndarray:
    """:data:`FEATURE_THRESHOLDS` with #40's pair replaced (read-only: shared)."""
    thr = _THRESHOLDS.copy()
    thr[39] = root_ang_vel_thresholds
    thr.flags.writeable = False
    return thr


def body_units(joints) -> np.ndarray:
    """The body-scale units of FEATURES.md §3 from frame 0 of ``joints`` ((n, 24, 3) float64, n ≥ 1):
    (hum_R, hum_L, chest length, shoulder width, hip width, body length), (6,) float64."""
    units = np.empty(6)
    _body_units_kernel(joints, units)
    return units


def feature_tests(joints, root_rotation, fps, units, *, root_ang_vel_thresholds=(50.0, 100.0)):
    """The lenient and strict test of every feature per frame, before the hysteresis (FEATURES.md §4, §6).

    ``joints`` (n ≥ 2, 24, 3) float64 contiguous and ``root_rotation`` ((n, 3, 3) or None) as in
    :func:`relational_features`, checked; ``units`` from :func:`body_units` of the take's frame 0.
    Row t depends on frames t − 30 … t + 31 at most (the velocity windows, the yaw rate's next
    frame) and on the take's ends, so a block of a long take computed with that much context on each
    side gives the whole take's rows.

    Returns
    -------
    f1, f2 : ndarray, shape (n, 40), bool
        The lenient and the strict test.
    """
    n = joints.shape[0]
    vel = np.empty((len(_VELOCITY_TRAJECTORIES), n, 3))
    _smoothed_velocity_kernel(joints, _VEL_Q, _VEL_P, _windows(fps), vel)

    thr = _thresholds(tuple(root_ang_vel_thresholds))
    f1 = np.empty((n, N_FEATURES), dtype=np.bool_)
    f2 = np.empty((n, N_FEATURES), dtype=np.bool_)
    _upper_kernel(joints, vel, units, thr, fps, f1, f2)
    _lower_kernel(joints, vel, units, thr, fps, f1, f2)
    _mix_kernel(joints, vel, units, thr, fps, f1, f2)

    if root_rotation is not None:
        axis = np.asarray(root_rotation[:, :, 0], dtype=np.float64)  # R·(1, 0, 0)
    else:
        axis = joints[:, _LHIP] - joints[:, _RHIP]
    rate = np.empty(n)
    _yaw_rate_kernel(np.ascontiguousarray(axis[:, 0]), np.ascontiguousarray(axis[:, 2]),
                     fps, rate)
    f1[:, 39] = rate >= thr[39, 0]
    f2[:, 39] = rate >= thr[39, 1]
    return f1, f2


def heading_turned(joints, root_rotation, fps, *, window_s=HEADING_WINDOW_S, thresholds=HEADING_THRESHOLDS,
                   axis=None):
    """Feature 41 (beyond the paper, FEATURES.md §10) per native frame: the heading turned far around the frame.

    The heading change across a window centred on the frame
    (:func:`mocapdb.features.heading.heading_change`) reaches the strict
    threshold, and the feature stays on while it stays above the lenient one
    (the §5 hysteresis).

    Parameters
    ----------
    joints : (n, 24, 3) float
    root_rotation : (n, 3, 3) float or None
    fps : float
    window_s : float, default 3.0
    thresholds : (float, float), default (45, 70)
        Lenient and strict heading change, degrees.
    axis : (n, 3) float, optional
        The pelvis axis per frame (:func:`mocapdb.features.heading.heading_axis`)
        instead of ``joints`` and ``root_rotation`` (a long take's, gathered a
        block at a time).

    Returns
    -------
    (n,) bool
    """
    try:
        lo, hi = (float(v) for v in thresholds)
    except (TypeError, ValueError):
        raise ParameterError(f"thresholds must be two numbers (lenient, strict) in degrees, got {thresholds!r}") from None
    if not (math.isfinite(hi) and 0.0 < lo <= hi):
        raise ParameterError(f"thresholds must satisfy 0 < lenient <= strict degrees, got {thresholds!r}")
    change = heading_change(joints, root_rotation, fps, window_s=window_s, axis=axis)
    if change.size < 2:
        return np.zeros(change.size, dtype=bool)
    return hysteresis(change >= lo, change >= hi)


__all__ = [
    "FEATURE_THRESHOLDS", "SMOOTHING_MS", "ROOT_ANG_VEL_THRESHOLDS_ALT", "relational_features",
    "hysteresis", "smoothing_window", "heading_turned", "body_units", "feature_tests",
]
