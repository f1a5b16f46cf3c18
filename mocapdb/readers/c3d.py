"""C3D marker files → the 24 canonical joints.

:func:`read_c3d` reads the points (:mod:`~mocapdb.readers.c3dfile`, ezc3d),
reads every label as an anatomical landmark (:mod:`~mocapdb.readers.c3d_names`),
picks for every canonical joint the first rule whose markers the file has
(:mod:`~mocapdb.readers.c3d_rules`: the toolbox's HDM05/CMU Vicon set, then
anatomical landmarks, then joints derived from the trunk, or a user marker
map), mends gaps, turns the axes so that Y is up and computes the joints:

1. **Gaps** (:mod:`~mocapdb.readers.gaps`). A sample is missing where its
   residual is negative, it is NaN or it is exactly (0, 0, 0). A marker lost
   for longer than :data:`MAX_GAP_S` (0.25 s) is first rebuilt from three or
   more markers of its rigid segment (LASI from RASI, LPSI and RPSI); a pelvis
   landmark missing from the whole take is mirrored from the other three.
   Remaining gaps up to 0.25 s in a marker a joint uses are filled by
   linear interpolation over time (held at the ends of the take). A joint
   whose every rule meets a longer gap makes those frames unrecoverable:
   the motion is the longest stretch without them, and the reader notes
   what was cut (the take is refused when little is left).
2. **Axes.** The vertical is ``POINT:Y_SCREEN``'s axis (C3D's default ``Z``
   when absent) unless the body's foot-to-head direction never lies along
   it, then the axis it lies along most often; its sign is where the head
   is above the feet in most frames. The lab frame is then rotated (a
   signed cyclic permutation of the axes, determinant +1: left stays left)
   so that this axis becomes +Y. For the usual Z-up file this is the
   toolbox's ``x = Y_c3d, y = Z_c3d, z = X_c3d``; where the toolbox
   would mirror (its ``(c[a3], c[a2], c[a1])`` for a Y-up file), we rotate.
3. **Units.** Joints of the toolbox marker set are in the toolbox's unit,
   mm × ``-POINT:SCALE`` of a float file (cm for HDM05, 2-cm units for CMU
   85_xx), as the oracle; every other file is converted by ``POINT:UNITS``
   (mm, cm, m) to cm. Features do not depend on the unit.
4. **Bone-length fit.** When all 24 joints come from the toolbox set (and no
   marker map is given), the toolbox's ``skelfitATS`` makes every bone
   length constant (:func:`fit_bone_lengths`); anatomical-landmark
   and mapped joints are used as placed.

A motion from C3D has no root rotation: feature #40 uses the hip axis
(``Motion.root_rotation`` is None). The joints stay at the file's rate.
``Motion.meta["notes"]`` says what the reader had to decide (derived joints,
rebuilt markers, cut frames) for the ingest summary.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from mocapdb.errors import ParameterError, ParseError
from mocapdb.readers.c3d_names import SEGMENT_OF
from mocapdb.readers.c3d_rules import (MAPPED, MARKER_RULES, PELVIS_QUAD, REQUIRED, TOOLBOX, MarkerIndex,
                                       candidate_rules, mapped_rule, usable_points)
from mocapdb.readers.c3dfile import printable, read_c3d_points
from mocapdb.readers.gaps import (MAX_GAP_S, fill_short, frames_text, long_gaps, longest_part, max_gap_frames,
                                  rigid_fill)
from mocapdb.bodies.joints import JOINT_INDEX, JOINT_NAMES
from mocapdb.bodies.motion import Motion, check_finite_motion
from mocapdb.readers.sources import motion_stem

log = logging.getLogger("mocapdb")

__all__ = ["read_c3d", "fit_bone_lengths", "SKELETON_EDGES", "MAX_GAP_S", "UNITS_MM", "vertical_axis"]

#: POINT:UNITS → millimetres per unit
UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0}
#: coordinates beyond this many millimetres (1000 km) are absurd: read as missing samples (READERS.md §3.3)
MAX_ABS_MM = 1e9

#: the toolbox's skeleton tree for the bone-length fit, parents before children
#: (``LCS/buildSkelTree.m``; FEATURES.md §2.4.6)
SKELETON_EDGES = (
    ("root", "lhip"), ("lhip", "lknee"), ("lknee", "lankle"), ("lankle", "ltoes"),
    ("root", "rhip"), ("rhip", "rknee"), ("rknee", "rankle"), ("rankle", "rtoes"),
    ("root", "belly"), ("belly", "chest"), ("chest", "neck"),
    ("neck", "lclavicle"), ("lclavicle", "lshoulder"), ("lshoulder", "lelbow"), ("lelbow", "lwrist"),
    ("lwrist", "lfingers"),
    ("neck", "rclavicle"), ("rclavicle", "rshoulder"), ("rshoulder", "relbow"), ("relbow", "rwrist"),
    ("rwrist", "rfingers"),
    ("neck", "head"), ("head", "headtop"),
)

_TOP = ("head", "headtop", "neck")
#: the top of a body whose head and neck are derived from the trunk (no markers of their own)
_TOP_DERIVED = ("lshoulder", "rshoulder")
_BOTTOM = ("lankle", "rankle", "ltoes", "rtoes")


def fit_bone_lengths(joints: np.ndarray) -> np.ndarray:
    """The toolbox's bone-length fit ``skelfitATS``: every bone gets its mean length, in every frame.

    For each edge (p, c) of :data:`SKELETON_EDGES`, parents first:
    ``d = c_orig − p_fit``, ``L = mean_t |d|``, ``c_fit = p_fit + L·d/|d|``;
    the root stays. Where ``|d| = 0`` the toolbox divides 0 by 0; here the
    child then sits on its parent in that frame (a zero-length bone, READERS.md §4).

    Parameters
    ----------
    joints : ndarray, shape (n_frames, 24, 3)
        In :data:`~mocapdb.bodies.joints.JOINT_NAMES` order.

    Returns
    -------
    ndarray, shape (n_frames, 24, 3)

    References
    ----------
    FEATURES.md §2.4.6; E. de Aguiar, C. Theobalt, H.-P. Seidel: Automatic
    learning of articulated skeletons from 3D marker trajectories, ISVC 2006.
    """
    out = joints.copy()
    for parent, child in SKELETON_EDGES:
        p, c = JOINT_INDEX[parent], JOINT_INDEX[child]
        d = joints[:, c] - out[:, p]
        n = np.sqrt(np.sum(d * d, axis=1))
        length = np.mean(n)
        step = np.divide(d, n[:, None], out=np.zeros_like(d), where=n[:, None] > 0)
        out[:, c] = out[:, p] + length * step
    return out


def vertical_axis(top: np.ndarray, bottom: np.ndarray, declared: str = "") -> tuple[int, int]:
    """The lab axis that points up: ``(axis 0/1/2, sign ±1)``.

    Parameters
    ----------
    top, bottom : ndarray, shape (n_frames, 3)
        Mean position of head-level and foot-level markers in the file's axes.
    declared : str
        ``POINT:Y_SCREEN`` (``"+Z"``, ``"-Y"``, …); its letter is the vertical
        unless the foot-to-head direction is dominant along it in fewer than
        10 % of the frames (then the axis where it is dominant most often).
        Its sign is not trusted (ezc3d's Qualisys sample says ``-Z`` with Z up):
        the sign is the one of the head-over-feet direction in most frames.
    """
    v = top - bottom
    ok = np.isfinite(v).all(axis=1) & (np.abs(v).sum(axis=1) > 0)
    v = v[ok]
    letter = declared.strip().lstrip("+-").upper()
    axis = "XYZ".index(letter) if letter in ("X", "Y", "Z") else 2
    if len(v):
        dominant = np.argmax(np.abs(v), axis=1)
        counts = np.bincount(dominant, minlength=3)
        if counts[axis] < 0.1 * len(v):
            axis = int(np.argmax(counts))
        along = v[dominant == axis, axis]
        sign = -1 if np.count_nonzero(along < 0) > np.count_nonzero(along > 0) else 1
    else:
        sign = 1
    return axis, sign


def _to_y_up(xyz: np.ndarray, axis: int, sign: int, factor: float) -> np.ndarray:
    """Scale and rotate lab coordinates so that ``sign``·``axis`` becomes +Y (a proper rotation).

    Cyclic: output (x, y, z) = (c[a+2], c[a], c[a+1]) (indices mod 3), which for
    a = Z is the toolbox's (Y, Z, X); a downward axis additionally turns 180°
    about X (y and z negated). Scaling comes first, as in the toolbox's ``convert``.
    """
    s = factor * xyz
    out = np.empty_like(s)
    out[..., 0] = s[..., (axis + 2) % 3]
    out[..., 1] = s[..., axis]
    out[..., 2] = s[..., (axis + 1) % 3]
    if sign < 0:
        out[..., 1:] *= -1
    return out


#: markers an error lists at most: enough to write a marker map from, short enough to read
SHOWN_MARKERS = 12

#: what each kind of required joint needs, said when one or two kinds cannot be placed
_NEEDS = {"root": "the pelvis needs both ASIS with the PSIS, a sacrum or lateral waist markers",
          "hip": "the pelvis needs both ASIS with the PSIS, a sacrum or lateral waist markers",
          "knee": "knees need a femoral epicondyle marker", "ankle": "ankles need a malleolus or heel marker",
          "toes": "toes need a toe or metatarsal marker",
          "shoulder": "shoulders need an acromion or front and back shoulder markers",
          "elbow": "elbows need a humeral epicondyle marker", "wrist": "wrists need a styloid or wrist marker"}


def _describe(index: MarkerIndex, limit=SHOWN_MARKERS):
    """At most ``limit`` of the file's markers: those read as no landmark first (what a marker map
    would name), then the others, in file order."""
    labels, unnamed = index.file_labels, index.unnamed
    order = unnamed + [i for i in range(len(labels)) if i not in set(unnamed)]
    shown = ", ".join(printable(labels[i]) for i in order[:limit])
    if len(labels) <= limit:
        return shown
    return shown + f", … ({limit} of {len(labels)}" + (
        f"; the {len(unnamed)} naming no landmark first)" if 0 < len(unnamed) < len(labels) else ")")


def _find(index: MarkerIndex, rule):
    """``[(name, point)]`` of a rule's markers in the file (``any_of`` ones that exist), or None."""
    points = [index.find(n, rule.source) for n in rule.markers]
    if None in points:
        return None
    extra = [(n, index.find(n, rule.source)) for n in rule.any_of]
    extra = [(n, i) for n, i in extra if i is not None]
    if rule.any_of and not extra:
        return None
    return list(zip(rule.markers, points)) + extra


