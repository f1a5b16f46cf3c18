"""BVH reading and writing: round trips from real ASF/AMC takes, channel orders,
the humanoid mapping of cmuconvert names, the rest frame, and the FK kernel vs a naive one."""
import re
from pathlib import Path
from dataclasses import replace

import numpy as np
import pytest

import mocapdb

from conftest import DATA, SAMPLE_86_09, SAMPLE_86_ASF, humerus
from mocapdb.readers.amc import read_amc
from mocapdb.readers.asf import read_asf
from mocapdb.writers import euler_angles, write_bvh
from mocapdb.readers import read_bvh
from mocapdb.readers.bvh import bvh_node_positions, fps_from_frame_time, parse_bvh
from mocapdb.errors import ParseError
from mocapdb.bodies.joints import JOINT_INDEX
from mocapdb.bodies.kinematics import asf_forward_kinematics, euler_matrix
from mocapdb.bodies.motion import Motion
from mocapdb.readers import read_motion
from naive_kinematics import naive_bvh_fk

HDM_ASF = DATA / "hdm05_cut/HDM_bd.asf"
HDM_AMC = DATA / "hdm05_cut/kickLFront1Reps/HDM_bd_kickLFront1Reps_001_120.amc"
CMU_ASF = SAMPLE_86_ASF  # cmu/86/86.asf and 86_09.amc, shipped with mocapdb
CMU_AMC = SAMPLE_86_09
ORDERS = ["ZYX", "XYZ", "YZX", "ZXY", "XZY", "YXZ"]


@pytest.fixture(scope="module")
def hdm():
    s = read_asf(HDM_ASF)
    m = read_amc(HDM_AMC, s)
    return s, m, asf_forward_kinematics(s, m)


@pytest.fixture(scope="module")
def cmu500():
    s = read_asf(CMU_ASF)
    m = read_amc(CMU_AMC, s)
    m = replace(m, values=m.values[:500])
    return s, m, asf_forward_kinematics(s, m)


def assert_same_motion(bvh_motion, joints, rot, *, exact=False):
    """Same joints within 1e-6 of the humerus (the requirement); what the writer
    achieves: ~1e-12 with 17 digits (float64 round trip), ~1e-10 with 12."""
    unit = humerus(joints)
    err = np.abs(bvh_motion.joints - joints).max()
    assert bvh_motion.joints.shape == joints.shape
    assert err <= 1e-6 * unit
    assert err <= (1e-12 if exact else 1e-9) * unit
    assert np.abs(bvh_motion.root_rotation - rot).max() <= (1e-14 if exact else 1e-10)


#: canonical joints the cmuconvert names place exactly where the ASF reader does (the
#: spine's belly/chest are placed at 1/3 and 2/3 of its length, the wrist at the
#: origin of LeftHand, i.e. before the ASF wrist bone)
CMU_EXACT = ["root", "lhip", "lknee", "lankle", "ltoes", "rhip", "rknee", "rankle", "rtoes", "neck",
             "head", "headtop", "lclavicle", "rclavicle", "lshoulder", "lelbow", "lfingers", "rshoulder",
             "relbow", "rfingers"]


@pytest.mark.parametrize("which", [pytest.param("hdm", marks=pytest.mark.shared), "cmu500"])
def test_asf_names_round_trip_reproduces_asf_joints_and_root_rotation(which, request, tmp_path):
    s, m, (joints, rot) = request.getfixturevalue(which)
    path = write_bvh(tmp_path / "take.bvh", s, m, layout="asf", precision=17)
    b = read_motion(path)
    assert b.meta["bvh_family"] == "asf" and b.skeleton == "bvh:asf"
    assert b.source_format == "bvh" and b.name == "take" and b.fps == 120.0
    assert not b.meta.get("rest_frame_skipped", False)
    assert_same_motion(b, joints, rot, exact=True)
    # the default 12 digits
    write_bvh(path, s, m, layout="asf")
    assert_same_motion(read_motion(path), joints, rot)


