"""The in-memory result of reading a recording: what every reader returns."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mocapdb._numba import jit
from mocapdb.errors import ParseError


@dataclass(frozen=True)
class Motion:
    """One recording, resolved to the 24 canonical joints.

    Attributes
    ----------
    joints : ndarray, shape (n_frames, 24, 3), float64
        Joint positions in the order of :data:`mocapdb.bodies.joints.JOINT_NAMES`,
        Y up, in the toolbox's length unit (ASF lengths / ``:units length`` ·
        2.54). Features do not depend on the unit.
    root_rotation : ndarray, shape (n_frames, 3, 3), float64, or None
        Rotation of the root as recorded (AMC ``Rz·Ry·Rx``, without the ASF
        root orientation); feature #40 reads its x axis. None for
        position-only sources (then #40 uses the hip axis, FEATURES.md §6).
    fps : float
        Native sampling rate in Hz.
    name : str
        Document name (file stem).
    skeleton : str
        Skeleton identifier (ASF name/path or BVH skeleton family).
    source_format : str
        ``"amc"``, ``"bvh"``, ...
    """

    joints: np.ndarray
    root_rotation: np.ndarray | None
    fps: float
    name: str = ""
    skeleton: str = ""
    source_format: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.joints.shape[0])


#: rates (Hz) a recorded frame time is snapped to (READERS.md §1)
COMMON_RATES = (24.0, 25.0, 29.97, 30.0, 48.0, 50.0, 59.94, 60.0, 72.0, 90.0, 96.0, 100.0, 120.0, 125.0,
                144.0, 150.0, 180.0, 200.0, 240.0, 250.0, 300.0, 360.0, 400.0, 480.0, 500.0, 600.0,
                960.0, 1000.0, 2000.0)
#: fastest rate accepted (READERS.md §4)
MAX_RATE = 10_000.0


def snap_rate(fps: float) -> float:
    """The nearest common rate when within 0.5 % (``1/.0083`` → 120), else ``fps``.

    Exactly integral rates are kept; a rate within 1e-4 of an integer becomes
    that integer (a rounded frame time must not change the toolbox's
    millisecond windows, ``ceil(0.1 · fps)``).
    """
    fps = float(fps)
    best = min(COMMON_RATES, key=lambda r: abs(fps - r))
    if abs(fps - best) <= 0.005 * best:
        return best
    r = round(fps)
    return float(r) if r > 0 and abs(fps - r) <= 1e-4 * fps else fps


def check_rate(fps, path, line=None) -> float:
    """``fps`` if it is a usable rate (0 < fps ≤ 10 kHz), else a ParseError naming the file."""
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and 0.0 < fps <= MAX_RATE):
        raise ParseError(path, line, f"frame rate {fps!r} Hz: expected a rate above 0 and at most "
                         f"{MAX_RATE:g} Hz")
    return float(fps)


@jit
def _extent_kernel(points, body, out):  # pragma: no cover - compiled
    """The checks of :func:`check_finite_motion` in one call (a take's NumPy steps on the first frame cost
    more than the pass, issue 35): ``out[0]`` = 1 if any coordinate of ``points`` (k, 3) is not finite,
    ``out[1]`` = the largest |x − centre|, ``out[2]`` = the body's size — of its first ``body`` points (the
    first frame): the largest range of a coordinate, 1 if that is 0; the centre is their mean, summed in
    order as ``np.mean(axis=0)`` sums (both meaningful only when ``out[0]`` is 0)."""
    centre = np.empty(3)
    size = 0.0
    for c in range(3):
        lo = points[0, c]
        hi = lo
        total = lo
        for k in range(1, body):
            x = points[k, c]
            lo = min(lo, x)
            hi = max(hi, x)
            total += x
        centre[c] = total / body
        size = max(size, hi - lo)
    bad = 0.0
    far = 0.0
    for k in range(points.shape[0]):
        for c in range(3):
            x = points[k, c]
            if not math.isfinite(x):
                bad = 1.0
            else:
                d = abs(x - centre[c])
                if d > far:
                    far = d
    out[0] = bad
    out[1] = far
    out[2] = size if size != 0.0 else 1.0


def check_finite_motion(joints: np.ndarray, path, *, first_line=None) -> None:
    """Refuse non-finite joint positions or positions absurdly far from the body.

    Raises
    ------
    ParseError
        Naming the file, the first bad frame (1-based) and, when
        ``first_line`` (the file line of frame 1) is given, its line.
    """
    if joints.size == 0:
        raise ParseError(path, first_line, "no frames")
    # one pass over the whole array first; frames only for the message
    extent = np.empty(3)
    _extent_kernel(np.ascontiguousarray(joints, dtype=np.float64).reshape(-1, 3), joints.shape[1], extent)
    if extent[0] == 0.0 and extent[1] <= 1e6 * extent[2]:
        return
    first = joints[0]
    size = float(np.ptp(first, axis=0).max()) or 1.0
    centre = first.mean(axis=0)
    finite = np.isfinite(joints).all(axis=(1, 2))
    if not finite.all():
        f = int(np.argmin(finite))
        raise ParseError(path, None if first_line is None else first_line + f,
                         "non-finite joint position (NaN or inf)", frame=f + 1)
    far = np.abs(joints - centre).max(axis=(1, 2)) > 1e6 * size
    if far.any():
        f = int(np.argmax(far))
        raise ParseError(path, None if first_line is None else first_line + f,
                         f"a joint lies more than 10^6 body sizes ({size:g} units) away: absurd values",
                         frame=f + 1)


__all__ = ["Motion", "snap_rate", "check_rate", "check_finite_motion", "COMMON_RATES", "MAX_RATE"]
