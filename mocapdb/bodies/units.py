"""The length unit of a motion's joints: read from the format, or decided from the body for BVH.

Features do not depend on the unit (FEATURES.md §2: lengths are in body
units), but joints sent to other tools (``export-joints``) must be metres.
ASF/AMC, C3D and AMASS carry their unit; a BVH file declares none, so the
BVH reader decides it here from the body and the recording:

* the legs (hip → knee → ankle, median over the take) must have a human
  length, :data:`LEG_BAND` metres — a band narrower than a factor 2.2, so
  no two of the candidate units (:data:`UNITS`, CMU's 1/0.45 inch the
  closest pair to inches at 2.22×) ever both fit;
* when no unit fits (a child, a figure of odd proportions), a skeleton with
  the CMU converters' bone names (``LHipJoint``, ``LowerBack``) is in CMU's
  unit, as those files are; otherwise the unit whose legs come closest to
  :data:`LEG_M`, and the reason says it is a guess.

The decision and its reason go to the motion's notes (``ingest_log``) and to
every export; a user overrides it with a unit name or a scale.

References
----------
README "Joints out"; READERS.md §2; issue 33 item 1.
"""
from __future__ import annotations

import math

import numpy as np

from mocapdb._numba import jit
from mocapdb.errors import ParameterError
from mocapdb.bodies.joints import JOINT_INDEX

__all__ = ["UNITS", "UNIT_NAMES", "LEG_BAND", "leg_length", "bvh_unit", "check_override", "metres_per_unit"]

#: length units a file may be in, metres each; ``cmu``: the CMU ASF's ``length 0.45`` (1/0.45 inch),
#: which the CMU BVH conversions keep
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "inch": 0.0254, "cmu": 0.0254 / 0.45}
UNIT_NAMES = tuple(UNITS)
#: an adult's leg (hip → knee → ankle), metres: 0.5–1.1 (a factor 2.2, below the 2.22 between inch and cmu)
LEG_BAND = (0.5, 1.1)
#: the middle of that band (geometrically): the guess when no unit fits
LEG_M = math.sqrt(LEG_BAND[0] * LEG_BAND[1])
#: bone names only the CMU BVH conversions (and CMU's ASF) have, lower case
_CMU_NAMES = frozenset({"lhipjoint", "rhipjoint", "lowerback"})


@jit
def _pair_lengths_kernel(joints, step, a, b, out):  # pragma: no cover - compiled
    """``out[i, k] = |joints[i·step, a[k]] − joints[i·step, b[k]]|``: the differences, squares and sum
    of three in the order of ``np.linalg.norm(…, axis=-1)``."""
    for i in range(out.shape[0]):
        f = i * step
        for k in range(a.shape[0]):
            dx = joints[f, a[k], 0] - joints[f, b[k], 0]
            dy = joints[f, a[k], 1] - joints[f, b[k], 1]
            dz = joints[f, a[k], 2] - joints[f, b[k], 2]
            out[i, k] = math.sqrt(dx * dx + dy * dy + dz * dz)