@pytest.mark.parametrize("which", [pytest.param("hdm", marks=pytest.mark.shared), "cmu500"])
def test_cmuconvert_names_map_onto_the_asf_points(which, request, tmp_path):
    s, m, (joints, rot) = request.getfixturevalue(which)
    path = write_bvh(tmp_path / "take.bvh", s, m, layout="cmu", rest_frame=True, precision=17)
    b = read_motion(path)
    assert b.skeleton == "bvh:humanoid" and b.meta["rest_frame_skipped"]
    assert b.meta["mapping"]["lknee"] == "LeftLeg" and b.meta["mapping"]["lwrist"] == "LeftHand"
    idx = [JOINT_INDEX[j] for j in CMU_EXACT]
    assert np.abs(b.joints[:, idx] - joints[:, idx]).max() <= 1e-11 * humerus(joints)
    # the pelvis has the ASF axes: feature #40 reads the root rotation
    assert np.abs(b.root_rotation - rot).max() <= 1e-13
    # belly and chest lie on the spine between root and neck, a third apart
    root, belly, chest, neck = (b.joints[:, JOINT_INDEX[j]] for j in ("root", "belly", "chest", "neck"))
    spine = np.linalg.norm(neck - root, axis=1)
    for p in (belly, chest):
        assert (np.linalg.norm(p - root, axis=1) < spine).all() and (np.linalg.norm(p - neck, axis=1) < spine).all()


@pytest.mark.shared
def test_cmu_layout_matches_the_cmuconvert_facts(hdm, tmp_path):
    s, m, _ = hdm
    text = write_bvh(tmp_path / "c.bvh", s, m, layout="cmu", rest_frame=True).read_text()
    assert text.startswith("HIERARCHY\nROOT Hips\n")
    assert "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation" in text
    assert len(re.findall(r"CHANNELS 3 Zrotation Yrotation Xrotation", text)) == 30
    for name in ("LHipJoint", "LeftUpLeg", "LeftToeBase", "LowerBack", "Spine1", "Neck1",
                 "LeftFingerBase", "LeftHandIndex1", "LThumb", "RThumb"):
        assert f"JOINT {name}\n" in text
    frames = text.split("MOTION\n")[1].split("\n")
    assert frames[0] == f"Frames: {m.n_frames + 1}"
    assert set(frames[2].split()) == {"0"}  # the added rest pose
    # the same file read with the rest frame kept has one frame more
    keep = read_bvh(tmp_path / "c.bvh", skip_rest_frame=False)
    assert keep.n_frames == m.n_frames + 1
    assert read_bvh(tmp_path / "c.bvh").n_frames == m.n_frames


@pytest.mark.shared
def test_a_rest_frame_that_is_not_all_zero_is_dropped(hdm, tmp_path):
    """cmuconvert keeps the root and a few degrees on the limbs in some rest frames
    (READERS.md §2): detected by its jump to frame 2, not by zeros."""
    s, m, (joints, _) = hdm
    text = write_bvh(tmp_path / "c.bvh", s, m, layout="cmu", rest_frame=True).read_text()
    head, body = text.split("MOTION\n")
    lines = body.split("\n")
    first = np.array(lines[3].split(), dtype=float)  # the take's first frame
    rest = np.zeros_like(first)
    rest[:3] = first[:3]  # the root where the take starts
    rest[6::3] += 3.0    # a few degrees on every joint
    lines[2] = " ".join(repr(float(v)) for v in rest)
    p = tmp_path / "rest.bvh"
    p.write_text(head + "MOTION\n" + "\n".join(lines))
    b = read_bvh(p)
    assert b.meta["rest_frame_skipped"] and b.n_frames == m.n_frames
    # a take without a rest frame keeps every frame
    plain = write_bvh(tmp_path / "plain.bvh", s, m, layout="cmu")
    assert read_bvh(plain).n_frames == m.n_frames and not read_bvh(plain).meta.get("rest_frame_skipped")


@pytest.mark.shared
@pytest.mark.parametrize("order", ORDERS)
def test_every_rotation_order_gives_the_same_positions(hdm, order, tmp_path):
    s, m, (joints, rot) = hdm
    path = write_bvh(tmp_path / "o.bvh", s, m, rotation_order=order)
    assert f"CHANNELS 3 {' '.join(a + 'rotation' for a in order)}" in path.read_text()
    assert_same_motion(read_bvh(path), joints, rot)


