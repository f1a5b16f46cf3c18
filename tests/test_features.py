"""Tests of mocapdb.features: the toolbox oracle, the naive reference, properties.

Oracle: ../shared/oracle/features (the toolbox's 40 features of 237 documents
at 120 and 30 Hz) and ../shared/oracle/positions (its joint positions for 13
of them). FEATURES.md §7 gives the properties tested on real data.
"""
import csv
import functools
import math

import numpy as np
import pytest

import naive_features as naive
from conftest import DATA, ORACLE, SAMPLE_86_ASF, shared_cases
from mocapdb import features as F
from mocapdb.errors import ParameterError
from mocapdb.bodies.joints import JOINT_INDEX, MIRROR_JOINTS
from mocapdb.bodies.motion import Motion
from mocapdb.readers import read_motion

J = JOINT_INDEX
PERM = list(F.MIRROR_FEATURES)

#: features whose quantity is a velocity (zero for a static pose), 1-based
VELOCITY_FEATURES = (1, 2, 5, 6, 10, 11, 12, 13, 14, 23, 24, 25, 26, 39, 40)
#: features using no asymmetric body unit (hum_R / hum_L / body_len), 1-based
SYMMETRIC_UNIT_FEATURES = (3, 4, 7, 8, 9, 20, 21, 22, 27, 28, 29, 30, 32, 40)


# --------------------------------------------------------------------------
# oracle access

def _read_manifest():
    with open(ORACLE / "features" / "manifest.csv", newline="") as fh:
        return {row["stem"]: row for row in csv.DictReader(fh)}


MANIFEST = _read_manifest() if (ORACLE / "features" / "manifest.csv").is_file() else {}
POSITION_STEMS = sorted(p.name[:-len("_pos120.csv")]
                        for p in (ORACLE / "positions").glob("*_pos120.csv"))


def oracle_features(stem, rate):
    a = np.loadtxt(ORACLE / "features" / f"{stem}_feat{rate}.csv", delimiter=",",
                   skiprows=1, dtype=np.uint8, ndmin=2)
    return a.astype(bool)


@functools.lru_cache(maxsize=None)
def oracle_positions(stem):
    a = np.loadtxt(ORACLE / "positions" / f"{stem}_pos120.csv", delimiter=",", skiprows=1)
    return a.reshape(len(a), 24, 3)


@functools.lru_cache(maxsize=None)
def amc_root_rotation(stem):
    """Throwaway: R = Rz(rz)·Ry(ry)·Rx(rx) from the AMC ``root`` lines (degrees).

    Only for the position-file tests while the reader is not there; the
    reader test goes through mocapdb.readers.
    """
    rows = []
    with open(DATA / MANIFEST[stem]["amc"], "rb") as fh:
        for line in fh:
            if line.startswith(b"root "):
                rows.append([float(x) for x in line.split()[4:7]])
    rx, ry, rz = np.radians(np.array(rows)).T
    c, s = np.cos, np.sin
    o, z = np.ones_like(rx), np.zeros_like(rx)
    Rx = np.stack([o, z, z, z, c(rx), -s(rx), z, s(rx), c(rx)], -1).reshape(-1, 3, 3)
    Ry = np.stack([c(ry), z, s(ry), z, o, z, -s(ry), z, c(ry)], -1).reshape(-1, 3, 3)
    Rz = np.stack([c(rz), -s(rz), z, s(rz), c(rz), z, z, z, o], -1).reshape(-1, 3, 3)
    return Rz @ Ry @ Rx


def agreement_table(fast, oracle):
    """Per-feature agreement, printed in assertion messages."""
    lines = [f"{'#':>3} {'feature':34} {'agree %':>8} {'fast on':>8} {'oracle on':>9}"]
    for k in range(F.N_FEATURES):
        agree = 100.0 * np.mean(fast[:, k] == oracle[:, k]) if len(fast) else 100.0
        mark = "" if agree == 100.0 else "  <--"
        lines.append(f"{k + 1:>3} {F.FEATURE_NAMES[k]:34} {agree:8.3f} "
                     f"{int(fast[:, k].sum()):8d} {int(oracle[:, k].sum()):9d}{mark}")
    return "\n".join(lines)


