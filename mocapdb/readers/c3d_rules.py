"""The rules that place the 24 canonical joints from C3D markers, written once per anatomical point.

Four sources of rules, tried per joint in this order:

1. **The toolbox's HDM05/CMU Vicon marker set** (``LCS/callbackFunctions/*_default.m``
   of the authors' toolbox): the 29 markers LFHD … RMT5 by their exact names.
   A file whose 24 joints all come from these rules is read exactly as the
   toolbox reads it, bone-length fit included (:mod:`~mocapdb.readers.c3d`).
2. **Anatomical landmarks** (:mod:`~mocapdb.readers.c3d_names` reads any
   vendor's label as a landmark: ``LASI``, ``L_IAS``, ``L.ASIS``, ``LASIS``
   are all the left ASIS). Per joint, from the best landmarks first:

   - a joint centre written as a point (Vicon Clinical Manager's virtual
     ``VRHI``, ``VLKN``, ``VRAN``; ``R_HJC``) is the joint, before any estimate;
   - pelvis (root) and hips from the ASIS pair with the PSIS pair, the
     sacrum or the lateral waist markers (a missing one of four is mirrored
     by :mod:`~mocapdb.readers.c3d`); hip centres by Bell et al. (1989);
   - knee and ankle: the midpoint of the lateral and medial epicondyles /
     malleoli, or the lateral marker moved medially by a fraction of the
     pelvis width; without malleoli the ankle follows the foot (heel, toes
     and knee);
   - toes from the toe / metatarsal markers;
   - shoulder from the acromion, or the midpoint of front and back shoulder
     markers; elbow from the epicondyles or the lateral marker; wrist from
     the styloids (inner/outer wrist markers), or a single wrist marker;
     fingers from finger, knuckle or hand markers;
   - neck from C7 with the sternum / thoracic markers; head and head top
     from head markers with C7 (the toolbox's weights); belly and chest from
     the thoracic markers and the pelvis.
3. **Derived from the trunk** (:data:`DERIVED`): where a set has no marker
   for a joint that the features need but no limb gives, it is placed from
   joints already placed, in the trunk's frame (up = root → neck, forward =
   up × (rshoulder − lshoulder)), with proportions measured on the HDM05
   and CMU recordings (toolbox joints of five takes, ``benchmarks/RESULTS.md``):
   neck between the shoulders, head and head top above the neck, belly and
   chest on the spine, fingers beyond the wrist along the forearm. Each such
   rule carries a note that the ingest summary shows.
4. **A user marker map** (``marker_map``): joint = mean of the named markers;
   it overrides 1–3 for the joints it names.

A set that cannot place the pelvis, both legs (hip, knee, ankle, toes) and
both arms (shoulder, elbow, wrist) is refused, naming what is missing
(:data:`REQUIRED`); every other joint then has a rule.

References
----------
A. L. Bell, R. A. Brand, D. R. Pedersen: Prediction of hip joint centre
location from external landmarks. Human Movement Science 8 (1989) 3–16 (the
0.19/0.30/0.36 pelvis-width regression as used by Davis et al. 1991 and
Plug-in Gait). G. Wu et al.: ISB recommendation on definitions of joint
coordinate systems, J. Biomech. 35 (2002) 543–548 and 38 (2005) 981–992.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from mocapdb.readers.c3d_names import TOOLBOX_ALIASES, landmark_of, marker_key
from mocapdb.bodies.joints import JOINT_NAMES

__all__ = ["Rule", "marker_key", "TOOLBOX_ALIASES", "TOOLBOX_MARKERS", "MarkerIndex", "candidate_rules",
           "mapped_rule", "TOOLBOX", "ROLES", "DERIVED", "MAPPED", "REQUIRED", "PELVIS_QUAD", "MARKER_RULES",
           "usable_points"]

TOOLBOX, ROLES, DERIVED, MAPPED = "toolbox", "roles", "derived", "marker_map"

#: the 29 markers the toolbox's joint formulas use
TOOLBOX_MARKERS = ("LFHD", "RFHD", "LBHD", "RBHD", "C7", "T10", "STRN", "LSHO", "LELB", "LWRA", "LWRB",
                   "LFIN", "RSHO", "RELB", "RWRA", "RWRB", "RFIN", "LFWT", "RFWT", "LBWT", "RBWT",
                   "LKNE", "LANK", "LTOE", "LMT5", "RKNE", "RANK", "RTOE", "RMT5")

#: joints a marker set must place from its markers (pelvis, both legs, both arms); the others
#: can be derived from these
REQUIRED = ("root", "lhip", "lknee", "lankle", "ltoes", "rhip", "rknee", "rankle", "rtoes",
            "lshoulder", "lelbow", "lwrist", "rshoulder", "relbow", "rwrist")

#: the four pelvis landmarks of which a missing one is mirrored from the other three
PELVIS_QUAD = ("l_asis", "r_asis", "l_psis", "r_psis")


class MarkerIndex:
    """Where each marker of a file is: by toolbox name, by landmark and by (marker-map) name.

    Parameters
    ----------
    labels : sequence of str
        The file's point labels, in point order.
    usable : sequence of bool
        Per point: holds at least one valid sample (an empty trajectory counts
        as absent).
    file_labels : sequence of str, optional
        Every label of the file, when ``labels`` are only the points a reader
        held (:func:`usable_points`): what messages list. Default ``labels``.
    """

    def __init__(self, labels, usable, file_labels=None):
        self.labels = tuple(labels)
        #: the file's own labels (points added later are not)
        self.file_labels = self.labels if file_labels is None else tuple(file_labels)
        #: positions of the file's labels that name no landmark (what a marker map would have to name)
        self.unnamed = [i for i, label in enumerate(self.file_labels) if landmark_of(label) is None]
        self._exact, self._compact, self._landmarks = {}, {}, {}
        for i, (label, ok) in enumerate(zip(self.labels, usable)):
            landmark = landmark_of(label)
            if not ok:
                continue
            self._exact.setdefault(marker_key(label), i)
            self._compact.setdefault(_compact(label), i)
            if landmark is not None:
                self._landmarks.setdefault(landmark, i)

    def add(self, landmark: str, label: str) -> int:
        """Register a point computed from others (a mirrored pelvis landmark) under ``landmark``; its index."""
        i = len(self.labels)
        self.labels += (label,)
        self._landmarks[landmark] = i
        return i

    def landmarks(self) -> dict:
        """``{landmark: point index}`` of every landmark the file has."""
        return dict(self._landmarks)

    def find(self, name: str, source: str = TOOLBOX):
        """Point index of a marker name, or None if the file has no usable point of that name.

        ``source`` says how ``name`` is meant: :data:`TOOLBOX` an exact toolbox
        name (``"LFWT"``); :data:`ROLES` / :data:`DERIVED` a landmark
        (``"l_asis"``); :data:`MAPPED` a user's name, exact or up to separators.
        """
        if source in (ROLES, DERIVED):
            return self._landmarks.get(name)
        key = marker_key(name)
        if key in self._exact or source == TOOLBOX:
            return self._exact.get(key)
        return self._compact.get(_compact(name))


def _compact(label: str) -> str:
    """:func:`marker_key` without blanks, ``_``, ``-`` and ``.``: how a marker map's names are compared."""
    return "".join(ch for ch in marker_key(label) if ch not in " \t_-.")


