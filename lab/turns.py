"""Walking turns for the turn evaluation: real walks straightened, then turned round or bent.

A recording of someone who turns round while walking is rare in the
development data; its walks are circles (CMU 86_09) or short and straight
(CMU 02_01, 02_02). These functions make turning walks from real walks by
changing only their path, never the body's own motion:

* :func:`turn_path` — the body's motion relative to its root kept (the gait,
  the pelvis's own swing), its path and heading turned about the vertical by
  an angle per frame;
* :func:`straightened_walk` — a walk whose path bends (86_09 walks in
  circles) with the slow part of its heading turned back: a straight walk of
  the same walker;
* :func:`turning_walk` — a walk that turns by an angle over a time: evenly
  (``style="smooth"``), step by step, the heading turning while a foot
  swings (``style="steps"``), or in short bursts at the fastest part of
  each swing (``style="bursts"``: how the recorded walkers of other labs
  turn round, the pelvis turning fast for 0.1–0.3 s per step and slowly in
  between).

The turn evaluation (``benchmarks/eval_turns.py``) annotates turning walks
(turned round: 135° or 180°) and walks that bend (30°–60°) made from several
walkers and labs.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from mocapdb.errors import ParameterError
from mocapdb.bodies import JOINT_INDEX, Motion

__all__ = ["turn_path", "straightened_walk", "turning_walk", "hip_heading", "TURN_STYLES"]

#: how :func:`turning_walk` distributes the turn over its time
TURN_STYLES = ("smooth", "steps", "bursts")
_LHIP, _RHIP, _LANKLE, _RANKLE = (JOINT_INDEX[n] for n in ("lhip", "rhip", "lankle", "rankle"))


def _yaw(theta):
    """(n, 3, 3) rotations about the vertical (y) axis that turn the heading by ``theta`` radians."""
    c, s = np.cos(theta), np.sin(theta)
    r = np.zeros((len(theta), 3, 3))
    r[:, 0, 0], r[:, 0, 2], r[:, 1, 1], r[:, 2, 0], r[:, 2, 2] = c, -s, 1.0, s, c
    return r


def hip_heading(motion: Motion) -> np.ndarray:
    """Heading of the hip axis (left hip − right hip) in the floor plane, radians, unwrapped.

    Returns
    -------
    (n_frames,) float64
        Angle of the axis's (x, z) direction, ``atan2(z, x)``; it grows when
        the walker turns from +x towards +z.
    """
    axis = motion.joints[:, _LHIP] - motion.joints[:, _RHIP]
    return np.unwrap(np.arctan2(axis[:, 2], axis[:, 0]))


def turn_path(motion: Motion, theta) -> Motion:
    """The motion with its path and heading turned by ``theta`` about the vertical.

    Each frame's joints relative to the root are turned by ``theta[t]``; the
    root's steps in the floor plane are turned by the same angle and summed
    from the first frame (heights kept), so the walker walks the turned
    path with the same gait. A recorded root rotation is turned too (feature
    #40 reads it).

    Parameters
    ----------
    motion : Motion
    theta : (n_frames,) array_like of float
        Heading change per native frame, radians (positive: the heading
        angle of :func:`hip_heading` grows).

    Returns
    -------
    Motion
    """
    theta = np.asarray(theta, dtype=np.float64)
    if theta.shape != (motion.n_frames,):
        raise ParameterError(f"theta must have one angle per frame ({motion.n_frames}), got shape {theta.shape}")
    r = _yaw(theta)
    joints = motion.joints
    root = joints[:, 0]
    steps = np.diff(root, axis=0)
    steps[:, 1] = 0.0
    steps = np.einsum("nij,nj->ni", r[:-1], steps)
    path = np.empty_like(root)
    path[0] = root[0]
    path[1:] = root[0] + np.cumsum(steps, axis=0)
    path[:, 1] = root[:, 1]
    turned = path[:, None, :] + np.einsum("nij,nkj->nki", r, joints - root[:, None, :])
    rotation = None if motion.root_rotation is None else np.einsum("nij,njk->nik", r, motion.root_rotation)
    return dataclasses.replace(motion, joints=turned, root_rotation=rotation)


def straightened_walk(motion: Motion, *, start=None, stop=None, seconds=1.0) -> Motion:
    """Native frames ``start:stop`` of a walk with its path straightened.

    The heading's slow part (its moving average over ``seconds``) is turned
    back; the faster swing of the pelvis within each stride stays.

    Returns
    -------
    Motion
    """
    rot = None if motion.root_rotation is None else motion.root_rotation[start:stop]
    part = dataclasses.replace(motion, joints=motion.joints[start:stop], root_rotation=rot)
    if part.n_frames < 2:
        raise ParameterError(f"{motion.name}: frames {start}:{stop} hold fewer than two frames")
    heading = hip_heading(part)
    k = max(1, int(round(seconds * part.fps)))
    padded = np.pad(heading, (k // 2, k - 1 - k // 2), mode="edge")
    slow = np.convolve(padded, np.ones(k) / k, mode="valid")
    return turn_path(part, -(slow - slow[0]))


def turning_walk(motion: Motion, start, seconds, degrees, *, style="steps") -> Motion:
    """The walk turning by ``degrees`` over ``seconds`` from ``start`` (seconds into it).

    Parameters
    ----------
    motion : Motion
        A walk (straight, e.g. :func:`straightened_walk`).
    start, seconds : float
        When the turn begins, and how long it takes.
    degrees : float
        The heading change (sign: the direction).
    style : {"steps", "smooth", "bursts"}
        ``"smooth"``: the heading turns along a cosine ramp; ``"steps"``:
        it turns in proportion to how fast the feet move (the sum of both
        ankles' speeds), so it turns while a foot swings and pauses while
        both stand; ``"bursts"``: in proportion to the fourth power of
        that speed, so most of each step's turn falls into the middle of
        the swing.

    Returns
    -------
    Motion
    """
    if style not in TURN_STYLES:
        raise ParameterError(f"style={style!r}; use one of {', '.join(TURN_STYLES)}")
    if not seconds > 0:
        raise ParameterError(f"seconds must be positive, got {seconds!r}")
    t = np.arange(motion.n_frames) / motion.fps
    inside = (t >= start) & (t < start + seconds)
    if not inside.any():
        raise ParameterError(f"{motion.name}: the turn at {start} s for {seconds} s lies outside the take")
    if style == "smooth":
        u = np.clip((t - start) / seconds, 0.0, 1.0)
        share = (1.0 - np.cos(np.pi * u)) / 2.0
    else:
        feet = motion.joints[:, [_LANKLE, _RANKLE]]
        speed = np.linalg.norm(np.diff(feet, axis=0), axis=2).sum(axis=1)
        speed = np.append(speed, speed[-1]) * inside
        if style == "bursts":
            speed = speed ** 4
        if speed.sum() <= 0:
            raise ParameterError(f"{motion.name}: the feet do not move between {start} and {start + seconds} s")
        share = np.cumsum(speed) / speed.sum()
    return turn_path(motion, np.radians(degrees) * share)