@pytest.mark.shared
def test_mixed_orders_and_position_channels_anywhere(hdm, tmp_path):
    s, m, (joints, rot) = hdm
    orders = {b.name: ORDERS[k % 6] for k, b in enumerate(s.bones)}
    orders["root"] = "YXZ"
    path = write_bvh(tmp_path / "mixed.bvh", s, m, rotation_order=orders)
    text = path.read_text()
    # move the root's position channels between its rotation channels and
    # permute the data columns the same way (rotation channels keep their order)
    head, body = text.split("MOTION\n")
    old = "CHANNELS 6 Xposition Yposition Zposition Yrotation Xrotation Zrotation"
    new = "CHANNELS 6 Yrotation Zposition Xrotation Xposition Zrotation Yposition"
    assert old in head
    perm = [3, 2, 4, 0, 5, 1]  # new column k = old column perm[k]
    lines = body.split("\n")
    out = lines[:2]
    for ln in lines[2:]:
        v = ln.split()
        if v:
            out.append(" ".join([v[p] for p in perm] + v[6:]))
    moved = tmp_path / "moved.bvh"
    moved.write_text(head.replace(old, new) + "MOTION\n" + "\n".join(out) + "\n")
    assert_same_motion(read_bvh(path), joints, rot)
    assert_same_motion(read_bvh(moved), joints, rot)


@pytest.mark.shared
def test_fk_kernel_equals_naive_on_random_channels(hdm, tmp_path):
    s, m, _ = hdm
    path = write_bvh(tmp_path / "r.bvh", s, replace(m, values=m.values[:20]),
                     rotation_order={"lfemur": "XZY", "thorax": "YXZ"})
    # add position channels to a non-root joint, then fill random values
    text = path.read_text()
    text2 = re.sub(r"(JOINT lradius\n\t*\{\n\t*OFFSET [^\n]*\n\t*)CHANNELS 3 (\w+) (\w+) (\w+)",
                   r"\1CHANNELS 5 \2 Xposition \3 Zposition \4", text)
    assert text2 != text
    data = parse_bvh(_with_random_values(text2, seed=4))
    origins, ends, rot = bvh_node_positions(data, rotation_joint=0)
    r_orig, r_ends, r_glob = naive_bvh_fk(data.hierarchy, data.values)
    scale = np.abs(r_orig).max()
    assert np.abs(origins - r_orig).max() <= 1e-12 * scale
    has = ~np.isnan(r_ends[0, :, 0])
    assert has.sum() == sum(1 for b in s.bones if not s.children(b.name)) == 7
    assert np.abs(ends[:, has] - r_ends[:, has]).max() <= 1e-12 * scale
    assert np.abs(rot - r_glob[:, 0]).max() <= 1e-14


def _with_random_values(text, seed):
    """The hierarchy of ``text`` with 20 frames of random channel values."""
    head = text.split("MOTION")[0]
    nch = sum(int(c) for c in re.findall(r"CHANNELS (\d+)", head))
    rng = np.random.default_rng(seed)
    vals = rng.uniform(-180, 180, size=(20, nch))
    body = "\n".join(" ".join(repr(float(v)) for v in row) for row in vals)
    return (head + f"MOTION\nFrames: 20\nFrame Time: 0.0083333\n{body}\n").encode()


@pytest.mark.parametrize("order", ORDERS)
def test_euler_angles_invert_euler_matrix(order):
    rng = np.random.default_rng(11)
    ang = rng.uniform(-np.pi, np.pi, size=(500, 3))
    ang[:, 1] = rng.uniform(-np.pi / 2 + 1e-3, np.pi / 2 - 1e-3, 500)
    r = euler_matrix(ang, order.lower())
    back = euler_angles(r, order)
    assert np.allclose(back, ang, atol=1e-12)
    assert np.allclose(euler_matrix(back, order.lower()), r, atol=1e-14)


@pytest.mark.parametrize("frame_time,fps", [(0.0083333, 120.0), (0.008333, 120.0), (0.0083, 120.0),
                                            (1 / 120, 120.0), (0.0333333, 30.0), (0.0333, 30.0),
                                            (0.04, 25.0), (0.041667, 24.0), (0.016667, 60.0),
                                            (0.005, 200.0), (0.0123, 1 / 0.0123)])
def test_fps_from_frame_time_snaps_to_common_rates(frame_time, fps):
    """READERS.md §1: within 0.5 % of a common rate it is that rate (``.0083`` is 120 Hz,
    not 120.48); otherwise the recorded rate stays."""
    assert fps_from_frame_time(frame_time) == fps