def assert_oracle(fast120, stem, label=""):
    o120 = oracle_features(stem, 120)
    o30 = oracle_features(stem, 30)
    assert fast120.shape == o120.shape, (stem, fast120.shape, o120.shape)
    assert np.array_equal(fast120, o120), \
        f"{stem}{label} at 120 Hz:\n{agreement_table(fast120, o120)}"
    fast30 = F.downsample(fast120)
    assert np.array_equal(fast30, o30), \
        f"{stem}{label} at 30 Hz:\n{agreement_table(fast30, o30)}"


# --------------------------------------------------------------------------
# 1. oracle agreement

@pytest.mark.shared
@pytest.mark.parametrize("stem", shared_cases(POSITION_STEMS))
def test_oracle_positions(stem):
    """Toolbox positions → features equal the toolbox features (120 and 30 Hz)."""
    pos = oracle_positions(stem)
    feats = F.relational_features(pos, amc_root_rotation(stem), 120.0)
    assert_oracle(feats, stem, " (root rotation)")
    # the position-only #40 (hip axis) reproduces the toolbox on AMC data (§2.4.8)
    assert_oracle(F.relational_features(pos, None, 120.0), stem, " (hip axis)")


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("stem", shared_cases(sorted(MANIFEST)))
def test_oracle_reader(stem):
    """Every oracle document read by mocapdb.readers: all 40 features, 120 and 30 Hz."""
    row = MANIFEST[stem]
    motion = read_motion(DATA / row["amc"], asf=DATA / row["asf"])
    assert motion.n_frames == int(row["frames_120hz"])
    assert_oracle(F.relational_features(motion.joints, motion.root_rotation, motion.fps),
                  stem)
    words = F.motion_features(motion)
    assert len(words) == int(row["frames_30hz"])
    # bits 0-39 are the toolbox's 40; bit 40 is feature 41 (FEATURES.md §10), beyond the paper
    assert np.array_equal(words & np.uint64((1 << F.N_FEATURES) - 1), F.pack_words(oracle_features(stem, 30)))


@pytest.mark.shared
def test_rare_features_are_exercised():
    """The oracle set turns every feature on somewhere (f09 in one clip only)."""
    on = np.zeros(40, bool)
    for stem in MANIFEST:
        on |= oracle_features(stem, 30).any(axis=0)
    assert on.all(), [k + 1 for k in np.flatnonzero(~on)]


# --------------------------------------------------------------------------
# fast vs naive reference

def _random_motion(rng, n, base):
    """A real pose plus a random walk of every joint: exercises every branch."""
    step = rng.choice([0.5, 2.0, 6.0])
    return base + np.cumsum(rng.normal(0.0, step, (n, 24, 3)), axis=0)


def _random_rotations(rng, n):
    """Root rotations turning about Y at a random (sometimes fast) rate, with tilt."""
    yaw = np.cumsum(rng.normal(0, rng.choice([0.2, 1.5]), n))
    tilt = rng.normal(0, 0.3, n)
    c, s = np.cos(yaw), np.sin(yaw)
    ct, st = np.cos(tilt), np.sin(tilt)
    o, z = np.ones(n), np.zeros(n)
    Ry = np.stack([c, z, s, z, o, z, -s, z, c], -1).reshape(n, 3, 3)
    Rx = np.stack([o, z, z, z, ct, -st, z, st, ct], -1).reshape(n, 3, 3)
    return Ry @ Rx


@pytest.mark.shared
@pytest.mark.parametrize("stem", ["HDM_bd_throwBasketball_001_120",
                                  "HDM_bd_hopBothLegs1hops_001_120", "02_01"])
def test_fast_matches_naive_real(stem):
    pos = oracle_positions(stem)
    rot = amc_root_rotation(stem)
    fast = F.relational_features(pos, rot, 120.0)
    ref = naive.relational_features(pos, rot, 120.0)
    assert np.array_equal(fast, ref), agreement_table(fast, ref)


