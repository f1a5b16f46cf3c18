"""C3D marker labels → anatomical landmarks, one normalisation for every vendor's names.

A marker set names the same bony landmark in many ways: ``LASI`` (Vicon
Plug-in Gait), ``L_IAS`` (ISB), ``L.ASIS`` (Motion Analysis Cortex),
``LASIS`` (Qualisys), ``Nick01:LFWT`` (a Vicon subject's front waist). A
label is read in three steps (:func:`landmark_of`):

1. **Normalise**: drop the subject prefix (up to the last ``:``), split into
   words at blanks, ``_``, ``-``, ``.`` and CamelCase (``LHeadTamp`` → L Head
   Tamp, ``WaistLFront`` → Waist L Front), upper case; words with the same
   meaning become one (Lateral/Out/Outer → LAT, Medial/In/Inner → MED,
   Anterior/Front → FRONT, Posterior/Rear/Back → BACK, Acromium → ACROMION, …).
2. **Side**: a word L/R/LEFT/RIGHT anywhere (``R.Knee``, ``Knee_L``,
   ``WaistLFront``), else a leading L/R glued to a known abbreviation
   (``LASI``, ``RKNE``).
3. **Landmark**: the remaining words, compared as a compact string
   (``ASI``, ``KNI``, ``IWR``, ``FM5``) or as a set of words (``KNEE LAT`` =
   ``LatKnee``), against :data:`LANDMARKS`.
4. **Virtual points**: a label that reads as none of them but does after a
   leading ``V`` (Vicon Clinical Manager's virtual points: ``VSAC`` the
   sacrum, ``VRHI``, ``VLKN``, ``VRAN`` the right hip, left knee and right
   ankle joint centres) is that point; a virtual hip, knee, ankle,
   shoulder, elbow or wrist is the joint centre (``r_hip_jc``, …), as are
   labels that say so (``R_HJC``, ``LKJC``, ``R.Hip.JC``).

Each landmark belongs to a rigid segment (:data:`SEGMENT_OF`: pelvis,
thorax, head, thigh, shank, foot, upper arm, forearm, hand); a marker lost
for longer than the gap limit is rebuilt from the other markers of its
segment (:mod:`~mocapdb.readers.gaps`; READERS.md §3.1, §3.3).

References
----------
G. Wu et al.: ISB recommendation on definitions of joint coordinate systems,
J. Biomech. 35 (2002) 543–548 and 38 (2005) 981–992 (landmark names); Vicon
Plug-in Gait marker placement; Motion Analysis Helen Hayes marker set; Vicon Clinical Manager
(virtual points); the OpenSim/OpenCap marker names (``r_mknee``, ``R_wrist_radius``).
"""
from __future__ import annotations

import re

__all__ = ["LANDMARKS", "SEGMENT_OF", "landmark_of", "label_words", "TOOLBOX_ALIASES", "marker_key"]

#: the toolbox's label aliases (``mapLabelNamesToVicon.m``), matched exactly and case-insensitively
TOOLBOX_ALIASES = {"LEFT FOREHEAD": "LFHD", "LEFTFHD": "LFHD", "RIGHT FOREHEAD": "RFHD", "RIGHTFHD": "RFHD",
                   "LARM": "LFRM", "RARM": "RFRM", "RLEG": "RSHN", "LLEG": "LSHN", "R10": "RBAC"}


def marker_key(label: str) -> str:
    """A label as the toolbox rules compare it: prefix to the first ``:`` removed, trimmed, upper case, aliases.

    ``"Daniel:LFHD"`` → ``"LFHD"``, ``"A:B:LFHD"`` → ``"B:LFHD"`` (the toolbox's
    exact matching), ``"left forehead"`` → ``"LFHD"``.
    """
    key = label.split(":", 1)[1] if ":" in label else label
    key = key.strip().upper()
    return TOOLBOX_ALIASES.get(key, key)


_SIDES = {"L": "l", "LEFT": "l", "LT": "l", "LFT": "l", "R": "r", "RIGHT": "r", "RT": "r", "RGT": "r"}