@pytest.mark.shared
def test_names_without_meaning_map_by_topology(hdm, tmp_path):
    """Joint names that say nothing (j0, j1, …) still give the cmuconvert points: limbs
    from the tree and their two longest bones, sides from the rest pose."""
    s, m, (joints, _) = hdm
    path = write_bvh(tmp_path / "x.bvh", s, replace(m, values=m.values[:40]), layout="cmu")
    text = path.read_text()
    names = re.findall(r"(?:ROOT|JOINT) (\w+)", text)
    for k, name in enumerate(sorted(names, key=len, reverse=True)):
        text = re.sub(rf"((?:ROOT|JOINT) ){name}\n", rf"\1q{k}z\n", text)
    anon = tmp_path / "anon.bvh"
    anon.write_text(text)
    named = read_bvh(path)
    b = read_bvh(anon)
    assert b.skeleton == "bvh:humanoid"
    assert all(v[0] == "q" or isinstance(v, list) or "spine" in v for v in b.meta["mapping"].values())
    idx = [JOINT_INDEX[j] for j in ("root", "lhip", "lknee", "lankle", "rhip", "rknee", "rankle", "lshoulder",
                                    "lelbow", "rshoulder", "relbow", "neck")]
    assert np.abs(b.joints[:, idx] - named.joints[:, idx]).max() <= 1e-12 * humerus(joints)


@pytest.mark.shared
def test_a_joint_map_overrides_the_automatic_mapping(hdm, tmp_path):
    s, m, _ = hdm
    path = write_bvh(tmp_path / "x.bvh", s, replace(m, values=m.values[:10]), layout="cmu")
    auto = read_bvh(path)
    b = read_bvh(path, joint_map={"lwrist": "LeftFingerBase", "neck": ["LeftShoulder", "RightShoulder"],
                                  "ltoes": "LeftToeBase/end"})
    assert b.skeleton == "bvh:joint_map"
    data = parse_bvh(path.read_bytes())
    origins, ends, _ = bvh_node_positions(data)
    h = data.hierarchy
    np.testing.assert_allclose(b.joints[:, JOINT_INDEX["lwrist"]], origins[:, h.index("LeftFingerBase")], atol=1e-12)
    np.testing.assert_allclose(b.joints[:, JOINT_INDEX["neck"]], (origins[:, h.index("LeftShoulder")]
                                                                  + origins[:, h.index("RightShoulder")]) / 2)
    np.testing.assert_allclose(b.joints[:, JOINT_INDEX["ltoes"]], ends[:, h.index("LeftToeBase")], atol=1e-12)
    np.testing.assert_array_equal(b.joints[:, JOINT_INDEX["lknee"]], auto.joints[:, JOINT_INDEX["lknee"]])
    with pytest.raises(ParseError, match=r"joint_map: lwrist = 'Nope': no such joint in this file "
                                         r"\(its joints: Hips, LHipJoint, "):
        read_bvh(path, joint_map={"lwrist": "Nope"})


@pytest.mark.shared
def test_cmuconvert_offsets_give_distinct_spine_points(hdm, tmp_path):
    """Real cmuconvert files drop the ASF thorax and wrist vectors (OFFSET 0 for
    Neck, Left/RightShoulder, Left/RightFingerBase, L/RThumb; FEATURES.md §2.3b):
    the neck collapses onto Spine1's origin. The spec's proposed chest = Spine1
    would then equal the neck (chest length 0, features #3–#6 undefined); the
    mapping keeps belly and chest at 1/3 and 2/3 of the spine instead."""
    s, m, (joints, rot) = hdm
    text = write_bvh(tmp_path / "c.bvh", s, m, layout="cmu", precision=17).read_text()
    for name in ("Neck", "LeftShoulder", "RightShoulder", "LeftFingerBase", "RightFingerBase",
                 "LThumb", "RThumb"):
        text, k = re.subn(rf"(JOINT {name}\n\t*\{{\n\t*)OFFSET [^\n]*", r"\1OFFSET 0 0 0", text)
        assert k == 1
    p = tmp_path / "folded.bvh"
    p.write_text(text)
    b = read_bvh(p)
    exact = ["root", "lhip", "lknee", "lankle", "ltoes", "rhip", "rknee", "rankle", "rtoes"]
    idx = [JOINT_INDEX[j] for j in exact]
    assert np.abs(b.joints[:, idx] - joints[:, idx]).max() <= 1e-12 * humerus(joints)
    assert np.abs(b.root_rotation - rot).max() <= 1e-14
    data = parse_bvh(p.read_bytes())
    origins, _, _ = bvh_node_positions(data)
    h = data.hierarchy
    assert np.array_equal(b.joints[:, JOINT_INDEX["neck"]], origins[:, h.index("Neck")])
    np.testing.assert_allclose(origins[:, h.index("Neck")], origins[:, h.index("Spine1")], atol=1e-12)
    assert np.array_equal(b.joints[:, JOINT_INDEX["lwrist"]], origins[:, h.index("LeftHand")])
    assert np.array_equal(b.joints[:, JOINT_INDEX["lclavicle"]], b.joints[:, JOINT_INDEX["neck"]])
    chest_len = np.linalg.norm(b.joints[0, JOINT_INDEX["chest"]] - b.joints[0, JOINT_INDEX["neck"]])
    assert chest_len > 0.2 * np.linalg.norm(b.joints[0, JOINT_INDEX["neck"]] - b.joints[0, JOINT_INDEX["root"]])


