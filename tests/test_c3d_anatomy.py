"""C3D marker sets by anatomy, not by vendor (issue 19 items 1, 2, 5c/d, 8).

Labels of any vendor read as anatomical landmarks; each canonical joint is placed by rules written
once per anatomical point; lost markers are rebuilt from their rigid segment; only what cannot be
rebuilt is cut. Marker sets we have no file of (a Qualisys 64-marker set, Plug-in Gait full body,
a 22-marker EVaRT set) are built from real trajectories: the HDM05/CMU recordings relabelled, or
with markers taken out, written with ezc3d to tmp_path; their features are compared with the
toolbox reading of the same trajectories.
"""
import struct

import ezc3d
import numpy as np
import pytest

from mocapdb.errors import ParseError
from mocapdb.features import downsample, relational_features
from mocapdb.bodies import JOINT_INDEX
from mocapdb.readers import read_c3d, read_motion
from mocapdb.readers.c3d_names import SEGMENT_OF, landmark_of
from mocapdb.readers.c3dfile import read_c3d_points

from conftest import DATA

pytestmark = pytest.mark.shared

DG = DATA / "hdm05_full" / "HDM_dg_06-03_03_120.c3d"
MM = DATA / "hdm05_full" / "HDM_mm_01-02_03_120.c3d"
CMU = DATA / "cmu" / "c3d" / "85_02.c3d"
FOREIGN2 = DATA / "foreign2" / "c3d"
HEAD = ("LFHD", "RFHD", "LBHD", "RBHD")


def features(motion):
    return downsample(relational_features(motion.joints, None, motion.fps))


def relabel(src, dst, names=None, drop=(), edit=None, only_named=False):
    """A copy of a real C3D file with its labels renamed (subject prefix dropped), some markers made
    empty (``drop``, or with ``only_named`` every marker ``names`` does not rename: missing in every
    frame) and the points edited."""
    c = ezc3d.c3d(str(src))
    labels = [lab.split(":")[-1] for lab in c["parameters"]["POINT"]["LABELS"]["value"]]
    pts = c["data"]["points"]
    for k, lab in enumerate(labels):
        if lab in drop or (only_named and lab not in (names or {})):
            pts[:3, k, :] = np.nan
    if edit is not None:
        edit(pts, labels)
    c["data"]["points"] = pts
    c["parameters"]["POINT"]["LABELS"]["value"] = [(names or {}).get(lab, lab) for lab in labels]
    c.write(str(dst))
    return dst


def sided(pattern, table):
    """``{LFHD: LHeadTamp, RFHD: RHeadTamp, ...}`` from ``{"{s}FHD": "{s}HeadTamp"}``."""
    return {k.format(s=s): v.format(s=s, side=side) for k, v in table.items()
            for s, side in (("L", "Left"), ("R", "Right"))} | pattern


#: the Qualisys 64-marker set of issue 19 (descriptive names)
QUALISYS64 = sided({"C7": "C7", "T10": "Th10", "STRN": "Sternum", "CLAV": "Jugular"},
                   {"{s}FHD": "{s}HeadTamp", "{s}BHD": "{s}HeadBack", "{s}SHO": "{s}Acromium",
                    "{s}ELB": "{s}ElbowLat", "{s}WRA": "{s}WristLat", "{s}WRB": "{s}WristMed",
                    "{s}FIN": "{s}HandLat", "{s}FWT": "{s}ASIS", "{s}BWT": "{s}PSIS", "{s}KNE": "{s}KneeLat",
                    "{s}ANK": "{s}AnkleLat", "{s}HEE": "{s}Heel", "{s}TOE": "{s}MT1", "{s}MT5": "{s}MT5"})
#: Vicon Plug-in Gait full body
PLUG_IN_GAIT = sided({"RBAC": "RBAK"}, {"{s}FWT": "{s}ASI", "{s}BWT": "{s}PSI", "{s}THI": "{s}THI",
                                        "{s}SHN": "{s}TIB"})
