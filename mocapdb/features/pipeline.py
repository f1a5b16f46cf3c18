"""A take's words, the whole feature pipeline (:func:`motion_features`): 40 features and feature 41 →
hysteresis → the 30 Hz grid → packed words, in one kernel call per take (issue 35).

The kernels of :mod:`~mocapdb.features.relational` (velocities, the tests, #40's yaw rate, the §5
hysteresis) are called from one kernel, :func:`_take_words_kernel`, with feature 41's hysteresis and the
packing of :func:`~mocapdb.features.words.pack_words`: on a take of a few hundred frames the per-step
Python and the dozen small arrays cost as much as the kernels. A take longer than :data:`BLOCK_FRAMES`
(at 120 Hz) runs through the same kernel a block at a time (:func:`_words_by_block`), bit for bit the
whole take's words.
"""
import numpy as np

from mocapdb._numba import jit
from mocapdb.errors import ParameterError
from mocapdb.features.heading import HEADING_THRESHOLDS, HeadingChangeStream, heading_axis, heading_change
from mocapdb.features.rates import (RATE_METHODS, TOOLBOX_RATE, feature_frame_count, grid_source_frames,
                                    resample_joints, resampled_count)
from mocapdb.features.relational import (_VEL_P, _VEL_Q, _check_threshold_pair, _checked_input, _hysteresis_kernel,
                                         _lower_kernel, _mix_kernel, _smoothed_velocity_kernel, _thresholds,
                                         _upper_kernel, _windows, _yaw_rate_kernel, body_units)
from mocapdb.features.words import N_FEATURES

__all__ = ["motion_features", "BLOCK_FRAMES"]


@jit
def _take_words_kernel(joints, axis, fps, vel_q, vel_p, windows, units, thr, first, count, change, turn_thr,
                       states, rows, words):  # pragma: no cover - compiled
    """A take's words in one call (issue 35): the tests of the 40 features on ``joints`` (rows ``first`` …
    ``first + count − 1`` and the context their windows read,
    :func:`~mocapdb.features.relational.feature_tests`), #40 from ``axis`` ((n, 3): the pelvis axis,
    :func:`~mocapdb.features.heading.heading_axis`), the §5 hysteresis of the 40 (continuing
    ``states[:40]``) and of feature 41 (``change`` (count,): the heading change of those rows, against
    ``turn_thr`` (lenient, strict), continuing ``states[40]``), then row ``first + rows[i]`` packed into
    ``words[i]`` (bit k − 1 = feature k, bit 40 = feature 41). The same kernels as the unfused
    :func:`~mocapdb.features.relational.relational_features`,
    :func:`~mocapdb.features.relational.heading_turned` and :func:`~mocapdb.features.words.pack_words`,
    called here so that a take costs one dispatch and no Python per step."""
    n = joints.shape[0]
    vel = np.empty((vel_q.shape[0], n, 3))
    _smoothed_velocity_kernel(joints, vel_q, vel_p, windows, vel)
    f1 = np.empty((n, 40), dtype=np.bool_)
    f2 = np.empty((n, 40), dtype=np.bool_)
    _upper_kernel(joints, vel, units, thr, fps, f1, f2)
    _lower_kernel(joints, vel, units, thr, fps, f1, f2)
    _mix_kernel(joints, vel, units, thr, fps, f1, f2)
    rate = np.empty(n)
    _yaw_rate_kernel(np.ascontiguousarray(axis[:, 0]), np.ascontiguousarray(axis[:, 2]), fps, rate)
    for t in range(n):
        f1[t, 39] = rate[t] >= thr[39, 0]
        f2[t, 39] = rate[t] >= thr[39, 1]
    feats = np.empty((count, 40), dtype=np.bool_)
    _hysteresis_kernel(f1[first:first + count], f2[first:first + count], feats, states[:40])
    turned = np.empty(count, dtype=np.bool_)
    state = states[40]
    for t in range(count):
        state = change[t] >= turn_thr[0] if state else change[t] >= turn_thr[1]
        turned[t] = state
    states[40] = state
    one = np.uint64(1)
    for i in range(rows.shape[0]):
        r = rows[i]
        w = np.uint64(0)
        for k in range(40):
            if feats[r, k]:
                w |= one << np.uint64(k)
        if turned[r]:
            w |= one << np.uint64(40)
        words[i] = w


