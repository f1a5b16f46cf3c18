"""The full-body C3D families refused before issue 26 (item 2), built from real trajectories.

* Vicon Clinical Manager / Helen Hayes: a virtual sacrum ``VSAC``, toes ``R.TO``/``L.TO`` and
  virtual joint centres ``VRHI``, ``VLKN``, ``VRAN``, … — refused with "cannot place root, lhip,
  rhip". Built from the shipped HDM05 C3D (so it runs in a bare clone): the sacrum is the middle
  of the back waist markers, the joint centres the toolbox's hips, knees and ankles of the same
  markers, written as points; the reader must take them as the joints.
* A Cortex set with OpenSim/OpenCap names (``r.ASIS``, ``r_mknee``, ``r_5meta``, ``r_lelbow`` /
  ``r_melbow``, ``R_wrist_radius`` / ``R_wrist_ulna``) — refused with "cannot place lwrist,
  rwrist". Built from the ISB walk of ``../shared`` by renaming its landmarks: the same
  landmarks, so the same joints.
* PSIS under other names (SIPS, EIPS, posterior superior iliac spine spelled out).
* A refusal names the joints it cannot place and at most a dozen markers.
"""
import lzma
import re

import ezc3d
import numpy as np
import pytest

from mocapdb.errors import ParseError
from mocapdb.features import downsample, relational_features
from mocapdb.bodies import JOINT_INDEX
from mocapdb.readers import read_c3d
from mocapdb.readers.c3d_names import SEGMENT_OF, landmark_of

from conftest import DATA, SAMPLE_C3D

ISB = DATA / "foreign2" / "c3d" / "isb_walk_2014001_C1_01.c3d"


def features(motion):
    return downsample(relational_features(motion.joints, None, motion.fps))


def test_the_new_names_read_as_landmarks():
    cases = {"VSAC": "sacr", "R.TO": "r_toe", "L.TO": "l_toe", "VRHI": "r_hip_jc", "VLKN": "l_knee_jc",
             "VRAN": "r_ankle_jc", "VLSH": "l_shoulder_jc", "V.RHip": "r_hip_jc", "R_HJC": "r_hip_jc",
             "LKJC": "l_knee_jc", "R.Hip.JC": "r_hip_jc", "r.ASIS": "r_asis", "L.PSIS": "l_psis",
             "r_mknee": "r_knee_med", "L_mankle": "l_ankle_med", "r_5meta": "r_mt5", "r_calc": "r_heel",
             "r_lelbow": "r_elbow_lat", "r_melbow": "r_elbow_med", "R_elbow_lat": "r_elbow_lat",
             "R_wrist_radius": "r_wrist_rad", "R_wrist_ulna": "r_wrist_uln", "r_lwrist": "r_wrist_rad",
             "r_mwrist": "r_wrist_uln", "RSIPS": "r_psis", "L.EIPS": "l_psis", "L_EIAS": "l_asis",
             "R_Post_Sup_Iliac": "r_psis",
             # unchanged: the first word's V is no virtual point when the label reads without it
             "V.Sacral": "sacr", "VERTEX": "head_top", "LWRIST": "l_wrist", "Marker_12": None, "VXYZ": None}
    assert {label: landmark_of(label) for label in cases} == cases
    assert SEGMENT_OF["l_hip_jc"] == "pelvis" and SEGMENT_OF["r_knee_jc"] == "r_thigh"
    assert SEGMENT_OF["l_wrist_jc"] == "l_forearm" and SEGMENT_OF["r_shoulder_jc"] is None


# -- Vicon Clinical Manager / Helen Hayes, from the shipped HDM05 C3D -------------------------------

def _unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _toolbox_hip(front, back, other_back, left):
    """The toolbox's hip (FEATURES.md §2.4.4) in the lab's own axes: 0.7 front + 0.3 back waist marker,
    0.4 pelvis depths along the normal of the back-waist plane."""
    v1, v2 = back - front, back - other_back
    n = np.cross(v1, v2) if left else np.cross(v2, v1)
    return 0.7 * front + 0.3 * back + 0.4 * np.mean(np.linalg.norm(v1, axis=1)) * _unit(n)


