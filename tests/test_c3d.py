"""C3D marker files (issue 10; FEATURES.md §2.4, READERS.md §3–§4): the toolbox oracle
(../shared/oracle/c3d), the dg AMC twin, units and axes, the anatomical-landmark rule on
the Qualisys take, marker maps, gaps and refusals with their messages.

Derived files (other units, other axes, gaps, relabelled, no points) are written to
tmp_path with ezc3d from the real recordings.
"""
import json
import re
import tomllib

import ezc3d
import numpy as np
import pytest

from mocapdb.errors import ParameterError, ParseError
from mocapdb.features import downsample, motion_features, pack_words, relational_features
from mocapdb.bodies import JOINT_INDEX
from mocapdb.readers import load_mapping, read_c3d, read_motion
from mocapdb.readers.c3d import MAX_GAP_S, SKELETON_EDGES

from conftest import DATA, ORACLE, REPO, SAMPLE_C3D, humerus

C3D_ORACLE = ORACLE / "c3d"
#: oracle stem -> the C3D file it was computed from (oracle/c3d/README.md)
ORACLE_FILES = {
    "HDM_dg_06-03_03_120_c3d": DATA / "hdm05_full" / "HDM_dg_06-03_03_120.c3d",
    "HDM_mm_01-02_03_120_c3d": SAMPLE_C3D,  # hdm05_full/HDM_mm_01-02_03_120.c3d, shipped with mocapdb
    "85_02_c3d": DATA / "cmu" / "c3d" / "85_02.c3d",
}
DG_C3D = ORACLE_FILES["HDM_dg_06-03_03_120_c3d"]
DG_AMC = DATA / "hdm05_full" / "HDM_dg_06-03_03_120.amc"
FOREIGN = DATA / "foreign" / "c3d"
QUALISYS = FOREIGN / "ezc3d_Qualisys.c3d"


def oracle_positions(stem, prefit=False):
    name = f"{stem}_pos120{'_prefit' if prefit else ''}.csv"
    return np.loadtxt(C3D_ORACLE / "positions" / name, delimiter=",", skiprows=1).reshape(-1, 24, 3)


def oracle_features(stem, rate, prefit=False):
    """Features 1–39 of the toolbox, as bool (its #40 is NaN on C3D input: no root rotation)."""
    name = f"{stem}{'_prefit' if prefit else ''}_feat{rate}.csv"
    a = np.genfromtxt(C3D_ORACLE / "features" / name, delimiter=",", skip_header=1)
    assert np.isnan(a[:, 39]).all() == stem.endswith("_c3d")
    return a[:, :39].astype(bool)


def oracle_f40(stem, rate):
    return np.loadtxt(C3D_ORACLE / "features" / f"{stem}_f40hipaxis{rate}.csv", skiprows=1).astype(bool)


def knee_angle(j, side):
    a, b, c = (j[:, JOINT_INDEX[side + n]] for n in ("hip", "knee", "ankle"))
    u, v = a - b, c - b
    return np.degrees(np.arccos(np.sum(u * v, 1) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)))


def body_left(j):
    """Per frame: is lhip on the body's left? Facing = mean foot direction (ankles → toes) on the floor."""
    fwd = (j[:, JOINT_INDEX["ltoes"]] + j[:, JOINT_INDEX["rtoes"]]
           - j[:, JOINT_INDEX["lankle"]] - j[:, JOINT_INDEX["rankle"]])
    fwd[:, 1] = 0.0
    left = np.cross([0.0, 1.0, 0.0], fwd)   # Y up, right-handed: left = up × forward
    return np.sum((j[:, JOINT_INDEX["lhip"]] - j[:, JOINT_INDEX["rhip"]]) * left, axis=1) > 0


def derived(src, dst, edit):
    """Write ``edit(c3d)``'s result of a real file to ``dst`` with ezc3d."""
    c = ezc3d.c3d(str(src))
    edit(c)
    c.write(str(dst))
    return dst