def pair_lengths(joints, a, b, step: int = 1) -> np.ndarray:
    """The distance between joints ``a[k]`` and ``b[k]`` ((p,) int64 each) in every ``step``-th frame of
    ``joints`` ((n, J, 3)): (⌈n / step⌉, p) float64, in one pass over the frames (issue 35: a per-pair
    NumPy gather and norm cost more than the distances on a take of a few hundred frames)."""
    j = np.asarray(joints, dtype=np.float64)
    out = np.empty(((len(j) + step - 1) // step, len(a)))
    _pair_lengths_kernel(j, step, a, b, out)
    return out


@jit
def _column_medians_kernel(values, out):  # pragma: no cover - compiled
    """``out[k]`` = the median of column k of ``values`` (np.median's value: the middle one, or the mean of
    the two middle ones; NaN when the column holds a NaN, as NumPy's)."""
    for k in range(values.shape[1]):
        col = values[:, k]
        if np.isnan(col).any():
            out[k] = np.nan
        else:
            out[k] = np.median(col)


def column_medians(values) -> np.ndarray:
    """``np.median(values, axis=0)`` of an (m ≥ 1, k) float64 array, in one kernel call (NumPy's median
    costs tens of microseconds of Python per call; a BVH take asks for two)."""
    values = np.asarray(values, dtype=np.float64)
    out = np.empty(values.shape[1])
    _column_medians_kernel(values, out)
    return out


#: the leg's bones (hip → knee, knee → ankle), left then right
_LEG_A = np.array([JOINT_INDEX[f"{s}{a}"] for s in "lr" for a in ("hip", "knee")], dtype=np.int64)
_LEG_B = np.array([JOINT_INDEX[f"{s}{b}"] for s in "lr" for b in ("knee", "ankle")], dtype=np.int64)


def leg_length(joints) -> float:
    """The median leg (hip → knee → ankle, both sides) over a take's frames, in its own unit."""
    ln = pair_lengths(joints, _LEG_A, _LEG_B)
    return float(column_medians(np.concatenate([ln[:, 0] + ln[:, 1], ln[:, 2] + ln[:, 3]])[:, None])[0])


def bvh_unit(joints, bone_names=(), *, leg=None) -> tuple:
    """``(unit name, reason)`` for a BVH take's joints (in the file's unit) and its hierarchy's names
    (``leg``: their :func:`leg_length`, when the caller measured it already)."""
    leg = leg_length(joints) if leg is None else leg
    if not (math.isfinite(leg) and leg > 0.0):
        return "m", "m assumed (the legs have no length)"
    fits = [u for u, s in UNITS.items() if LEG_BAND[0] <= leg * s <= LEG_BAND[1]]
    if fits:
        (unit,) = fits   # the band is narrower than any two units' ratio
        return unit, f"{unit}: the only unit giving the legs an adult's length ({leg * UNITS[unit]:.2f} m)"
    lo, hi = LEG_BAND
    if _CMU_NAMES <= {str(n).rsplit(":", 1)[-1].lower() for n in bone_names}:   # namespaces stripped
        return "cmu", (f"cmu: the CMU converters' bone names (no unit gives the legs {lo:g}-{hi:g} m; "
                       f"in cmu they are {leg * UNITS['cmu']:.2f} m)")
    unit = min(UNITS, key=lambda u: abs(math.log(leg * UNITS[u] / LEG_M)))
    return unit, (f"{unit} guessed: no unit gives the legs {lo:g}-{hi:g} m; in {unit} they are "
                  f"{leg * UNITS[unit]:.2f} m (override with --unit or --scale)")


def check_override(unit=None, scale=None) -> tuple:
    """A user's ``(unit, scale)`` override checked: at most one, a known unit, a positive finite scale.

    Raises
    ------
    ParameterError
        An unknown unit, a scale that is not a positive finite number, or both given.
    """
    if unit is not None and scale is not None:
        raise ParameterError("give unit or scale, not both")
    if unit is not None and unit not in UNITS:
        raise ParameterError(f"unit must be one of {', '.join(UNIT_NAMES)}, got {unit!r}")
    if scale is not None:
        try:
            value = float(scale)
        except (TypeError, ValueError, OverflowError):
            value = math.nan
        if not (math.isfinite(value) and value > 0.0):
            raise ParameterError(f"scale must be a positive number of metres per unit, got {scale!r}")
        scale = value
    return unit, scale


def metres_per_unit(motion, *, unit=None, scale=None) -> tuple:
    """``(metres per unit of motion.joints, how that is known)``.

    Parameters
    ----------
    motion : Motion
    unit : {"m", "cm", "mm", "inch", "cmu"}, optional, keyword-only
        The user's unit for a BVH source, overriding the reader's decision.
    scale : float, optional, keyword-only
        The user's metres per unit of a BVH source, likewise.

    Other formats carry their unit: AMASS metres, ASF/AMC centimetres (the
    ASF reader's unit, READERS.md §5), C3D the unit the reader records
    (``cm``, or ``mm × s`` for the toolbox set); an override applies to BVH
    only, whose unit is a decision (:func:`bvh_unit`).

    Raises
    ------
    ParameterError
        A bad override (:func:`check_override`).
    """
    unit, scale = check_override(unit, scale)
    if motion.source_format == "amc":
        return 0.01, "cm (the ASF reader's)"
    known = str(motion.meta.get("unit", ""))
    if motion.source_format != "bvh":
        if known in UNITS:
            return UNITS[known], f"{known} (the {motion.source_format.upper()} reader's)"
        if known.startswith("mm × "):
            return 0.001 / float(known.removeprefix("mm × ")), f"{known} (the C3D reader's)"
    if scale is not None:
        return scale, f"{scale:g} m per unit (given)"
    if unit is not None:
        return UNITS[unit], f"{unit} (given)"
    if known in UNITS:
        return UNITS[known], motion.meta.get("unit_reason", known)
    name, reason = bvh_unit(motion.joints)
    return UNITS[name], reason