#: words of the same meaning → one word
_SYNONYMS = {
    "LATERAL": "LAT", "OUTER": "LAT", "OUT": "LAT", "OUTSIDE": "LAT", "EXTERNAL": "LAT", "EXT": "LAT",
    "MEDIAL": "MED", "INNER": "MED", "IN": "MED", "INSIDE": "MED", "INTERNAL": "MED",
    "ANTERIOR": "FRONT", "ANT": "FRONT", "FRT": "FRONT", "FWD": "FRONT", "FORWARD": "FRONT",
    "POSTERIOR": "BACK", "POST": "BACK", "REAR": "BACK", "BK": "BACK",
    "SUPERIOR": "UPPER", "SUP": "UPPER", "UP": "UPPER", "PROXIMAL": "UPPER",
    "INFERIOR": "LOWER", "INF": "LOWER", "LOW": "LOWER", "DISTAL": "LOWER",
    "MIDDLE": "MID", "CENTER": "MID", "CENTRE": "MID",
    "ACROMIUM": "ACROMION", "ACROMIAL": "ACROMION", "ACR": "ACROMION",
    "TEMPLE": "TAMP", "TEMPORAL": "TAMP", "TEMP": "TAMP",
    "MALLEOLUS": "MALL", "MALLEOLI": "MALL", "MAL": "MALL",
    "EPICONDYLE": "EPI", "CONDYLE": "EPI", "STYLOID": "STY", "STYL": "STY",
    "SHOULDERS": "SHOULDER", "SHO": "SHOULDER", "SHLD": "SHOULDER",
    "ELB": "ELBOW", "WRI": "WRIST", "WRT": "WRIST", "ANK": "ANKLE", "KNE": "KNEE",
    "HEELS": "HEEL", "TOES": "TOE", "FINGERS": "FINGER", "FIN": "FINGER",
    "HD": "HEAD", "FOREHEAD": "FOREHEAD",
}