def set_points(c, fn):
    pts = c["data"]["points"]
    fn(pts)
    c["data"]["points"] = pts


# ----------------------------------------------------------------------------
# 1. the toolbox oracle (three files)

@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("stem", list(ORACLE_FILES))
def test_joints_match_the_toolbox_before_and_after_the_fit(stem):
    for prefit in (True, False):
        motion = read_c3d(ORACLE_FILES[stem], bone_fit=not prefit)
        oracle = oracle_positions(stem, prefit)
        assert motion.joints.shape == oracle.shape and motion.fps == 120.0
        err = np.abs(motion.joints - oracle).max() / humerus(oracle)
        assert err <= 1e-9, f"{stem} prefit={prefit}: {err:.2e} humerus lengths"
    assert motion.root_rotation is None and motion.skeleton == "c3d:toolbox"


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("stem", list(ORACLE_FILES))
def test_features_1_to_39_bit_for_bit_at_120_and_30_hz(stem):
    for prefit in (True, False):
        motion = read_c3d(ORACLE_FILES[stem], bone_fit=not prefit)
        f120 = relational_features(motion.joints, motion.root_rotation, motion.fps)
        np.testing.assert_array_equal(f120[:, :39], oracle_features(stem, 120, prefit))
        np.testing.assert_array_equal(downsample(f120)[:, :39], oracle_features(stem, 30, prefit))


@pytest.mark.shared
@pytest.mark.parametrize("stem", list(ORACLE_FILES))
def test_feature_40_is_the_hip_axis_version(stem):
    """Without a root rotation the pipeline's #40 is the oracle's f40hipaxis; the stored words are the
    oracle's 30 Hz features with that #40."""
    motion = read_c3d(ORACLE_FILES[stem])
    f120 = relational_features(motion.joints, None, motion.fps)
    np.testing.assert_array_equal(f120[:, 39], oracle_f40(stem, 120))
    np.testing.assert_array_equal(downsample(f120)[:, 39], oracle_f40(stem, 30))
    expected = np.column_stack([oracle_features(stem, 30), oracle_f40(stem, 30)])
    # bits 0-39: the toolbox's 40 (bit 40 is feature 41, FEATURES.md §10, beyond the paper)
    np.testing.assert_array_equal(motion_features(motion) & np.uint64((1 << 40) - 1), pack_words(expected))


@pytest.mark.shared
def test_fit_makes_bone_lengths_constant_and_separates_the_clavicles_from_the_neck():
    j = read_c3d(DG_C3D).joints
    for parent, child in SKELETON_EDGES:
        length = np.linalg.norm(j[:, JOINT_INDEX[child]] - j[:, JOINT_INDEX[parent]], axis=1)
        assert length.std() <= 1e-12 * length.mean(), (parent, child)
    np.testing.assert_array_equal(j[:, JOINT_INDEX["lclavicle"]], j[:, JOINT_INDEX["rclavicle"]])
    gap = np.linalg.norm(j[:, JOINT_INDEX["lclavicle"]] - j[:, JOINT_INDEX["neck"]], axis=1)
    assert 0.2 < gap.mean() < 0.4   # 0.28 cm on dg (FEATURES.md §2.4.6)


@pytest.mark.parametrize("stem, height", [pytest.param("HDM_dg_06-03_03_120_c3d", 103.0, marks=pytest.mark.shared),
                                          ("HDM_mm_01-02_03_120_c3d", 98.5),
                                          pytest.param("85_02_c3d", 50.4, marks=pytest.mark.shared)])
def test_toolbox_unit_is_mm_times_minus_point_scale(stem, height):
    """cm for SCALE −0.1 (HDM05), 2-cm units for SCALE −0.05 (CMU 85_xx): root height at frame 1 (§2.4.3)."""
    motion = read_c3d(ORACLE_FILES[stem])
    assert round(motion.joints[0, JOINT_INDEX["root"], 1], 1) == height