#: feature 41's (lenient, strict) heading change, as the fused kernel reads it
_TURN_THRESHOLDS = np.array(HEADING_THRESHOLDS, dtype=np.float64)


def _words_into(words, joints, axis, fps, units, thr, first, count, change, states, rows) -> None:
    """:func:`_take_words_kernel` of checked input (``joints`` contiguous float64, ``axis`` their
    :func:`~mocapdb.features.heading.heading_axis`, contiguous): the words of rows ``first`` …
    ``first + count − 1`` whose offsets ``rows`` are written to ``words``."""
    _take_words_kernel(joints, axis, fps, _VEL_Q, _VEL_P, _windows(fps), units, thr, first, count,
                       change, _TURN_THRESHOLDS, states, rows, words)


def motion_features(motion, *, root_ang_vel_thresholds=(50.0, 100.0), rate_method: str = "resample"):
    """The whole feature pipeline of one motion: 40 features (+ feature 41) → 30 Hz → words.

    Parameters
    ----------
    motion : mocapdb.bodies.motion.Motion
    root_ang_vel_thresholds : (float, float), optional
        See :func:`~mocapdb.features.relational.relational_features`.
    rate_method : {"resample", "native"}, keyword-only
        How a source not at 120 Hz reaches the 30 Hz grid
        (:mod:`mocapdb.features.rates`): ``"resample"`` (default) resamples
        the joints to 120 Hz and takes the toolbox path; ``"native"``
        computes at the source rate and samples the nearest frames. At
        120 Hz both are the toolbox path (native frames 0, 4, 8, …).

    Returns
    -------
    ndarray, shape (feature_frame_count(n_frames, fps),), uint64
        One packed word per 30 Hz frame (``ceil(n_frames/4)`` at 120 Hz):
        bits 0–39 the toolbox's 40 features, bit 40 feature 41
        (:func:`~mocapdb.features.relational.heading_turned`).

    References
    ----------
    FEATURES.md §1; READERS.md §1.
    """
    if rate_method not in RATE_METHODS:
        raise ParameterError(f"rate_method={rate_method!r}: expected one of {RATE_METHODS}")
    fps = float(motion.fps)
    joints, rot = motion.joints, motion.root_rotation
    toolbox_path = fps == TOOLBOX_RATE or rate_method == "resample"
    if toolbox_path and resampled_count(motion.n_frames, fps) > BLOCK_FRAMES:
        words = _words_by_block(motion, root_ang_vel_thresholds)   # a long take: bounded memory
    else:
        if fps != TOOLBOX_RATE and rate_method == "resample":
            joints, rot = resample_joints(joints, rot, fps)
            fps = TOOLBOX_RATE
        words = _take_words(joints, rot, fps, root_ang_vel_thresholds)
    # a resampled take can end a hair before the source's last grid time
    want = feature_frame_count(motion.n_frames, motion.fps)
    if len(words) < want:
        words = np.concatenate([words, np.repeat(words[-1:], want - len(words))])
    return words[:want]


