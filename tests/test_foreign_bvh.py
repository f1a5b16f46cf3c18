"""Other tools' BVH files (../shared/data/foreign/bvh, issue 9): every humanoid
ingests without a mapping file, rates reach 30 Hz, dialects parse, bad files stay
with themselves.

Files: Mixamo via 20tab/bvh-python, PyMO, bvhio, fairmotion (BSD/MIT; see
../shared/data/README.md).
"""
import math
import re
import shutil

import numpy as np
import pytest

import mocapdb
from conftest import DATA, SAMPLE_86_09, SAMPLE_86_ASF, SAMPLE_BVH
from mocapdb.errors import ParseError
from mocapdb.features import FEATURE_RATE, motion_features, unpack_words
from mocapdb.bodies import JOINT_INDEX, Motion
from mocapdb.readers import (bvh_joint_map, joint_map_template, load_mapping, parse_bvh, read_amc, read_asf,
                             read_bvh, read_motion)
from mocapdb.writers import write_bvh

FOREIGN = DATA / "foreign" / "bvh"
HUMANOIDS = {  # file: (source rate, frames after a dropped rest frame)
    "bvhio_example.bvh": (30.0, 2),
    "fairmotion_pfnn_hierarchy.bvh": (30.0, 60),
    "mixamo_freebvh.bvh": (30.0, 69),
    "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh": (120.0, 1064),
}
NON_HUMANOID = "fairmotion_sinusoidal.bvh"


@pytest.mark.shared
def test_the_folder_holds_what_the_tests_expect():
    assert sorted(p.name for p in FOREIGN.glob("*.bvh")) == sorted([*HUMANOIDS, NON_HUMANOID])


@pytest.fixture(scope="module")
def foreign_db(tmp_path_factory):
    con = mocapdb.connect(tmp_path_factory.mktemp("foreign") / "f.duckdb")
    report = mocapdb.ingest(con, [FOREIGN])
    yield con, report
    con.close()


@pytest.mark.shared
def test_every_humanoid_ingests_with_no_mapping_file(foreign_db):
    con, report = foreign_db
    assert sorted(p.split("/")[-1] for p, *_ in report.ingested) == sorted(HUMANOIDS)
    rows = {r[0]: r[1:] for r in con.execute(
        "SELECT name || '.bvh', source_fps, fps, n_source_frames, n_frames, format FROM motions").fetchall()}
    for name, (rate, frames) in HUMANOIDS.items():
        source_fps, fps, n_src, n30, fmt = rows[name]
        assert (source_fps, n_src, fmt) == (rate, frames, "bvh"), name
        # features always at 30 Hz: every grid time k/30 up to the last frame
        assert fps == FEATURE_RATE and n30 == math.floor((frames - 1) * 30 / rate + 1e-9) + 1, name


@pytest.mark.shared
def test_the_non_humanoid_is_refused_naming_its_joints(foreign_db):
    _, report = foreign_db
    (path, reason), = report.failed
    assert path.endswith(NON_HUMANOID)
    assert reason.startswith(f"{path}: not a humanoid skeleton")
    assert "its 4 joints: base, child1, child2, child3" in reason
    assert "could not place: root, lhip" in reason and "mocapdb joint-map-template" in reason


@pytest.mark.shared
@pytest.mark.parametrize("name,expect", [
    ("mixamo_freebvh.bvh", {"root": "mixamorig:Hips", "lknee": "mixamorig:LeftLeg", "rwrist": "mixamorig:RightHand",
                            "neck": "mixamorig:Neck", "head": "mixamorig:Head", "lshoulder": "mixamorig:LeftArm"}),
    ("bvhio_example.bvh", {"lknee": "LeftLowLeg", "relbow": "RightLowArm", "lshoulder": "LeftUpArm",
                           "ltoes": "LeftFoot/end"}),
    ("fairmotion_pfnn_hierarchy.bvh", {"lhip": "LeftUpLeg", "neck": "Neck", "lwrist": "LeftHand",
                                        "lfingers": "LeftHandIndex1"}),
    ("pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh", {"rknee": "RightLeg", "neck": ["LeftShoulder", "RightShoulder"],
                                               "rfingers": "RightHand_End"}),
])
def test_names_place_the_joints(name, expect):
    mapping = read_bvh(FOREIGN / name).meta["mapping"]
    for joint, where in expect.items():
        assert mapping[joint] == where, (joint, mapping[joint])