# ----------------------------------------------------------------------------
# 2. the same take as AMC (dg excerpt)

@pytest.mark.shared
def test_dg_agrees_with_its_amc_twin_as_well_as_the_toolbox_does():
    amc, c3d = read_motion(DG_AMC), read_motion(DG_C3D)
    fa = downsample(relational_features(amc.joints, amc.root_rotation, amc.fps))[:, :39]
    fc = downsample(relational_features(c3d.joints, None, c3d.fps))[:, :39]
    ours = np.mean(fa == fc)
    stem = "HDM_dg_06-03_03_120"
    toolbox = np.mean(oracle_features(stem + "_amc", 30) == oracle_features(stem + "_c3d", 30))
    assert round(toolbox, 3) == 0.952 and ours >= toolbox, (ours, toolbox)
    # one world frame: the roots lie ~2.2 cm apart, at lag 0 (§2.4.3, §2.4.9)
    assert np.linalg.norm(amc.joints[:, 0] - c3d.joints[:, 0], axis=1).mean() < 3.0


# ----------------------------------------------------------------------------
# 3. units and axes

@pytest.mark.shared
@pytest.mark.parametrize("unit, factor", [("m", 1e-3), ("cm", 0.1)])
def test_a_copy_in_other_units_gives_the_same_joints_and_features(tmp_path, unit, factor):
    def edit(c):
        set_points(c, lambda p: p[:3].__imul__(factor))
        c["parameters"]["POINT"]["UNITS"]["value"] = [unit]
    copy = derived(DG_C3D, tmp_path / f"dg_{unit}.c3d", edit)
    a, b = read_c3d(DG_C3D), read_c3d(copy)
    # ezc3d stores float32: the rescaled copy differs from the file in the 7th digit
    np.testing.assert_allclose(b.joints, a.joints, rtol=0, atol=1e-6 * np.abs(a.joints).max())
    np.testing.assert_array_equal(motion_features(b), motion_features(a))


@pytest.mark.shared
def test_unknown_units_are_refused(tmp_path):
    copy = derived(DG_C3D, tmp_path / "inch.c3d",
                   lambda c: c["parameters"]["POINT"]["UNITS"].__setitem__("value", ["in"]))
    with pytest.raises(ParseError, match=re.escape(f"{copy}: POINT:UNITS is 'in'; expected mm, cm or m")):
        read_c3d(copy)


@pytest.mark.shared
@pytest.mark.parametrize("screen, rotate", [
    ("+Y", lambda p: np.stack([p[0], p[2], -p[1]])),     # Y-up lab: (X, Z, −Y), a rotation about X
    ("-Z", lambda p: np.stack([-p[0], p[1], -p[2]])),    # upside-down Z: 180° about Y (sign from the data)
])
def test_other_vertical_axes_give_the_same_body(tmp_path, screen, rotate):
    """A proper rotation of the lab changes the joints by a rotation about the vertical only."""
    def edit(c):
        set_points(c, lambda p: p.__setitem__(slice(0, 3), rotate(p[:3].copy())))
        c.add_parameter("POINT", "Y_SCREEN", screen)
    copy = derived(DG_C3D, tmp_path / "turned.c3d", edit)
    a, b = read_c3d(DG_C3D), read_c3d(copy)
    assert b.meta["vertical"] in ("+Y", "-Z") and a.meta["vertical"] == "+Z"
    np.testing.assert_allclose(b.joints[..., 1], a.joints[..., 1], atol=1e-9 * humerus(a.joints))
    for x in (a, b):  # lengths and heights agree, so the bodies are the same up to a turn
        assert body_left(x.joints).all()
    np.testing.assert_allclose(np.linalg.norm(b.joints - b.joints[:, :1], axis=2),
                               np.linalg.norm(a.joints - a.joints[:, :1], axis=2), atol=1e-9 * humerus(a.joints))
    assert np.mean(motion_features(a) == motion_features(b)) == 1.0