def _take_words(joints, rot, fps, root_ang_vel_thresholds) -> np.ndarray:
    """The words of a whole take at ``fps`` (a 30 Hz grid row each: every 4th frame at 120 Hz, else the
    nearest source frame): :func:`~mocapdb.features.relational.relational_features`,
    :func:`~mocapdb.features.relational.heading_turned` (bit 40) and :func:`~mocapdb.features.words.pack_words`
    of the grid's rows, bit for bit, in one kernel call (:func:`_take_words_kernel`)."""
    j, r, fps, ang_thr = _checked_input(joints, rot, fps, root_ang_vel_thresholds)
    n = j.shape[0]
    rows = np.arange(0, n, 4) if fps == TOOLBOX_RATE else grid_source_frames(n, fps)
    words = np.zeros(len(rows), dtype=np.uint64)
    if n < 2:   # no velocities: every feature off (FEATURES.md §7), feature 41 too
        return words
    axis = np.ascontiguousarray(heading_axis(j, r))
    change = heading_change(j, r, fps, axis=axis)
    _words_into(words, j, axis, fps, body_units(j), _thresholds(ang_thr), 0, n, change,
                np.zeros(N_FEATURES + 1, dtype=np.bool_), rows)
    return words


#: a take longer than this (120 Hz frames, resampled) has its features computed a block of this many
#: frames at a time (a multiple of 4: blocks start on the 30 Hz grid): 9 minutes of features, not 9
#: hours, in memory
BLOCK_FRAMES = 1 << 16
#: frames of context on each side of a block (:func:`~mocapdb.features.relational.feature_tests`: 30 frames
#: and the next one)
_CONTEXT = 64


def _words_by_block(motion, root_ang_vel_thresholds) -> np.ndarray:
    """:func:`motion_features` (the 120 Hz path) of a long take, a block of frames at a time: the same
    words as the whole take's, bit for bit — each block's tests see the frames their windows read
    (:func:`~mocapdb.features.relational.feature_tests`), the units come from frame 0 and the hysteresis
    runs on from block to block."""
    fps = float(motion.fps)
    j = np.ascontiguousarray(motion.joints, dtype=np.float64)
    rot = motion.root_rotation
    if j.ndim != 3 or j.shape[1:] != (24, 3):
        raise ParameterError(f"joints must have shape (n_frames, 24, 3) in JOINT_NAMES order, got {j.shape}")
    ang_thr = _check_threshold_pair(root_ang_vel_thresholds)
    n = resampled_count(len(j), fps)

    def frames(a, b):   # the 120 Hz joints and rotation of frames a … b − 1
        if fps == TOOLBOX_RATE:
            return j[a:b], None if rot is None else rot[a:b]
        return resample_joints(j, rot, fps, frames=(a, b))

    units = body_units(frames(0, 1)[0])
    thr = _thresholds(ang_thr)
    step = max(4, BLOCK_FRAMES // 4 * 4)
    # feature 41 streams too (HeadingChangeStream: the unwrap and the held heading carried from block to
    # block, its hysteresis state in states[40]); a block's bits need the pelvis axis 1.5 s beyond the block
    heading = HeadingChangeStream(n, TOOLBOX_RATE)
    change, change0, axis_fed = np.zeros(0), 0, 0   # the heading change of frames change0 …
    states = np.zeros(N_FEATURES + 1, dtype=np.bool_)
    words = np.empty((n + 3) // 4, dtype=np.uint64)
    for a in range(0, n, step):
        b = min(n, a + step)
        while change0 + change.size < b:
            if axis_fed < n:
                part = heading.feed(heading_axis(*frames(axis_fed, min(n, axis_fed + step))))
                axis_fed = min(n, axis_fed + step)
            else:
                part = heading.finish()
            change = np.concatenate([change, part])
        lo, hi = max(0, a - _CONTEXT), min(n, b + _CONTEXT)
        jw, rw = frames(lo, hi)
        jw = np.ascontiguousarray(jw)
        _words_into(words[a // 4:(b + 3) // 4], jw, np.ascontiguousarray(heading_axis(jw, rw)), TOOLBOX_RATE,
                    units, thr, a - lo, b - a, change[a - change0:b - change0], states, np.arange(0, b - a, 4))
        change, change0 = change[b - change0:], b
    return words