@pytest.mark.shared
@pytest.mark.parametrize("name", sorted(HUMANOIDS))
def test_left_is_left_and_features_are_defined(name):
    """Left/right are not swapped: in the rest pose the left hip is on the side of
    up × forward (forward from the feet). Zero-length bones (pfnn: Neck, LHipJoint
    and the toe End Sites have OFFSET 0) still give defined features."""
    m = read_bvh(FOREIGN / name)
    hier = parse_bvh((FOREIGN / name).read_bytes()).hierarchy
    j = bvh_joint_map(hier).weights @ hier.tree().rest  # the rest pose
    forward = (j[JOINT_INDEX["ltoes"]] + j[JOINT_INDEX["rtoes"]]) / 2 - (j[JOINT_INDEX["lankle"]] + j[JOINT_INDEX["rankle"]]) / 2
    forward[1] = 0
    left = np.cross([0.0, 1.0, 0.0], forward)
    # (bvhio's feet end straight down at rest: no forward to judge by)
    if np.linalg.norm(forward) > 0.2 * np.linalg.norm(j[JOINT_INDEX["lhip"]] - j[JOINT_INDEX["rhip"]]):
        assert np.dot(j[JOINT_INDEX["lhip"]] - j[JOINT_INDEX["rhip"]], left) > 0
        assert np.dot(j[JOINT_INDEX["lshoulder"]] - j[JOINT_INDEX["rshoulder"]], left) > 0
    j = m.joints[0]
    words = motion_features(m)
    assert len(words) == math.floor((m.n_frames - 1) * 30 / m.fps + 1e-9) + 1
    # distinct spine points: chest length > 0 for #3-#6
    assert np.linalg.norm(j[JOINT_INDEX["chest"]] - j[JOINT_INDEX["neck"]]) > 0


def test_the_pymo_walk_walks_forward():
    """The walking take (a figure eight) moves the root along the facing direction
    of the hips (left × up) frame by frame: a mirrored mapping walks backwards."""
    m = read_bvh(SAMPLE_BVH)  # foreign/bvh/pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh, shipped with mocapdb
    step = m.joints[30:, 0] - m.joints[:-30, 0]  # quarter-second displacements
    step[:, 1] = 0
    hips = m.joints[:-30, JOINT_INDEX["lhip"]] - m.joints[:-30, JOINT_INDEX["rhip"]]
    facing = np.cross(hips, [0.0, 1.0, 0.0])
    cos = np.einsum("ij,ij->i", step, facing) / (np.linalg.norm(step, axis=1) * np.linalg.norm(facing, axis=1) + 1e-12)
    moving = np.linalg.norm(step, axis=1) > np.median(np.linalg.norm(step, axis=1)) * 0.5
    assert np.mean(cos[moving] > 0.5) > 0.9
    # a walk: the feet take turns (features #15/#16 'foot raised'-style bits change often)
    bits = unpack_words(motion_features(m))
    assert (np.diff(bits.astype(int), axis=0) != 0).sum() > 20


@pytest.fixture(scope="module")
def amc_120():
    s = read_asf(SAMPLE_86_ASF)  # cmu/86, shipped with mocapdb
    a = read_amc(SAMPLE_86_09, s)
    from dataclasses import replace
    return s, replace(a, values=a.values[:2400])


@pytest.mark.parametrize("step,frame_time", [(2, "0.0166667"), (4, ".0333333"), (5, "0.041667")])
def test_a_decimated_bvh_agrees_with_the_120hz_reading(amc_120, tmp_path, step, frame_time):
    """A real 120 Hz take written as BVH and decimated to 60, 30 and 24 Hz gives
    features on the same 30 Hz grid, agreeing with the 120 Hz reading on ≥ 99.5 %
    of values (RESULTS.md has the full table)."""
    s, a = amc_120
    full = write_bvh(tmp_path / "full.bvh", s, a, layout="cmu")
    head, body = full.read_text().split("MOTION\n")
    lines = [ln for ln in body.split("\n")[2:] if ln.strip()]
    kept = lines[::step]
    p = tmp_path / f"dec{step}.bvh"
    p.write_text(head + f"MOTION\nFrames: {len(kept)}\nFrame Time: {frame_time}\n" + "\n".join(kept) + "\n")
    ref = unpack_words(motion_features(read_bvh(full)))
    m = read_bvh(p)
    assert m.fps == 120.0 / step
    got = unpack_words(motion_features(m))
    assert len(got) == math.floor((len(kept) - 1) * 30 / m.fps + 1e-9) + 1
    k = min(len(got), len(ref))
    assert (got[:k] == ref[:k]).mean() >= 0.995