@pytest.mark.shared
def test_motion_values_equal_python_float(hdm, tmp_path):
    s, m, _ = hdm
    for precision in (17, 12, 6):
        p = write_bvh(tmp_path / "v.bvh", s, m, precision=precision, rest_frame=True)
        data = parse_bvh(p.read_bytes())
        text = p.read_text().split("MOTION\n")[1].split("\n")[2:]
        ref = np.array([[float(t) for t in ln.split()] for ln in text if ln.strip()])
        assert data.values.shape == ref.shape == (m.n_frames + 1, 96)
        assert np.array_equal(data.values, ref)  # bit for bit, fast and slow paths


def test_bvh_round_trip_gives_the_same_feature_words(cmu500, tmp_path):
    from mocapdb.features import motion_features

    s, m, (joints, rot) = cmu500
    amc_words = motion_features(Motion(joints=joints, root_rotation=rot, fps=120.0))
    p = write_bvh(tmp_path / "asf.bvh", s, m, layout="asf", precision=17)
    assert np.array_equal(motion_features(read_bvh(p)), amc_words)
    # cmuconvert names: belly/chest and the wrist move a little; features nearly agree
    from mocapdb.features import unpack_words

    p = write_bvh(tmp_path / "cmu.bvh", s, m, layout="cmu", precision=17)
    agree = (unpack_words(motion_features(read_bvh(p))) == unpack_words(amc_words)).mean()
    assert agree >= 0.99, agree


def _motion_regex(data, pos):
    """The reader's former way of finding the MOTION keyword: ``(match start, match end)`` or None."""
    m = re.compile(rb"(?m)^[ \t]*MOTION\b").search(data, pos)
    return None if m is None else (m.start(), m.end())


