"""The human test's kernel (issue 35) against the NumPy it replaced: the same distances, medians and
upright booleans bit for bit, on the joints of real takes (humans, an animal, a folded pose) and on
random ones (grid coordinates: ties in the medians, equalities in every comparison; NaN)."""
import gzip

import numpy as np
import pytest

import mocapdb.readers.bvh as bvh_reader
from bvh_edit import channel, edit_bvh
from conftest import DATA, SAMPLE_86_09, SAMPLE_86_ASF, SAMPLE_BVH, shared_cases
from mocapdb.bodies.humanoid import _SAMPLE, _human_measures, humanoid_problem, upright_frames
from mocapdb.bodies.joints import JOINT_INDEX
from mocapdb.errors import ParseError
from mocapdb.readers import read_motion

# ----------------------------------------------------------------------------
# the NumPy the kernel replaced (mocapdb 994c261), verbatim but for the names

_PAIRS = (("lhip", "lknee"), ("lknee", "lankle"), ("rhip", "rknee"), ("rknee", "rankle"),
          ("lshoulder", "lelbow"), ("lelbow", "lwrist"), ("rshoulder", "relbow"), ("relbow", "rwrist"),
          ("root", "neck"), ("lhip", "rhip"), ("lshoulder", "rshoulder"))


def numpy_lengths(j, step=1):
    j = j[::step]
    return {(a, b): np.linalg.norm(j[:, JOINT_INDEX[a]] - j[:, JOINT_INDEX[b]], axis=-1) for a, b in _PAIRS}


def numpy_upright(j, ln):
    y = j[..., 1]
    leg = 0.5 * (ln["lhip", "lknee"] + ln["lknee", "lankle"] + ln["rhip", "rknee"] + ln["rknee", "rankle"])
    spine = j[:, JOINT_INDEX["neck"]] - j[:, JOINT_INDEX["root"]]
    vertical = spine[:, 1] > np.cos(np.radians(45.0)) * np.linalg.norm(spine, axis=1)
    shoulders = 0.5 * (y[:, JOINT_INDEX["lshoulder"]] + y[:, JOINT_INDEX["rshoulder"]])
    head_up = y[:, JOINT_INDEX["head"]] > shoulders
    feet = np.minimum(y[:, JOINT_INDEX["lankle"]], y[:, JOINT_INDEX["rankle"]])
    hands = np.minimum(y[:, JOINT_INDEX["lwrist"]], y[:, JOINT_INDEX["rwrist"]])
    hips = np.minimum(y[:, JOINT_INDEX["lhip"]], y[:, JOINT_INDEX["rhip"]])
    return vertical & head_up & (hands - feet > 0.25 * leg) & (feet < hips)


def numpy_median_leg(ln):
    return float(np.median(np.concatenate([ln["lhip", "lknee"] + ln["lknee", "lankle"],
                                           ln["rhip", "rknee"] + ln["rknee", "rankle"]])))


def numpy_medians(ln):
    measures = {"arm": 0.5 * (ln["lshoulder", "lelbow"] + ln["lelbow", "lwrist"]
                              + ln["rshoulder", "relbow"] + ln["relbow", "rwrist"]),
                "trunk": ln["root", "neck"], "hip width": ln["lhip", "rhip"],
                "shoulder width": ln["lshoulder", "rshoulder"]}
    return {what: float(np.median(m)) for what, m in measures.items()}


def assert_twins(joints, step):
    leg, med, upright, stands = _human_measures(joints, step)
    ln = numpy_lengths(joints, step)
    want_leg, want_med, want_up = numpy_median_leg(ln), numpy_medians(ln), numpy_upright(joints[::step], ln)
    # bit for bit (NaN where NumPy gives NaN)
    assert np.array_equal(np.float64(leg), np.float64(want_leg), equal_nan=True)
    assert list(med) == list(want_med)
    assert np.array_equal(np.array(list(med.values())), np.array(list(want_med.values())), equal_nan=True)
    assert np.array_equal(upright, want_up)
    assert stands == float(want_up.mean())
    if not np.isnan(joints).any():
        assert np.array_equal(upright_frames(joints[::step]), want_up)


# ----------------------------------------------------------------------------
# real takes: the joints the BVH reader hands to the human test


def _tested_joints(monkeypatch, read):
    """The (joints, rest) the BVH reader asks the human test about while ``read()`` runs."""
    seen = []

    def recording(joints, rest=None, **kw):
        seen.append((np.array(joints), None if rest is None else np.array(rest)))
        return humanoid_problem(joints, rest, **kw)

    monkeypatch.setattr(bvh_reader, "humanoid_problem", recording)
    try:
        read()
    except ParseError:
        pass
    assert seen
    return seen


