"""A motion as an MP4 video of its stick figure: the media ELAN plays beside the label tiers.

ELAN plays audio and video only, so a motion capture file linked as an
``.eaf``'s media gives it nothing to show (issue 33 item 9).
``annotate --format eaf --video`` writes this video beside each ``.eaf`` and
links it. Its frames are the motion's 30 Hz feature frames — frame i shown from
i/30 s, the grid of the segments' ``start_s`` / ``end_s`` — so the video plays
in step with the tiers.

The figure is drawn here, without a plotting library: a numba kernel stamps
the bones into RGB frames (a few milliseconds a frame), a block of frames at a
time so that memory does not grow with the take, and Debian's ``ffmpeg``
encodes them as H.264 in ``yuv420p``, which every player ELAN uses opens. The
view is orthographic, from the front-right (30° about the vertical); the
camera follows the root across the floor and frames the body's extent over the
whole take, so a take with large vertical motion (a jump, a dance) or without
root translation stays inside the picture, and the floor line stays put.
"""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np

from mocapdb._numba import inline_jit, jit
from mocapdb.errors import ParameterError
from mocapdb.features import FEATURE_RATE
from mocapdb.viewer.encoding import BONES

#: picture size in pixels (even, as yuv420p needs)
WIDTH, HEIGHT = 640, 480
#: frames drawn and handed to ffmpeg at once: 64 × 640 × 480 × 3 bytes ≈ 59 MB
BLOCK_FRAMES = 64
#: the view's turn about the vertical axis, from the front
YAW_DEG = 30.0
#: the free border around the body's extent, as a share of the picture
MARGIN = 0.08
#: stroke radius of a bone and of a joint, in pixels
BONE_RADIUS, JOINT_RADIUS = 2, 3
_RADII = np.array((BONE_RADIUS, JOINT_RADIUS), np.int64)
_BACKGROUND = np.array((250, 250, 247), np.uint8)
_BONE = np.array((40, 70, 130), np.uint8)
_JOINT = np.array((200, 80, 40), np.uint8)
_FLOOR = np.array((170, 170, 170), np.uint8)
_CLOCK = np.array((120, 160, 210), np.uint8)


def ffmpeg_path() -> str:
    """The ``ffmpeg`` on PATH.

    Raises
    ------
    ParameterError
        If there is none (it is a system package: Debian's ``apt-get install ffmpeg``).
    """
    exe = shutil.which("ffmpeg")
    if exe is None:
        raise ParameterError("a video needs ffmpeg on PATH (Debian/Ubuntu: apt-get install ffmpeg; macOS: "
                             "brew install ffmpeg)")
    return exe


def picture_coordinates(joints, width=WIDTH, height=HEIGHT):
    """Pixel coordinates of the joints in the video's view, and the floor's row.

    Parameters
    ----------
    joints : (n, J, 3) float
        Joint positions, Y up (any unit: the view is framed on the body).
    width, height : int

    Returns
    -------
    uv : (n, J, 2) float64
        Column and row of each joint (rows grow downwards), inside the picture
        for every frame.
    floor : float
        The row of the lowest point of the take.
    """
    joints = np.asarray(joints, np.float64)
    if joints.ndim != 3 or joints.shape[0] == 0 or joints.shape[2] != 3:
        raise ParameterError(f"joints must be (frames, joints, 3) with at least one frame, got {joints.shape}")
    if not np.isfinite(joints).all():
        raise ParameterError("joints must be finite")
    yaw = np.deg2rad(YAW_DEG)
    across = joints[..., 0] * np.cos(yaw) + joints[..., 2] * np.sin(yaw)
    across = across - across[:, :1]  # the camera follows the root
    up = joints[..., 1]
    lo_a, hi_a = across.min(), across.max()
    lo_u, hi_u = up.min(), up.max()
    span = max(hi_a - lo_a, hi_u - lo_u, 1e-9)
    inner_w, inner_h = width * (1 - 2 * MARGIN), height * (1 - 2 * MARGIN)
    scale = min(inner_w / max(hi_a - lo_a, 1e-9 * span), inner_h / max(hi_u - lo_u, 1e-9 * span))
    mid_a, mid_u = (lo_a + hi_a) / 2, (lo_u + hi_u) / 2
    uv = np.empty(joints.shape[:2] + (2,), np.float64)
    uv[..., 0] = width / 2 + (across - mid_a) * scale
    uv[..., 1] = height / 2 - (up - mid_u) * scale
    return uv, height / 2 - (lo_u - mid_u) * scale


@inline_jit
def _stamp(frame, x, y, radius, color):
    h, w = frame.shape[0], frame.shape[1]
    cx, cy = int(round(x)), int(round(y))
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            if dx * dx + dy * dy <= radius * radius:
                px, py = cx + dx, cy + dy
                if 0 <= px < w and 0 <= py < h:
                    frame[py, px, 0] = color[0]
                    frame[py, px, 1] = color[1]
                    frame[py, px, 2] = color[2]


