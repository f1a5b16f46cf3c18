"""Feature 41 (FEATURES.md §10, beyond the paper): the heading turned far within a few seconds.

A brute-force twin of the heading change, invariances (turning the whole
take about the vertical, mirroring), the 40 toolbox features untouched,
and what it says on real takes: every turning walk of the studio's clips
turns, no straight walk or run does.
"""
import dataclasses

import numpy as np
import pytest

from conftest import DATA, SAMPLE_86_09, SAMPLE_86_ASF, SAMPLE_BVH, shared_cases
from mocapdb import features as F
from mocapdb.errors import ParameterError
from lab.turns import turn_path, turning_walk
from mocapdb.features.heading import heading_change, heading_degrees
from mocapdb.readers import read_motion

BIT = np.uint64(F.N_FEATURES)  # feature 41 is bit 40


def bit41(words):
    return ((np.asarray(words, np.uint64) >> BIT) & np.uint64(1)).astype(bool)


def naive_heading_change(joints, rot, fps, window_s):
    """Frame by frame: the angle between the axis directions half a window before and after, summed
    over the frames in between (the unwrapped change), with the same rules for an upright axis."""
    axis = rot[:, :, 0] if rot is not None else joints[:, 1] - joints[:, 5]   # lhip - rhip
    n = len(axis)
    last = None
    ang = []
    for t in range(n):
        a = axis[t]
        if np.hypot(a[0], a[2]) > 0.5 * np.linalg.norm(a):
            last = np.arctan2(a[2], a[0])
        ang.append(last)
    first = next((x for x in ang if x is not None), 0.0)
    ang = [first if x is None else x for x in ang]
    # unwrap step by step
    h = [ang[0]]
    for t in range(1, n):
        d = (ang[t] - ang[t - 1] + np.pi) % (2 * np.pi) - np.pi
        h.append(h[-1] + d)
    h = np.degrees(h)
    half = max(1, int(round(window_s * fps / 2)))
    return np.array([abs(h[min(t + half, n - 1)] - h[max(t - half, 0)]) for t in range(n)])


@pytest.fixture(scope="module")
def walk():
    return read_motion(SAMPLE_BVH)


def test_heading_change_matches_its_naive_twin(walk):
    rng = np.random.default_rng(5)
    for rot in (None, walk.root_rotation):
        for window in (0.5, 3.0):
            got = heading_change(walk.joints, rot, walk.fps, window_s=window)
            np.testing.assert_allclose(got, naive_heading_change(walk.joints, rot, walk.fps, window), atol=1e-9)
    # random axes, some of them nearly upright (their heading holds)
    joints = rng.normal(size=(200, 24, 3))
    joints[50:60, 1] = joints[50:60, 5] + [0.01, 1.0, 0.0]
    np.testing.assert_allclose(heading_change(joints, None, 30.0, window_s=1.0),
                               naive_heading_change(joints, None, 30.0, 1.0), atol=1e-9)


def test_feature_41_does_not_change_the_40(walk):
    words = F.motion_features(walk)
    assert bit41(words).dtype == bool
    forty = F.pack_words(F.relational_features(*F.resample_joints(walk.joints, walk.root_rotation, walk.fps),
                                               120.0)[::4][:len(words)])
    np.testing.assert_array_equal(words & np.uint64((1 << 40) - 1), forty)


def test_feature_41_ignores_where_the_take_faces(walk):
    """Turning the whole take about the vertical by a constant angle changes no bit."""
    turned = turn_path(walk, np.full(walk.n_frames, 1.3))
    np.testing.assert_array_equal(bit41(F.motion_features(turned)), bit41(F.motion_features(walk)))


def test_feature_41_has_no_side():
    w = np.array([1 << 40, (1 << 40) | 1, 2], dtype=np.uint64)
    np.testing.assert_array_equal(bit41(F.mirror_words(w)), bit41(w))
    np.testing.assert_array_equal(F.mirror_words(F.mirror_words(w)), w)


def test_a_walk_turned_round_turns_and_the_straight_walk_does_not():
    """The CMU walker of the sample, straightened, then turned by 120° over 2 s: feature 41 holds
    around the turn and nowhere on the straight part."""
    from lab.turns import straightened_walk

    m = read_motion(SAMPLE_86_09, asf=SAMPLE_86_ASF)
    walk = dataclasses.replace(m, joints=m.joints[:880], root_rotation=m.root_rotation[:880])
    straight = straightened_walk(walk)
    assert not bit41(F.motion_features(straight)).any()
    turned = turning_walk(straight, 3.0, 2.0, 120.0, style="smooth")
    b = bit41(F.motion_features(turned))
    assert b.any()
    on = np.flatnonzero(b) / 30.0
    assert on.min() > 1.0 and on.max() < 6.5           # around the turn (3–5 s), not at the ends