#: a 22-marker EVaRT (Motion Analysis, Helen Hayes style) set: dotted names, no C7, no sternum
#: (the toolbox set's back waist markers stand in for the sacrum pair)
EVART22 = sided({"LFHD": "Front.Head", "LBHD": "Rear.Head", "RBHD": "Top.Head", "RBAC": "R.Offset"},
                {"{s}SHO": "{s}.Shoulder", "{s}ELB": "{s}.Elbow", "{s}WRA": "{s}.Wrist", "{s}FWT": "{s}.ASIS",
                 "{s}BWT": "{s}.PSIS", "{s}KNE": "{s}.Knee", "{s}ANK": "{s}.Ankle", "{s}HEE": "{s}.Heel",
                 "{s}TOE": "{s}.Toe"})


def test_vendor_labels_read_as_landmarks():
    cases = {"Nick01:LFSH": "l_shoulder_front", "Nick01:LIWR": "l_wrist_uln", "Nick01:LOWR": "l_wrist_rad",
             "Nick01:RMWT": "r_waist_mid", "R.Shoulder": "r_acromion", "L.ASIS": "l_asis", "Sacrum": "sacr",
             "L_SAE": "l_acromion", "L_HLE": "l_elbow_lat", "L_RSP": "l_wrist_rad", "CV7": "c7",
             "LHeadTamp": "l_head_front", "LAcromium": "l_acromion", "LElbowLat": "l_elbow_lat",
             "LWristMed": "l_wrist_uln", "LASIS": "l_asis", "LKneeLat": "l_knee_lat", "LAnkleLat": "l_ankle_lat",
             "LHeel": "l_heel", "LMT1": "l_mt1", "WaistLFront": "l_asis", "Knee_R": "r_knee_lat",
             "Top.Head": "head_top", "Rear.Head": "c_head_back", "V.Sacral": "sacr", "ARIEL": "head_top",
             "Marker_12": None, "R.Offset": None}
    assert {label: landmark_of(label) for label in cases} == cases
    assert SEGMENT_OF["l_asis"] == SEGMENT_OF["r_psis"] == "pelvis"
    assert SEGMENT_OF["l_knee_lat"] == "l_thigh" and SEGMENT_OF["l_acromion"] is None


@pytest.mark.slow
@pytest.mark.parametrize("src", [DG, MM, CMU], ids=lambda p: p.stem)
@pytest.mark.parametrize("names, drop, least", [
    (QUALISYS64, (), 0.955), (PLUG_IN_GAIT, (), 0.955), (EVART22, "others", 0.93), ({}, HEAD, 0.98)],
    ids=["qualisys64", "plug_in_gait", "evart22", "no_head_markers"])
def test_other_sets_of_the_same_trajectories_read_like_the_toolbox_set(src, names, drop, least, tmp_path):
    """Whatever the names, the features of the same markers agree with the toolbox reading on most
    feature-frames (the toolbox's own AMC/C3D agreement on dg is 95.2 %)."""
    copy = relabel(src, tmp_path / "relabelled.c3d", names, () if drop == "others" else drop,
                   only_named=drop == "others")
    ref, motion = read_c3d(src), read_c3d(copy)
    assert motion.skeleton == "c3d:landmarks" and motion.joints.shape == ref.joints.shape
    assert np.mean(features(motion) == features(ref)) >= least
    notes = " | ".join(motion.meta["notes"])
    if drop == HEAD:
        assert notes == "head and headtop placed from the neck and the trunk's axis (no head markers)"
    if drop == "others":   # 22 markers: no C7, sternum, thoracic or hand markers
        assert len(read_c3d_points(copy).valid.any(axis=0).nonzero()[0]) == 22
        for note in ("neck placed between the shoulders", "belly and chest placed on the trunk's axis",
                     "fingers placed beyond the wrists"):
            assert note in notes