@pytest.mark.shared
def test_fast_matches_naive_random():
    """Seeded random motions: lengths below/above every window, several rates."""
    rng = np.random.default_rng(20090801)
    base = np.concatenate([oracle_positions(s) for s in (
        "HDM_bd_squat1Reps_001_120", "HDM_bd_depositFloorR_001_120",
        "HDM_bd_lieDownFloor_001_120")])
    ever_on = np.zeros(40, bool)
    ever_off = np.zeros(40, bool)
    cases = [(n, fps) for n in (2, 3, 7, 12, 13, 29, 31, 64, 300)
             for fps in (120.0, 60.0, 100.0, 30.0, 240.0)]
    for n, fps in cases:
        joints = _random_motion(rng, n, base[rng.integers(len(base))])
        rot = _random_rotations(rng, n) if rng.random() < 0.5 else None
        thr = (50.0, 100.0) if rng.random() < 0.7 else F.ROOT_ANG_VEL_THRESHOLDS_ALT
        fast = F.relational_features(joints, rot, fps, root_ang_vel_thresholds=thr)
        ref = naive.relational_features(joints, rot, fps, root_ang_vel_thresholds=thr)
        assert np.array_equal(fast, ref), f"n={n} fps={fps}\n{agreement_table(fast, ref)}"
        ever_on |= fast.any(axis=0)
        ever_off |= ~fast.all(axis=0)
    # the random data must decide every feature both ways, or the test is vacuous
    assert ever_on.all(), [k + 1 for k in np.flatnonzero(~ever_on)]
    assert ever_off.all(), [k + 1 for k in np.flatnonzero(~ever_off)]


def test_smoothing_window_conversion():
    """ceil(ms/1000·fps) with a minimum of 1 (FEATURES.md §1)."""
    assert F.smoothing_window(100, 120) == 12
    assert F.smoothing_window(250, 120) == 30
    assert F.smoothing_window(0, 120) == 1
    assert F.smoothing_window(100, 30) == 3
    assert F.smoothing_window(250, 30) == 8
    for ms in (0, 100, 250):
        for fps in (24.0, 25.0, 30.0, 50.0, 59.94, 60.0, 100.0, 119.88, 120.0, 240.0):
            assert F.smoothing_window(ms, fps) == naive.window_frames(ms, fps)


# --------------------------------------------------------------------------
# 2. properties on real data (FEATURES.md §7)

def _mirror(joints, rotation=None):
    """Left/right swap of the joints, x → −x: a proper mirror image."""
    m = joints[:, list(MIRROR_JOINTS)].copy()
    m[..., 0] *= -1.0
    if rotation is None:
        return m, None
    s = np.diag([-1.0, 1.0, 1.0])
    return m, s @ rotation @ s  # the mirrored root frame, S·R·S


def _symmetric_limbs(joints):
    """The same motion with the left humerus, femur and tibia as long as the right.

    The body units (§3) measure the right humerus and right leg (and hum_L for
    #1/2/5/6/35/36); the skeletons here are asymmetric by up to 8 %, so the
    mirror image would see other units. Rescale the left bones rigidly (the
    bones below move along) so that the units are mirror invariant.
    """
    p = joints.copy()
    for parent, child, below, rparent, rchild in (
            ("lshoulder", "lelbow", ("lwrist", "lfingers"), "rshoulder", "relbow"),
            ("lhip", "lknee", ("lankle", "ltoes"), "rhip", "rknee"),
            ("lknee", "lankle", ("ltoes",), "rknee", "rankle")):
        bone = p[:, J[child]] - p[:, J[parent]]
        scale = (np.linalg.norm(joints[0, J[rchild]] - joints[0, J[rparent]])
                 / np.linalg.norm(bone[0]))
        shift = p[:, J[parent]] + bone * scale - p[:, J[child]]
        for j in (child,) + below:
            p[:, J[j]] += shift
    return p


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("stem", shared_cases(POSITION_STEMS))
def test_mirror_symmetry(stem):
    """Mirroring the motion permutes the features by MIRROR_FEATURES.

    Exception, with reason: #1/#2 measure both hands' velocity relative to
    *lhip* (plane neck/rhip/lhip, anchor lhip), so the mirror image of #1 is
    #2 measured relative to rhip. The anchor matters because the normal is
    taken at frame t while the velocity is averaged over 250 ms. Those two are
    checked against the naive reference with anchor rhip instead.
    #40 is mirror invariant (a reflection keeps angles between floor-plane
    directions), both from the root rotation (mirrored as S·R·S) and from the
    hip axis.
    """
    raw = oracle_positions(stem)
    rot = amc_root_rotation(stem)
    # raw skeleton: the features without asymmetric units are exactly permuted
    cols = [k - 1 for k in SYMMETRIC_UNIT_FEATURES]
    a = F.relational_features(raw, rot, 120.0)
    b = F.relational_features(*_mirror(raw, rot), 120.0)
    assert np.array_equal(b[:, PERM][:, cols], a[:, cols])
    # symmetric limbs: everything is permuted, #1/#2 up to their anchor
    pos = _symmetric_limbs(raw)
    for rotation in (rot, None):
        a = F.relational_features(pos, rotation, 120.0)
        mirrored = F.relational_features(*_mirror(pos, rotation), 120.0)
        back = mirrored[:, PERM]
        rest = list(range(2, 40))
        assert np.array_equal(back[:, rest], a[:, rest]), agreement_table(back, a)
    head = pos[:1200]  # the naive reference is slow; body units come from frame 0
    back = F.relational_features(*_mirror(head), 120.0)[:, PERM]
    rhip = naive.relational_features(head, None, 120.0, to_front_anchor="rhip")
    assert np.array_equal(back[:, :2], rhip[:, :2]), agreement_table(back, rhip)
    # and the words: mirror_words of the original = words of the mirror image
    # (bits of #1/#2 masked, see above)
    mask = ~np.uint64(0b11)
    assert np.array_equal(F.mirror_words(F.pack_words(a)) & mask,
                          F.pack_words(mirrored) & mask)


