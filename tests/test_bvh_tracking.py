"""BVH takes with lost tracking, non-human rigs and rigs that only their names explain (issue 19
items 3 and 4).

Lost tracking (NaN, inf, absurd values) is a gap: short stretches are interpolated, longer ones cut
the take to its longest part, too little left is refused. Only humans are read: the dog and the
chicken of foreign2 are refused with one line, every human rig of foreign/ and foreign2/ is read.
Names that say thigh, knee and ankle are trusted over a frame's geometry, and a file reads the same
whatever was read before it. Rigs are built from real takes: an HDM05 kick written as BVH, its rest
pose turned on its side (the motion kept upright), joints renamed as the Bandai dataset names them.
"""
import re

import numpy as np
import pytest

import mocapdb
from mocapdb.errors import ParseError
from mocapdb.features import motion_features
from mocapdb.bodies import JOINT_INDEX, euler_matrix
from mocapdb.readers import read_amc, read_asf, read_bvh, read_motion
from mocapdb.writers import write_bvh
from mocapdb.readers.bvh import parse_bvh
from mocapdb.writers.bvh_write import euler_angles

from conftest import DATA

pytestmark = pytest.mark.shared

FOREIGN = DATA / "foreign" / "bvh"
FOREIGN2 = DATA / "foreign2" / "bvh"
WALK = FOREIGN / "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh"   # 120 Hz, XYZ rotation order
KICK = DATA / "hdm05_cut" / "kickLFront1Reps" / "HDM_bd_kickLFront1Reps_001_120.amc"


def with_values(path, dst, edit):
    """A copy of a BVH file with ``edit(tokens)`` applied to its motion lines (a list of token lists)."""
    text = path.read_bytes()
    head, _, body = text.partition(b"MOTION")
    lines = body.split(b"\n")
    start = next(i for i, ln in enumerate(lines) if ln.strip().lower().startswith(b"frame time")) + 1
    rows = [ln.split() for ln in lines[start:] if ln.strip()]
    edit(rows)
    out = [b"MOTION", b"Frames: %d" % len(rows), lines[start - 1].strip()] + [b" ".join(r) for r in rows]
    dst.write_bytes(head + b"\n".join(out) + b"\n")
    return dst


def lose(columns, frames, token=b"NaN"):
    def edit(rows):
        for f in frames:
            for c in columns:
                rows[f][c] = token
    return edit


@pytest.fixture(scope="module")
def walk():
    return read_bvh(WALK)


def test_the_kinect_take_with_nan_frames_reads():
    motion = read_motion(FOREIGN2 / "kinect_clap_nan.bvh")
    assert motion.n_frames == 100 and np.isfinite(motion.joints).all()
    assert motion.meta["notes"] == ["lost tracking (NaN, infinite or absurd values) interpolated in 97 frames "
                                    "(stretches up to 0.25 s; 22 channels of Head, Hips, LeftFoot, LeftHand, "
                                    "LeftLeg, Neck …)",
                                    "unit cm: the only unit giving the legs an adult's length (0.59 m)"]
    assert len(motion_features(motion)) == 100


def test_a_short_lost_stretch_is_interpolated_near_the_truth(walk, tmp_path):
    """0.2 s of every channel lost in the middle of a 120 Hz walk: interpolated, the joints stay within a
    few centimetres of the recorded ones and the features agree almost everywhere."""
    n_cols = len(WALK.read_text().split("MOTION")[1].split("\n")[3].split())
    lost = read_bvh(with_values(WALK, tmp_path / "lost.bvh", lose(range(n_cols), range(500, 524))))
    assert lost.n_frames == walk.n_frames and lost.meta["notes"][0].startswith(
        "lost tracking (NaN, infinite or absurd values) interpolated in 24 frames")
    body = np.ptp(walk.joints[0, :, 1])
    err = np.linalg.norm(lost.joints - walk.joints, axis=2).max(axis=1)
    assert err[:499].max() == 0 and err[525:].max() == 0 and err.max() < 0.15 * body
    assert np.mean(motion_features(lost) == motion_features(walk)) > 0.95   # words: all 40 features alike


@pytest.mark.parametrize("token", [b"nan", b"-inf", b"1e36", b"-1.#IND"])
def test_a_long_lost_stretch_cuts_the_take_to_its_longest_part(walk, tmp_path, token):
    """1.5 s of the root's channels lost (NaN, infinite or a finite absurd number alike): the take keeps
    its longest stretch without it, with exactly the joints of those frames."""
    part = read_bvh(with_values(WALK, tmp_path / "cut.bvh", lose(range(6), range(300, 480), token)))
    n = walk.n_frames + walk.meta.get("rest_frame_skipped", False)
    assert part.meta["frames"] == (481, n) and part.n_frames == n - 480
    assert part.meta["notes"][0].startswith(f"kept frames 481–{n} of {n}, the longest stretch without an "
                                            "unrecoverable gap (480 frames cut: tracking lost for longer than "
                                            "0.25 s in frames 301–480 (1.50 s) (Hips))")
    offset = 480 - walk.meta.get("rest_frame_skipped", False)
    np.testing.assert_array_equal(part.joints, walk.joints[offset:])