@pytest.mark.shared
@pytest.mark.parametrize("path", [DG_C3D, ORACLE_FILES["85_02_c3d"], QUALISYS])
def test_left_stays_left(path):
    """Z-up files become Y-up by a rotation, never a mirror: lhip is on the body's left (in all but
    a few frames of 85_02, where the feet do not show the facing direction; a mirror gives ~0 %)."""
    assert body_left(read_c3d(path).joints).mean() > 0.9


def param_data_offset(buf, group, name):
    """Byte offset of a parameter's data in a C3D parameter section (a plain walk of the records)."""
    pos, groups = 512 * (buf[0] - 1) + 4, {}
    while buf[pos]:
        n, gid = abs(int.from_bytes(buf[pos:pos + 1], "little", signed=True)), buf[pos + 1]
        gid = gid - 256 if gid > 127 else gid
        label = bytes(buf[pos + 2:pos + 2 + n]).decode()
        cur = pos + 2 + n
        if gid < 0:
            groups[-gid] = label
        elif groups.get(gid) == group and label == name:
            return cur + 2 + 2 + buf[cur + 3]       # offset word, type, ndims, dims
        pos = cur + int.from_bytes(buf[cur:cur + 2], "little")
    raise KeyError(name)


@pytest.mark.shared
def test_integer_c3d_reads_right_side_up(tmp_path):
    """An int16 copy of dg (POINT:SCALE +0.1, FEATURES.md §2.4.3): ezc3d applies the scale; the
    toolbox's double scaling and negation (the body upside down) is not copied."""
    src = DG_C3D.read_bytes()
    data_at = 512 * (int.from_bytes(src[16:18], "little") - 1)
    head = bytearray(src[:data_at])
    scale = np.float32(0.1)
    head[12:16] = scale.tobytes()                                     # header: scale > 0 = integers
    at = param_data_offset(head, "POINT", "SCALE")
    head[at:at + 4] = scale.tobytes()
    mm = ezc3d.c3d(str(DG_C3D))["data"]["points"][:3].transpose(2, 1, 0)
    words = np.zeros(mm.shape[:2] + (4,), "<i2")
    words[..., :3] = np.round(mm / scale)
    copy = tmp_path / "int16.c3d"
    copy.write_bytes(bytes(head) + words.tobytes() + bytes(512))
    a, b = read_c3d(DG_C3D), read_c3d(copy)
    assert b.meta["unit"] == "cm" and b.skeleton == "c3d:toolbox"
    assert np.abs(b.joints - a.joints).max() < 0.05                  # cm: 0.1-mm quantization
    assert (b.joints[:, JOINT_INDEX["head"], 1] > b.joints[:, JOINT_INDEX["lankle"], 1] + 100).all()


# ----------------------------------------------------------------------------
# 4. other marker sets: the Qualisys landmark set and a marker map

