"""Lost tracking in a BVH take: NaN, infinite or absurd channel values, mended or cut.

Motion-capture systems that lose a body (Kinect and other markerless
trackers) write ``NaN`` (or ``inf``, ``1.#QNAN``, a number like ``1e36``)
into its channels. Each channel of a joint the canonical joints need is
mended on its own: a lost stretch up to 0.25 s is interpolated (angles the
shorter way round); a longer one makes its frames unrecoverable, and the
take keeps its longest stretch without them, or is refused when little is
left (:mod:`~mocapdb.readers.gaps`).
"""
from __future__ import annotations

import numpy as np

from mocapdb._numba import jit
from mocapdb.errors import ParseError
from mocapdb.readers.gaps import MAX_GAP_S, frames_text, longest_part, max_gap_frames, runs

__all__ = ["MAX_ANGLE_DEG", "MAX_POSITION_SIZES", "lost_samples", "pose_frame", "mend"]


#: a rotation channel beyond this many degrees is not a recorded angle (2,800 turns)
MAX_ANGLE_DEG = 1e6
#: a position channel beyond this many skeleton sizes is not a recorded position
MAX_POSITION_SIZES = 1e6
#: frames per block of the lost-tracking scan
_SCAN_BLOCK = 1024


def lost_samples(values: np.ndarray, hier: BvhHierarchy) -> np.ndarray | None:
    """Where tracking was lost: NaN, infinite or absurd channel values; None when nowhere.

    Checked in blocks of frames: no temporary of the take's size (only the
    mask, and only when something was lost)."""
    limit = _limits(hier)
    if values.shape[1] == limit.shape[0] and not _any_lost(values, limit):
        return None   # the usual take: one pass, no temporaries
    bad = None
    with np.errstate(invalid="ignore"):
        for a in range(0, values.shape[0], _SCAN_BLOCK):
            block = ~(np.abs(values[a:a + _SCAN_BLOCK]) <= limit)   # NaN compares False: lost too
            if block.any():
                if bad is None:
                    bad = np.zeros(values.shape, dtype=bool)
                bad[a:a + _SCAN_BLOCK] = block
    return bad


def _limits(hier) -> np.ndarray:
    """The largest plausible magnitude of each channel: :data:`MAX_ANGLE_DEG` for a rotation,
    :data:`MAX_POSITION_SIZES` skeleton sizes for a position; once per hierarchy (read-only; an archive's
    takes share a few hierarchies)."""
    cached = hier.__dict__.get("_lost_limits")
    if cached is not None:
        return cached
    _, _, _, _, kinds, _, _, _ = hier.arrays()
    size = float(np.ptp(hier.tree().rest, axis=0).max()) or 1.0
    limit = np.where(kinds == 1, MAX_ANGLE_DEG, MAX_POSITION_SIZES * size)
    limit.flags.writeable = False
    object.__setattr__(hier, "_lost_limits", limit)   # a frozen dataclass: a private memo
    return limit


@jit
def _any_lost(values, limit):  # pragma: no cover - numba
    """Whether any ``values[f, c]`` is not within ``±limit[c]`` (NaN is not): :func:`lost_samples`'s test."""
    for f in range(values.shape[0]):
        ok = True
        for c in range(values.shape[1]):   # a frame's test without a branch per value: vector instructions
            ok &= abs(values[f, c]) <= limit[c]
        if not ok:
            return True
    return False


def pose_frame(values, bad) -> int:
    """The first frame without lost samples (the one the mapper may judge a rig by)."""
    if bad is None:
        return 0
    clean = np.flatnonzero(~bad.any(axis=1))
    return int(clean[0]) if len(clean) else int(np.argmin(bad.sum(axis=1)))


def mend(values, bad, hier, needed, fps, path, notes):
    """Interpolate short lost stretches of the channels FK needs; return the frames kept ``(start, stop)``.

    Each channel of a needed joint is mended on its own: stretches up to
    0.25 s are interpolated (angles along the shorter way round); a longer
    one makes its frames unrecoverable, and the take keeps its longest
    stretch without them (:func:`~mocapdb.readers.gaps.longest_part`).
    ``values`` is changed in place.
    """
    _, _, ch_start, ch_count, kinds, _, _, _ = hier.arrays()
    cols = [c for j in np.flatnonzero(needed) for c in range(ch_start[j], ch_start[j] + ch_count[j])]
    cols = [c for c in cols if bad[:, c].any()]
    n = values.shape[0]
    if not cols:
        return 0, n
    owner = np.repeat(np.arange(len(hier.joints)), ch_count)
    max_gap = max_gap_frames(fps)
    unrecoverable = np.zeros(n, dtype=bool)
    filled = np.zeros(n, dtype=bool)
    lost_joints = {}
    for c in cols:
        b = bad[:, c]
        joint = hier.joints[owner[c]].name
        lost_joints.setdefault(joint, 0)
        lost_joints[joint] += 1
        if b.all():
            raise ParseError(path, None, f"lost tracking: channel {hier.joints[owner[c]].channels[c - ch_start[owner[c]]]} "
                             f"of joint {joint!r} holds no usable value in any frame")
        for a, e in runs(b):
            if e - a > max_gap:
                unrecoverable[a:e] = True
            else:
                filled[a:e] = True
        good = ~b
        column = values[:, c]
        known = column[good]
        if kinds[c] == 1:   # an angle: interpolate the shorter way round (unwrapped)
            known = np.unwrap(known, period=360.0)
        column[b] = np.interp(np.flatnonzero(b), np.flatnonzero(good), known)
    names = ", ".join(sorted(lost_joints)[:6]) + (" …" if len(lost_joints) > 6 else "")
    short = filled & ~unrecoverable
    if short.any():
        notes.append(f"lost tracking (NaN, infinite or absurd values) interpolated in {int(short.sum())} frames "
                     f"(stretches up to {MAX_GAP_S} s; {len(cols)} channels of {names})")
    start, stop, cut = longest_part(unrecoverable, fps, path,
                                    f"tracking lost for longer than {MAX_GAP_S} s in "
                                    + "; ".join(frames_text(a, e, fps) for a, e in runs(unrecoverable)[:3])
                                    + (" …" if len(runs(unrecoverable)) > 3 else "") + f" ({names})")
    if cut:
        notes.append(cut)
    return start, stop