def test_a_take_with_little_left_is_refused(tmp_path):
    n = len([ln for ln in WALK.read_text().split("Frame Time")[1].split("\n")[1:] if ln.strip()])
    keep = set(range(40, 100))   # 0.5 s tracked
    path = with_values(WALK, tmp_path / "little.bvh", lose(range(6), [f for f in range(n) if f not in keep]))
    with pytest.raises(ParseError, match="tracking lost for longer than 0.25 s in frames 1–40 \\(0.33 s\\); frames "
                                         f"101–{n} .* the longest stretch without it, frames 41–100 \\(0.50 s\\), "
                                         f"is too little of the {n} frames to keep"):
        read_bvh(path)


@pytest.mark.parametrize("name, why", [
    ("dog_D1_007_KAN01_001.bvh", "not a human skeleton: it stands upright (two legs to the floor, arms off it, "
                                 "head above the shoulders) in 0% of the frames and not in its rest pose; trunk "
                                 "1.21 × the leg length (a human's: 0.2–1.1)"),
    ("chicken_walk.bvh", "not a humanoid skeleton mocapdb can map: cannot find the joints of an arm in "
                         "Bip01_Spine1 → BN_Finger_R_01 → BN_Finger_R_02 → BN_Finger_R_02/end (an arm has upper "
                         "arm, forearm and hand)")])
def test_animals_are_refused_in_one_line_that_says_why(name, why, tmp_path, open_db):
    path = FOREIGN2 / name
    with pytest.raises(ParseError) as info:
        read_motion(path)
    assert str(info.value).startswith(f"{path}: {why}") and "\n" not in str(info.value)
    con = open_db(tmp_path / "t.duckdb")
    report = mocapdb.ingest(con, [path])
    assert report.failed == [(str(path), str(info.value))] and not report.ingested


def test_every_human_rig_of_the_other_labs_reads():
    humans = sorted((set(FOREIGN.glob("*.bvh")) | set(FOREIGN2.glob("*.bvh")))
                    - {FOREIGN / "fairmotion_sinusoidal.bvh", FOREIGN2 / "dog_D1_007_KAN01_001.bvh",
                       FOREIGN2 / "chicken_walk.bvh"})
    assert len(humans) == 5
    for path in humans:
        motion = read_motion(path)
        assert motion.skeleton == "bvh:humanoid" and np.isfinite(motion.joints).all(), path


# ----------------------------------------------------------------------------
# rigs explained by their names, and the same reading whatever came before

#: HDM05 bone (the BVH joint at its start) → the joint names of the Bandai-Namco dataset
BANDAI = {"root": "Hips", "lhipjoint": "Pelvis_L", "lfemur": "UpperLeg_L", "ltibia": "LowerLeg_L",
          "lfoot": "Foot_L", "ltoes": "Toes_L", "rhipjoint": "Pelvis_R", "rfemur": "UpperLeg_R",
          "rtibia": "LowerLeg_R", "rfoot": "Foot_R", "rtoes": "Toes_R", "lowerback": "Spine", "upperback": "Chest",
          "thorax": "Chest2", "lowerneck": "Neck", "upperneck": "Neck2", "head": "Head",
          "lclavicle": "Shoulder_L", "lhumerus": "UpperArm_L", "lradius": "LowerArm_L", "lwrist": "Hand_L",
          "lhand": "Palm_L", "lfingers": "Fingers_L", "lthumb": "Thumb_L", "rclavicle": "Shoulder_R",
          "rhumerus": "UpperArm_R", "rradius": "LowerArm_R", "rwrist": "Hand_R", "rhand": "Palm_R",
          "rfingers": "Fingers_R", "rthumb": "Thumb_R"}