@dataclass(frozen=True)
class Rule:
    """One way to place one joint.

    Attributes
    ----------
    joint : str
        Canonical joint.
    source : str
        :data:`TOOLBOX`, :data:`ROLES`, :data:`DERIVED` or :data:`MAPPED`.
    markers : tuple of str
        Marker names (toolbox names, landmarks or the user's names) the formula reads; all needed.
    formula : callable
        ``formula(m)`` with ``m[name]`` an ``(n_frames, 3)`` array per marker
        name returns the joint, ``(n_frames, 3)``.
    joints : tuple of str
        Joints the formula needs placed first (passed in ``m`` under their name
        prefixed with ``@``).
    any_of : tuple of str
        Landmarks of which at least one is needed; the formula gets those the file has.
    note : str or None
        What the ingest summary says when the rule is used (derived joints).
    """

    joint: str
    source: str
    markers: tuple
    formula: Callable
    joints: tuple = ()
    any_of: tuple = ()
    note: str | None = None


def _norm(v):
    return np.sqrt(np.sum(v * v, axis=-1, keepdims=True))


def _unit(v):
    """Unit vectors; a zero vector stays zero (a degenerate frame gives no NaN)."""
    n = _norm(v)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


# --------------------------------------------------------------------------
# 1. the toolbox's formulas, in its order of operations
def _toolbox_hip(front, back, other_back, *, left):
    def f(m):
        v1 = m[back] - m[front]
        v2 = m[back] - m[other_back]
        n = np.cross(v1, v2) if left else np.cross(v2, v1)
        ell = np.mean(_norm(v1))
        return 0.7 * m[front] + 0.3 * m[back] + 0.4 * ell * _unit(n)
    return f