def _asf_bones(path):
    """(name, dof tokens) of every bone of an ASF, for writing a rest-pose AMC."""
    bones, name, dof = [], None, []
    with open(path, "rb") as fh:
        for raw in fh:
            tok = raw.decode("latin-1").split()
            if not tok:
                continue
            if tok[0] == "begin":
                name, dof = None, []
            elif tok[0] == "name":
                name = tok[1]
            elif tok[0] == "dof":
                dof = tok[1:]
            elif tok[0] == "end" and name is not None:
                bones.append((name, dof))
                name = None
    return bones


@pytest.mark.parametrize("asf", [
    pytest.param(DATA / "hdm05_cut/HDM_bd.asf", marks=pytest.mark.shared, id="hdm05_cut/HDM_bd.asf"),
    pytest.param(DATA / "cmu/02/02.asf", marks=pytest.mark.shared, id="cmu/02/02.asf"),
    pytest.param(SAMPLE_86_ASF, id="cmu/86/86.asf")])
def test_rest_pose(asf, tmp_path):
    """All AMC values 0 → exactly {3, 4, 9, 19, 27, 28, 38} (FEATURES.md §7)."""
    lines = [":FULLY-SPECIFIED", ":DEGREES"]
    for frame in range(1, 41):
        lines.append(str(frame))
        lines.append("root 0 0 0 0 0 0")
        lines += [" ".join([name] + ["0"] * len(dof)) for name, dof in _asf_bones(asf)
                  if dof]
    amc = tmp_path / "rest.amc"
    amc.write_text("\n".join(lines) + "\n")
    motion = read_motion(amc, asf=asf)
    assert np.ptp(motion.joints, axis=0).max() == 0.0
    feats = F.relational_features(motion.joints, motion.root_rotation, motion.fps)
    on = {k + 1 for k in np.flatnonzero(feats.any(axis=0))}
    assert on == {3, 4, 9, 19, 27, 28, 38}
    assert feats.all(axis=0).sum() == 7  # constant over time
    # the hip-axis #40 agrees (no turning either way)
    assert np.array_equal(F.relational_features(motion.joints, None, motion.fps), feats)


def _t_pose(pose):
    """A real standing pose with both arms stretched out sideways, horizontally."""
    p = pose.copy()
    for side, other in (("l", "r"), ("r", "l")):
        out = p[J[side + "shoulder"]] - p[J[other + "shoulder"]]
        out[1] = 0.0
        out /= np.linalg.norm(out)
        chain = [side + j for j in ("shoulder", "elbow", "wrist", "fingers")]
        for parent, child in zip(chain, chain[1:]):
            length = np.linalg.norm(pose[J[child]] - pose[J[parent]])
            p[J[child]] = p[J[parent]] + out * length
    return p