@pytest.mark.shared
def test_dialects_parse(tmp_path):
    """One-line End Sites, ``Frame Time:0.0083`` without a space (and 120.48 Hz
    snapped to 120), CR-only line ends, and tabs everywhere."""
    text = (FOREIGN / "bvhio_example.bvh").read_text()
    one_line = re.sub(r"End Site\s*\{\s*OFFSET\s+([^\n]+?)\s*\}", r"End Site { OFFSET \1 }", text)
    one_line = re.sub(r"Frame Time:\s*\S+", "Frame Time:0.0083", one_line)
    assert one_line != text and "End Site { OFFSET" in one_line
    p = tmp_path / "one_line.bvh"
    p.write_text(one_line)
    m = read_bvh(p)
    assert m.fps == 120.0 and m.n_frames == 2
    cr = tmp_path / "cr.bvh"
    cr.write_bytes(one_line.replace("\r\n", "\n").replace("\n", "\r").encode())
    np.testing.assert_array_equal(read_bvh(cr).joints, m.joints)


@pytest.mark.shared
def test_position_channels_of_a_joint_replace_its_offset(tmp_path):
    """bvhio/MotionBuilder/Blender read a non-root joint's position channels as its
    offset: the elbow of a file with LeftLowArm position channels equal to the
    OFFSET is where it was, and moving them moves the elbow to exactly there."""
    text = (FOREIGN / "bvhio_example.bvh").read_text()
    m0 = read_bvh(FOREIGN / "bvhio_example.bvh")
    off = re.search(r"JOINT LeftLowArm\s*\{\s*OFFSET\s+(\S+)\s+(\S+)\s+(\S+)", text)
    offset = [float(x) for x in off.groups()]
    chans = re.search(r"(JOINT LeftLowArm\s*\{\s*OFFSET[^\n]*\n\s*)CHANNELS 3 ", text)
    text2 = text[:chans.end(1)] + "CHANNELS 6 Xposition Yposition Zposition " + text[chans.end(1) + len("CHANNELS 3 "):]
    # the new columns sit before LeftLowArm's rotations: find their index
    head = text2.split("MOTION")[0]
    before = head[:head.index("JOINT LeftLowArm")]
    col = sum(int(c) for c in re.findall(r"CHANNELS (\d+)", before))
    body = text2.split("MOTION")[1].strip().split("\n")
    rows = []
    for ln in body[2:]:
        v = ln.split()
        rows.append(" ".join(v[:col] + [repr(x) for x in offset] + v[col:]))
    p = tmp_path / "pos.bvh"
    p.write_text(head + "MOTION\n" + "\n".join(body[:2]) + "\n" + "\n".join(rows) + "\n")
    m1 = read_bvh(p)
    np.testing.assert_allclose(m1.joints, m0.joints, atol=1e-9)
    rows2 = [" ".join(r.split()[:col] + ["0", "0", "0"] + r.split()[col + 3:]) for r in rows]
    p.write_text(head + "MOTION\n" + "\n".join(body[:2]) + "\n" + "\n".join(rows2) + "\n")
    m2 = read_bvh(p)
    # a zero offset puts the elbow on the shoulder (replaced, not added)
    np.testing.assert_allclose(m2.joints[:, JOINT_INDEX["lelbow"]], m2.joints[:, JOINT_INDEX["lshoulder"]], atol=1e-9)