@jit
def _draw_kernel(uv, bones, floor, first, n_total, out, background, bone, joint, ground, clock, radii):
    """Draw frames first … first + len(out) − 1 of ``uv`` into ``out`` (frames × rows × columns × RGB)."""
    n, h, w = out.shape[0], out.shape[1], out.shape[2]
    for f in range(n):
        frame = out[f]
        for r in range(h):
            for c in range(w):
                frame[r, c, 0] = background[0]
                frame[r, c, 1] = background[1]
                frame[r, c, 2] = background[2]
        row = int(round(floor)) + 2
        if 0 <= row < h:
            for c in range(w):
                frame[row, c, 0] = ground[0]
                frame[row, c, 1] = ground[1]
                frame[row, c, 2] = ground[2]
        # the time: a bar along the bottom edge that fills as the take plays
        filled = int(w * (first + f + 1) / n_total)
        for r in range(h - 4, h):
            for c in range(filled):
                frame[r, c, 0] = clock[0]
                frame[r, c, 1] = clock[1]
                frame[r, c, 2] = clock[2]
        pose = uv[first + f]
        for b in range(bones.shape[0]):
            x0, y0 = pose[bones[b, 0], 0], pose[bones[b, 0], 1]
            x1, y1 = pose[bones[b, 1], 0], pose[bones[b, 1], 1]
            steps = int(max(abs(x1 - x0), abs(y1 - y0)) * 2) + 1
            for s in range(steps + 1):
                t = s / steps
                _stamp(frame, x0 + (x1 - x0) * t, y0 + (y1 - y0) * t, radii[0], bone)
        for j in range(pose.shape[0]):
            _stamp(frame, pose[j, 0], pose[j, 1], radii[1], joint)


def draw_frames(joints, first=0, count=None, width=WIDTH, height=HEIGHT):
    """Frames ``first … first + count − 1`` of a motion's stick-figure video as RGB pictures.

    Parameters
    ----------
    joints : (n, 24, 3) float
        The canonical joints (:data:`mocapdb.bodies.JOINT_NAMES`), Y up.
    first, count : int
        The frames to draw (default: all from ``first``).

    Returns
    -------
    (count, height, width, 3) uint8
    """
    uv, floor = picture_coordinates(joints, width, height)
    n = uv.shape[0]
    count = n - first if count is None else count
    if not (0 <= first and 0 <= count and first + count <= n):
        raise ParameterError(f"frames {first}…{first + count - 1} are not frames of a {n}-frame motion")
    out = np.empty((count, height, width, 3), np.uint8)
    _draw_kernel(uv, np.array(BONES, np.int64), floor, first, n, out, _BACKGROUND, _BONE, _JOINT, _FLOOR, _CLOCK, _RADII)
    return out


def write_video(path, joints, fps=FEATURE_RATE):
    """Write a motion's stick figure as an H.264 MP4 (frame i shown from i / fps seconds).

    Parameters
    ----------
    path : str or Path
        The ``.mp4`` file (replaced if it exists).
    joints : (n, 24, 3) float
        The canonical joints on the video's frame grid (the 30 Hz feature
        frames: :func:`mocapdb.viewer.motion_poses`).
    fps : float

    Raises
    ------
    ParameterError
        If ffmpeg is missing or fails (its last message quoted).
    """
    path = Path(path)
    joints = np.asarray(joints, np.float64)
    uv, floor = picture_coordinates(joints)  # validates before ffmpeg starts
    cmd = [ffmpeg_path(), "-loglevel", "error", "-nostdin", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24",
           "-s", f"{WIDTH}x{HEIGHT}", "-r", repr(float(fps)), "-i", "pipe:0", "-an", "-c:v", "libx264",
           "-pix_fmt", "yuv420p", "-movflags", "+faststart", str(path)]
    bones = np.array(BONES, np.int64)
    n = uv.shape[0]
    with subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) as proc:
        try:
            block = np.empty((min(BLOCK_FRAMES, n), HEIGHT, WIDTH, 3), np.uint8)
            for first in range(0, n, BLOCK_FRAMES):
                part = block[:min(BLOCK_FRAMES, n - first)]
                _draw_kernel(uv, bones, floor, first, n, part, _BACKGROUND, _BONE, _JOINT, _FLOOR, _CLOCK, _RADII)
                proc.stdin.write(part.tobytes())
        except BrokenPipeError:
            pass  # ffmpeg stopped: its own message follows
        finally:
            proc.stdin.close()
        err = proc.stderr.read().decode("utf-8", "replace").strip()
        code = proc.wait()
    if code != 0:
        path.unlink(missing_ok=True)
        last = err.splitlines()[-1] if err else f"exit status {code}"
        raise ParameterError(f"{path}: ffmpeg could not write the video ({last})")
    return path


__all__ = ["draw_frames", "picture_coordinates", "write_video", "ffmpeg_path", "WIDTH", "HEIGHT"]