#: landmark → aliases; an alias with a blank is a set of words (any order), one without a
#: blank a compact string. ``l_``/``r_`` landmarks are looked up without the side.
_SIDED = {
    # pelvis
    # SIAS/SIPS (Italian, German: spina iliaca), EIAS/EIPS (French, Spanish: épine/espina iliaque)
    "asis": ("ASI", "ASIS", "IAS", "FWT", "SIAS", "EIAS", "WAIST FRONT", "PELVIS FRONT", "ILIAC FRONT",
             "ILIUM FRONT", "SPINE ILIAC FRONT", "ASIS FRONT", "ILIAC FRONT UPPER", "SPINE ILIAC FRONT UPPER",
             "ILIAC SPINE FRONT"),
    "psis": ("PSI", "PSIS", "IPS", "BWT", "SIPS", "EIPS", "WAIST BACK", "PELVIS BACK", "ILIAC BACK",
             "ILIUM BACK", "SPINE ILIAC BACK", "PSIS BACK", "ILIAC BACK UPPER", "SPINE ILIAC BACK UPPER",
             "ILIAC SPINE BACK"),
    "waist_mid": ("MWT", "WAIST MID", "WAIST LAT", "ICT", "ILIAC CREST", "CREST", "WAIST", "PELVIS LAT"),
    # leg
    "trochanter": ("FTC", "TROC", "GTR", "TROCHANTER", "GREATER TROCHANTER", "HIP", "HIP LAT"),
    "thigh": ("THI", "THIGH", "THIGH1", "THIGH2", "THIGH3", "UPPERLEG", "UPPER LEG", "FEMUR", "THIGH FRONT",
              "THIGH LAT", "THIGH UPPER", "THIGH LOWER"),
    # LKNEE/MKNEE: a side word apart (OpenSim's r_lknee, r_mknee)
    "knee_lat": ("KNE", "KNEE", "FLE", "LFE", "KNEL", "KNEE1", "LATKNEE", "LKNEE", "KNEE LAT", "KNEE EPI LAT",
                 "FEMUR EPI LAT", "EPI LAT"),
    "knee_med": ("KNM", "KNI", "MKNE", "MKNEE", "FME", "MFE", "KNEM", "KNEE2", "MEDKNEE", "KNEEMED", "KNEE MED",
                 "KNEE EPI MED", "FEMUR EPI MED", "EPI MED"),
    "shank": ("SHN", "TIB", "SHANK", "SHIN", "TIBIA", "LOWERLEG", "LOWER LEG", "SHANK MID", "SHANK LOWER",
              "SHANK UPPER", "MIDSHANK", "DISTALSHANK", "TTC", "TIBTUBERCLE", "TIB TUBERCLE", "TUBEROSITY",
              "FAX", "FIBULA", "FIBULA HEAD", "CALF"),
    "ankle_lat": ("ANK", "ANKLE", "FAL", "LMAL", "LATMALL", "ANKL", "LANKLE", "MALL", "ANKLE LAT", "MALL LAT",
                  "FIBULA MALL"),
    "ankle_med": ("MED", "MMAL", "TAM", "MEDMALL", "ANKM", "ANKI", "MANKLE", "ANKLE MED", "MALL MED",
                  "TIBIA MALL"),
    "heel": ("HEE", "HEEL", "HEL", "FCC", "CAL", "CALC", "CALCANEUS", "HEEL BACK", "HEEL LOWER", "HEEL UPPER"),
    # TO: Vicon Clinical Manager's toe (R.TO); 2META/5META: OpenSim's metatarsal heads (r_5meta)
    "toe": ("TOE", "TO", "FM2", "MT2", "MET2", "2META", "META2", "TOETIP", "TOE TIP", "FOREFOOT2", "BIGTOE",
            "TOE BIG", "TOE FRONT"),
    "mt1": ("FM1", "MT1", "MET1", "MH1", "1META", "META1", "FOREFOOT1", "TOE MED", "FOOT MED"),
    "mt5": ("MT5", "FM5", "MET5", "MH5", "5META", "META5", "MET", "FOREFOOT5", "LATERALFOOT", "FOOT LAT",
            "TOE LAT"),
    "foot": ("FOOT", "POSTERIORFOOT", "FOOT BACK", "MIDFOOT", "FOOT MID", "NAV", "FOOT UPPER", "INSTEP"),
    # arm
    "acromion": ("SHOULDER", "SHOU", "SHOULD", "SAJ", "SAE", "ACROMION", "SHOULDER TOP", "SHOULDER UPPER",
                 "ACROMION LAT"),
    "shoulder_front": ("FSH", "SHOULDER FRONT"),
    "shoulder_back": ("BSH", "SHOULDER BACK", "SAA", "ACROMION BACK"),
    "upper_arm": ("UPA", "UPA1", "UPA2", "ARM", "UPPERARM", "UPPER ARM", "HUMERUS", "BICEP", "BICEPS",
                  "ARM UPPER", "TRICEP", "TRICEPS"),
    "elbow_lat": ("ELBOW", "HLE", "LEL", "ELBL", "LATELB", "LELBOW", "ELBOW LAT", "HUMERUS EPI LAT",
                  "ELBOW EPI LAT"),
    "elbow_med": ("HME", "MEL", "MELB", "IEL", "ELBM", "MEDELB", "MELBOW", "ELBOW MED", "HUMERUS EPI MED",
                  "ELBOW EPI MED"),
    "forearm": ("FRM", "FOREARM", "FORE ARM", "LOWERARM", "LOWER ARM", "ARM LOWER", "WRE", "UOA", "OLECRANON",
                "OLEC", "ULNA", "RADIUS"),
    # in the anatomical position the radius is lateral: OpenSim's r_lwrist / R_wrist_radius
    "wrist_rad": ("WRA", "RSP", "WRR", "RADSTY", "OWR", "LWRIST", "WRIST LAT", "RADIUS STY", "STY RADIUS",
                  "WRIST THUMB", "WRIST RADIUS", "WRIST RADIAL", "RADIAL STY"),
    "wrist_uln": ("WRB", "UHE", "USP", "WRU", "ULNSTY", "IWR", "MWRIST", "WRIST MED", "ULNA STY", "STY ULNA",
                  "WRIST PINKY", "WRIST ULNA", "WRIST ULNAR", "ULNAR STY"),
    "wrist": ("WRIST", "WRIST MID", "WRIST BACK", "WRIST FRONT", "WRIST UPPER"),
    "finger": ("FINGER", "FING", "FINGERTIP", "FINGER TIP", "FINGER MID", "FINGER2", "FINGER3"),
    "mcp2": ("HM2", "MCP2", "MH2", "MC2", "INDEX", "HAND MED", "IHAND", "HAND INDEX", "HAND THUMB"),
    "mcp5": ("HM5", "MCP5", "MH5", "MC5", "HAND LAT", "OHAND", "HAND PINKY", "HAND LITTLE"),
    "hand": ("HAND", "PALM", "PALA1", "PAL", "HAND BACK", "HAND UPPER", "HAND FRONT", "HAND MID", "KNUCKLE"),
    # head
    "head_front": ("FHD", "HDF", "FH", "FRONTHEAD", "HEAD FRONT", "FOREHEAD", "HEAD TAMP", "TAMP",
                   "HEAD FOREHEAD"),
    "head_back": ("BHD", "HDB", "BH", "BACKHEAD", "HEAD BACK"),
    "head_side": ("HEAD", "HEAD LAT", "EAR"),
    # joint centres a lab's software computed and wrote as points (Plug-in Gait, OpenSim, Vicon
    # Clinical Manager's virtual points: see _VIRTUAL_JOINTS)
    "hip_jc": ("HJC", "HIPJC", "HIP JC"),
    "knee_jc": ("KJC", "KNEEJC", "KNEE JC"),
    "ankle_jc": ("AJC", "ANKLEJC", "ANKLE JC"),
    "shoulder_jc": ("SJC", "GHJC", "SHOULDERJC", "SHOULDER JC", "GH JC"),
    "elbow_jc": ("EJC", "ELBOWJC", "ELBOW JC"),
    "wrist_jc": ("WJC", "WRISTJC", "WRIST JC"),
}

