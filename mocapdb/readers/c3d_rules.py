"""Marker names and the rules that place the 24 canonical joints from C3D markers.

Three sources of rules, tried per joint in this order:

1. **The toolbox's HDM05/CMU Vicon marker set** (FEATURES.md §2.4.4–§2.4.5,
   ``LCS/callbackFunctions/*_default.m``): the 29 markers LFHD … RMT5 by
   their exact names. A file whose 24 joints all come from these rules is
   read exactly as the toolbox reads it, bone-length fit included
   (:mod:`~mocapdb.readers.c3d`).
2. **Anatomical roles** (READERS.md §3): Vicon Plug-in Gait names (LASI,
   LPSI/SACR, LKNE, LANK, LTOE, LSHO, LELB, LWRA/LWRB, LFIN, LFHD…) and
   ISB-style landmarks (Qualisys: L_IAS/L_IPS, L_FLE/L_FME knee epicondyles,
   L_FAL/L_TAM malleoli, L_FM1/L_FM5, L_HLE/L_HME elbow, L_RSP/L_UHE wrist,
   L_HM2/L_HM5, L_SAJ acromion, L_HDF/L_HDB head, CV7, TV8, SXS, SNJ), matched
   by name after removing the side word's separator (``L_FLE``, ``l fle``,
   ``LeftFLE`` are one name). Joint centres are the midpoint of a medial
   and a lateral landmark where both exist; the hip centres follow Bell et
   al. (1990) from the pelvis landmarks; a lateral-only knee or ankle marker
   is moved medially by a fraction of the pelvis width (Plug-in Gait without
   its knee/ankle widths); trunk and head joints use the toolbox's weights
   with the pelvis landmarks in place of the waist markers.
3. **A user marker map** (``marker_map``): joint = mean of the named markers;
   it overrides 1 and 2 for the joints it names.

Names are compared after :func:`marker_key`: the subject prefix up to the
first ``:`` removed, blanks trimmed, upper case (FEATURES.md §2.4.4
"(proposed)": exact matching, not the toolbox's prefix test), then the
toolbox's aliases (``Left Forehead`` → LFHD, …, ``R10`` → RBAC).

References
----------
FEATURES.md §2.4; READERS.md §3. A. L. Bell, R. A. Brand, D. R. Pedersen:
Prediction of hip joint centre location from external landmarks. Human
Movement Science 8 (1989) 3–16 (the 0.19/0.30/0.36 pelvis-width regression as
used by Davis et al. 1991 and Plug-in Gait). G. Wu et al.: ISB
recommendation on definitions of joint coordinate systems, J. Biomech. 35
(2002) 543–548 and 38 (2005) 981–992 (landmark names).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable

import numpy as np

from mocapdb.readers.joints import JOINT_NAMES

__all__ = ["Rule", "marker_key", "compact_key", "TOOLBOX_ALIASES", "TOOLBOX_MARKERS", "ROLE_ALIASES",
           "MarkerIndex", "candidate_rules", "mapped_rule", "TOOLBOX", "ROLES", "MAPPED"]

TOOLBOX, ROLES, MAPPED = "toolbox", "roles", "marker_map"

#: the toolbox's label aliases (``mapLabelNamesToVicon.m``), matched exactly and case-insensitively
TOOLBOX_ALIASES = {"LEFT FOREHEAD": "LFHD", "LEFTFHD": "LFHD", "RIGHT FOREHEAD": "RFHD", "RIGHTFHD": "RFHD",
                   "LARM": "LFRM", "RARM": "RFRM", "RLEG": "RSHN", "LLEG": "LSHN", "R10": "RBAC"}

#: the 29 markers the toolbox's joint formulas use (FEATURES.md §2.4.4)
TOOLBOX_MARKERS = ("LFHD", "RFHD", "LBHD", "RBHD", "C7", "T10", "STRN", "LSHO", "LELB", "LWRA", "LWRB",
                   "LFIN", "RSHO", "RELB", "RWRA", "RWRB", "RFIN", "LFWT", "RFWT", "LBWT", "RBWT",
                   "LKNE", "LANK", "LTOE", "LMT5", "RKNE", "RANK", "RTOE", "RMT5")

_SIDE_WORDS = {"l": ("L", "LEFT"), "r": ("R", "RIGHT")}

#: anatomical role -> compact names (``{s}`` = side letter or word), first match wins
_SIDED = {
    "asis": ("{s}ASI", "{s}ASIS", "{s}IAS", "{s}FWT"),
    "psis": ("{s}PSI", "{s}PSIS", "{s}IPS", "{s}BWT"),
    "knee_lat": ("{s}KNE", "{s}KNEE", "{s}FLE", "{s}LFE", "{s}KNEE1", "{s}LKNE", "{s}KNEL", "{s}LATKNEE"),
    "knee_med": ("{s}KNM", "{s}KNEM", "{s}MKNE", "{s}FME", "{s}MFE", "{s}KNEE2", "{s}MEDKNEE", "{s}KNEEMED"),
    "ankle_lat": ("{s}ANK", "{s}ANKLE", "{s}FAL", "{s}LMAL", "{s}MALL", "{s}LATMALL", "{s}ANKL"),
    "ankle_med": ("{s}MED", "{s}MMAL", "{s}TAM", "{s}MEDMALL", "{s}ANKM"),
    "toe": ("{s}TOE", "{s}FM2", "{s}MT2", "{s}MET2"),
    "mt1": ("{s}FM1", "{s}MT1", "{s}MET1"),
    "mt5": ("{s}MT5", "{s}FM5", "{s}MET5", "{s}MET"),
    "sho": ("{s}SHO", "{s}SHOU", "{s}SHOULDER", "{s}SHOULD", "{s}SAJ", "{s}ACR", "{s}ACROMION"),
    "elb_lat": ("{s}ELB", "{s}ELBOW", "{s}HLE", "{s}LEL", "{s}ELBL", "{s}LATELB"),
    "elb_med": ("{s}HME", "{s}MEL", "{s}MELB", "{s}ELBM", "{s}MEDELB"),
    "wra": ("{s}WRA", "{s}RSP", "{s}WRR", "{s}RADSTY"),
    "wrb": ("{s}WRB", "{s}UHE", "{s}USP", "{s}WRU", "{s}ULNSTY"),
    "fin": ("{s}FIN", "{s}HAND", "{s}FING"),
    "mcp2": ("{s}HM2", "{s}MCP2"),
    "mcp5": ("{s}HM5", "{s}MCP5"),
    "fhd": ("{s}FHD", "{s}HDF", "{s}FH", "{s}FRONTHEAD"),
    "bhd": ("{s}BHD", "{s}HDB", "{s}BH", "{s}BACKHEAD"),
}
_CENTRAL = {
    "c7": ("C7", "CV7", "VC7"),
    "t10": ("T10", "TV10", "T8", "TV8", "T9"),   # the thoracic marker: T8 stands in for T10
    "clav": ("CLAV", "SNJ", "IJ", "JN", "SJN"),
    "strn": ("STRN", "SXS", "PX", "XP", "XIPH", "STERNUM"),
    "sacr": ("SACR", "SACRUM", "SACRAL"),
}

#: role name (``l_asis``, ``c7``, …) -> compact names, in order of preference
ROLE_ALIASES = {**{f"{side}_{role}": tuple(p.format(s=w) for p in pats for w in _SIDE_WORDS[side])
                   for role, pats in _SIDED.items() for side in "lr"},
                **_CENTRAL}

_SEPARATORS = re.compile(r"[\s_\-.]+")


def marker_key(label: str) -> str:
    """A label as the toolbox rules compare it: prefix to the first ``:`` removed, trimmed, upper case, aliases.

    ``"Daniel:LFHD"`` → ``"LFHD"``, ``"A:B:LFHD"`` → ``"B:LFHD"`` (FEATURES.md §2.4.4),
    ``"left forehead"`` → ``"LFHD"``.
    """
    key = label.split(":", 1)[1] if ":" in label else label
    key = key.strip().upper()
    return TOOLBOX_ALIASES.get(key, key)


def compact_key(label: str) -> str:
    """:func:`marker_key` without blanks, ``_``, ``-`` and ``.``: the form role aliases are compared in."""
    return _SEPARATORS.sub("", marker_key(label))


class MarkerIndex:
    """Where each marker of a file is: by toolbox name, by role and by (marker-map) name.

    Parameters
    ----------
    labels : sequence of str
        The file's point labels, in point order.
    usable : sequence of bool
        Per point: holds at least one valid sample (an empty trajectory counts
        as absent).
    """

    def __init__(self, labels, usable):
        self.labels = tuple(labels)
        self._exact, self._compact = {}, {}
        for i, (label, ok) in enumerate(zip(self.labels, usable)):
            if not ok:
                continue
            self._exact.setdefault(marker_key(label), i)
            self._compact.setdefault(compact_key(label), i)

    def find(self, name: str, source: str = TOOLBOX):
        """Point index of a marker name, or None if the file has no usable point of that name.

        ``source`` says how ``name`` is meant: :data:`TOOLBOX` an exact toolbox
        name (``"LFWT"``); :data:`ROLES` a role (``"l_asis"``) tried through its
        aliases; :data:`MAPPED` a user's name, exact or up to separators.
        """
        if source == ROLES:
            for alias in ROLE_ALIASES[name]:
                if alias in self._compact:
                    return self._compact[alias]
            return None
        key = marker_key(name)
        if key in self._exact or source == TOOLBOX:
            return self._exact.get(key)
        return self._compact.get(compact_key(name))


@dataclass(frozen=True)
class Rule:
    """One way to place one joint.

    Attributes
    ----------
    joint : str
        Canonical joint.
    source : str
        :data:`TOOLBOX`, :data:`ROLES` or :data:`MAPPED`.
    markers : tuple of str
        Marker names (toolbox names, roles or the user's names) the formula reads.
    formula : callable
        ``formula(m)`` with ``m[name]`` an ``(n_frames, 3)`` array per marker
        name returns the joint, ``(n_frames, 3)``.
    joints : tuple of str
        Joints the formula needs placed first (passed in ``m`` under their name
        prefixed with ``@``).
    """

    joint: str
    source: str
    markers: tuple
    formula: Callable
    joints: tuple = ()


def _norm(v):
    return np.sqrt(np.sum(v * v, axis=-1, keepdims=True))


def _unit(v):
    """Unit vectors; a zero vector stays zero (a degenerate frame gives no NaN)."""
    n = _norm(v)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


# --------------------------------------------------------------------------
# 1. the toolbox's formulas (FEATURES.md §2.4.5), in its order of operations

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
    """The toolbox's rfingers without RFIN (FEATURES.md §2.4.7) and its mirror for lfingers (proposed)."""
    out = []
    for s, o in (("R", "L"), ("L", "R")):
        keys = (f"{s}WRA", f"{s}WRB", f"{o}FIN", f"{o}WRA")
        out.append(Rule(f"{s.lower()}fingers", TOOLBOX, keys,
                        lambda m, k=keys: (m[k[0]] + m[k[1]]) / 2 + m[k[2]] - m[k[3]]))
    return out


# --------------------------------------------------------------------------
# 2. anatomical roles

#: Bell et al.: hip centre from the mid-ASIS point, in pelvis widths (posterior, inferior, lateral)
BELL = (0.19, 0.30, 0.36)
#: a lateral-only knee / ankle marker lies this many pelvis widths from the joint centre (half a
#: typical knee width of 0.4 and ankle width of 0.28 pelvis widths, plus the marker's radius)
MEDIAL_OFFSET = {"knee": 0.22, "ankle": 0.16}


def _mean(*keys):
    return lambda m: sum(m[k] for k in keys) / len(keys)


def _pelvis_back(m, back):
    return (m["l_psis"] + m["r_psis"]) / 2 if back == "psis" else m["sacr"]


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


def _trunk(back):
    """belly, chest: the toolbox's weights with ASIS for the front and PSIS (or the sacrum) for the back waist."""
    pel = ("l_psis", "r_psis") if back == "psis" else ("sacr",)

    def b(m):
        return _pelvis_back(m, back)

    belly = (lambda m: 0.1 * m["strn"] + 0.3 * m["t10"] + 0.1 * m["r_asis"] + 0.1 * m["l_asis"]
             + 0.4 * b(m))
    chest = (lambda m: 0.1 * m["strn"] + 0.35 * m["t10"] + 0.1 * m["r_asis"] + 0.1 * m["l_asis"]
             + 0.1 * b(m) + 0.25 * m["c7"])
    keys = ("strn", "t10", "l_asis", "r_asis") + pel
    return [Rule("belly", ROLES, keys, belly), Rule("chest", ROLES, keys + ("c7",), chest)]


def _role_rules():
    R = ROLES
    rules = [
        Rule("root", R, ("l_asis", "r_asis", "l_psis", "r_psis"), _mean("l_asis", "r_asis", "l_psis", "r_psis")),
        Rule("root", R, ("l_asis", "r_asis", "sacr"),
             lambda m: 0.25 * (m["l_asis"] + m["r_asis"]) + 0.5 * m["sacr"]),
        Rule("neck", R, ("c7", "strn", "t10"), lambda m: 0.7 * m["c7"] + 0.15 * m["strn"] + 0.15 * m["t10"]),
        Rule("neck", R, ("c7", "clav"), _mean("c7", "clav")),
        Rule("head", R, ("l_fhd", "r_fhd", "l_bhd", "r_bhd", "c7"),
             lambda m: 0.4 * (m["r_fhd"] + m["l_fhd"] + m["r_bhd"] + m["l_bhd"]) / 4 + 0.6 * m["c7"]),
        Rule("headtop", R, ("l_fhd", "r_fhd", "l_bhd", "r_bhd"),
             lambda m: 0.15 * m["r_fhd"] + 0.15 * m["l_fhd"] + 0.35 * m["r_bhd"] + 0.35 * m["l_bhd"]),
        *_trunk("psis"), *_trunk("sacr"),
    ]
    for j in ("lclavicle", "rclavicle"):
        rules.append(Rule(j, R, (), lambda m: m["@neck"], joints=("neck",)))
    for s in "lr":
        p = f"{s}_"
        pelvis = ("l_asis", "r_asis")
        rules += [
            Rule(f"{s}hip", R, pelvis + ("l_psis", "r_psis"), _bell_hip(s, "psis")),
            Rule(f"{s}hip", R, pelvis + ("sacr",), _bell_hip(s, "sacr")),
            Rule(f"{s}knee", R, (p + "knee_lat", p + "knee_med"), _mean(p + "knee_lat", p + "knee_med")),
            Rule(f"{s}knee", R, (p + "knee_lat",) + pelvis, _medial(s, p + "knee_lat", "knee")),
            Rule(f"{s}ankle", R, (p + "ankle_lat", p + "ankle_med"), _mean(p + "ankle_lat", p + "ankle_med")),
            Rule(f"{s}ankle", R, (p + "ankle_lat",) + pelvis, _medial(s, p + "ankle_lat", "ankle")),
            Rule(f"{s}toes", R, (p + "toe", p + "mt5"), _mean(p + "toe", p + "mt5")),
            Rule(f"{s}toes", R, (p + "mt1", p + "mt5"), _mean(p + "mt1", p + "mt5")),
            Rule(f"{s}toes", R, (p + "toe",), _mean(p + "toe")),
            Rule(f"{s}toes", R, (p + "mt5",), _mean(p + "mt5")),
            Rule(f"{s}shoulder", R, (p + "sho",), _mean(p + "sho")),
            Rule(f"{s}elbow", R, (p + "elb_lat", p + "elb_med"), _mean(p + "elb_lat", p + "elb_med")),
            Rule(f"{s}elbow", R, (p + "elb_lat",), _mean(p + "elb_lat")),
            Rule(f"{s}wrist", R, (p + "wra", p + "wrb"), _mean(p + "wra", p + "wrb")),
            Rule(f"{s}fingers", R, (p + "fin",), _mean(p + "fin")),
            Rule(f"{s}fingers", R, (p + "mcp2", p + "mcp5"), _mean(p + "mcp2", p + "mcp5")),
        ]
    return rules


def _by_joint(rules):
    out = {j: [] for j in JOINT_NAMES}
    for r in rules:
        out[r.joint].append(r)
    return out


_TOOLBOX = _by_joint(_toolbox_rules())
_ROLES = _by_joint(_role_rules())
_FALLBACK = _by_joint(_toolbox_finger_fallbacks())


def candidate_rules(joint: str) -> list:
    """The automatic rules for a joint, in order of preference (toolbox, roles, toolbox fallbacks)."""
    return _TOOLBOX[joint] + _ROLES[joint] + _FALLBACK[joint]


def mapped_rule(joint: str, names) -> Rule:
    """The marker-map rule: the joint is the mean of the named markers."""
    names = (names,) if isinstance(names, str) else tuple(names)
    return Rule(joint, MAPPED, names, _mean(*names))