def _toolbox_rules():
    T = TOOLBOX
    neck = (("C7", "STRN", "T10"), lambda m: 0.7 * m["C7"] + 0.15 * m["STRN"] + 0.15 * m["T10"])
    rules = [
        Rule("root", T, ("RFWT", "LFWT", "LBWT", "RBWT"),
             lambda m: (m["RFWT"] + m["LFWT"] + m["LBWT"] + m["RBWT"]) / 4),
        Rule("belly", T, ("STRN", "T10", "RFWT", "LFWT", "LBWT", "RBWT"),
             lambda m: (0.1 * m["STRN"] + 0.3 * m["T10"] + 0.1 * m["RFWT"] + 0.1 * m["LFWT"]
                        + 0.2 * m["LBWT"] + 0.2 * m["RBWT"])),
        Rule("chest", T, ("STRN", "T10", "RFWT", "LFWT", "LBWT", "RBWT", "C7"),
             lambda m: (0.1 * m["STRN"] + 0.1 * m["T10"] + 0.1 * m["RFWT"] + 0.1 * m["LFWT"]
                        + 0.05 * m["LBWT"] + 0.05 * m["RBWT"] + 0.25 * m["C7"] + 0.25 * m["T10"])),
        Rule("neck", T, *neck), Rule("lclavicle", T, *neck), Rule("rclavicle", T, *neck),
        Rule("head", T, ("RFHD", "LFHD", "RBHD", "LBHD", "C7"),
             lambda m: 0.4 * (m["RFHD"] + m["LFHD"] + m["RBHD"] + m["LBHD"]) / 4 + 0.6 * m["C7"]),
        Rule("headtop", T, ("RFHD", "LFHD", "RBHD", "LBHD"),
             lambda m: 0.15 * m["RFHD"] + 0.15 * m["LFHD"] + 0.35 * m["RBHD"] + 0.35 * m["LBHD"]),
        Rule("lhip", T, ("LFWT", "LBWT", "RBWT"), _toolbox_hip("LFWT", "LBWT", "RBWT", left=True)),
        Rule("rhip", T, ("RFWT", "RBWT", "LBWT"), _toolbox_hip("RFWT", "RBWT", "LBWT", left=False)),
    ]
    for s in "LR":
        j = s.lower()
        kne, ank, toe, mt5 = f"{s}KNE", f"{s}ANK", f"{s}TOE", f"{s}MT5"
        rules += [
            Rule(f"{j}shoulder", T, (f"{s}SHO",), lambda m, k=f"{s}SHO": m[k]),
            Rule(f"{j}elbow", T, (f"{s}ELB",), lambda m, k=f"{s}ELB": m[k]),
            Rule(f"{j}wrist", T, (f"{s}WRB", f"{s}WRA"),
                 lambda m, a=f"{s}WRB", b=f"{s}WRA": (m[a] + m[b]) / 2),
            Rule(f"{j}fingers", T, (f"{s}FIN",), lambda m, k=f"{s}FIN": m[k]),
            Rule(f"{j}toes", T, (toe, mt5), lambda m, a=toe, b=mt5: (m[a] + m[b]) / 2),
            Rule(f"{j}ankle", T, (ank, toe, mt5),
                 lambda m, a=ank, t=toe, f=mt5: m[a] + 0.3 * (m[t] - m[f])),
            Rule(f"{j}knee", T, (kne, toe, mt5, ank),
                 lambda m, k=kne, t=toe, f=mt5, a=ank: m[k] + 0.6 * (m[t] - m[f]) + 0.2 * (m[f] - m[a])),
        ]
    return rules


