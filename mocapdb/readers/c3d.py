"""C3D marker files → the 24 canonical joints (FEATURES.md §2.4, READERS.md §3).

:func:`read_c3d` reads the points (:mod:`~mocapdb.readers.c3dfile`, ezc3d),
picks for every canonical joint the first rule whose markers the file has
(:mod:`~mocapdb.readers.c3d_rules`: the toolbox's HDM05/CMU Vicon set, then
Plug-in Gait / ISB anatomical landmarks, or a user marker map), fills short
gaps, turns the axes so that Y is up and computes the joints:

1. **Gaps.** A sample is missing where its residual is negative, it is NaN or
   it is exactly (0, 0, 0). Gaps up to :data:`MAX_GAP_S` (0.25 s) in a marker
   that a joint uses are filled by linear interpolation over time (held at
   the ends of the take); a longer gap is refused, naming the marker, the
   joint and the frames. A marker missing in every frame counts as absent.
2. **Axes.** The vertical is ``POINT:Y_SCREEN``'s axis (C3D's default ``Z``
   when absent) unless the body's foot-to-head direction never lies along
   it, then the axis it lies along most often; its sign is where the head
   is above the feet in most frames. The lab frame is then rotated (a
   signed cyclic permutation of the axes, determinant +1: left stays left)
   so that this axis becomes +Y. For the usual Z-up file this is the
   toolbox's ``x = Y_c3d, y = Z_c3d, z = X_c3d`` (§2.4.3); where the toolbox
   would mirror (its ``(c[a3], c[a2], c[a1])`` for a Y-up file), we rotate.
3. **Units.** Joints of the toolbox marker set are in the toolbox's unit,
   mm × ``-POINT:SCALE`` of a float file (cm for HDM05, 2-cm units for CMU
   85_xx), as the oracle; every other file is converted by ``POINT:UNITS``
   (mm, cm, m) to cm. Features do not depend on the unit.
4. **Bone-length fit.** When all 24 joints come from the toolbox set (and no
   marker map is given), the toolbox's ``skelfitATS`` makes every bone
   length constant (§2.4.6; :func:`fit_bone_lengths`); anatomical-landmark
   and mapped joints are used as placed.

A motion from C3D has no root rotation: feature #40 uses the hip axis
(``Motion.root_rotation`` is None). The joints stay at the file's rate.
"""
from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

from mocapdb.errors import ParseError
from mocapdb.readers.c3d_rules import MAPPED, TOOLBOX, MarkerIndex, candidate_rules, mapped_rule
from mocapdb.readers.c3dfile import printable, read_c3d_points
from mocapdb.readers.joints import JOINT_INDEX, JOINT_NAMES
from mocapdb.readers.motion import Motion, check_finite_motion

log = logging.getLogger("mocapdb")

__all__ = ["read_c3d", "fit_bone_lengths", "SKELETON_EDGES", "MAX_GAP_S", "UNITS_MM", "vertical_axis"]

#: longest gap (seconds) filled by interpolation
MAX_GAP_S = 0.25
#: POINT:UNITS → millimetres per unit
UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0}
#: coordinates beyond this many millimetres (1000 km) are refused as absurd (READERS.md §4)
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
        In :data:`~mocapdb.readers.joints.JOINT_NAMES` order.

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


