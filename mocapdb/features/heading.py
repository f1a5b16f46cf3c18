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

import math

import numpy as np

from mocapdb._numba import jit
from mocapdb.errors import ParameterError
from mocapdb.bodies.joints import JOINT_INDEX

__all__ = ["HEADING_WINDOW_S", "HEADING_THRESHOLDS", "heading_axis", "heading_degrees", "heading_change",
           "HeadingChangeStream"]

#: the window (seconds) over which the heading change is measured, centred on the frame
HEADING_WINDOW_S = 3.0
#: (lenient, strict) heading change in degrees over the window
HEADING_THRESHOLDS = (45.0, 70.0)
#: the floor-plane part of the unit axis below which its direction is unreliable (sin 30°)
_MIN_FLOOR = 0.5
_LHIP, _RHIP = JOINT_INDEX["lhip"], JOINT_INDEX["rhip"]


def heading_axis(joints, root_rotation=None) -> np.ndarray:
    """The pelvis's left-right axis per frame, (n, 3) float64: the root's x axis, or the hip axis (left hip −
    right hip) for position-only data — the axis #40 reads and :func:`heading_degrees` turns into a heading."""
    if root_rotation is not None:
        return np.asarray(root_rotation, dtype=np.float64)[:, :, 0]
    j = np.asarray(joints, dtype=np.float64)
    return j[:, _LHIP] - j[:, _RHIP]


def heading_degrees(joints, root_rotation=None, *, axis=None) -> np.ndarray:
    """The unwrapped floor-plane heading of the pelvis per frame, in degrees.

    Parameters
    ----------
    joints : (n, 24, 3) float
        Y-up joint positions.
    root_rotation : (n, 3, 3) float or None
        The root's rotation; its x axis is the pelvis's left-right axis. None:
        the hip axis (left hip − right hip).
    axis : (n, 3) float, optional, keyword-only
        :func:`heading_axis` of the take, instead of ``joints`` and ``root_rotation``.

    Returns
    -------
    (n,) float64
        ``atan2(z, x)`` of the axis, unwrapped; frames where the axis is within
        30° of the vertical repeat the last reliable heading (the first
        reliable one before any).
    """
    h = np.empty(0 if axis is None and joints is None else len(axis if axis is not None else joints))
    _heading(joints, root_rotation, axis, 0, h, np.empty(0))
    return h


def _heading(joints, root_rotation, axis, half, h, change) -> None:
    """:func:`heading_degrees` into ``h`` (n,) and, when ``change`` has n elements, the change across
    ``half`` frames each side into it: NumPy's ``arctan2`` of every frame (its vector loop is not libm's
    ``atan2`` to the last bit), the rest in one kernel (:func:`_heading_kernel`)."""
    if axis is None:
        axis = heading_axis(joints, root_rotation)
    axis = np.asarray(axis, dtype=np.float64)
    raw = np.arctan2(axis[:, 2], axis[:, 0])   # elementwise: a frame's angle whichever frames surround it
    _heading_kernel(axis, raw, half, h, change)


@jit
def _heading_kernel(axis, raw, half, h, change):  # pragma: no cover - compiled
    """The unwrapped heading (degrees) of the axes ``axis`` (n, 3) with their ``raw`` angles
    (``arctan2(z, x)``) into ``h``, frames whose axis is within 30° of the vertical holding the last
    reliable angle (the first reliable one before any; 0 throughout if none is), and, if ``change`` has n
    elements, ``|h[t + half] − h[t − half]|`` (clipped at the ends) into it. Element by element what
    ``np.linalg.norm``, ``np.hypot``, ``np.unwrap`` (period 2π) and ``np.degrees`` give."""
    n = axis.shape[0]
    first = -1
    for t in range(n):
        x, y, z = axis[t, 0], axis[t, 1], axis[t, 2]
        norm = math.sqrt(x * x + y * y + z * z)
        if math.hypot(x, z) > _MIN_FLOOR * max(norm, 1e-12):
            first = t
            break
    if first < 0:
        h[:] = 0.0
    else:
        held = raw[first]
        prev = held
        total = 0.0
        for t in range(n):
            if t > first:
                x, y, z = axis[t, 0], axis[t, 1], axis[t, 2]
                norm = math.sqrt(x * x + y * y + z * z)
                if math.hypot(x, z) > _MIN_FLOOR * max(norm, 1e-12):
                    held = raw[t]
            angle = held
            if t > 0:
                dd = angle - prev
                ddmod = np.mod(dd + math.pi, 2 * math.pi) - math.pi
                if ddmod == -math.pi and dd > 0:
                    ddmod = math.pi
                correct = ddmod - dd
                if abs(dd) < math.pi:
                    correct = 0.0
                total = correct if t == 1 else total + correct   # NumPy's cumsum: starts at the first step
                h[t] = (angle + total) * (180.0 / math.pi)
            else:
                h[t] = angle * (180.0 / math.pi)
            prev = angle
    if change.shape[0] == n:
        for t in range(n):
            change[t] = abs(h[min(t + half, n - 1)] - h[max(t - half, 0)])


def heading_change(joints, root_rotation, fps, *, window_s=HEADING_WINDOW_S, axis=None) -> np.ndarray:
    """How far the heading turns across the window centred on each frame, in degrees (≥ 0).

    Parameters
    ----------
    joints : (n, 24, 3) float
    root_rotation : (n, 3, 3) float or None
    fps : float
        Frame rate of ``joints``.
    window_s : float, default 3.0
        The window; clipped at the ends of the take.
    axis : (n, 3) float, optional, keyword-only
        As :func:`heading_degrees`.

    Returns
    -------
    (n,) float64
        ``|h(t + w/2) − h(t − w/2)|`` of :func:`heading_degrees`.
    """
    if not (float(window_s) > 0 and float(fps) > 0):
        raise ParameterError(f"window_s and fps must be positive, got {window_s!r}, {fps!r}")
    if axis is None:
        axis = heading_axis(joints, root_rotation)
    n = len(axis)
    change = np.empty(n)
    _heading(joints, root_rotation, axis, max(1, int(round(float(window_s) * float(fps) / 2))), np.empty(n), change)
    return change