def _toolbox_finger_fallbacks():
    """The toolbox's rfingers without RFIN and its mirror for lfingers."""
    out = []
    for s, o in (("R", "L"), ("L", "R")):
        keys = (f"{s}WRA", f"{s}WRB", f"{o}FIN", f"{o}WRA")
        out.append(Rule(f"{s.lower()}fingers", TOOLBOX, keys,
                        lambda m, k=keys: (m[k[0]] + m[k[1]]) / 2 + m[k[2]] - m[k[3]]))
    return out


# --------------------------------------------------------------------------
# 2. anatomical landmarks

#: Bell et al.: hip centre from the mid-ASIS point, in pelvis widths (posterior, inferior, lateral)
BELL = (0.19, 0.30, 0.36)
#: a lateral-only knee / ankle marker lies this many pelvis widths from the joint centre (half a
#: typical knee width of 0.4 and ankle width of 0.28 pelvis widths, plus the marker's radius)
MEDIAL_OFFSET = {"knee": 0.22, "ankle": 0.16}
#: a lateral elbow marker lies this many upper-arm lengths from the elbow centre (half a typical
#: elbow width of 6.5 cm plus the marker's radius, for a 31 cm humerus: Plug-in Gait places the
#: centre so from the measured elbow width)
ELBOW_MEDIAL = 0.13
#: the ankle centre from the heel marker, in heel-to-toe lengths: along the foot and up the
#: shank (medians of 12 feet with malleolus, heel and toe markers: HDM05, CMU, ISB, Qualisys,
#: Vicon; spread ±0.05)
ANKLE_FROM_HEEL = (0.33, 0.23)

#: what may stand behind the ASIS pair to give the pelvis its forward direction
_BACKS = {"psis": ("l_psis", "r_psis"), "sacr": ("sacr",), "waist_mid": ("l_waist_mid", "r_waist_mid")}


def _mean(*keys):
    return lambda m: sum(m[k] for k in keys) / len(keys)


def _pelvis_back(m, back):
    keys = _BACKS[back]
    return sum(m[k] for k in keys) / len(keys)


def _pelvis_frame(m, back):
    """Mid-ASIS origin, unit right/anterior/up axes, and the mean pelvis width."""
    la, ra = m["l_asis"], m["r_asis"]
    origin = (la + ra) / 2
    right = _unit(ra - la)
    fwd = origin - _pelvis_back(m, back)
    anterior = _unit(fwd - np.sum(fwd * right, axis=-1, keepdims=True) * right)
    up = np.cross(right, anterior)
    width = float(np.mean(_norm(ra - la)))
    return origin, right, anterior, up, width


def _bell_hip(side, back):
    def f(m):
        origin, right, anterior, up, w = _pelvis_frame(m, back)
        lateral = right if side == "r" else -right
        return origin - BELL[0] * w * anterior - BELL[1] * w * up + BELL[2] * w * lateral
    return f


def _medial(side, key, part):
    """A lateral marker moved towards the body's midline (along the pelvis's left-right axis)."""
    def f(m):
        right = _unit(m["r_asis"] - m["l_asis"])
        width = float(np.mean(_norm(m["r_asis"] - m["l_asis"])))
        medial = right if side == "l" else -right
        return m[key] + MEDIAL_OFFSET[part] * width * medial
    return f


def _elbow_centre(side, key):
    """The elbow centre from the lateral epicondyle marker: moved medially (towards the body's
    midline across the upper arm) by :data:`ELBOW_MEDIAL` upper-arm lengths."""
    def f(m):
        elbow, shoulder = m[key], m[f"@{side}shoulder"]
        upper = elbow - shoulder
        length = float(np.mean(_norm(upper)))
        axis = _unit(upper)
        right = m["@rshoulder"] - m["@lshoulder"]
        medial = right if side == "l" else -right
        medial = _unit(medial - np.sum(medial * axis, axis=-1, keepdims=True) * axis)
        return elbow + ELBOW_MEDIAL * length * medial
    return f


def _ankle_from_foot(side):
    """The ankle centre from the heel marker, the toes and the knee (a foot without malleolus markers)."""
    def f(m):
        heel, toes, knee = m[f"{side}_heel"], m[f"@{side}toes"], m[f"@{side}knee"]
        along = toes - heel
        length = _norm(along)
        x = _unit(along)
        up = knee - heel
        up = _unit(up - np.sum(up * x, axis=-1, keepdims=True) * x)
        return heel + length * (ANKLE_FROM_HEEL[0] * x + ANKLE_FROM_HEEL[1] * up)
    return f