@pytest.mark.slow
def test_a_lost_pelvis_marker_is_rebuilt_from_its_segment(tmp_path):
    """LASI (Plug-in Gait names) missing for 0.42 s: rebuilt from RASI, LPSI, RPSI, the joints stay within a
    millimetre of the full reading; with the whole pelvis gone for 0.83 s the take is cut there."""
    full = read_c3d(relabel(MM, tmp_path / "full.c3d", PLUG_IN_GAIT))

    def gap(markers, a, b):
        def edit(pts, labels):
            for m in markers:
                pts[:3, labels.index(m), a:b] = np.nan
        return edit
    one = read_c3d(relabel(MM, tmp_path / "lasi.c3d", PLUG_IN_GAIT, edit=gap(["LFWT"], 1000, 1050)))
    assert one.meta["notes"] == ["rebuilt LASI in 50 of the 50 frames it is missing for longer than 0.25 s, "
                                 "from RASI, LPSI, RPSI (its rigid segment: pelvis)"]
    assert np.abs(one.joints - full.joints).max() < 0.1   # cm
    cut = read_c3d(relabel(MM, tmp_path / "pelvis.c3d", PLUG_IN_GAIT,
                           edit=gap(["LFWT", "RFWT", "LBWT", "RBWT"], 2000, 2100)))
    assert cut.meta["frames"] == (1, 2000) and cut.n_frames == 2000
    assert cut.meta["notes"][0].startswith("kept frames 1–2000 of 3990, the longest stretch without an "
                                           "unrecoverable gap (1990 frames cut: LASI, RASI, LPSI, RPSI missing in "
                                           "frames 2001–2100 (0.83 s)")
    # the same joints (the Bell hips' pelvis width is the mean over the frames kept)
    np.testing.assert_allclose(cut.joints, full.joints[:2000], atol=1e-3)


@pytest.mark.slow
@pytest.mark.parametrize("how", ["nan", "zeros", "residual"])
def test_a_gap_nothing_rebuilds_is_cut_or_refused_naming_marker_and_frames(tmp_path, how):
    """LELB lost for 0.33 s (its upper-arm segment has no three other markers): the long take keeps
    its longest stretch; the 1.7 s dg take would keep less than a second and is refused."""
    def edit_at(a, b):
        def edit(c):
            labels = [lab.split(":")[-1] for lab in c["parameters"]["POINT"]["LABELS"]["value"]]
            k = labels.index("LELB")
            if how == "residual":
                r = c["data"]["meta_points"]["residuals"]
                r[0, k, a:b] = -1
                c["data"]["meta_points"]["residuals"] = r
            else:
                pts = c["data"]["points"]
                pts[:3, k, a:b] = np.nan if how == "nan" else 0.0
                c["data"]["points"] = pts
        return edit

    def derived(src, dst, edit):
        c = ezc3d.c3d(str(src))
        edit(c)
        c.write(str(dst))
        return dst
    long_take = read_c3d(derived(MM, tmp_path / "mm.c3d", edit_at(3000, 3040)))
    assert long_take.meta["frames"] == (1, 3000)
    assert "meinard:LELB missing in frames 3001–3040 (0.33 s)" in long_take.meta["notes"][0]
    short = derived(DG, tmp_path / "dg.c3d", edit_at(100, 140))
    with pytest.raises(ParseError, match="Daniel:LELB missing in frames 101–140 \\(0.33 s\\).*the longest stretch "
                                         "without it, frames 1–100 \\(0.83 s\\), is too little"):
        read_c3d(short)


@pytest.mark.slow
def test_a_pelvis_landmark_absent_from_the_take_is_mirrored(tmp_path):
    full = read_c3d(relabel(MM, tmp_path / "full.c3d", PLUG_IN_GAIT))
    motion = read_c3d(relabel(MM, tmp_path / "no_lasi.c3d", PLUG_IN_GAIT, drop={"LFWT"}))
    assert motion.meta["notes"] == ["l_asis mirrored from RASI (the pelvis has no such marker)"]
    err = np.linalg.norm(motion.joints - full.joints, axis=2)
    assert err[:, JOINT_INDEX["root"]].mean() < 1.5 and err.mean() < 1.5   # cm: the pelvis is nearly symmetric