def _assert_heads(heads):
    from mocapdb.readers.bvh_head import find_motion

    for head in heads:
        for pos in (0, 1, head.find(b"MOTION"), len(head) // 2):
            assert find_motion(head, max(0, pos)) == _motion_regex(head, max(0, pos))


def test_the_motion_keyword_is_found_where_the_regular_expression_finds_it():
    """Issue 35: ``find_motion`` (bytes.find, then the line's start and the word's end checked) gives the
    match of ``(?m)^[ \\t]*MOTION\\b`` searched from any position, on the shipped BVH's header and on 20,000
    seeded texts of keyword fragments, blanks, line ends and word bytes."""
    import lzma

    from mocapdb.readers.bvh_head import find_motion

    sample = next(Path(mocapdb.__file__).parent.joinpath("sample").glob("*.bvh.xz"))
    _assert_heads([lzma.decompress(sample.read_bytes())[:20_000]])
    rng = np.random.default_rng(35)
    pieces = [b"MOTION", b"MOTIONS", b"MOTION_", b"MOTION1", b"xMOTION", b"MOTIO", b" ", b"\t", b"\n", b"\r",
              b"\r\n", b"\x00", b"\xe9", b"-", b"a", b"_", b"9", b"\v"]
    for _ in range(20_000):
        data = b"".join(pieces[k] for k in rng.integers(0, len(pieces), rng.integers(0, 12)))
        pos = int(rng.integers(0, len(data) + 1))
        assert find_motion(data, pos) == _motion_regex(data, pos), (data, pos)
        assert find_motion(bytearray(data), pos) == _motion_regex(data, pos)


@pytest.mark.shared
def test_the_motion_keyword_is_found_in_the_shared_bvh_headers_where_the_regular_expression_finds_it():
    """The same on the headers of the shared BVH files of other tools and labs."""
    heads = [p.read_bytes()[:20_000] for p in sorted(DATA.rglob("*.bvh"))[:40]]
    assert heads
    _assert_heads(heads)


def _frame_by_frame_joints(data, jm, point, weight, end_of, needed):
    """The 24 joints and the rotation that FK a frame at a time (``bvh_node_positions``) and a plain
    weighted sum of each joint's points give, its terms added in the kernel's order (0, then weight × point
    for each point of weight ≠ 0): what the lanes of ``_bvh_joints_kernel`` must reproduce bit for bit."""
    origins, ends, rot = bvh_node_positions(data, rotation_joint=jm.rotation_point, needed=needed)
    nj = origins.shape[1]
    joints = np.empty((len(data.values), point.shape[0], 3))
    for q in range(point.shape[0]):
        acc = np.zeros((len(data.values), 3))
        for w, p in zip(weight[q], point[q]):
            if w != 0.0:
                acc = acc + w * (origins[:, p] if p < nj else ends[:, end_of[p - nj]])
        joints[:, q] = acc
    return joints, rot


def _lane_and_frame_results(data):
    from mocapdb.readers.bvh import _joints_and_rotation, _judged_frame
    from mocapdb.readers.bvh_mapping import plan
    hier = data.hierarchy
    planned = plan(hier, None, data.path, lambda: _judged_frame(hier, data.values, None, 0, data))
    return _joints_and_rotation(data, *planned), _frame_by_frame_joints(data, *planned)


@pytest.mark.parametrize("frames", [1, 7, 64, 65, 131])
def test_fk_lanes_equal_the_frame_by_frame_kernels_bit_for_bit(cmu500, frames, tmp_path):
    """Blocks cut anywhere (a partial last block, a single frame), random angles with exact zeros and
    negative zeros (the skipped sine and cosine), position channels on a joint that is not the root."""
    s, m, _ = cmu500
    path = write_bvh(tmp_path / "r.bvh", s, replace(m, values=m.values[:frames]),
                     rotation_order={"lfemur": "XZY", "thorax": "YXZ"})
    text = re.sub(r"(JOINT lradius\n\t*\{\n\t*OFFSET [^\n]*\n\t*)CHANNELS 3 (\w+) (\w+) (\w+)",
                  r"\1CHANNELS 5 \2 Xposition \3 Zposition \4", path.read_text())
    assert "CHANNELS 5" in text
    head = text.split("MOTION")[0]
    nch = sum(int(c) for c in re.findall(r"CHANNELS (\d+)", head))
    rng = np.random.default_rng(frames)
    vals = rng.uniform(-180, 180, size=(frames, nch))
    vals[rng.random(vals.shape) < 0.2] = 0.0
    vals[rng.random(vals.shape) < 0.05] = -0.0
    vals[:, 1] += 100.0   # the root stands up: the mapper judges a person
    body = "\n".join(" ".join(repr(float(v)) for v in row) for row in vals)
    data = parse_bvh((head + f"MOTION\nFrames: {frames}\nFrame Time: 0.0083333\n{body}\n").encode())
    (joints, rot), (ref_joints, ref_rot) = _lane_and_frame_results(data)
    assert joints.tobytes() == ref_joints.tobytes()   # bit for bit, signs of zeros included
    assert rot.tobytes() == ref_rot.tobytes()


@pytest.mark.shared
@pytest.mark.parametrize("name", ["bandai2_dev", "accad_dev", "foreign"])
def test_fk_lanes_equal_the_frame_by_frame_kernels_on_real_takes(name):
    import gzip
    files = sorted(p for p in (DATA / name).rglob("*") if p.name.endswith((".bvh", ".bvh.gz")))[:6]
    assert files
    for f in files:
        raw = f.read_bytes()
        data = parse_bvh(gzip.decompress(raw) if f.name.endswith(".gz") else raw, path=f)
        try:
            (joints, rot), (ref_joints, ref_rot) = _lane_and_frame_results(data)
        except ParseError:   # a rig the mapper refuses (foreign/ holds such files on purpose)
            continue
        assert joints.tobytes() == ref_joints.tobytes(), f
        assert rot.tobytes() == ref_rot.tobytes(), f