def _unwrap_corrections(dd):
    """``np.unwrap``'s per-step corrections (period 2π) of the steps ``dd``, element by element as NumPy's."""
    ddmod = np.mod(dd + np.pi, 2 * np.pi) - np.pi
    np.copyto(ddmod, np.pi, where=(ddmod == -np.pi) & (dd > 0))
    correct = ddmod - dd
    np.copyto(correct, 0, where=np.abs(dd) < np.pi)
    return correct


class HeadingChangeStream:
    """:func:`heading_change` of a long take fed its pelvis axis a block at a time, bit for bit.

    ``feed(axis)`` takes the next frames' :func:`heading_axis` and returns the
    change of every frame it can already tell; ``finish()`` returns the rest.
    What it keeps between blocks: the last raw angle and the sum of the
    unwrapping's corrections so far (added in the same order as
    ``np.unwrap``'s ``cumsum`` over the whole take), the last reliable angle
    (held over unreliable frames), the count of leading frames before the first
    reliable one (they take its angle), and the heading of the last ``2 ×
    half`` frames. A frame's change needs the heading ``half`` frames ahead
    (1.5 s: the window's second half), so the answer trails the input by
    ``half`` frames — memory is the block plus ``half`` frames, not the take.

    Parameters
    ----------
    n_frames : int
        Frames of the whole take (the window is clipped at its end).
    fps : float
    window_s : float, default 3.0
    """

    def __init__(self, n_frames: int, fps: float, *, window_s=HEADING_WINDOW_S):
        if not (float(window_s) > 0 and float(fps) > 0):
            raise ParameterError(f"window_s and fps must be positive, got {window_s!r}, {fps!r}")
        self.n = int(n_frames)
        self.half = max(1, int(round(float(window_s) * float(fps) / 2)))
        self._held = None        # the last reliable raw angle (radians)
        self._pending = 0        # leading frames before the first reliable one
        self._prev = None        # the last raw angle unwrapped
        self._carry = None       # the unwrapping's corrections summed so far (None: none yet)
        self._h = np.zeros(0)    # heading (degrees) of frames [_h0, _fed)
        self._h0 = 0
        self._fed = 0            # frames whose heading is known
        self._done = 0           # frames whose change was returned

    def feed(self, axis) -> np.ndarray:
        """The change (degrees) of the frames that the axes fed so far decide, in frame order."""
        axis = np.asarray(axis, dtype=np.float64)
        if axis.shape[0] == 0:
            return np.zeros(0)
        norm = np.linalg.norm(axis, axis=1)
        floor = np.hypot(axis[:, 0], axis[:, 2])
        ok = floor > _MIN_FLOOR * np.maximum(norm, 1e-12)
        m = axis.shape[0]
        if self._held is None:
            if not ok.any():
                self._pending += m
                return np.zeros(0)
            first = int(np.flatnonzero(ok)[0])
            lead = self._pending + first      # the frames before the take's first reliable one
            self._pending = 0
            axis, ok = axis[first:], ok[first:]
            m = axis.shape[0]
        else:
            lead = 0
        idx = np.where(ok, np.arange(m), -1)
        idx = np.maximum.accumulate(idx)
        angle = np.empty(m)
        have = idx >= 0
        angle[have] = np.arctan2(axis[idx[have], 2], axis[idx[have], 0])
        angle[~have] = self._held          # held from the block before
        if lead:
            angle = np.concatenate([np.full(lead, angle[0]), angle])
        self._held = angle[-1]
        self._push(angle)
        return self._emit(final=False)

    def finish(self) -> np.ndarray:
        """The change of the remaining frames (all frames fed: ``n_frames`` of them)."""
        if self._held is None and self._pending:   # never reliable: the heading is 0 throughout
            self._push(np.zeros(self._pending))
            self._pending = 0
        if self._fed != self.n:
            raise ParameterError(f"fed {self._fed} frames of a take of {self.n}")
        return self._emit(final=True)

    def _push(self, angle):
        """Unwrap the next raw angles and append their heading."""
        if self._prev is None:
            corr = _unwrap_corrections(np.diff(angle))
            up = angle.copy()
        else:
            corr = _unwrap_corrections(np.diff(np.concatenate([[self._prev], angle])))
            up = np.empty_like(angle)
        if corr.size:
            # the running sum continues exactly as np.unwrap's cumsum over the whole take adds
            total = corr.cumsum() if self._carry is None else np.concatenate([[self._carry], corr]).cumsum()[1:]
            up[up.size - corr.size:] = angle[angle.size - corr.size:] + total
            self._carry = total[-1]
        self._prev = angle[-1]
        self._h = np.concatenate([self._h, np.degrees(up)])
        self._fed += angle.size

    def _emit(self, *, final: bool) -> np.ndarray:
        last = self.n if final else min(self.n, self._fed - self.half)   # frames < last are decided
        if last <= self._done:
            return np.zeros(0)
        t = np.arange(self._done, last)
        ahead = np.minimum(t + self.half, self.n - 1) - self._h0
        behind = np.maximum(t - self.half, 0) - self._h0
        out = np.abs(self._h[ahead] - self._h[behind])
        self._done = last
        keep = max(0, last - self.half) - self._h0   # the frames a later change can still read
        self._h, self._h0 = self._h[keep:], self._h0 + keep
        return out