def _patch_parameter(data, group_id, name, value):
    """``data`` with the first element of parameter ``name`` of group ``group_id`` set to ``value``."""
    d = bytearray(data)
    i = 512 * (d[0] - 1) + 4
    while True:
        n, gid = struct.unpack("bb", d[i:i + 2])
        if n == 0:
            return d
        label = bytes(d[i + 2:i + 2 + abs(n)]).decode("latin-1").upper()
        offset, = struct.unpack("<H", d[i + 2 + abs(n):i + 4 + abs(n)])
        if gid == group_id and label == name:
            at = i + 4 + abs(n)
            typ, ndims = struct.unpack("bB", d[at:at + 2])
            at += 2 + ndims
            d[at:at + 4] = struct.pack("<f", value) if typ == 4 else struct.pack("<h", int(value)) + d[at + 2:at + 4]
            return d
        if offset == 0:
            return d
        i += 2 + abs(n) + offset


def _groups(path):
    """``{GROUP: id}`` of a C3D file's parameter section."""
    d = path.read_bytes()
    i, out = 512 * (d[0] - 1) + 4, {}
    while True:
        n, gid = struct.unpack("bb", d[i:i + 2])
        if n == 0:
            return out
        if gid < 0:
            out[bytes(d[i + 2:i + 2 + abs(n)]).decode("latin-1").upper()] = -gid
        offset, = struct.unpack("<H", d[i + 2 + abs(n):i + 4 + abs(n)])
        if offset == 0:
            return out
        i += 2 + abs(n) + offset


def test_the_point_rate_from_the_parameters_when_the_header_has_none(tmp_path):
    data = bytearray(DG.read_bytes())
    data[20:24] = struct.pack("<f", 0.0)                  # the header's rate
    zero = tmp_path / "header_rate_0.c3d"
    zero.write_bytes(bytes(data))
    motion = read_c3d(zero)
    assert motion.fps == 120.0 and "rate 120 Hz from POINT:RATE (the header's rate is 0)" in motion.meta["notes"]
    np.testing.assert_array_equal(motion.joints, read_c3d(DG).joints)
    groups = _groups(DG)
    camera = tmp_path / "camera_rate.c3d"   # the point rate only in TRIAL:CAMERA_RATE (Vicon writes it)
    camera.write_bytes(bytes(_patch_parameter(bytes(data), groups["POINT"], "RATE", 0.0)))
    motion = read_c3d(camera)
    assert motion.fps == 120.0 and motion.meta["notes"] == [
        "rate 120 Hz from TRIAL:CAMERA_RATE (POINT:RATE and the header have none)"]
    none = tmp_path / "no_rate.c3d"
    none.write_bytes(bytes(_patch_parameter(camera.read_bytes(), groups["TRIAL"], "CAMERA_RATE", 0.0)))
    with pytest.raises(ParseError, match="no point rate: POINT:RATE is 0, the header's rate 0, and no "
                                         "TRIAL:CAMERA_RATE"):
        read_c3d(none)


@pytest.mark.parametrize("name", ["SCALE", "OFFSET", "GEN_SCALE"])
def test_broken_analog_metadata_never_blocks_the_points(tmp_path, name):
    """The EVaRT case (ANALOG:SCALE shorter than ANALOG:USED): ezc3d would index past it, so the analog
    samples are taken out and the points read as they are, with a note."""
    src = DATA / "foreign" / "c3d" / "ezc3d_FP_Type1.c3d"
    data = bytearray(src.read_bytes())
    analog = _groups(src)["ANALOG"]
    i = 512 * (data[0] - 1) + 4
    while True:   # rename ANALOG:<name> so that the file has none
        n, gid = struct.unpack("bb", data[i:i + 2])
        label = bytes(data[i + 2:i + 2 + abs(n)]).decode("latin-1").upper()
        offset, = struct.unpack("<H", data[i + 2 + abs(n):i + 4 + abs(n)])
        if gid == analog and label == name:
            data[i + 1 + abs(n)] = ord("X")
            break
        i += 2 + abs(n) + offset
    broken = tmp_path / "broken_analog.c3d"
    broken.write_bytes(bytes(data))
    pts, ref = read_c3d_points(broken), read_c3d_points(src)
    np.testing.assert_array_equal(pts.valid, ref.valid)
    np.testing.assert_array_equal(pts.xyz[pts.valid], ref.xyz[ref.valid])
    assert pts.meta["notes"] == [f"analog channels not read: ANALOG:{name} "
                                 + ("is missing, but the file declares analog channels" if name == "GEN_SCALE"
                                    else "has 0 values for ANALOG:USED = 24 channels") + " (the points do not need them)"]