@pytest.mark.shared
@pytest.mark.parametrize("stem", ["HDM_bd_squat1Reps_001_120", "02_01", "86_09"])
def test_t_pose(stem):
    """T-pose: #27, #28 (upper arms abducted) and #9 (hands apart) on; arms straight."""
    joints = np.repeat(_t_pose(oracle_positions(stem)[0])[None], 30, axis=0)
    feats = F.relational_features(joints, None, 120.0)
    assert feats[:, [26, 27, 8]].all()
    assert not feats[:, [6, 7]].any()  # elbows not bent


@pytest.mark.shared
@pytest.mark.parametrize("stem", shared_cases(POSITION_STEMS))
def test_static_pose(stem):
    """Frame 0 repeated: velocity features 0, the others constant = frame 0 of the take."""
    pos = oracle_positions(stem)
    static = np.repeat(pos[:1], 50, axis=0)
    rot = np.repeat(amc_root_rotation(stem)[:1], 50, axis=0)
    feats = F.relational_features(static, rot, 120.0)
    vel = [k - 1 for k in VELOCITY_FEATURES]
    assert not feats[:, vel].any()
    other = [k for k in range(40) if k + 1 not in VELOCITY_FEATURES]
    assert (feats[:, other] == feats[0, other]).all()
    moving = F.relational_features(pos, amc_root_rotation(stem), 120.0)
    assert np.array_equal(feats[0, other], moving[0, other])


@pytest.mark.shared
@pytest.mark.parametrize("stem", shared_cases(POSITION_STEMS))
def test_unit_independence(stem):
    """Scaling every position (any length unit) changes no feature."""
    pos = oracle_positions(stem)
    rot = amc_root_rotation(stem)
    ref = F.relational_features(pos, rot, 120.0)
    for scale in (0.37, 2.54, 1000.0):
        assert np.array_equal(F.relational_features(pos * scale, rot, 120.0), ref), scale


@pytest.mark.shared
def test_degenerate_lengths():
    """n = 1 → all zero (the toolbox errors, §7); n = 0 → empty; n = 2 works."""
    pos = oracle_positions("HDM_bd_squat1Reps_001_120")
    assert F.relational_features(pos[:0], None, 120.0).shape == (0, 40)
    one = F.relational_features(pos[:1], None, 120.0)
    assert one.shape == (1, 40) and not one.any()
    assert F.motion_features(Motion(pos[:1], None, 120.0)).tolist() == [0]
    two = F.relational_features(pos[:2], None, 120.0)
    assert np.array_equal(two, naive.relational_features(pos[:2], None, 120.0))


@pytest.mark.shared
def test_parameter_errors():
    pos = oracle_positions("HDM_bd_squat1Reps_001_120")[:10]
    with pytest.raises(ParameterError, match=r"joints must have shape \(n_frames, 24, 3\)"):
        F.relational_features(pos[:, :20], None, 120.0)
    with pytest.raises(ParameterError, match="fps must be a positive number"):
        F.relational_features(pos, None, 0.0)
    with pytest.raises(ParameterError, match="fps must be a positive number"):
        F.relational_features(pos, None, float("nan"))
    with pytest.raises(ParameterError, match=r"root_rotation must have shape \(10, 3, 3\)"):
        F.relational_features(pos, np.zeros((9, 3, 3)), 120.0)
    with pytest.raises(ParameterError, match="lenient <= strict"):
        F.relational_features(pos, None, 120.0, root_ang_vel_thresholds=(100.0, 50.0))
    with pytest.raises(ParameterError, match="two numbers"):
        F.relational_features(pos, None, 120.0, root_ang_vel_thresholds=50.0)
    with pytest.raises(ParameterError, match="at most 64 columns"):
        F.pack_words(np.zeros((3, 65), bool))
    with pytest.raises(ParameterError, match="0/1 values"):
        F.pack_words(np.full((3, 4), 2))
    with pytest.raises(ParameterError, match="factor must be a positive integer"):
        F.downsample(np.zeros((8, 40), bool), factor=0)
    with pytest.raises(ParameterError, match="same shape"):
        F.hysteresis(np.zeros((5, 2), bool), np.zeros((5, 3), bool))