def lying_rig(path, dst, names, start):
    """The BVH file at ``path`` from frame ``start`` on, its rest pose turned 90° about z (the rig lies on
    its side, as some exporters bake a joint orientation) while every frame keeps its pose: OFFSETs
    R·o, the root's rotation L·Rᵀ, every other joint's R·L·Rᵀ (so each global rotation becomes G·Rᵀ
    and every joint stays where it was). Joints renamed by ``names`` (an index for others)."""
    data = parse_bvh(path.read_bytes(), path=path)
    hier = data.hierarchy
    rot = euler_matrix(np.radians([90.0]), "z")
    values = data.values[start:].copy()
    for k, joint in enumerate(hier.joints):
        cols = [c for c, ch in enumerate(joint.channels) if ch.endswith("rotation")]
        order = "".join(joint.channels[c][0].lower() for c in cols)
        at = [joint.channel_start + c for c in cols]
        local = euler_matrix(np.radians(values[:, at]), order)
        local = local @ rot.T if joint.parent < 0 else rot @ local @ rot.T
        values[:, at] = np.degrees(euler_angles(local, order))
    text = path.read_text()
    head = text.split("MOTION")[0]
    offsets = iter([rot @ j.offset if j.parent >= 0 else j.offset for j in hier.joints])
    ends = {k: rot @ j.end_site for k, j in enumerate(hier.joints) if j.end_site is not None}
    out, joint = [], -1
    for line in head.split("\n"):
        if re.match(r"\s*(ROOT|JOINT)\s", line):
            joint += 1
            key, name = line.split()[:2]
            line = line.replace(f"{key} {name}", f"{key} {names.get(name, f'J{joint}')}")
        if line.strip().startswith("OFFSET"):
            indent = line[:len(line) - len(line.lstrip())]
            v = ends.pop(joint) if out and out[-1].strip() == "{" and out[-2].strip() == "End Site" else next(offsets)
            line = indent + "OFFSET " + " ".join(f"{x:.12g}" for x in v)
        out.append(line)
    rows = "\n".join(" ".join(f"{x:.12g}" for x in row) for row in values)
    dst.write_text("\n".join(out) + f"MOTION\nFrames: {len(values)}\nFrame Time: {data.frame_time}\n{rows}\n")
    return dst


@pytest.fixture(scope="module")
def kick(tmp_path_factory):
    """An HDM05 kick as ASF-named BVH, the frame where the kicking foot is highest, and its joints."""
    skeleton = read_asf(DATA / "hdm05_cut" / "HDM_bd.asf")
    motion = read_amc(KICK, skeleton)
    path = write_bvh(tmp_path_factory.mktemp("kick") / "kick.bvh", skeleton, motion)
    joints = read_bvh(path, skip_rest_frame=False).joints
    apex = int(np.argmax(joints[:, JOINT_INDEX["ltoes"], 1]))
    return path, apex, joints


def test_names_are_trusted_over_a_frame_with_a_foot_in_the_air(kick, tmp_path):
    """The Bandai 'dash' case: a rest pose on its side makes the mapper judge the first frame, in which
    one foot is up at the hip; the names UpperLeg_L, LowerLeg_L, Foot_L place the legs anyway."""
    path, apex, joints = kick
    rig = lying_rig(path, tmp_path / "dash.bvh", BANDAI, apex)
    motion = read_bvh(rig, skip_rest_frame=False)
    assert motion.skeleton == "bvh:humanoid"
    assert motion.meta["mapping"]["lknee"] == "LowerLeg_L" and motion.meta["mapping"]["lankle"] == "Foot_L"
    idx = [JOINT_INDEX[j] for j in ("root", "lknee", "lankle", "rknee", "rankle", "lelbow", "relbow")]
    assert np.abs(motion.joints[:, idx] - joints[apex:, idx]).max() < 1e-6


def test_a_file_reads_the_same_whatever_was_read_before_it(kick, tmp_path):
    """Two files of one skeleton whose names say nothing and whose rest pose lies on its side: the
    mapper judges each by its own first frame. A file whose first frame stands reads; one whose first
    frame has a foot up at the hip is refused, alone, after the other, or before it (a mapping cached
    from the other file used to read it)."""
    path, apex, _ = kick
    standing = lying_rig(path, tmp_path / "a_standing.bvh", {}, 0)
    kicking = lying_rig(path, tmp_path / "b_kicking.bvh", {}, apex)

    def outcome(p):
        try:
            return read_bvh(p, skip_rest_frame=False).joints
        except ParseError as exc:
            return str(exc)
    alone = outcome(kicking)
    assert isinstance(alone, str) and "not a humanoid skeleton mocapdb can map" in alone
    first = outcome(standing)
    assert not isinstance(first, str)
    assert outcome(kicking) == alone
    assert np.array_equal(outcome(standing), first)
    for order in ([standing, kicking], [kicking, standing]):
        with mocapdb.connect(tmp_path / f"{order[0].stem}.duckdb") as con:
            report = mocapdb.ingest(con, order)
            assert [p for p, *_ in report.ingested] == [str(standing)]
            assert [p for p, _ in report.failed] == [str(kicking)]