#: what a virtual (``V``-prefixed) hip, knee, … is: the joint centre (``VRHI``, ``VLKN``, ``VRAN``)
_VIRTUAL_JOINTS = {"HI": "hip_jc", "HIP": "hip_jc", "KN": "knee_jc", "KNE": "knee_jc", "KNEE": "knee_jc",
                   "AN": "ankle_jc", "ANK": "ankle_jc", "ANKLE": "ankle_jc", "SH": "shoulder_jc",
                   "SHO": "shoulder_jc", "SHOULDER": "shoulder_jc", "EL": "elbow_jc", "ELB": "elbow_jc",
                   "ELBOW": "elbow_jc", "WR": "wrist_jc", "WRI": "wrist_jc", "WRIST": "wrist_jc"}

_CENTRAL = {
    "c7": ("C7", "CV7", "VC7", "C07", "SPINETOP", "SPINE TOP", "NECK BACK", "C7 SPINE"),
    "t10": ("T10", "TV10", "TH10", "T8", "TV8", "TH8", "T9", "TV9", "TH9", "T12", "TV12", "TH12", "SPINE MID"),
    "clav": ("CLAV", "SJN", "SNJ", "IJ", "JN", "JUGULAR", "STERNUM UPPER", "STERNUM TOP", "MANUBRIUM",
             "CLAVICLE", "NECK FRONT", "SUPRASTERNAL"),
    "strn": ("STRN", "SXS", "PX", "XP", "XIPH", "XIPHOID", "STERNUM", "STERNUM LOWER", "CHEST", "CHEST FRONT"),
    "back": ("BAC", "BACK", "RBAC", "BACK UPPER", "BACK MID", "SCAP", "SCAPULA", "THORAX BACK", "SPINE"),
    "sacr": ("SACR", "SAC", "SACRUM", "SACRAL", "VSACRAL", "V SACRAL", "SACRUM MID", "PELVIS BACK", "WAIST BACK",
             "PSIS MID", "MIDPSIS"),
    "head_top": ("ARIEL", "HEADTOP", "HEAD TOP", "TOP HEAD", "TOPHEAD", "VERTEX", "HEAD UPPER", "HEAD MID"),
    "head_front": ("HEAD FRONT", "FRONTHEAD", "FOREHEAD", "FHD", "HEAD FOREHEAD"),
    "head_back": ("HEAD BACK", "BACKHEAD", "BHD", "OCCIPUT"),
}

#: every landmark a label can name: ``l_asis``, ``r_asis``, …, ``c7``, ``head_top``, …
LANDMARKS = tuple(f"{s}_{k}" for k in _SIDED for s in "lr") + tuple(f"c_{k}" if k in _SIDED else k
                                                                   for k in _CENTRAL)

_SEGMENTS = {
    "pelvis": ("asis", "psis", "waist_mid", "sacr", "hip_jc"),
    "thorax": ("c7", "t10", "clav", "strn", "back"),
    "head": ("head_front", "head_back", "head_side", "head_top"),
    "thigh": ("trochanter", "thigh", "knee_lat", "knee_med", "knee_jc"),
    "shank": ("shank", "ankle_lat", "ankle_med", "ankle_jc"),
    "foot": ("heel", "toe", "mt1", "mt5", "foot"),
    "upper_arm": ("upper_arm", "elbow_lat", "elbow_med", "elbow_jc"),
    "forearm": ("forearm", "wrist_rad", "wrist_uln", "wrist", "wrist_jc"),
    "hand": ("finger", "mcp2", "mcp5", "hand"),
}
_CENTRAL_SEGMENTS = {"pelvis", "thorax", "head"}


def _segment(landmark: str) -> str | None:
    side, _, base = landmark.partition("_") if landmark[:2] in ("l_", "r_", "c_") else ("", "", landmark)
    for seg, members in _SEGMENTS.items():
        if base in members:
            return seg if (seg in _CENTRAL_SEGMENTS or side not in "lr" or not side) else f"{side}_{seg}"
    return None