def _turned_rig(full, tmp_path, r0):
    """The take of ``full`` on a rig whose every joint frame is turned by ``r0``:
    offsets (and End Sites) R0·o, root rotation R·R0ᵀ, local rotations R0·L·R0ᵀ.
    The motion is the same; the rest pose (all channels 0) is the body turned by
    R0, and the root's own x axis is R·R0ᵀ·x."""
    from mocapdb.writers import euler_angles
    from mocapdb.bodies.kinematics import euler_matrix

    data = parse_bvh(full.read_bytes())
    h = data.hierarchy
    vals = data.values.copy()
    text = full.read_text()
    head = text.split("MOTION")[0]
    for k, jt in enumerate(h.joints):
        cols = [jt.channel_start + i for i in range(len(jt.channels)) if jt.channels[i].endswith("rotation")]
        r = euler_matrix(np.radians(vals[:, cols]), "zyx")
        vals[:, cols] = np.degrees(euler_angles((r @ r0.T) if k == 0 else (r0 @ r @ r0.T), "zyx"))
    lines = head.split("\n")
    for i, ln in enumerate(lines):
        if ln.strip().startswith("OFFSET"):
            o = r0 @ np.array([float(x) for x in ln.split()[1:4]])
            lines[i] = ln[:ln.index("OFFSET")] + f"OFFSET {o[0]:.17g} {o[1]:.17g} {o[2]:.17g}"
    body = "\n".join(" ".join(f"{x:.17g}" for x in row) for row in vals)
    p = tmp_path / "turned.bvh"
    p.write_text("\n".join(lines) + f"MOTION\nFrames: {len(vals)}\nFrame Time: 0.0083333\n{body}\n")
    return p


def test_a_rig_lying_at_rest_with_its_root_axis_along_the_spine(amc_120, tmp_path):
    """The studio rigs of issue 9: every joint frame turned 90° about z, so the
    rest pose lies on its side and the root's x axis runs along the spine. The
    mapping reads the body from a frame of the motion, root_rotation is None and
    #40 (hip axis) agrees with the ASF reading, where the root's own x axis would
    be the spine."""
    from mocapdb.bodies.kinematics import euler_matrix

    s, a = amc_120
    full = write_bvh(tmp_path / "full.bvh", s, a, layout="cmu")
    base = read_bvh(full)
    assert base.root_rotation is not None
    r0 = euler_matrix(np.array([[0.0, 0.0, np.pi / 2]]), "xyz")[0]
    turned = read_bvh(_turned_rig(full, tmp_path, r0))
    np.testing.assert_allclose(turned.joints, base.joints, atol=1e-6)
    assert turned.root_rotation is None
    f40 = unpack_words(motion_features(turned))[:, 39]
    ref = unpack_words(motion_features(base))[:, 39]
    assert (f40 == ref).mean() >= 0.98
    # the root's own x axis (the spine) gives another #40
    rr = parse_bvh((tmp_path / "turned.bvh").read_bytes())
    from mocapdb.readers.bvh import bvh_node_positions
    _, _, root_rot = bvh_node_positions(rr)
    wrong = unpack_words(motion_features(Motion(turned.joints, root_rot, 120.0)))[:, 39]
    assert (wrong == ref).mean() < (f40 == ref).mean()