def _select(path, index: MarkerIndex, valid, max_gap, marker_map, marker_rules="toolbox") -> dict:
    """The rule and markers of every joint, in an order where a joint follows the joints it derives from.

    Per joint, the first rule (in :func:`~mocapdb.readers.c3d_rules.candidate_rules`
    order) whose markers the file has and have no gap longer than ``max_gap``;
    a rule whose joints are not placed yet waits for them; without a gap-free
    rule, the first usable one (its long gaps are cut later).

    Returns
    -------
    dict
        ``{joint: (rule, [(marker name, point)])}``.

    Raises
    ------
    ParseError
        A joint no rule can place (names every such joint and the file's markers).
    """
    gappy_cache = {}

    def gappy(i):
        if i not in gappy_cache:
            gappy_cache[i] = bool(long_gaps(valid[:, i], max_gap))
        return gappy_cache[i]

    candidates = {}
    for joint in JOINT_NAMES:
        if marker_map and joint in marker_map:
            rule = mapped_rule(joint, marker_map[joint])
            absent = [n for n in rule.markers if index.find(n, MAPPED) is None]
            if absent:
                raise ParseError(path, None, f"marker_map: {joint} = {marker_map[joint]!r}, but the file has no "
                                 f"usable marker {', '.join(map(repr, absent))} (its markers: "
                                 f"{_describe(index)})")
            candidates[joint] = [rule]
        else:
            candidates[joint] = candidate_rules(joint, marker_rules)

    chosen, dead, with_gaps = {}, set(), set()

    def decide(joint):
        fallback = None
        for rule in candidates[joint]:
            found = _find(index, rule)
            if found is None:
                continue
            if any(j not in chosen for j in rule.joints):
                if all(j in chosen or j in dead for j in rule.joints) and any(j in dead for j in rule.joints):
                    continue
                return "wait"
            if not any(gappy(i) for _, i in found) and not with_gaps.intersection(rule.joints):
                return rule, found
            fallback = fallback or (rule, found)
        if fallback is not None:
            with_gaps.add(joint)
        return fallback

    pending = list(JOINT_NAMES)
    while pending:
        progress = False
        for joint in list(pending):
            got = decide(joint)
            if got == "wait":
                continue
            pending.remove(joint)
            progress = True
            if got is None:
                dead.add(joint)
            else:
                chosen[joint] = got
                dead.discard(joint)
        if not progress:
            if dead.issuperset(pending):
                dead.update(pending)
                break
            dead.update(pending)   # what they wait for can no longer be placed: try their other rules
    unplaced = [j for j in JOINT_NAMES if j not in chosen]
    if unplaced:
        required = [j for j in unplaced if j in REQUIRED]
        what = (f"{len(required)} of the {len(REQUIRED)} joints a marker set must place: pelvis, hips, knees, "
                "ankles, toes, shoulders, elbows and wrists") if required else f"{len(unplaced)} of the 24 joints"
        # what the missing ones need, when a near miss (a set without wrist markers), not a set of other names
        needs = list(dict.fromkeys(_NEEDS[j if j == "root" else j[1:]] for j in required))
        needs = needs if len(needs) <= 2 else []
        raise ParseError(path, None, f"no full-body marker set: cannot place {', '.join(required or unplaced)} "
                         f"({what}{'; ' + ', '.join(needs) if needs else ''}) from the markers {_describe(index)}; "
                         "name them in a marker map (marker_map= / --marker-map FILE, see docs/READING_FILES.md)")
    return chosen