def _trunk(back):
    """belly, chest: the toolbox's weights with ASIS for the front and PSIS (or the sacrum) for the back waist."""
    pel = _BACKS[back]

    def b(m):
        return _pelvis_back(m, back)

    belly = (lambda m: 0.1 * m["strn"] + 0.3 * m["t10"] + 0.1 * m["r_asis"] + 0.1 * m["l_asis"]
             + 0.4 * b(m))
    chest = (lambda m: 0.1 * m["strn"] + 0.35 * m["t10"] + 0.1 * m["r_asis"] + 0.1 * m["l_asis"]
             + 0.1 * b(m) + 0.25 * m["c7"])
    keys = ("strn", "t10", "l_asis", "r_asis") + pel
    return [Rule("belly", ROLES, keys, belly), Rule("chest", ROLES, keys + ("c7",), chest)]


#: head markers and their weight in the head top (the toolbox: 0.15 per front, 0.35 per back marker)
_HEAD_MARKERS = {"l_head_front": 0.3, "r_head_front": 0.3, "c_head_front": 0.3, "l_head_side": 0.5,
                 "r_head_side": 0.5, "head_top": 0.5, "l_head_back": 0.7, "r_head_back": 0.7,
                 "c_head_back": 0.7}


def _head_band(m):
    """The weighted mean of the head markers a file has (the toolbox's head top for its four)."""
    keys = [k for k in _HEAD_MARKERS if k in m]
    w = np.array([_HEAD_MARKERS[k] for k in keys])
    return sum(wk * m[k] for wk, k in zip(w, keys)) / w.sum()


def _head_mean(m):
    keys = [k for k in _HEAD_MARKERS if k in m]
    return sum(m[k] for k in keys) / len(keys)


def _side_rules(s):
    R = ROLES
    p = f"{s}_"
    pelvis = ("l_asis", "r_asis")
    # a joint centre the lab's software wrote as a point (VRHI, R_HJC) is taken as it is, before
    # any estimate from the landmarks around it
    rules = [Rule(f"{s}{joint}", R, (f"{p}{joint}_jc",), _mean(f"{p}{joint}_jc"))
             for joint in ("hip", "knee", "ankle", "shoulder", "elbow", "wrist")]
    for back, keys in _BACKS.items():
        rules.append(Rule(f"{s}hip", R, pelvis + keys, _bell_hip(s, back)))
    rules += [
        Rule(f"{s}knee", R, (p + "knee_lat", p + "knee_med"), _mean(p + "knee_lat", p + "knee_med")),
        Rule(f"{s}knee", R, (p + "knee_lat",) + pelvis, _medial(s, p + "knee_lat", "knee")),
        Rule(f"{s}ankle", R, (p + "ankle_lat", p + "ankle_med"), _mean(p + "ankle_lat", p + "ankle_med")),
        Rule(f"{s}ankle", R, (p + "ankle_lat",) + pelvis, _medial(s, p + "ankle_lat", "ankle")),
        Rule(f"{s}ankle", R, (p + "heel",), _ankle_from_foot(s), joints=(f"{s}toes", f"{s}knee"),
             note="ankles placed from heel, toes and knee (no malleolus markers)"),
        Rule(f"{s}toes", R, (p + "toe", p + "mt5"), _mean(p + "toe", p + "mt5")),
        Rule(f"{s}toes", R, (p + "mt1", p + "mt5"), _mean(p + "mt1", p + "mt5")),
        Rule(f"{s}toes", R, (p + "toe",), _mean(p + "toe")),
        Rule(f"{s}toes", R, (p + "mt5",), _mean(p + "mt5")),
        Rule(f"{s}toes", R, (p + "mt1",), _mean(p + "mt1")),
        Rule(f"{s}shoulder", R, (p + "acromion",), _mean(p + "acromion")),
        Rule(f"{s}shoulder", R, (p + "shoulder_front", p + "shoulder_back"),
             _mean(p + "shoulder_front", p + "shoulder_back")),
        Rule(f"{s}elbow", R, (p + "elbow_lat", p + "elbow_med"), _mean(p + "elbow_lat", p + "elbow_med")),
        Rule(f"{s}elbow", R, (p + "elbow_lat",), _elbow_centre(s, p + "elbow_lat"),
             joints=("lshoulder", "rshoulder")),
        Rule(f"{s}wrist", R, (p + "wrist_rad", p + "wrist_uln"), _mean(p + "wrist_rad", p + "wrist_uln")),
        Rule(f"{s}wrist", R, (p + "wrist",), _mean(p + "wrist")),
        Rule(f"{s}wrist", R, (p + "wrist_rad",), _mean(p + "wrist_rad")),
        Rule(f"{s}wrist", R, (p + "wrist_uln",), _mean(p + "wrist_uln")),
        Rule(f"{s}fingers", R, (p + "finger",), _mean(p + "finger")),
        Rule(f"{s}fingers", R, (p + "mcp2", p + "mcp5"), _mean(p + "mcp2", p + "mcp5")),
        Rule(f"{s}fingers", R, (p + "hand",), _mean(p + "hand")),
        Rule(f"{s}fingers", R, (p + "mcp2",), _mean(p + "mcp2")),
        Rule(f"{s}fingers", R, (p + "mcp5",), _mean(p + "mcp5")),
    ]
    return rules