@pytest.mark.shared
def test_qualisys_landmarks_read_at_200_hz_with_straight_stance_legs():
    """The Qualisys take (a walk, 200 Hz, ISB landmark names) reads at its native rate. Rule for
    a standing frame: for each leg, the frame of the take where the pelvis is highest while the
    other ankle is in the air (> 5 cm above its lowest height), i.e. single-support mid-stance:
    the standing knee is straight (≥ 160°; the lateral markers L_FTC–L_FLE–L_FAL give 164–165°
    there too) and the swinging one clearly bent."""
    motion = read_c3d(QUALISYS)
    j = motion.joints
    assert motion.fps == 200.0 and motion.n_frames == 340 and motion.skeleton == "c3d:landmarks"
    assert motion.meta["vertical"] == "+Z" and motion.meta["unit"] == "cm"
    assert 120 < j[:, JOINT_INDEX["headtop"], 1].mean() - j[:, JOINT_INDEX["lankle"], 1].mean() < 200
    for stand, swing in (("l", "r"), ("r", "l")):
        ankle = j[:, JOINT_INDEX[swing + "ankle"], 1]
        frames = np.flatnonzero(ankle > ankle.min() + 5.0)
        f = frames[np.argmax(j[frames, JOINT_INDEX["root"], 1])]
        assert knee_angle(j, stand)[f] >= 160.0, (stand, f)
        assert knee_angle(j, swing)[f] < knee_angle(j, stand)[f] - 10.0
    # anatomical lengths, cm, constant to a few mm without any fit
    for a, b, lo, hi in (("lhip", "lknee", 35, 50), ("lknee", "lankle", 33, 48), ("lshoulder", "lelbow", 25, 36)):
        d = np.linalg.norm(j[:, JOINT_INDEX[a]] - j[:, JOINT_INDEX[b]], axis=1)
        assert lo < d.mean() < hi and d.std() < 1.0, (a, b)


@pytest.mark.shared
def test_marker_map_overrides_and_the_rest_stays_automatic(tmp_path):
    auto = read_c3d(QUALISYS)
    mapping = tmp_path / "qualisys.toml"
    mapping.write_text('lknee = "L_FLE"\nrknee = ["Qualisys:R_FLE", "r_fme"]\n', encoding="utf-8")
    mapped = read_motion(QUALISYS, marker_map=mapping)
    k = JOINT_INDEX
    pts = read_c3d(QUALISYS, marker_map={"lknee": "L_FME"}).joints[:, k["lknee"]]
    same = [i for i in range(24) if i not in (k["lknee"], k["rknee"])]
    np.testing.assert_array_equal(mapped.joints[:, same], auto.joints[:, same])
    np.testing.assert_allclose(mapped.joints[:, k["rknee"]], auto.joints[:, k["rknee"]], atol=1e-12)
    np.testing.assert_allclose((mapped.joints[:, k["lknee"]] + pts) / 2, auto.joints[:, k["lknee"]], atol=1e-12)
    assert mapped.skeleton == "c3d:marker_map"
    with pytest.raises(ParseError, match=re.escape(f"{QUALISYS}: marker_map: lknee = 'L_KNX', but the file "
                                                   "has no usable marker 'L_KNX' (its markers: R_SCAP, L_WAND1, ")):
        read_c3d(QUALISYS, marker_map={"lknee": "L_KNX"})
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"knee": "L_FLE"}), encoding="utf-8")
    with pytest.raises(ParameterError, match="'knee' is not a canonical joint"):
        read_motion(QUALISYS, marker_map=bad)


@pytest.mark.shared
def test_a_marker_map_reads_a_file_of_unknown_names(tmp_path):
    """dg relabelled M1…M44: refused without a map; with a map naming the 24 joints' markers it reads."""
    labels = ezc3d.c3d(str(DG_C3D))["parameters"]["POINT"]["LABELS"]["value"]
    copy = derived(DG_C3D, tmp_path / "anon.c3d", lambda c: c["parameters"]["POINT"]["LABELS"].__setitem__(
        "value", [f"M{i + 1}" for i in range(len(labels))]))
    with pytest.raises(ParseError, match="cannot place root, lhip, .*rwrist \\(15 of the 15 joints a marker set "
                                         "must place: .*\\) from the markers M1, M2, .*marker map"):
        read_c3d(copy)
    m = {name.split(":")[-1]: f"M{i + 1}" for i, name in enumerate(labels)}
    mapping = {"root": [m["LFWT"], m["RFWT"], m["LBWT"], m["RBWT"]], "lhip": m["LFWT"], "rhip": m["RFWT"],
               "belly": [m["T10"], m["STRN"]], "chest": [m["T10"], m["STRN"], m["C7"]],
               "neck": m["C7"], "lclavicle": m["C7"], "rclavicle": m["C7"],
               "head": [m["LFHD"], m["RFHD"], m["LBHD"], m["RBHD"]], "headtop": [m["LBHD"], m["RBHD"]]}
    for s in "LR":
        j = s.lower()
        mapping.update({f"{j}knee": m[f"{s}KNE"], f"{j}ankle": m[f"{s}ANK"], f"{j}toes": m[f"{s}TOE"],
                        f"{j}shoulder": m[f"{s}SHO"], f"{j}elbow": m[f"{s}ELB"],
                        f"{j}wrist": [m[f"{s}WRA"], m[f"{s}WRB"]], f"{j}fingers": m[f"{s}FIN"]})
    motion = read_c3d(copy, marker_map=mapping)
    orig = read_c3d(DG_C3D, bone_fit=False).joints
    assert motion.skeleton == "c3d:marker_map" and motion.meta["unit"] == "cm"
    np.testing.assert_allclose(motion.joints[:, JOINT_INDEX["lelbow"]], orig[:, JOINT_INDEX["lelbow"]],
                               rtol=1e-7)   # cm vs the toolbox's mm × float32(0.1)
    assert body_left(motion.joints).mean() > 0.95


