"""Which frames of a clip the body travels in: the root's smoothed horizontal speed over a walking threshold.

A clip whose truth is per clip ("stand, then walk"; a walking turn that starts
from standing; a side step of one metre) stands still for part of it, and
``move`` there is not expected of an annotation: the share of a locomotion
clip's frames under ``move`` counts those frames as missed. The second
figure of the evaluation (``move`` over travelling frames, docs/CLASSES.md §6)
counts only the frames where the root travels:

* the root's horizontal position (X, Z; Y is up) in metres — the unit the
  reader decided (:func:`mocapdb.bodies.units.metres_per_unit`) — on the
  30 Hz feature grid;
* its speed as the displacement between the frames :data:`TRAVEL_HALF_WINDOW`
  before and after (0.53 s, about one step: a step's sway and a side step's
  stop-and-go average out), clipped at the clip's ends;
* travelling where that speed is at least :data:`TRAVEL_SPEED`.

0.2 m/s lies above every standing motion of accad_dev (swaying peaks at
0.17 m/s, swinging arms and looking around at 0.02) and far below its
slowest locomotion (backward walks, median 0.8 m/s); benchmarks/RESULTS.md
(issue 32, where ACCAD's ``move`` is lost) shows the figure for 0.1–0.4 m/s.
"""
from __future__ import annotations

import numpy as np

from mocapdb.bodies.joints import JOINT_INDEX
from mocapdb.bodies.units import metres_per_unit
from mocapdb.features.rates import feature_grid

__all__ = ["TRAVEL_SPEED", "TRAVEL_HALF_WINDOW", "root_speed", "travelling_frames"]

#: metres per second of the root's smoothed horizontal speed at and above which the body travels
TRAVEL_SPEED = 0.2
#: frames (30 Hz) either side of a frame over which its speed is measured
TRAVEL_HALF_WINDOW = 8


def root_speed(motion, *, half_window=TRAVEL_HALF_WINDOW) -> np.ndarray:
    """The root's horizontal speed (m/s) on the 30 Hz feature grid, over ±``half_window`` frames."""
    scale, _ = metres_per_unit(motion)
    grid = feature_grid(motion.n_frames, motion.fps)
    t = np.arange(motion.n_frames) / motion.fps
    root = motion.joints[:, JOINT_INDEX["root"]]
    x, z = (np.interp(grid, t, root[:, k] * scale) for k in (0, 2))
    i = np.arange(grid.size)
    a, b = np.maximum(i - half_window, 0), np.minimum(i + half_window, grid.size - 1)
    dt = grid[b] - grid[a]
    dist = np.hypot(x[b] - x[a], z[b] - z[a])
    return np.divide(dist, dt, out=np.zeros_like(dist), where=dt > 0)   # a one-frame clip does not travel


def travelling_frames(motion, *, speed=TRAVEL_SPEED, half_window=TRAVEL_HALF_WINDOW) -> np.ndarray:
    """A boolean per 30 Hz feature frame: the root travels (module docstring)."""
    return root_speed(motion, half_window=half_window) >= speed
