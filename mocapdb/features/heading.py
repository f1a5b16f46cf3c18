"""Feature 41, beyond the paper: the body's heading turned far within a few seconds (FEATURES.md §10).

The 40 features see a turn only through #40, the pelvis turning faster than
100°/s. A walker who turns round over two or three steps turns the pelvis
that fast for a tenth of a second per step, or never (a slow, even turn of
90° in 2 s is 45°/s), so the words of a turning walk and a straight one look
alike. Feature 41 reads the turn itself: the heading — the floor-plane
direction of the pelvis (the root's x axis, or the hip axis left hip − right
hip for position-only data, the same axis #40 reads) — compared 1.5 s before
and 1.5 s after the frame:

* strict: it changed by at least 70° (a turn of 90° or more within about
  2 s reaches it however the walker spreads it over the steps);
* lenient: at least 45°, so that once on it stays on over the whole turn
  (hysteresis, FEATURES.md §5).

A straight walk or run changes its heading by under 35° within 3 s, the
pelvis's own swing with the steps included (the walks and runs of
``bandai2_dev``, CMU 02_01–02_03, HDM05 sneaks; RESULTS.md, issue 25). The
window is clipped at the ends of the take. While the axis stands nearly
upright (within 30° of the vertical: lying on one's side, a cartwheel) its
floor-plane direction means nothing: the heading holds its last reliable
value there.

The feature is bit 40 of the packed word (:data:`mocapdb.features.words.DERIVED_FEATURE_NAMES`):
the toolbox's 40 features and everything computed from them stay identical
to the authors' (the reference mode, the oracle tests); templates and
keyframes that do not name it never read it.
"""
from __future__ import annotations

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.readers.joints import JOINT_INDEX

__all__ = ["HEADING_WINDOW_S", "HEADING_THRESHOLDS", "heading_degrees", "heading_change"]

#: the window (seconds) over which the heading change is measured, centred on the frame
HEADING_WINDOW_S = 3.0
#: (lenient, strict) heading change in degrees over the window
HEADING_THRESHOLDS = (45.0, 70.0)
#: the floor-plane part of the unit axis below which its direction is unreliable (sin 30°)
_MIN_FLOOR = 0.5
_LHIP, _RHIP = JOINT_INDEX["lhip"], JOINT_INDEX["rhip"]


def heading_degrees(joints, root_rotation=None) -> np.ndarray:
    """The unwrapped floor-plane heading of the pelvis per frame, in degrees.

    Parameters
    ----------
    joints : (n, 24, 3) float
        Y-up joint positions.
    root_rotation : (n, 3, 3) float or None
        The root's rotation; its x axis is the pelvis's left-right axis. None:
        the hip axis (left hip − right hip).

    Returns
    -------
    (n,) float64
        ``atan2(z, x)`` of the axis, unwrapped; frames where the axis is within
        30° of the vertical repeat the last reliable heading (the first
        reliable one before any).
    """
    j = np.asarray(joints, dtype=np.float64)
    axis = (np.asarray(root_rotation, dtype=np.float64)[:, :, 0] if root_rotation is not None
            else j[:, _LHIP] - j[:, _RHIP])
    n = axis.shape[0]
    if n == 0:
        return np.zeros(0)
    norm = np.linalg.norm(axis, axis=1)
    floor = np.hypot(axis[:, 0], axis[:, 2])
    ok = floor > _MIN_FLOOR * np.maximum(norm, 1e-12)
    if not ok.any():
        return np.zeros(n)
    idx = np.where(ok, np.arange(n), -1)
    idx = np.maximum.accumulate(idx)
    idx[idx < 0] = int(np.flatnonzero(ok)[0])
    angle = np.arctan2(axis[idx, 2], axis[idx, 0])
    return np.degrees(np.unwrap(angle))


def heading_change(joints, root_rotation, fps, *, window_s=HEADING_WINDOW_S) -> np.ndarray:
    """How far the heading turns across the window centred on each frame, in degrees (≥ 0).

    Parameters
    ----------
    joints : (n, 24, 3) float
    root_rotation : (n, 3, 3) float or None
    fps : float
        Frame rate of ``joints``.
    window_s : float, default 3.0
        The window; clipped at the ends of the take.

    Returns
    -------
    (n,) float64
        ``|h(t + w/2) − h(t − w/2)|`` of :func:`heading_degrees`.
    """
    if not (float(window_s) > 0 and float(fps) > 0):
        raise ParameterError(f"window_s and fps must be positive, got {window_s!r}, {fps!r}")
    h = heading_degrees(joints, root_rotation)
    n = h.size
    half = max(1, int(round(float(window_s) * float(fps) / 2)))
    t = np.arange(n)
    return np.abs(h[np.minimum(t + half, n - 1)] - h[np.maximum(t - half, 0)])