# ----------------------------------------------------------------------------
# 5. gaps, bad values and refusals

LELB = 14   # Daniel:LELB, point 15 of dg (3 unlabelled points first)


@pytest.mark.shared
def test_short_gaps_are_interpolated_and_unused_markers_ignored(tmp_path):
    n = int(MAX_GAP_S * 120)  # 30 frames = 0.25 s: the longest gap filled

    def edit(c):
        def gaps(p):
            p[:3, LELB, 100:100 + n] = np.nan          # inside the take: linear interpolation
            p[:3, LELB + 1, :n] = 0.0                  # LFRM: used by no formula
            p[:3, 3, -n:] = np.nan                     # LFHD at the end: held
        set_points(c, gaps)
    copy = derived(DG_C3D, tmp_path / "short.c3d", edit)
    a, b = read_c3d(DG_C3D, bone_fit=False), read_c3d(copy, bone_fit=False)
    assert b.meta["filled_samples"] == 2 * n
    e = JOINT_INDEX["lelbow"]
    lo, hi = a.joints[99, e], a.joints[100 + n, e]
    t = (np.arange(1, n + 1) / (n + 1))[:, None]
    np.testing.assert_allclose(b.joints[100:100 + n, e], lo + t * (hi - lo), atol=1e-9)
    np.testing.assert_array_equal(b.joints[:100, e], a.joints[:100, e])
    assert np.abs(b.joints - a.joints).max() < 15.0   # cm: the body stays in place


@pytest.mark.shared
def test_a_gap_in_one_landmark_falls_back_to_another_rule(tmp_path):
    """Qualisys without the medial epicondyle: the knee comes from the lateral one moved medially."""
    labels = ezc3d.c3d(str(QUALISYS))["parameters"]["POINT"]["LABELS"]["value"]
    fme = labels.index("L_FME")
    copy = derived(QUALISYS, tmp_path / "no_fme.c3d",
                   lambda c: set_points(c, lambda p: p[:3, fme, 50:200].__setitem__(Ellipsis, np.nan)))
    a, b = read_c3d(QUALISYS), read_c3d(copy)
    k = JOINT_INDEX["lknee"]
    assert 0.5 < np.linalg.norm(b.joints[:, k] - a.joints[:, k], axis=1).mean() < 3.0   # cm
    assert knee_angle(b.joints, "l").max() > 170.0