def test_thresholds_are_checked(walk):
    with pytest.raises(ParameterError, match="lenient <= strict"):
        F.heading_turned(walk.joints, None, walk.fps, thresholds=(80, 40))
    with pytest.raises(ParameterError, match="positive"):
        heading_change(walk.joints, None, walk.fps, window_s=0)
    assert heading_degrees(np.zeros((0, 24, 3))).shape == (0,)


STUDIO = sorted((DATA / "bandai2_dev").glob("*walk*.bvh.gz")) + sorted((DATA / "bandai2_dev").glob("*_run_*.bvh.gz"))


@pytest.mark.shared
@pytest.mark.parametrize("path", shared_cases(STUDIO), ids=lambda p: getattr(p, "name", str(p))[10:-7])
def test_studio_walks_turn_exactly_when_their_names_say(path):
    """Every walk-turn clip of bandai2_dev (90–105°) holds feature 41 somewhere; no straight walk or run does."""
    b = bit41(F.motion_features(read_motion(path)))
    assert b.any() == ("walk-turn" in path.name)


def test_the_heading_streamed_block_by_block_is_the_whole_takes_bit_for_bit(walk):
    """Issue 32 item 5: HeadingChangeStream carries the unwrap, the held heading and the leading unreliable
    frames over blocks of any size; real takes (the sample walk, the CMU document, a walk turned round,
    a lie-down clip whose pelvis axis stands upright) and the same with unreliable stretches made."""
    from lab.turns import straightened_walk
    from mocapdb.features.heading import HeadingChangeStream, heading_axis

    cmu = read_motion(SAMPLE_86_09, asf=SAMPLE_86_ASF)
    turned = turning_walk(straightened_walk(dataclasses.replace(cmu, joints=cmu.joints[:880],
                                                                root_rotation=cmu.root_rotation[:880])),
                          3.0, 2.0, 200.0, style="smooth")
    takes = [walk, cmu, turned]
    lie = sorted((DATA / "hdm05_cut" / "lieDownFloor").glob("*.amc"))
    if lie:
        takes.append(read_motion(lie[0]))
    checked = 0
    for take in takes:
        for rot in (take.root_rotation, None):
            base = heading_axis(take.joints, rot)
            for made in ("as is", "upright start", "upright half", "upright middle"):
                axis = base.copy()
                if made == "upright start":
                    axis[:50] = [0.0, 1.0, 0.0]
                elif made == "upright half":
                    axis[: len(axis) // 2] = [0.05, 1.0, 0.0]
                elif made == "upright middle":   # held over block boundaries
                    axis[len(axis) // 3: len(axis) // 2] = [0.0, 1.0, 0.05]
                whole = heading_change(None, None, take.fps, axis=axis)
                for block in (1, 37, 500, len(axis)):
                    stream = HeadingChangeStream(len(axis), take.fps)
                    got = np.concatenate([stream.feed(axis[a:a + block]) for a in range(0, len(axis), block)]
                                         + [stream.finish()])
                    assert got.tobytes() == whole.tobytes(), (take.name, made, block)
                    checked += 1
                    if take is turned and made == "as is":
                        assert whole.max() > 150   # a real turn crossed ±180° on the way
    upright = np.tile([0.0, 1.0, 0.0], (400, 1))
    stream = HeadingChangeStream(400, 120.0)
    parts = [stream.feed(upright[:150]), stream.feed(upright[150:]), stream.finish()]
    np.testing.assert_array_equal(np.concatenate(parts), heading_change(None, None, 120.0, axis=upright))
    assert checked >= 3 * 2 * 4 * 4


def test_feature_41_of_a_long_take_by_blocks_is_the_whole_takes(monkeypatch):
    """The block path of a long take (pipeline._words_by_block) with the heading streamed: the same
    words, feature 41 included, as the whole take's — on a walk turned round twice (the feature on)."""
    import mocapdb.features.pipeline as pipeline
    from lab.turns import straightened_walk

    m = read_motion(SAMPLE_86_09, asf=SAMPLE_86_ASF)
    walk = straightened_walk(dataclasses.replace(m, joints=m.joints[:880], root_rotation=m.root_rotation[:880]))
    turned = turning_walk(walk, 3.0, 2.0, 170.0, style="smooth")
    whole = F.motion_features(turned)
    assert bit41(whole).any() and not bit41(whole).all()
    for block in (8, 60, 256):
        monkeypatch.setattr(pipeline, "BLOCK_FRAMES", block)
        np.testing.assert_array_equal(F.motion_features(turned), whole, err_msg=f"blocks of {block}")