def _folded(tmp_path):
    data = gzip.decompress((DATA / "accad_dev" / "Male1_B3_Walk.bvh.gz").read_bytes())

    def fold(values, hier):
        values[:, channel(hier, "Spine1", "Zrotation")] += 170.0

    path = tmp_path / "folded.bvh"
    path.write_bytes(edit_bvh(data, values=fold))
    return path


REAL = shared_cases(["accad_dev/Male1_B3_Walk.bvh.gz", "foreign2/bvh/dog_D1_007_KAN01_001.bvh",
                     "foreign/bvh/mixamo_freebvh.bvh", "folded"])


@pytest.mark.parametrize("which", REAL)
def test_real_takes_agree_with_numpy(which, monkeypatch, tmp_path):
    path = _folded(tmp_path) if which == "folded" else DATA / which
    for joints, rest in _tested_joints(monkeypatch, lambda: read_motion(path)):
        for step in sorted({1, 2, 7, max(1, len(joints) // _SAMPLE)}):
            assert_twins(joints, step)
        assert_twins(rest[None], 1)


def test_the_shipped_takes_agree_with_numpy(monkeypatch):
    (joints, rest), = _tested_joints(monkeypatch, lambda: read_motion(SAMPLE_BVH))
    assert_twins(joints, 1)
    assert_twins(joints, max(1, len(joints) // _SAMPLE))
    assert_twins(rest[None], 1)
    amc = read_motion(SAMPLE_86_09, asf=SAMPLE_86_ASF).joints
    assert_twins(amc, 1)
    assert_twins(amc[::-1], 3)   # a negative-stride view


# ----------------------------------------------------------------------------
# random joints


@pytest.mark.parametrize("seed", range(15))
@pytest.mark.parametrize("n", [1, 2, 3, 10, 511, 1200])
def test_random_joints_agree_with_numpy(seed, n):
    rng = np.random.default_rng(seed * 1000 + n)
    kind = seed % 5
    if kind == 0:     # anything
        joints = rng.normal(size=(n, 24, 3)) * rng.uniform(0.01, 100.0)
    elif kind == 1:   # a small grid: ties in every median, equal heights, hands exactly 0.25 leg above the feet
        joints = rng.integers(-2, 3, size=(n, 24, 3)).astype(np.float64)
    elif kind == 2:   # a standing body jittered: the upright test goes both ways
        joints = np.zeros((n, 24, 3))
        for name, y in (("root", 1.0), ("neck", 1.5), ("head", 1.7), ("lshoulder", 1.45), ("rshoulder", 1.45),
                        ("lhip", 0.95), ("rhip", 0.95), ("lknee", 0.5), ("rknee", 0.5), ("lankle", 0.1),
                        ("rankle", 0.1), ("lelbow", 1.2), ("relbow", 1.2), ("lwrist", 0.95), ("rwrist", 0.95)):
            joints[:, JOINT_INDEX[name], 1] = y
        joints += rng.normal(size=joints.shape) * rng.choice([0.0, 0.05, 0.3], size=(n, 1, 1))
    elif kind == 3:   # NaN here and there (the NumPy test gives NaN medians and False frames)
        joints = rng.normal(size=(n, 24, 3))
        joints[rng.random(size=joints.shape) < 0.01] = np.nan
    else:             # every joint on the vertical: whole lengths, hands exactly a quarter leg above the feet
        joints = np.zeros((n, 24, 3))
        joints[..., 1] = rng.integers(0, 9, size=(n, 24))
    for step in sorted({1, 3, max(1, n // _SAMPLE)}):
        assert_twins(joints, step)


def test_the_measures_end_in_the_same_answers():
    # the decisions the reader acts on, on edge cases of the test files: a body lying down, one standing
    rng = np.random.default_rng(5)
    stand = np.zeros((40, 24, 3))
    for name, y in (("root", 1.0), ("neck", 1.5), ("head", 1.7), ("lshoulder", 1.45), ("rshoulder", 1.45),
                    ("lhip", 0.95), ("rhip", 0.95), ("lknee", 0.5), ("rknee", 0.5), ("lankle", 0.1),
                    ("rankle", 0.1), ("lelbow", 1.2), ("relbow", 1.2), ("lwrist", 0.95), ("rwrist", 0.95)):
        stand[:, JOINT_INDEX[name], 1] = y
    for s in "lr":
        x = 0.1 if s == "l" else -0.1
        for name in ("hip", "knee", "ankle"):
            stand[:, JOINT_INDEX[s + name], 0] = x
        for name in ("shoulder", "elbow", "wrist"):
            stand[:, JOINT_INDEX[s + name], 0] = 2 * x
    stand += rng.normal(size=stand.shape) * 0.01
    assert humanoid_problem(stand) is None
    lying = stand[..., [1, 0, 2]]
    what, why = humanoid_problem(lying)
    assert what == "skeleton" and "stands upright" in why
    assert humanoid_problem(lying, stand[0]) is None