#: landmark → the rigid segment it moves with (``l_thigh``, ``pelvis``, …); None for the
#: shoulder landmarks (they sit on the scapula, which slides on the thorax)
SEGMENT_OF = {lm: _segment(lm) for lm in LANDMARKS}


def _aliases(table):
    compact, phrases = {}, {}
    for landmark, aliases in table.items():
        for a in aliases:
            if " " in a:
                phrases.setdefault(frozenset(_SYNONYMS.get(w, w) for w in a.split()), landmark)
            else:
                compact.setdefault(a, landmark)
    return compact, phrases


_SIDED_COMPACT, _SIDED_PHRASES = _aliases(_SIDED)
_CENTRAL_COMPACT, _CENTRAL_PHRASES = _aliases(_CENTRAL)

_SPLIT = re.compile(r"[^A-Za-z0-9#*?]+")
_CAMEL_LOWER_UPPER = re.compile(r"([a-z0-9])([A-Z])")
_CAMEL_ACRONYM = re.compile(r"([A-Z]+)([A-Z][a-z])")


def label_words(label: str) -> list:
    """The words of a label: subject prefix dropped, split at separators and CamelCase, upper case.

    ``"Nick01:LFSH"`` → ``["LFSH"]``, ``"R.Shoulder"`` → ``["R", "SHOULDER"]``,
    ``"LHeadTamp"`` → ``["L", "HEAD", "TAMP"]``, ``"WaistLFront"`` → ``["WAIST", "L", "FRONT"]``.
    """
    base = label.rsplit(":", 1)[-1]
    base = _CAMEL_LOWER_UPPER.sub(r"\1 \2", base)
    base = _CAMEL_ACRONYM.sub(r"\1 \2", base)
    return [w.upper() for w in _SPLIT.split(base) if w]


def _lookup(words, compact_table, phrase_table):
    if not words:
        return None
    same = [_SYNONYMS.get(w, w) for w in words]
    return (compact_table.get("".join(words)) or compact_table.get("".join(same))
            or phrase_table.get(frozenset(same)))


def landmark_of(label: str) -> str | None:
    """The anatomical landmark a marker label names (``"l_asis"``, ``"c7"``, ``"r_knee_jc"``, …), or None.

    See the module docstring for the rules. Central landmarks of a sided name
    (``c_head_front``) are the unsided forms of head markers.
    """
    words = label_words(label)
    found = _landmark(words)
    if found is not None or not words:
        return found
    # a virtual point (Vicon Clinical Manager): V, then a label (VSAC, V.RHip, VRHI, VLKN)
    if words[0] in ("V", "VIRT", "VIRTUAL") and len(words) > 1:
        rest = words[1:]
    elif words[0].startswith("V") and len(words[0]) > 2:
        rest = [words[0][1:]] + words[1:]
    else:
        return None
    return _joint_centre(rest) or _landmark(rest)


def _joint_centre(words):
    """``r_knee_jc`` for the words of a virtual right knee (``RKN``, ``R KNEE``), else None."""
    sides = [i for i, w in enumerate(words) if w in _SIDES]
    if len(sides) == 1 and len(words) == 2:
        side, base = _SIDES[words[sides[0]]], words[1 - sides[0]]
    elif len(words) == 1:
        for prefix, side in (("L", "l"), ("R", "r")):
            if words[0].startswith(prefix):
                base = words[0][len(prefix):]
                break
        else:
            return None
    else:
        return None
    joint = _VIRTUAL_JOINTS.get(base)
    return f"{side}_{joint}" if joint else None


def _landmark(words):
    if not words:
        return None
    sides = [i for i, w in enumerate(words) if w in _SIDES]
    if len(sides) == 1 and len(words) > 1:
        side = _SIDES[words[sides[0]]]
        rest = words[:sides[0]] + words[sides[0] + 1:]
        hit = _lookup(rest, _SIDED_COMPACT, _SIDED_PHRASES)
        return f"{side}_{hit}" if hit else None
    central = _lookup(words, _CENTRAL_COMPACT, _CENTRAL_PHRASES)
    if central is not None:
        return f"c_{central}" if central in _SIDED else central
    first = words[0]
    for prefix, side in (("LEFT", "l"), ("RIGHT", "r"), ("L", "l"), ("R", "r")):
        if first.startswith(prefix) and len(first) > len(prefix):
            rest = [first[len(prefix):]] + words[1:]
            hit = _lookup(rest, _SIDED_COMPACT, _SIDED_PHRASES)
            if hit is not None:
                return f"{side}_{hit}"
    return None