def _runs(missing: np.ndarray):
    """(start, stop) of each run of True in a 1-d bool array (stop exclusive)."""
    edges = np.diff(np.concatenate(([0], missing.view(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def _long_gaps(valid: np.ndarray, max_gap: int):
    return [(a, b) for a, b in _runs(~valid) if b - a > max_gap]


def _fill(xyz: np.ndarray, valid: np.ndarray) -> int:
    """Fill a marker's missing samples in place by linear interpolation over time (ends held); returns how many."""
    missing = ~valid
    k = int(missing.sum())
    if k:
        t = np.flatnonzero(valid)
        for axis in range(3):
            xyz[missing, axis] = np.interp(np.flatnonzero(missing), t, xyz[valid, axis])
    return k


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


def _describe(labels, limit=60):
    shown = ", ".join(printable(label) for label in labels[:limit])
    return shown + (f", … ({len(labels)} in all)" if len(labels) > limit else "")


def _select(path, index: MarkerIndex, valid, rate, marker_map):
    """The rule and the point indices of every joint, or a ParseError naming what is missing."""
    max_gap = int(math.floor(MAX_GAP_S * rate + 1e-9))
    chosen, unplaced, gap_errors = {}, [], []
    for joint in JOINT_NAMES:
        if marker_map and joint in marker_map:
            rule = mapped_rule(joint, marker_map[joint])
            absent = [n for n in rule.markers if index.find(n, MAPPED) is None]
            if absent:
                raise ParseError(path, None, f"marker_map: {joint} = {marker_map[joint]!r}, but the file has no "
                                 f"usable marker {', '.join(map(repr, absent))} (its markers: "
                                 f"{_describe(index.labels)})")
            candidates = [rule]
        else:
            candidates = candidate_rules(joint)
        gap_error = None
        for rule in candidates:
            points = [index.find(n, rule.source) for n in rule.markers]
            if None in points or any(j not in chosen for j in rule.joints):
                continue
            gaps = [(i, g) for i in points for g in _long_gaps(valid[:, i], max_gap)[:1]]
            if gaps:
                i, (a, b) = gaps[0]
                gap_error = gap_error or (f"marker {index.labels[i]!r} (used for {joint}) is missing in "
                                          f"frames {a + 1}–{b} ({(b - a) / rate:.2f} s); gaps up to "
                                          f"{MAX_GAP_S} s are filled, longer ones refused")
                continue
            chosen[joint] = (rule, points)
            break
        else:
            if gap_error:
                gap_errors.append(gap_error)
            else:
                unplaced.append(joint)
    if unplaced:
        raise ParseError(path, None, f"no full-body marker set: cannot place {', '.join(unplaced)} "
                         f"({len(unplaced)} of the 24 canonical joints) from the markers "
                         f"{_describe(index.labels)}; name them in a marker map "
                         "(marker_map= / --marker-map FILE, see the README)")
    if gap_errors:
        raise ParseError(path, None, gap_errors[0] + (f" (and {len(gap_errors) - 1} more joints)"
                                                      if len(gap_errors) > 1 else ""))
    return chosen


def read_c3d(path, *, marker_map=None, bone_fit: bool = True) -> Motion:
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

    Returns
    -------
    Motion
        ``joints`` (n_frames, 24, 3), Y up, at the file's rate (``fps`` =
        ``POINT:RATE``); ``root_rotation`` None; ``skeleton`` = ``"c3d:toolbox"``
        (the HDM05/CMU Vicon set, fitted), ``"c3d:landmarks"`` or
        ``"c3d:marker_map"``; ``meta`` holds the unit, the vertical axis, the
        rule source per joint and the number of filled samples.

    Raises
    ------
    ParseError
        Unreadable or corrupt file (:func:`~mocapdb.readers.c3dfile.read_c3d_points`),
        no 3D points, joints that no rule can place (names them), a gap longer
        than 0.25 s in a marker a joint needs (names marker, joint and frames),
        unsupported ``POINT:UNITS``, non-finite or absurd coordinates.

    References
    ----------
    FEATURES.md §2.4; READERS.md §1, §3, §4.
    """
    path = Path(path)
    pts = read_c3d_points(path)
    if not pts.labels:
        raise ParseError(path, None, "no 3D points (force plates or analog channels only): cannot place "
                         "any of the 24 canonical joints")
    if pts.units not in UNITS_MM:
        raise ParseError(path, None, f"POINT:UNITS is {pts.units!r}; expected mm, cm or m")
    index = MarkerIndex(pts.labels, pts.valid.any(axis=0))
    chosen = _select(path, index, pts.valid, pts.rate, marker_map)

    needed = sorted({i for _, points in chosen.values() for i in points})
    xyz = pts.xyz[:, needed].copy()
    bad = np.isinf(xyz) | (np.abs(xyz) * UNITS_MM[pts.units] > MAX_ABS_MM)
    if bad.any():
        f, k, _ = np.argwhere(bad)[0]
        raise ParseError(path, None, f"marker {pts.labels[needed[k]]!r} has the absurd coordinate "
                         f"{xyz[f, k].tolist()} {pts.units}", frame=int(f) + 1)
    filled = sum(_fill(xyz[:, k], pts.valid[:, i]) for k, i in enumerate(needed))
    column = {i: k for k, i in enumerate(needed)}

    def markers_of(joints):
        cols = [column[i] for j in joints for i in chosen[j][1]]
        return xyz[:, cols].mean(axis=1) if cols else np.zeros((pts.n_frames, 3))

    axis, sign = vertical_axis(markers_of(_TOP), markers_of(_BOTTOM), pts.screen[1])
    sources = {rule.source for rule, _ in chosen.values()}
    toolbox = sources == {TOOLBOX}
    # the toolbox's unit: mm × -POINT:SCALE of a float file (FEATURES.md §2.4.3)
    per_mm = -pts.scale if (toolbox and pts.scale < 0) else 0.1
    lab = _to_y_up(xyz, axis, sign, per_mm * UNITS_MM[pts.units])

    joints = np.empty((pts.n_frames, len(JOINT_NAMES), 3))
    for joint in JOINT_NAMES:
        rule, points = chosen[joint]
        m = {name: lab[:, column[i]] for name, i in zip(rule.markers, points)}
        m.update({f"@{j}": joints[:, JOINT_INDEX[j]] for j in rule.joints})
        joints[:, JOINT_INDEX[joint]] = rule.formula(m)
    if toolbox and bone_fit:
        joints = fit_bone_lengths(joints)
    check_finite_motion(joints, path)
    if filled:
        log.info("%s: filled %d missing marker samples (gaps ≤ %.2f s)", path, filled, MAX_GAP_S)
    kind = "toolbox" if toolbox else ("marker_map" if MAPPED in sources else "landmarks")
    unit = f"mm × {per_mm:.9g}" if (toolbox and pts.scale < 0) else "cm"
    return Motion(joints=joints, root_rotation=None, fps=float(pts.rate), name=path.stem,
                  skeleton=f"c3d:{kind}", source_format="c3d",
                  meta={"unit": unit, "vertical": ("-" if sign < 0 else "+") + "XYZ"[axis],
                        "rules": {j: r.source for j, (r, _) in chosen.items()}, "filled_samples": filled,
                        "declared_frames": pts.meta.get("declared_frames")})