def test_the_anatomical_path_brings_the_dg_c3d_to_its_amc_twin():
    """Issue 19 item 8: the toolbox's formulas put the elbow on its lateral marker (and the hips 40 %
    wider apart than the ASF); read by anatomical joint centres, the C3D agrees better with its AMC twin
    on the upper-arm features that made the default model call it a jump."""
    amc = read_motion(DATA / "hdm05_full" / "HDM_dg_06-03_03_120.amc")
    fa = downsample(relational_features(amc.joints, amc.root_rotation, amc.fps))
    toolbox = features(read_c3d(DG))
    anatomical = features(read_motion(DG, marker_rules="anatomical"))
    assert round(float(np.mean(fa == toolbox)), 4) == 0.9529
    assert round(float(np.mean(fa == anatomical)), 4) == 0.9696
    right_arm = 26   # #27 humerus_right_abduct_rel_spine
    assert np.mean(fa[:, right_arm] == toolbox[:, right_arm]) < 0.5 < 0.9 < np.mean(
        fa[:, right_arm] == anatomical[:, right_arm])
    with pytest.raises(Exception, match="marker_rules must be one of toolbox, anatomical"):
        read_c3d(DG, marker_rules="vendor")


FOREIGN2_C3D = {   # file -> (frames kept, notes that must be there)
    "vicon53_freeform.c3d": ((1, 1101), ["rebuilt Nick01:RBWT in 37 of the 37 frames"]),
    "cortex_dotted_trial1.c3d": ((844, 1286), ["kept frames 844–1286 of 1526", "no marker tracked in frames 1–843",
                                               "head and headtop placed from the neck",
                                               "ankles placed from heel, toes and knee",
                                               "fingers placed beyond the wrists"]),
    "isb_walk_2014001_C1_01.c3d": ((1, 387), ["head and headtop placed from the neck and the trunk's axis"]),
}


@pytest.mark.parametrize("name", list(FOREIGN2_C3D))
def test_the_full_body_sets_of_other_labs_read_as_bodies(name):
    frames, notes = FOREIGN2_C3D[name]
    motion = read_c3d(FOREIGN2 / name)
    assert motion.meta["frames"] == frames and motion.n_frames == frames[1] - frames[0] + 1
    text = " | ".join(motion.meta["notes"])
    assert all(n in text for n in notes), text
    j = motion.joints
    y = j[..., 1]
    # a standing body: head above neck above root above knees above ankles, in most frames
    order = [JOINT_INDEX[k] for k in ("headtop", "neck", "root", "lknee", "lankle")]
    assert np.mean(np.all(np.diff(y[:, order], axis=1) < 0, axis=1)) > 0.9
    # left is left: the left hip lies on the body's left of the facing direction (toes ahead of ankles)
    fwd = j[:, JOINT_INDEX["ltoes"]] + j[:, JOINT_INDEX["rtoes"]] - j[:, JOINT_INDEX["lankle"]] - j[:, JOINT_INDEX["rankle"]]
    fwd[:, 1] = 0
    left = np.cross([0.0, 1.0, 0.0], fwd)
    assert np.mean(np.sum((j[:, JOINT_INDEX["lhip"]] - j[:, JOINT_INDEX["rhip"]]) * left, axis=1) > 0) > 0.9
    # human proportions: thigh and shin of similar length, upper arm shorter than the leg
    def length(a, b):
        return np.median(np.linalg.norm(j[:, JOINT_INDEX[a]] - j[:, JOINT_INDEX[b]], axis=1))
    assert 0.7 < length("lhip", "lknee") / length("lknee", "lankle") < 1.4
    assert 0.25 < length("lshoulder", "lelbow") / (length("lhip", "lknee") + length("lknee", "lankle")) < 0.55