def _mirror_pelvis(index: MarkerIndex, xyz, valid, notes):
    """A pelvis landmark of :data:`PELVIS_QUAD` missing from the whole take, mirrored from the other three.

    The mirror plane is the pelvis's sagittal plane: through the midpoint of
    the complete pair, perpendicular to it. Returns the arrays with the
    mirrored point appended (or as given).
    """
    have = index.landmarks()
    missing = [lm for lm in PELVIS_QUAD if lm not in have]
    if len(missing) != 1:
        return xyz, valid
    lost = missing[0]
    side, kind = lost.split("_", 1)
    other = "r" if side == "l" else "l"
    twin = have[f"{other}_{kind}"]
    pair = (have["l_psis"], have["r_psis"]) if kind == "asis" else (have["l_asis"], have["r_asis"])
    mid = (xyz[:, pair[0]] + xyz[:, pair[1]]) / 2
    normal = xyz[:, pair[1]] - xyz[:, pair[0]]
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    p = xyz[:, twin]
    mirrored = p - 2.0 * np.sum((p - mid) * normal, axis=1, keepdims=True) * normal
    ok = valid[:, twin] & valid[:, pair[0]] & valid[:, pair[1]]
    mirrored[~ok] = np.nan
    label = f"{lost} mirrored from {printable(index.labels[twin])}"
    index.add(lost, label)
    notes.append(f"{label} (the pelvis has no such marker)")
    return np.concatenate([xyz, mirrored[:, None]], axis=1), np.concatenate([valid, ok[:, None]], axis=1)


