"""Which frames the body travels in (lab/travel.py): the root's smoothed horizontal speed, in metres."""
import numpy as np
import pytest

from mocapdb.bodies.motion import Motion
from lab.travel import TRAVEL_SPEED, root_speed, travelling_frames


def _walker(speeds, fps=120.0, unit="m", scale=1.0):
    """A body whose root moves along x at ``speeds`` (m/s, a value per source frame), Y up, in ``unit``."""
    x = np.concatenate(([0.0], np.cumsum(speeds[:-1]) / fps))
    joints = np.zeros((len(speeds), 24, 3))
    joints[:, :, 1] = 1.0 / scale                     # every joint a metre up: height does not count
    joints[:, 0, 0] = x / scale
    return Motion(joints, None, fps, source_format="bvh", meta={"unit": unit})


def test_standing_then_walking_travels_from_the_step_on():
    speeds = np.r_[np.zeros(240), np.full(360, 1.0)]      # 2 s still, 3 s at 1 m/s, 120 Hz
    t = travelling_frames(_walker(speeds))
    assert t.size == 150                                   # the 30 Hz grid
    assert not t[:52].any() and t[68:].all()               # the ±8-frame window straddles the start at frame 60
    assert root_speed(_walker(speeds))[100] == pytest.approx(1.0)


@pytest.mark.parametrize("unit,scale", [("cm", 0.01), ("inch", 0.0254), ("m", 1.0)])
def test_speed_is_in_metres_whatever_the_unit(unit, scale):
    speeds = np.full(300, 0.5)
    assert root_speed(_walker(speeds, unit=unit, scale=scale))[30] == pytest.approx(0.5)


def test_vertical_motion_and_sway_under_the_threshold_do_not_travel():
    m = _walker(np.zeros(300))
    m.joints[:, 0, 1] += 0.3 * np.sin(np.arange(300) / 20)                   # crouching: up and down
    m.joints[:, 0, 2] += 0.04 * np.sin(2 * np.pi * np.arange(300) / 120)     # 4 cm sway at 1 Hz
    assert not travelling_frames(m).any()
    assert travelling_frames(_walker(np.full(300, TRAVEL_SPEED * 1.1))).all()


def test_a_one_frame_clip_does_not_travel():
    assert travelling_frames(_walker(np.zeros(1))).tolist() == [False]