def vcm_helen_hayes(src, dst):
    """The sample's trajectories as a Vicon Clinical Manager Helen Hayes file: LASI/RASI, a virtual sacrum
    instead of the back waist markers, R.TO/L.TO toes without fifth metatarsals, LTIB shanks, and the
    virtual hip, knee and ankle centres VLHI … VRAN (the toolbox's joints of these markers, lab axes)."""
    c = ezc3d.c3d(str(src))
    labels = [lab.split(":")[-1] for lab in c["parameters"]["POINT"]["LABELS"]["value"]]
    pts = c["data"]["points"]
    m = {lab: pts[:3, k, :].T for k, lab in enumerate(labels)}
    virtual = {"VSAC": (m["LBWT"] + m["RBWT"]) / 2,
               "VLHI": _toolbox_hip(m["LFWT"], m["LBWT"], m["RBWT"], True),
               "VRHI": _toolbox_hip(m["RFWT"], m["RBWT"], m["LBWT"], False)}
    for s in "LR":
        toe, mt5, ank, kne = (m[f"{s}{k}"] for k in ("TOE", "MT5", "ANK", "KNE"))
        virtual[f"V{s}KN"] = kne + 0.6 * (toe - mt5) + 0.2 * (mt5 - ank)
        virtual[f"V{s}AN"] = ank + 0.3 * (toe - mt5)
    names = {"LFWT": "LASI", "RFWT": "RASI", "LTOE": "L.TO", "RTOE": "R.TO", "LSHN": "LTIB", "RSHN": "RTIB"}
    keep = [k for k, lab in enumerate(labels) if lab not in ("LBWT", "RBWT", "LMT5", "RMT5") and
            not lab.startswith("*")]
    out = np.concatenate([pts[:, keep], np.stack([np.vstack([p.T, np.ones(len(p))]) for p in virtual.values()],
                                                 axis=1)], axis=1)
    c["data"]["points"] = out
    del c["data"]["meta_points"]
    c["parameters"]["POINT"]["LABELS"]["value"] = [names.get(labels[k], labels[k]) for k in keep] + list(virtual)
    c["parameters"]["POINT"]["DESCRIPTIONS"]["value"] = [""] * out.shape[1]
    c.write(str(dst))
    return dst


@pytest.fixture(scope="module")
def sample_c3d(tmp_path_factory):
    plain = tmp_path_factory.mktemp("sample") / "HDM_mm_01-02_03_120.c3d"
    plain.write_bytes(lzma.decompress(SAMPLE_C3D.read_bytes()))
    return plain


@pytest.mark.slow
def test_vicon_clinical_manager_takes_its_virtual_joint_centres(sample_c3d, tmp_path):
    """The virtual sacrum and joint centres are read as such (they were refused: "cannot place root,
    lhip, rhip"): hips, knees and ankles are the virtual points, the root the middle of the ASIS and
    the sacrum — the toolbox's joints of the same markers (before its bone-length fit) — and the
    features agree with the toolbox reading of the original file."""
    vcm = read_c3d(vcm_helen_hayes(sample_c3d, tmp_path / "vcm.c3d"))
    prefit, ref = read_c3d(sample_c3d, bone_fit=False), read_c3d(sample_c3d)
    assert vcm.skeleton == "c3d:landmarks" and vcm.joints.shape == ref.joints.shape
    for joint in ("root", "lhip", "rhip", "lknee", "rknee", "lankle", "rankle"):
        k = JOINT_INDEX[joint]
        np.testing.assert_allclose(vcm.joints[:, k], prefit.joints[:, k], atol=1e-3, err_msg=joint)   # cm
    toes = np.linalg.norm(vcm.joints[:, JOINT_INDEX["ltoes"]] - prefit.joints[:, JOINT_INDEX["ltoes"]], axis=1)
    assert 1 < np.median(toes) < 8   # the toe marker, not the middle of toe and fifth metatarsal
    assert np.mean(features(vcm) == features(ref)) >= 0.97


# -- OpenSim / OpenCap names on a Cortex set, from the ISB walk ------------------------------------

def _isb_names(elbows, wrists):
    out = {"L_IAS": "L.ASIS", "R_IAS": "r.ASIS", "L_IPS": "L.PSIS", "R_IPS": "r.PSIS", "CV7": "C7"}
    for s, o in (("L", "L"), ("R", "r")):   # OpenCap writes the right side in lower case
        out |= {f"{s}_FLE": f"{o}_knee", f"{s}_FME": f"{o}_mknee", f"{s}_FAL": f"{o}_ankle",
                f"{s}_TAM": f"{o}_mankle", f"{s}_FCC": f"{o}_calc", f"{s}_FM2": f"{o}_toe",
                f"{s}_FM5": f"{o}_5meta", f"{s}_SAE": f"{s}_Shoulder",
                f"{s}_HLE": elbows[0].format(s=o, S=s), f"{s}_HME": elbows[1].format(s=o, S=s),
                f"{s}_RSP": wrists[0].format(s=o, S=s), f"{s}_UHE": wrists[1].format(s=o, S=s)}
    return out