@pytest.mark.shared
def test_alternative_root_thresholds():
    """#40 with (100, 110) deg/s is on in a subset of the (50, 100) frames."""
    pos = oracle_positions("86_09")
    rot = amc_root_rotation("86_09")
    default = F.relational_features(pos, rot, 120.0)
    alt = F.relational_features(pos, rot, 120.0,
                                root_ang_vel_thresholds=F.ROOT_ANG_VEL_THRESHOLDS_ALT)
    assert np.array_equal(alt[:, :39], default[:, :39])
    assert not (alt[:, 39] & ~default[:, 39]).any()
    assert default[:, 39].sum() > alt[:, 39].sum()


# --------------------------------------------------------------------------
# 3. hysteresis

def test_hysteresis_worked_example():
    f1 = np.array([0, 1, 1, 1, 1, 1, 0, 1, 1, 1], bool)
    f2 = np.array([0, 0, 0, 1, 0, 0, 0, 0, 1, 0], bool)
    expected = np.array([0, 0, 0, 1, 1, 1, 0, 0, 1, 1], bool)
    assert np.array_equal(F.hysteresis(f1, f2), expected)
    assert np.array_equal(naive.edge_rule(f1, f2), expected)


def test_hysteresis_matches_edge_rule():
    """State machine = the toolbox's edge rule on random nested f2 ⊆ f1."""
    rng = np.random.default_rng(5)
    for _ in range(300):
        n = int(rng.integers(1, 80))
        k = int(rng.integers(1, 5))
        # runs of f1 with random switching rates; f2 a random subset of f1
        f1 = np.cumsum(rng.random((n, k)) < rng.uniform(0.05, 0.6), axis=0) % 2 == 1
        f1 ^= rng.random(k) < 0.5
        f2 = f1 & (rng.random((n, k)) < rng.uniform(0.0, 0.6))
        fast = F.hysteresis(f1, f2)
        for j in range(k):
            ref = naive.edge_rule(f1[:, j], f2[:, j])
            assert np.array_equal(fast[:, j], ref), (f1[:, j], f2[:, j])
            assert np.array_equal(naive.state_machine(f1[:, j], f2[:, j]), ref)


# --------------------------------------------------------------------------
# 4. words: pack / unpack / downsample / runs

def test_pack_bit_order():
    """Bit k−1 of the word is feature k."""
    for k in range(40):
        row = np.zeros((1, 40), bool)
        row[0, k] = True
        assert F.pack_words(row)[0] == np.uint64(1) << np.uint64(k)
    assert F.pack_words(np.ones((1, 40), bool))[0] == np.uint64(2**40 - 1)
    assert F.pack_words(np.ones((1, 64), bool))[0] == np.uint64(2**64 - 1)


@pytest.mark.shared
def test_pack_unpack_roundtrip():
    rng = np.random.default_rng(1)
    for n in (0, 1, 7, 1000):
        for k in (1, 12, 14, 40, 64):
            f = rng.random((n, k)) < rng.random()
            w = F.pack_words(f)
            assert w.dtype == np.uint64 and w.shape == (n,)
            assert np.array_equal(w, naive.pack_words(f))
            assert np.array_equal(F.unpack_words(w, k), f)
    o = oracle_features("86_09", 30)
    assert np.array_equal(F.unpack_words(F.pack_words(o)), o)
    # 0/1 integers (as read from CSV) pack like booleans
    assert np.array_equal(F.pack_words(o.astype(np.uint8)), F.pack_words(o))


def test_downsample():
    for n in range(0, 10):
        x = np.arange(n * 40).reshape(n, 40) % 3 == 0
        d = F.downsample(x)
        assert len(d) == math.ceil(n / 4)
        assert np.array_equal(d, x[[t for t in range(n) if t % 4 == 0]])
    w = np.arange(11, dtype=np.uint64)
    assert F.downsample(w).tolist() == [0, 4, 8]
    assert F.downsample(w, factor=1).tolist() == w.tolist()