@pytest.mark.shared
def test_a_mixed_folder_stores_every_good_file(tmp_path, open_db):
    """Good AMC takes, a truncated one, the zero-length-bone BVH, an unsupported
    file and two identical broken copies: each good file stored, each bad one
    failed with its reason, the unsupported one listed."""
    folder = tmp_path / "mixed"
    folder.mkdir()
    src = DATA / "cmu/02"
    for name in ("02.asf", "02_01.amc", "02_02.amc"):
        (folder / name).symlink_to(src / name)
    take = (src / "02_03.amc").read_bytes()
    (folder / "02_03.amc").write_bytes(take[: len(take) // 2 - 7])
    (folder / "copy_a.bvh").write_bytes(b"HIERARCHY\nROOT Hips\n{\n")
    (folder / "copy_b.bvh").write_bytes(b"HIERARCHY\nROOT Hips\n{\n")
    shutil.copy(FOREIGN / "fairmotion_pfnn_hierarchy.bvh", folder / "pfnn.bvh")
    (folder / "notes.txt").write_text("session notes")
    con = open_db(tmp_path / "m.duckdb")
    report = mocapdb.ingest(con, [folder])
    assert sorted(p.split("/")[-1] for p, *_ in report.ingested) == ["02_01.amc", "02_02.amc", "pfnn.bvh"]
    failed = dict(report.failed)
    assert sorted(p.split("/")[-1] for p in failed) == ["02_03.amc", "copy_a.bvh", "copy_b.bvh"]
    assert "02_03.amc:" in failed[str(folder / "02_03.amc")]
    assert "same bytes as" in failed[str(folder / "copy_b.bvh")] and "which failed" in failed[str(folder / "copy_b.bvh")]
    unsupported = dict(report.unsupported)
    assert sorted(p.split("/")[-1] for p in unsupported) == ["02.asf", "notes.txt"]
    assert "unsupported file type '.txt'" in unsupported[str(folder / "notes.txt")]
    assert con.execute("SELECT count(*) FROM motions").fetchall()[0][0] == 3
    assert report.summary() == "3 ingested, 0 skipped, 3 failed, 2 not motion files; 1 read with notes"   # a unit


@pytest.mark.shared
def test_a_joint_map_file_and_its_template(tmp_path):
    """The template of a file is a valid joint map; edited, it reads the file."""
    src = FOREIGN / "mixamo_freebvh.bvh"
    text = joint_map_template(src)
    assert text.startswith("# mocapdb joint map") and 'lknee = "mixamorig:LeftLeg"' in text
    p = tmp_path / "map.toml"
    p.write_text(text.replace('lwrist = "mixamorig:LeftHand"', 'lwrist = "mixamorig:LeftHandMiddle1"'))
    jm = load_mapping(p)
    m = read_motion(src, joint_map=p)
    assert m.skeleton == "bvh:joint_map" and jm["lwrist"] == "mixamorig:LeftHandMiddle1"
    auto = read_bvh(src)
    assert not np.allclose(m.joints[:, JOINT_INDEX["lwrist"]], auto.joints[:, JOINT_INDEX["lwrist"]])
    np.testing.assert_array_equal(m.joints[:, JOINT_INDEX["rknee"]], auto.joints[:, JOINT_INDEX["rknee"]])
    # the non-humanoid: its template lists its joints and leaves every canonical joint to fill
    t = joint_map_template(FOREIGN / NON_HUMANOID)
    assert "# the file's joints: base, child1, child2, child3" in t and '# root = ""' in t


@pytest.mark.shared
def test_deep_hierarchies_and_huge_frame_counts_are_refused_clearly(tmp_path):
    deep = "HIERARCHY\nROOT r\n{\nOFFSET 0 0 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"
    deep += "JOINT j\n{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n" * 300 + "}\n" * 301
    p = tmp_path / "deep.bvh"
    p.write_text(deep + "MOTION\nFrames: 1\nFrame Time: 0.0083333\n" + " 0" * 903 + "\n")
    with pytest.raises(ParseError, match=r"deep\.bvh:\d+: hierarchy deeper than 256 joints"):
        read_motion(p)
    text = (FOREIGN / "bvhio_example.bvh").read_text()
    p = tmp_path / "huge.bvh"
    p.write_text(re.sub(r"Frames:\s*\d+", "Frames: 1000000000000", text))
    with pytest.raises(ParseError, match=r"'Frames: 1000000000000' but only 2 motion lines follow"):
        read_motion(p)
    p.write_text(re.sub(r"Frame Time:\s*\S+", "Frame Time: 5e-324", text))
    with pytest.raises(ParseError, match=r"huge\.bvh:\d+: Frame Time: expected a time of at least 0.0001 s"):
        read_motion(p)


#: the cmuconvert joint names in other tools' conventions (READERS.md §2): the
#: same skeleton renamed must give the same canonical joints without a map
CONVENTIONS = {
    "mixamo": lambda n: "mixamorig:" + n,
    "unreal": {"Hips": "pelvis", "LHipJoint": "hip_root_l", "LeftUpLeg": "thigh_l", "LeftLeg": "calf_l",
               "LeftFoot": "foot_l", "LeftToeBase": "ball_l", "LowerBack": "spine_01", "Spine": "spine_02",
               "Spine1": "spine_03", "Neck": "neck_01", "Neck1": "neck_02", "Head": "head",
               "LeftShoulder": "clavicle_l", "LeftArm": "upperarm_l", "LeftForeArm": "lowerarm_l",
               "LeftHand": "hand_l", "LeftFingerBase": "middle_metacarpal_l", "LeftHandIndex1": "index_01_l",
               "LThumb": "thumb_01_l"},
    "biped": {"Hips": "Bip01 Pelvis", "LHipJoint": "Bip01 L HipRoot", "LeftUpLeg": "Bip01 L Thigh",
              "LeftLeg": "Bip01 L Calf", "LeftFoot": "Bip01 L Foot", "LeftToeBase": "Bip01 L Toe0",
              "LowerBack": "Bip01 Spine", "Spine": "Bip01 Spine1", "Spine1": "Bip01 Spine2", "Neck": "Bip01 Neck",
              "Neck1": "Bip01 Neck1", "Head": "Bip01 Head", "LeftShoulder": "Bip01 L Clavicle",
              "LeftArm": "Bip01 L UpperArm", "LeftForeArm": "Bip01 L Forearm", "LeftHand": "Bip01 L Hand",
              "LeftFingerBase": "Bip01 L Finger2", "LeftHandIndex1": "Bip01 L Finger21",
              "LThumb": "Bip01 L Finger0"},
    "smpl": {"Hips": "pelvis", "LHipJoint": "left_hip_root", "LeftUpLeg": "left_hip", "LeftLeg": "left_knee",
             "LeftFoot": "left_ankle", "LeftToeBase": "left_foot", "LowerBack": "spine1", "Spine": "spine2",
             "Spine1": "spine3", "Neck": "neck", "Neck1": "neck_upper", "Head": "head", "LeftShoulder": "left_collar",
             "LeftArm": "left_shoulder", "LeftForeArm": "left_elbow", "LeftHand": "left_wrist",
             "LeftFingerBase": "left_hand", "LeftHandIndex1": "left_index1", "LThumb": "left_thumb1"},
    "studio": lambda n: "joint_" + n.replace("Left", "").replace("Right", "") + (
        "LT" if n.startswith(("Left", "L")) and n not in ("LowerBack",) else
        "RT" if n.startswith(("Right", "R")) else ""),
}


def _rename(name, convention):
    rule = CONVENTIONS[convention]
    if callable(rule):
        return rule(name)
    if name in rule:
        return rule[name]
    # the right side mirrors the left one's names
    left = "Left" + name[5:] if name.startswith("Right") else "L" + name[1:] if name.startswith("R") else None
    out = rule[left]
    return (out.replace("_l", "_r").replace(" L ", " R ").replace("left", "right") if left in rule else out)


@pytest.mark.parametrize("convention", sorted(CONVENTIONS))
def test_other_naming_conventions_need_no_map(amc_120, tmp_path, convention):
    s, a = amc_120
    from dataclasses import replace as dc_replace
    p = write_bvh(tmp_path / "cmu.bvh", s, dc_replace(a, values=a.values[:120]), layout="cmu")
    text = p.read_text()
    names = re.findall(r"(?:ROOT|JOINT) (\w+)", text)
    renamed = {n: _rename(n, convention) for n in names}
    assert len(set(renamed.values())) == len(names)
    for n in sorted(names, key=len, reverse=True):
        text = re.sub(rf"((?:ROOT|JOINT) ){n}\n", lambda m, n=n: m.group(1) + renamed[n] + "\n", text)
    q = tmp_path / f"{convention}.bvh"
    q.write_text(text)
    ref = read_bvh(p)
    got = read_bvh(q)
    np.testing.assert_allclose(got.joints, ref.joints, atol=1e-9)
    assert (got.root_rotation is None) == (ref.root_rotation is None)


def test_a_z_up_file_is_turned_to_y_up_not_mirrored(amc_120, tmp_path):
    """The same take recorded Z-up (root position and rotation turned +90° about x):
    read back Y-up, the joints are the Y-up reading's (a rotation, no mirror:
    left stays left) and the features are the same."""
    from dataclasses import replace as dc_replace

    from mocapdb.writers import euler_angles
    from mocapdb.bodies.kinematics import euler_matrix

    s, a = amc_120
    full = write_bvh(tmp_path / "y_up.bvh", s, dc_replace(a, values=a.values[:600]), layout="cmu")
    data = parse_bvh(full.read_bytes())
    root = data.hierarchy.joints[0]
    vals = data.values.copy()
    r0 = euler_matrix(np.array([[np.pi / 2, 0.0, 0.0]]), "xyz")[0]  # +Y -> +Z
    pos = [root.channel_start + i for i in range(3)]
    rot = [root.channel_start + 3 + i for i in range(3)]
    vals[:, pos] = vals[:, pos] @ r0.T
    vals[:, rot] = np.degrees(euler_angles(r0 @ euler_matrix(np.radians(vals[:, rot]), "zyx"), "zyx"))
    head = full.read_text().split("MOTION")[0]
    body = "\n".join(" ".join(f"{x:.17g}" for x in row) for row in vals)
    z_up = tmp_path / "z_up.bvh"
    z_up.write_text(head + f"MOTION\nFrames: {len(vals)}\nFrame Time: 0.0083333\n{body}\n")
    ref = read_bvh(full)
    got = read_bvh(z_up)
    np.testing.assert_allclose(got.joints, ref.joints, atol=1e-6)
    np.testing.assert_array_equal(motion_features(got), motion_features(ref))