OPENSIM = {"opencap": _isb_names(("{s}_lelbow", "{s}_melbow"), ("{s}_lwrist", "{s}_mwrist")),
           "cortex_opensim": _isb_names(("{S}_elbow_lat", "{S}_elbow_med"), ("{S}_wrist_radius", "{S}_wrist_ulna"))}


def relabelled(src, dst, names):
    c = ezc3d.c3d(str(src))
    c["parameters"]["POINT"]["LABELS"]["value"] = [names.get(lab, lab) for lab in
                                                   c["parameters"]["POINT"]["LABELS"]["value"]]
    c.write(str(dst))
    return dst


@pytest.mark.shared
@pytest.mark.parametrize("names", list(OPENSIM))
def test_opensim_names_read_as_the_same_landmarks(names, tmp_path):
    """Elbows as lateral/medial pairs and wrists as radius/ulna styloids under OpenSim's names read as
    the ISB landmarks they are: the joints of the relabelled walk are the original's."""
    motion = read_c3d(relabelled(ISB, tmp_path / f"{names}.c3d", OPENSIM[names]))
    np.testing.assert_array_equal(motion.joints, read_c3d(ISB).joints)


@pytest.mark.shared
@pytest.mark.parametrize("psis", ["{s}SIPS", "{s}.EIPS", "{s}_Post_Sup_Iliac", "{side}PSIS"])
def test_psis_under_other_names(psis, tmp_path):
    names = {f"{s}_IPS": psis.format(s=s, side=side) for s, side in (("L", "Left"), ("R", "Right"))}
    motion = read_c3d(relabelled(ISB, tmp_path / "psis.c3d", names))
    np.testing.assert_array_equal(motion.joints, read_c3d(ISB).joints)


# -- refusals ---------------------------------------------------------------------------------------

def _listed(message):
    """The markers a refusal lists (before its ", … (k of n)")."""
    return message.split("from the markers ", 1)[1].split("; name them", 1)[0].split(", … (")[0].split(", ")


def test_a_refusal_names_a_dozen_markers_not_all(sample_c3d, tmp_path):
    """44 markers of unknown names: the 15 joints, 12 markers and how many there are."""
    c = ezc3d.c3d(str(sample_c3d))
    c["parameters"]["POINT"]["LABELS"]["value"] = [f"M{i + 1}" for i in range(44)]
    c.write(str(tmp_path / "anonymous.c3d"))
    with pytest.raises(ParseError) as info:
        read_c3d(tmp_path / "anonymous.c3d")
    msg = str(info.value)
    assert "cannot place root, lhip, lknee, lankle, ltoes, rhip, rknee, rankle, rtoes, lshoulder, lelbow, " \
           "lwrist, rshoulder, relbow, rwrist (15 of the 15 joints" in msg
    assert _listed(msg) == [f"M{i + 1}" for i in range(12)] and "M13" not in msg and "(12 of 44)" in msg


@pytest.mark.shared
def test_a_near_miss_says_what_is_missing_and_lists_the_unknown_markers_first(tmp_path):
    """Wrist markers under names nobody reads: the wrists are named with what they need, and the
    file's markers that name no landmark come first among the twelve listed."""
    names = OPENSIM["cortex_opensim"] | {"L_RSP": "L_wristband_a", "L_UHE": "L_wristband_b",
                                         "R_RSP": "R_wristband_a", "R_UHE": "R_wristband_b"}
    with pytest.raises(ParseError) as info:
        read_c3d(relabelled(ISB, tmp_path / "no_wrists.c3d", names))
    msg = str(info.value)
    assert re.search(r"cannot place lwrist, rwrist \(2 of the 15 joints a marker set must place: .*; wrists need "
                     r"a styloid or wrist marker\)", msg)
    listed = _listed(msg)
    assert len(listed) == 12 and {"L_wristband_a", "L_wristband_b", "R_wristband_a", "R_wristband_b"} <= set(listed)
    assert all(landmark_of(m) is None for m in listed[:listed.index("R_wristband_b") + 1])
    assert "(12 of 52; the " in msg