def _rebuild(index: MarkerIndex, xyz, valid, max_gap, rate, notes, n_real):
    """Rebuild every landmark lost for longer than ``max_gap`` from its rigid segment (in place)."""
    landmarks = {lm: i for lm, i in index.landmarks().items() if i < n_real}
    segment = {i: SEGMENT_OF.get(lm) for lm, i in landmarks.items()}
    for lm, i in landmarks.items():
        if segment[i] is None:
            continue
        gaps = long_gaps(valid[:, i], max_gap)
        if not gaps:
            continue
        donors = [d for d in landmarks.values() if d != i and segment[d] == segment[i]]
        frames, used = 0, set()
        for gap in gaps:
            k, by = rigid_fill(xyz, valid, i, donors, gap)
            frames += k
            used.update(by)
        if frames:
            names = ", ".join(printable(index.labels[d]) for d in sorted(used))
            total = sum(b - a for a, b in gaps)
            notes.append(f"rebuilt {printable(index.labels[i])} in {frames} of the {total} frames it is missing "
                         f"for longer than {MAX_GAP_S} s, from {names} (its rigid segment: "
                         f"{segment[i].replace('_', ' ')})")


def read_c3d(path, *, marker_map=None, bone_fit: bool = True, marker_rules: str = "toolbox") -> Motion:
    """Read a C3D marker file into the 24 canonical joints.

    Parameters
    ----------
    path : str or Path
    marker_map : dict, optional, keyword-only
        ``{canonical joint: marker name or [names]}`` (checked by
        :func:`mocapdb.readers.load_mapping`): the joint is the mean of the
        named markers (names compared after removing the ``Subject:`` prefix,
        case-insensitively). Joints it does not name come from the automatic
        rules.
    bone_fit : bool, keyword-only
        Apply the toolbox's bone-length fit to a toolbox-marker-set file
        (default, as the toolbox); False gives its joints before the fit
        (``generateLCS`` output, the oracle's ``_prefit`` files).
    marker_rules : {"toolbox", "anatomical"}, keyword-only
        ``"toolbox"`` (default, the reference): the HDM05/CMU marker set by the
        toolbox's formulas, bit for bit. ``"anatomical"``: every set by its
        anatomical landmarks — joint centres where the toolbox puts joints on
        markers (Bell hips, elbow centres medial of the lateral epicondyle
        marker), which brings a take's C3D features closer to its AMC twin's.

    Returns
    -------
    Motion
        ``joints`` (n_frames, 24, 3), Y up, at the file's rate (``fps`` =
        ``POINT:RATE``); ``root_rotation`` None; ``skeleton`` = ``"c3d:toolbox"``
        (the HDM05/CMU Vicon set, fitted), ``"c3d:landmarks"`` or
        ``"c3d:marker_map"``; ``meta`` holds the unit, the vertical axis, the
        rule source per joint, the number of filled samples, the frames kept
        (``"frames"``: first and last, 1-based) and ``"notes"``.

    Raises
    ------
    ParseError
        Unreadable or corrupt file (:func:`~mocapdb.readers.c3dfile.read_c3d_points`),
        no 3D points, a set that cannot place the pelvis, both legs and both
        arms (names the joints), unrecoverable gaps that leave too little of
        the take (names marker and frames), unsupported ``POINT:UNITS``.
    """
    path = Path(path)
    # only the points a rule or the map can use are held (a dense marker set has thousands)
    pts = read_c3d_points(path, keep=lambda labels: usable_points(labels, marker_map))
    if not pts.meta["file_labels"]:
        raise ParseError(path, None, "no 3D points (force plates or analog channels only): cannot place "
                         "any of the 24 canonical joints")
    if pts.units not in UNITS_MM:
        raise ParseError(path, None, f"POINT:UNITS is {pts.units!r}; expected mm, cm or m")
    notes = list(pts.meta.get("notes", ()))
    xyz, valid = pts.xyz, pts.valid.copy()
    # an infinite or absurd coordinate (beyond 1000 km) is a lost sample, as a gap
    absurd = valid & (np.isinf(xyz) | (np.abs(xyz) * UNITS_MM[pts.units] > MAX_ABS_MM)).any(axis=2)
    if absurd.any():
        f, k = np.argwhere(absurd)[0]
        notes.append(f"{int(absurd.sum())} absurd marker samples (e.g. {printable(pts.labels[k])} in frame "
                     f"{f + 1}) read as missing")
        valid &= ~absurd
        xyz[absurd] = np.nan
    n, n_real = pts.n_frames, len(pts.labels)
    max_gap = max_gap_frames(pts.rate)
    index = MarkerIndex(pts.labels, valid.any(axis=0), file_labels=pts.meta["file_labels"])
    xyz, valid = _mirror_pelvis(index, xyz, valid, notes)
    _rebuild(index, xyz, valid, max_gap, pts.rate, notes, n_real)
    if marker_rules not in MARKER_RULES:
        raise ParameterError(f"marker_rules must be one of {', '.join(MARKER_RULES)}, got {marker_rules!r}")
    chosen = _select(path, index, valid, max_gap, marker_map, marker_rules)

    needed = sorted({i for _, found in chosen.values() for _, i in found})
    unrecoverable = np.zeros(n, dtype=bool)
    lost = {}   # (start, stop) -> markers missing there
    for i in needed:
        for a, b in long_gaps(valid[:, i], max_gap):
            unrecoverable[a:b] = True
            lost.setdefault((a, b), []).append(printable(index.labels[i]))
    spans = sorted(lost, key=lambda g: g[0])
    every = len({index.labels[i] for i in needed})

    def missing(g):
        return "no marker tracked" if len(lost[g]) == every else f"{', '.join(lost[g])} missing"

    why = "; ".join(f"{missing(g)} in {frames_text(*g, pts.rate)}" for g in spans[:3]) + (
        f"; {len(spans) - 3} more gaps" if len(spans) > 3 else "") + (
        f" (longer than {MAX_GAP_S} s, not rebuildable from the marker's segment)")
    start, stop, cut = longest_part(unrecoverable, pts.rate, path, why)
    if cut:
        notes.append(cut)
    filled = 0
    column = {i: k for k, i in enumerate(needed)}
    sub = np.empty((stop - start, len(needed), 3))
    for k, i in enumerate(needed):
        track, ok = xyz[start:stop, i].copy(), valid[start:stop, i]
        if not ok.any():
            raise ParseError(path, None, f"marker {printable(index.labels[i])!r} has no sample in the frames kept")
        filled += fill_short(track, ok)
        sub[:, k] = track
    if filled:
        notes.append(f"interpolated {filled} missing marker samples (gaps up to {MAX_GAP_S} s)")
    n_kept = stop - start

    def markers_of(*groups):
        for joints in groups:
            cols = [column[i] for j in joints for _, i in chosen[j][1]]
            if cols:
                return sub[:, cols].mean(axis=1)
        return np.zeros((n_kept, 3))

    axis, sign = vertical_axis(markers_of(_TOP, _TOP_DERIVED), markers_of(_BOTTOM), pts.screen[1])
    sources = {rule.source for rule, _ in chosen.values()}
    toolbox = sources == {TOOLBOX}
    # the toolbox's unit: mm × -POINT:SCALE of a float file
    per_mm = -pts.scale if (toolbox and pts.scale < 0) else 0.1
    lab = _to_y_up(sub, axis, sign, per_mm * UNITS_MM[pts.units])

    joints = np.empty((n_kept, len(JOINT_NAMES), 3))
    for joint, (rule, found) in chosen.items():   # in the order joints were chosen: derived ones last
        m = {name: lab[:, column[i]] for name, i in found}
        m.update({f"@{j}": joints[:, JOINT_INDEX[j]] for j in rule.joints})
        joints[:, JOINT_INDEX[joint]] = rule.formula(m)
    if toolbox and bone_fit:
        joints = fit_bone_lengths(joints)
    check_finite_motion(joints, path)
    for note in dict.fromkeys(rule.note for rule, _ in chosen.values() if rule.note):
        notes.append(note)
    if filled:
        log.info("%s: filled %d missing marker samples (gaps ≤ %.2f s)", path, filled, MAX_GAP_S)
    kind = "toolbox" if toolbox else ("marker_map" if MAPPED in sources else "landmarks")
    unit = f"mm × {per_mm:.9g}" if (toolbox and pts.scale < 0) else "cm"
    return Motion(joints=joints, root_rotation=None, fps=float(pts.rate), name=motion_stem(path),
                  skeleton=f"c3d:{kind}", source_format="c3d",
                  meta={"unit": unit, "vertical": ("-" if sign < 0 else "+") + "XYZ"[axis],
                        "rules": {j: r.source for j, (r, _) in chosen.items()}, "filled_samples": filled,
                        "declared_frames": pts.meta.get("declared_frames"), "frames": (start + 1, stop),
                        "notes": notes})