@pytest.mark.shared
@pytest.mark.parametrize("value", [np.inf, 1e13])
def test_non_finite_or_absurd_coordinates_are_missing_samples(tmp_path, value):
    """An infinite or absurd coordinate (beyond 1000 km) is a lost sample, interpolated as a gap."""
    bad = derived(DG_C3D, tmp_path / "absurd.c3d",
                  lambda c: set_points(c, lambda p: p.__setitem__((1, LELB, 57), value)))
    lost = derived(DG_C3D, tmp_path / "lost.c3d",
                   lambda c: set_points(c, lambda p: p.__setitem__((slice(0, 3), LELB, 57), np.nan)))
    motion = read_c3d(bad)
    assert motion.meta["notes"][0] == "1 absurd marker samples (e.g. Daniel:LELB in frame 58) read as missing"
    np.testing.assert_array_equal(motion.joints, read_c3d(lost).joints)


PARTIAL = {  # foreign file -> the joints its message names (and the file's own markers it lists first: those
    #           naming no landmark, then the others)
    "ezc3d_BTS.c3d": (["lelbow", "lwrist", "relbow", "rwrist"], "r bar 1, RATT"),      # lower body and shoulders
    "ezc3d_FP_Type1.c3d": (["lelbow", "lwrist", "relbow", "rwrist"], "r bar 1, r bar 2"),
    "ezc3d_read_NOTworking2.c3d": (["root", "lhip", "lknee", "lankle", "ltoes", "rhip", "rknee", "rankle",
                                    "rtoes"], "ASI, LFHD, RFHD"),                      # upper body
    "ezc3d_Optotrak.c3d": (["root", "lhip", "lknee", "lankle", "ltoes", "rhip", "rknee", "rankle", "rtoes",
                            "lshoulder", "lelbow", "lwrist", "rshoulder", "relbow", "rwrist"], "Marker_1, Marker_2"),
}


@pytest.mark.shared
@pytest.mark.parametrize("name", list(PARTIAL))
def test_partial_and_unknown_marker_sets_are_refused_naming_the_joints(name):
    path = FOREIGN / name
    joints, markers = PARTIAL[name]
    with pytest.raises(ParseError) as info:
        read_motion(path)
    msg = str(info.value)
    assert msg.startswith(f"{path}: no full-body marker set: cannot place ")
    placed = re.search(r"cannot place (.*?) \((\d+) of the 15 joints a marker set must place", msg)
    names = placed.group(1).split(", ")
    assert names == joints and int(placed.group(2)) == len(names)
    assert f"from the markers {markers}" in msg and "--marker-map" in msg
    # a dozen markers at most, not the file's 22-54 (issue 26)
    listed = msg.split("from the markers ", 1)[1].split("; name them", 1)[0].split(", … (")[0].split(", ")
    assert len(listed) == 12


@pytest.mark.shared
def test_files_without_points_are_refused(tmp_path):
    def no_points(c):
        c["data"]["points"] = np.zeros((4, 0, c["data"]["points"].shape[2]))
        del c["data"]["meta_points"]
        c["parameters"]["POINT"]["LABELS"]["value"] = []
        c["parameters"]["POINT"]["DESCRIPTIONS"]["value"] = []
    plates = derived(FOREIGN / "ezc3d_FP_Type1.c3d", tmp_path / "plates_only.c3d", no_points)
    assert ezc3d.c3d(str(plates))["data"]["analogs"].shape[1] == 24    # the force-plate channels stay
    empty = derived(DG_C3D, tmp_path / "empty.c3d", no_points)
    for path in (plates, empty):
        with pytest.raises(ParseError, match=re.escape(f"{path}: no 3D points (force plates or analog channels "
                                                       "only): cannot place any of the 24 canonical joints")):
            read_motion(path)


def test_the_readme_marker_map_example_is_a_valid_map():
    readme = (REPO / "docs" / "READING_FILES.md").read_text(encoding="utf-8")
    section = readme[readme.index("**C3D marker maps**"):]
    block = section[section.index("```toml") + len("```toml"):]
    mapping = load_mapping(tomllib.loads(block[:block.index("```")]), what="marker_map")
    assert mapping["lknee"] == ["LKNE", "LKNM"] and mapping["headtop"] == "HEADTOP"