def _role_rules():
    R = ROLES
    head = tuple(_HEAD_MARKERS)
    rules = [
        Rule("root", R, ("l_asis", "r_asis", "l_psis", "r_psis"), _mean("l_asis", "r_asis", "l_psis", "r_psis")),
        Rule("root", R, ("l_asis", "r_asis", "sacr"),
             lambda m: 0.25 * (m["l_asis"] + m["r_asis"]) + 0.5 * m["sacr"]),
        Rule("root", R, ("l_asis", "r_asis", "l_waist_mid", "r_waist_mid"),
             _mean("l_asis", "r_asis", "l_waist_mid", "r_waist_mid")),
        Rule("neck", R, ("c7", "strn", "t10"), lambda m: 0.7 * m["c7"] + 0.15 * m["strn"] + 0.15 * m["t10"]),
        Rule("neck", R, ("c7", "clav"), _mean("c7", "clav")),
        Rule("neck", R, ("c7", "strn"), lambda m: 0.7 * m["c7"] + 0.3 * m["strn"]),
        Rule("head", R, ("c7",), lambda m: 0.4 * _head_mean(m) + 0.6 * m["c7"], any_of=head),
        Rule("head", R, (), lambda m: 0.4 * _head_mean(m) + 0.6 * m["@neck"], joints=("neck",), any_of=head),
        Rule("headtop", R, (), _head_band, any_of=head),
        *_trunk("psis"), *_trunk("sacr"),
    ]
    for j in ("lclavicle", "rclavicle"):
        rules.append(Rule(j, R, (), lambda m: m["@neck"], joints=("neck",)))
    for s in "lr":
        rules += _side_rules(s)
    return rules


# --------------------------------------------------------------------------
# 3. derived from the trunk: proportions of the toolbox joints of HDM05 dg and mm and CMU
# 85_02, 85_12 and 135_02, in units of the root-to-neck length along the trunk's up and
# forward axes (their spread between takes: ±0.05)

#: joint → (up, forward) from its origin joint
TRUNK_PROPORTIONS = {"neck": (-0.06, -0.08),      # from the mid-shoulder point
                     "head": (0.28, 0.05), "headtop": (0.45, 0.10),   # from the neck
                     "belly": (0.25, -0.08), "chest": (0.58, -0.03)}  # from the root
#: the fingers lie this fraction of the forearm beyond the wrist (HDM05: 0.41–0.49, CMU: 0.09–0.25)
FINGERS_BEYOND_WRIST = 0.3

_SHOULDERS = ("lshoulder", "rshoulder")


def _trunk_axes(m, top):
    """Unit up (root → ``top``), unit forward (up × left-to-right shoulders) and the root-to-top length."""
    up_vec = top - m["@root"]
    length = _norm(up_vec)
    up = _unit(up_vec)
    right = m["@rshoulder"] - m["@lshoulder"]
    right = right - np.sum(right * up, axis=-1, keepdims=True) * up
    return up, _unit(np.cross(up, right)), length