@pytest.mark.shared
def test_feature_runs():
    rng = np.random.default_rng(2)
    for n in (0, 1, 2, 50, 2000):
        words = rng.integers(0, 4, n).astype(np.uint64) << np.uint64(38)
        starts, lengths, values = F.feature_runs(words)
        assert starts.dtype == np.int64 and lengths.dtype == np.int64
        assert values.dtype == np.uint64
        assert np.array_equal(np.repeat(values, lengths), words)
        assert np.array_equal(starts, np.concatenate(([0], np.cumsum(lengths)[:-1]))
                              if n else starts)
        assert (values[1:] != values[:-1]).all()  # maximal
        ref = naive.feature_runs(words.tolist())
        assert (starts.tolist(), lengths.tolist(), values.tolist()) == ref
    words = F.pack_words(oracle_features("86_09", 30))
    s, ln, v = F.feature_runs(words)
    assert np.array_equal(np.repeat(v, ln), words) and ln.sum() == len(words)


def test_mirror_words():
    rng = np.random.default_rng(3)
    f = rng.random((500, 40)) < 0.3
    w = F.pack_words(f)
    m = F.mirror_words(w)
    assert np.array_equal(F.unpack_words(m), f[:, PERM])
    assert np.array_equal(F.mirror_words(m), w)  # an involution
    single = F.mirror_words(np.array([1 << 34], dtype=np.uint64))  # #35 -> #36
    assert single.tolist() == [1 << 35]


@pytest.mark.shared
def test_motion_features_pipeline():
    stem = "HDM_bd_kickLFront1Reps_001_120"
    motion = Motion(oracle_positions(stem), amc_root_rotation(stem), 120.0, name=stem)
    words = F.motion_features(motion)
    assert words.dtype == np.uint64
    # bits 0-39 are the toolbox's 40; bit 40 is feature 41 (FEATURES.md §10), beyond the paper
    assert np.array_equal(words & np.uint64((1 << F.N_FEATURES) - 1), F.pack_words(oracle_features(stem, 30)))


def _sample_order_velocity(joints, q, p, windows):
    """The smoothed velocities in plain Python, one output at a time in the toolbox's ``conv`` order (each
    sample times 1/w, oldest first), the forward difference as ``(P_q − P_p)(t + 1) − (P_q − P_p)(t)`` and
    NumPy's 'symmetric' padding: what the kernel must give bit for bit, however it lays out its loops."""
    n = len(joints)
    out = np.empty((len(q), n, 3))
    for k in range(len(q)):
        w = int(windows[k])
        traj = joints[:, q[k]] - joints[:, p[k]] if p[k] >= 0 else joints[:, q[k]]
        v = np.vstack([traj[1:] - traj[:-1], traj[-1:] - traj[-2:-1]])
        if n < w:
            v = np.pad(v, ((0, w - n), (0, 0)), mode="symmetric")
        half = (w + 1) // 2
        u = np.pad(v, ((half, half), (0, 0)), mode="symmetric")
        inv_w = 1.0 / w
        for t in range(n):
            for c in range(3):
                a = 0.0
                for j in range(w):
                    a = float(u[t + 1 + j, c]) * inv_w + a
                out[k, t, c] = a
    return out


@pytest.mark.parametrize("n", [2, 3, 5, 12, 31, 64, 150])
def test_smoothed_velocity_kernel_sums_in_the_toolbox_order(n):
    """The velocity kernel (its trajectories' coordinates in one pass, its box sums a window offset at a
    time over every output, issue 35) equals the one-output-at-a-time sums bit for bit: the shipped take's
    frames and seeded random ones, takes shorter than the windows, the 120 Hz and other rates' windows."""
    from mocapdb.features.relational import _VEL_P, _VEL_Q, _smoothed_velocity_kernel, _windows
    real = read_motion(SAMPLE_86_ASF.parent / "86_09.amc.xz", asf=SAMPLE_86_ASF).joints
    rng = np.random.default_rng(n)
    for joints, fps in ((real[:n], 120.0), (real[40:40 + n], 100.0),
                        (rng.normal(0, 30, size=(n, 24, 3)), 120.0), (rng.normal(0, 1, size=(n, 24, 3)), 240.0)):
        joints = np.ascontiguousarray(joints)
        windows = _windows(fps)
        out = np.empty((len(_VEL_Q), n, 3))
        _smoothed_velocity_kernel(joints, _VEL_Q, _VEL_P, windows, out)
        assert np.array_equal(out, _sample_order_velocity(joints, _VEL_Q, _VEL_P, windows))