def _from_trunk(joint, origin):
    up_k, fwd_k = TRUNK_PROPORTIONS[joint]

    def f(m):
        if origin == "shoulders":
            base = (m["@lshoulder"] + m["@rshoulder"]) / 2
            up, fwd, length = _trunk_axes(m, base)
        else:
            up, fwd, length = _trunk_axes(m, m["@neck"])
            base = m[f"@{origin}"]
        return base + length * (up_k * up + fwd_k * fwd)
    return f


def _derived_rules():
    D = DERIVED
    trunk = ("root",) + _SHOULDERS
    head_note = "head and headtop placed from the neck and the trunk's axis (no head markers)"
    rules = [
        Rule("neck", D, (), _from_trunk("neck", "shoulders"), joints=trunk,
             note="neck placed between the shoulders (no C7 with a sternum or clavicle marker)"),
        Rule("head", D, (), _from_trunk("head", "neck"), joints=trunk + ("neck",), note=head_note),
        Rule("headtop", D, (), _from_trunk("headtop", "neck"), joints=trunk + ("neck",), note=head_note),
        Rule("belly", D, (), _from_trunk("belly", "root"), joints=trunk + ("neck",),
             note="belly and chest placed on the trunk's axis (no thoracic and sternum markers)"),
        Rule("chest", D, (), _from_trunk("chest", "root"), joints=trunk + ("neck",),
             note="belly and chest placed on the trunk's axis (no thoracic and sternum markers)"),
    ]
    for s in "lr":
        rules.append(Rule(f"{s}fingers", D, (),
                          lambda m, s=s: m[f"@{s}wrist"] + FINGERS_BEYOND_WRIST * (m[f"@{s}wrist"]
                                                                                  - m[f"@{s}elbow"]),
                          joints=(f"{s}wrist", f"{s}elbow"),
                          note="fingers placed beyond the wrists along the forearms (no hand markers)"))
    return rules


def _by_joint(rules):
    out = {j: [] for j in JOINT_NAMES}
    for r in rules:
        out[r.joint].append(r)
    return out


_TOOLBOX = _by_joint(_toolbox_rules())
_ROLES = _by_joint(_role_rules())
_FALLBACK = _by_joint(_toolbox_finger_fallbacks())
_DERIVED = _by_joint(_derived_rules())


#: ``marker_rules`` values: the toolbox's formulas first (the reference), or anatomical landmarks only
MARKER_RULES = ("toolbox", "anatomical")


def candidate_rules(joint: str, marker_rules: str = "toolbox") -> list:
    """The automatic rules for a joint, in order of preference: the toolbox's (unless
    ``marker_rules="anatomical"``), landmarks, the toolbox's finger fallbacks, derived from the trunk."""
    if marker_rules == "anatomical":
        return _ROLES[joint] + _DERIVED[joint]
    return _TOOLBOX[joint] + _ROLES[joint] + _FALLBACK[joint] + _DERIVED[joint]


#: the exact keys of the markers the toolbox's rules name
_TOOLBOX_KEYS = frozenset(marker_key(n) for group in (_TOOLBOX, _ROLES, _FALLBACK, _DERIVED) for rules in group.values()
                          for rule in rules if rule.source == TOOLBOX for n in (*rule.markers, *rule.any_of))


def usable_points(labels, marker_map=None) -> list:
    """The indices of the points any rule or ``marker_map`` can use: a toolbox marker name, an anatomical
    landmark (:func:`~mocapdb.readers.c3d_names.landmark_of`) or a name the map gives, exact or up to
    separators. :class:`MarkerIndex` finds nothing else, so a reader need not hold the others (the
    other 4,950 markers of a dense set)."""
    names = [n for v in (marker_map or {}).values() for n in ([v] if isinstance(v, str) else v)]
    exact = _TOOLBOX_KEYS | {marker_key(n) for n in names}
    compact = {_compact(n) for n in names}
    return [i for i, label in enumerate(labels) if marker_key(label) in exact or landmark_of(label) is not None
            or (compact and _compact(label) in compact)]


def mapped_rule(joint: str, names) -> Rule:
    """The marker-map rule: the joint is the mean of the named markers."""
    names = (names,) if isinstance(names, str) else tuple(names)
    return Rule(joint, MAPPED, names, _mean(*names))
