"""ASF/AMC reading and forward kinematics on the real data and the toolbox oracle.

Checks: every published file reads (frame counts, exact float parsing), the
kernel FK equals a per-frame reference written from FEATURES.md §2.2, the
joint positions equal the toolbox oracle, and the edge cases of the text
(radians, rates, root position/orientation, zero directions, DOF subsets,
bone order, line endings).
"""
import csv
import lzma
import math
import os
import re
import shutil
import time
from dataclasses import replace

import numpy as np
import pytest

from conftest import DATA, HAVE_SHARED, ORACLE, SAMPLE_86_09, SAMPLE_86_ASF, humerus, shared_cases
from mocapdb.readers.textscan import NUM_BAD, NUM_OK, NUM_SLOW, has_line_longer, longest_line, parse_numbers
from mocapdb.bodies.acclaim import column_layout
from mocapdb.readers.amc import parse_amc, read_amc
from mocapdb.readers.asf import parse_asf, read_asf
from mocapdb.bodies.joints import JOINT_INDEX, JOINT_NAMES
from mocapdb.bodies.kinematics import (asf_forward_kinematics, euler_matrix, node_positions,
                                orientation_matrix, sincos)
from mocapdb.errors import ParseError
from mocapdb.readers import find_skeleton, read_motion
from naive_kinematics import naive_amc_values, naive_asf_fk

ALL_AMC = sorted(DATA.glob("**/*.amc"))
ALL_ASF = sorted(DATA.glob("**/*.asf"))
# the CMU and HDM05 skeletons as their databases published them (30 bones each);
# foreign/ and foreign2/ hold other writers' dialects, checked on their own below
PUBLISHED_ASF = [p for p in ALL_ASF if p.relative_to(DATA).parts[0] in ("cmu", "hdm05_cut", "hdm05_full")]
MASS_KG = DATA / "foreign2/amc/test_mass_kg.asf"
SQUAT = DATA / "hdm05_cut/squat1Reps/HDM_bd_squat1Reps_001_120.amc"
CMU86 = DATA / "cmu/86/86_09.amc"

# a sample for the slow Python references: every CMU subject, the uncut HDM05
# excerpt, and the first take of every class (actors vary by class)
SAMPLE = [CMU86, DATA / "cmu/02/02_01.amc", DATA / "cmu/13/13_29.amc",
          DATA / "cmu/14/14_14.amc", DATA / "hdm05_full/HDM_dg_06-03_03_120.amc"] + [
    sorted(d.glob("*.amc"))[k % 7]
    for k, d in enumerate(sorted(p for p in (DATA / "hdm05_cut").iterdir() if p.is_dir()))] if HAVE_SHARED else []


def skeleton_path(amc):
    return find_skeleton(amc) or DATA / "cmu/02/02.asf"  # cmu/13, cmu/14: any CMU ASF


def fk(asf_text, amc_bytes, path="x"):
    s = parse_asf(asf_text, path=path + ".asf")
    m = parse_amc(amc_bytes, s, path=path + ".amc")
    return s, m, asf_forward_kinematics(s, m)


# ----------------------------------------------------------------------------
# ASF

@pytest.mark.shared
@pytest.mark.parametrize("asf", shared_cases(PUBLISHED_ASF), ids=lambda p: str(p.relative_to(DATA)))
def test_asf_reads_as_published(asf):
    s = read_asf(asf)
    text = asf.read_bytes().decode("latin-1")
    assert len(s.bones) == 30
    assert s.bones[0].name == "lhipjoint" and s.bones[-1].name == "rthumb"
    assert s.root_order == ("tx", "ty", "tz", "rx", "ry", "rz")
    assert s.length_unit == 0.45 and s.angle_unit == "deg"
    norms = np.array([np.linalg.norm(b.direction) for b in s.bones])
    assert np.all(np.abs(norms - 1) < 1e-15)  # re-normalised (files: 6 digits)
    raw = float(re.search(r"name lhumerus\s+direction[^\n]*\n\s*length\s+(\S+)", text).group(1))
    assert s.bone("lhumerus").length == pytest.approx(raw / 0.45 * 2.54, rel=1e-15)
    assert s.bone("lfemur").parent == "lhipjoint" and s.bone("lhipjoint").parent == "root"
    assert s.children("thorax") == ("lowerneck", "lclavicle", "rclavicle")
    assert s.bone("lfoot").dof == ("rx", "rz")
    assert list(s.topological_order()) == list(range(30))


@pytest.mark.shared
def test_every_asf_reads():
    for asf in ALL_ASF:
        s = read_asf(asf)
        assert len(s.bones) >= 15 and s.topological_order() is not None, asf


@pytest.mark.shared
def test_named_and_unknown_units_read():
    # foreign2: `:units mass kg / length m / angle deg`, and `fps:30` in :documentation
    s = read_asf(MASS_KG)
    assert s.angle_unit == "deg" and s.documented_fps == 30.0
    assert s.length_unit == pytest.approx(2.54 / 100)  # metres, in the toolbox's centimetres
    assert s.bone("Head").length == pytest.approx(123.9 * 100)
    assert any("mass" in n for n in s.notes)
    text = """:version 1.10
:name x
:units
  mass 1.0
  length mm
  angle deg
  time sec
:documentation
  recorded at 60 fps by a lab
:root
  order TX TY TZ RX RY RZ
  axis XYZ
  position 0 0 0
  orientation 0 0 0
:bonedata
  begin
    id 1
    name lfemur
    direction 0 -1 0
    length 400
    axis 0 0 0 XYZ
  end
:hierarchy
  begin
    root lfemur
  end
"""
    s = parse_asf(text, path="t.asf")
    assert s.length_unit == pytest.approx(25.4) and s.bone("lfemur").length == pytest.approx(40.0)
    assert s.documented_fps == 60.0 and any("time" in n for n in s.notes)
    m = parse_amc(b":FULLY-SPECIFIED\n1\nroot 0 0 0 0 0 0\nlfemur\n", s, path="t.amc")
    assert m.fps == 60.0  # no :SAMPLES-PER-SECOND: the documented rate
    m = parse_amc(b":SAMPLES-PER-SECOND 50\n1\nroot 0 0 0 0 0 0\nlfemur\n", s, path="t.amc")
    assert m.fps == 50.0  # the AMC's own rate wins
    with pytest.raises(ParseError, match="t.asf:5: units length: expected a positive number"):
        parse_asf(text.replace("length mm", "length -2"), path="t.asf")


@pytest.mark.shared
def test_asf_offsets_follow_the_toolbox_rounding():
    text = (DATA / "hdm05_cut/HDM_bd.asf").read_bytes().decode("latin-1")
    s = read_asf(DATA / "hdm05_cut/HDM_bd.asf")
    for b in s.bones:
        raw = re.search(rf"name {b.name}\s+direction ([^\r\n]*)\s+length\s+(\S+)", text)
        d = np.array([float(v) for v in raw.group(1).split()])
        # readBone.m: direction/norm(direction) * (length/L); readASF.m: then * 2.54
        expected = (d / np.linalg.norm(d) * (float(raw.group(2)) / 0.45)) * 2.54
        assert np.array_equal(b.offset, expected), b.name


# ----------------------------------------------------------------------------
# AMC: every file, exact numbers

@pytest.mark.slow
@pytest.mark.shared
def test_every_amc_reads_with_the_right_frame_count():
    frame_line = re.compile(rb"(?m)^[ \t]*\d+[ \t\r]*$")
    total = 0
    for amc in ALL_AMC:
        s = read_asf(skeleton_path(amc))
        m = read_amc(amc, s)
        data = amc.read_bytes()
        assert m.n_frames == len(frame_line.findall(data)), amc
        # the PyAsfAmc pair notes its rate in the ASF's :documentation (fps:30)
        assert m.fps == (30.0 if amc.stem == "test_mass_kg" else 120.0), amc
        assert m.angle_unit == "deg" and m.first_frame == 1
        assert np.all(np.isfinite(m.values))
        total += m.n_frames
    # 248 HDM05/CMU takes (92,061 frames), the fairmotion CMU take foreign/amc/11_01 (597)
    # and the PyAsfAmc take foreign2/amc/test_mass_kg (300)
    assert len(ALL_AMC) == 250 and total == 92061 + 597 + 300
    assert read_amc(CMU86, read_asf(DATA / "cmu/86/86.asf")).n_frames == 4794


@pytest.mark.shared
def test_frame_counts_match_the_oracle_manifest():
    rows = list(csv.DictReader(open(ORACLE / "features/manifest.csv")))
    skels = {}
    for r in rows:
        s = skels.setdefault(r["asf"], read_asf(DATA / r["asf"]))
        assert read_amc(DATA / r["amc"], s).n_frames == int(r["frames_120hz"]), r["stem"]


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("amc", shared_cases(SAMPLE), ids=lambda p: p.stem)
def test_amc_values_equal_python_float(amc):
    s = read_asf(skeleton_path(amc))
    data = amc.read_bytes()
    m = parse_amc(data, s)
    frames, fps, unit = naive_amc_values(data, s)
    assert m.n_frames == len(frames) and m.fps == fps and unit == "deg"
    for name, sl in m.columns.items():
        ref = np.array([fr[name] for fr in frames])
        assert np.array_equal(m.values[:, sl], ref), name  # bit for bit


@pytest.mark.slow
@pytest.mark.shared
def test_number_parser_equals_float_on_real_tokens():
    toks = set()
    for p in SAMPLE[:5] + ALL_ASF:
        toks.update(re.findall(rb"[-+]?[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?", p.read_bytes()))
    toks = sorted(toks)
    assert len(toks) > 50_000 and any(b"e-0" in t for t in toks)
    vals, st = parse_numbers(toks)
    assert np.all(st != NUM_BAD)
    slow = st == NUM_SLOW
    assert slow.sum() < 0.01 * len(toks)  # e.g. 2.72109e-026: converted by float() later
    ref = np.array([float(t) for t in toks])
    ok = ~slow
    assert np.array_equal(vals[ok].view(np.int64), ref[ok].view(np.int64))


def test_number_parser_equals_float_on_random_tokens():
    rng = np.random.default_rng(7)
    toks = []
    for _ in range(20000):
        nd = int(rng.integers(1, 21))
        digits = "".join(str(d) for d in rng.integers(0, 10, nd))
        point = int(rng.integers(0, nd + 1))
        t = digits[:point] + "." + digits[point:] if rng.random() < 0.8 else digits
        if rng.random() < 0.4:
            t += ("e" if rng.random() < 0.5 else "E") + str(int(rng.integers(-40, 40)))
        if rng.random() < 0.5:
            t = "-" + t
        toks.append(t.encode())
    toks += [b"0", b"-0", b"0.0", b".5", b"5.", b"+1.5", b"9007199254740993", b"1e22",
             b"1e23", b"1.7976931348623157e308", b"4.9e-324", b"0.1", b"123456789012345678"]
    vals, st = parse_numbers(toks)
    assert np.all(st != NUM_BAD)
    ref = np.array([float(t) for t in toks])
    ok = st == NUM_OK
    assert ok.mean() > 0.5
    assert np.array_equal(vals[ok].view(np.int64), ref[ok].view(np.int64))


@pytest.mark.parametrize("tok", [b"abc", b"1.2.3", b"-", b"+", b".", b"1e", b"e5", b"nan",
                                 b"inf", b"-inf", b"1_0", b"0x10", b"1,5", b"--1", b"1e+"])
def test_number_parser_rejects_non_numbers(tok):
    _, st = parse_numbers([tok])
    assert st[0] == NUM_BAD


# ----------------------------------------------------------------------------
# forward kinematics

MANIFEST = {r["stem"]: r for r in csv.DictReader(open(ORACLE / "features/manifest.csv"))} if HAVE_SHARED else {}
ORACLE_FILES = sorted((ORACLE / "positions").glob("*_pos120.csv"))


@pytest.mark.shared
@pytest.mark.parametrize("oracle", shared_cases(ORACLE_FILES), ids=lambda p: p.name[:-len("_pos120.csv")])
def test_joint_positions_equal_the_toolbox_oracle(oracle):
    row = MANIFEST[oracle.name[:-len("_pos120.csv")]]
    m = read_motion(DATA / row["amc"], asf=DATA / row["asf"])
    ref = np.loadtxt(oracle, delimiter=",", skiprows=1).reshape(-1, 24, 3)
    header = open(oracle).readline().strip().split(",")
    assert header[::3] == [f"{j}_x" for j in JOINT_NAMES]
    assert m.joints.shape == ref.shape
    unit = humerus(ref)
    err = np.abs(m.joints - ref).max()
    assert err <= 1e-6 * unit          # the requirement
    assert err <= 1e-12 * unit         # what the kernel achieves (~1e-13 absolute)


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("amc", shared_cases(SAMPLE[:5] + SAMPLE[5::3]), ids=lambda p: p.stem)
def test_fk_kernel_equals_naive_reference(amc):
    s = read_asf(skeleton_path(amc))
    data = amc.read_bytes()
    m = parse_amc(data, s)
    frames, _, _ = naive_amc_values(data, s)
    sub = replace(m, values=m.values[:80])
    joints, rot = asf_forward_kinematics(s, sub)
    ref_joints, ref_nodes, ref_rot = naive_asf_fk(s, frames[:80])
    nodes, rot2 = node_positions(s, sub)
    unit = humerus(ref_joints)
    assert np.abs(joints - ref_joints).max() <= 1e-12 * unit
    assert np.abs(nodes - ref_nodes).max() <= 1e-12 * unit
    assert np.abs(rot - ref_rot).max() <= 1e-14 and np.array_equal(rot, rot2)
    # lclavicle/rclavicle are the neck point
    assert np.array_equal(joints[:, JOINT_INDEX["lclavicle"]], joints[:, JOINT_INDEX["neck"]])
    assert np.array_equal(joints[:, JOINT_INDEX["rclavicle"]], joints[:, JOINT_INDEX["neck"]])


def _perturbed_skeleton_text(seed):
    """HDM_bd.asf with random axes, root position and orientation (seeded)."""
    rng = np.random.default_rng(seed)
    text = (DATA / "hdm05_cut/HDM_bd.asf").read_bytes().decode("latin-1")

    def axis(mo):
        a = [float(v) for v in rng.uniform(-180, 180, 3)]
        return f"axis {a[0]!r} {a[1]!r} {a[2]!r}  XYZ"
    text = re.sub(r"axis -?[\d.e+-]+ -?[\d.e+-]+ -?[\d.e+-]+\s+XYZ", axis, text)
    p = [float(v) for v in rng.uniform(-20, 20, 3)]
    o = [float(v) for v in rng.uniform(-90, 90, 3)]
    text = text.replace("position 0 0 0", f"position {p[0]!r} {p[1]!r} {p[2]!r}")
    text = text.replace("orientation 0 0 0", f"orientation {o[0]!r} {o[1]!r} {o[2]!r}")
    return text


@pytest.mark.shared
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_fk_kernel_equals_naive_on_random_skeletons_and_angles(seed):
    rng = np.random.default_rng(seed)
    s = parse_asf(_perturbed_skeleton_text(seed))
    assert np.any(s.root_orientation != 0) and np.any(s.root_position != 0)
    _, _, _, columns, dof_names = column_layout(s)
    m = parse_amc(SQUAT.read_bytes(), s)
    vals = rng.uniform(-180, 180, size=(50, m.values.shape[1]))
    vals[:, :3] = rng.uniform(-50, 50, size=(50, 3))  # root translation
    sub = replace(m, values=vals)
    frames = [{b: list(vals[f, sl]) for b, sl in columns.items()} for f in range(50)]
    joints, rot = asf_forward_kinematics(s, sub)
    ref_joints, _, ref_rot = naive_asf_fk(s, frames)
    assert np.abs(joints - ref_joints).max() <= 1e-12 * humerus(ref_joints)
    assert np.abs(rot - ref_rot).max() <= 1e-14


def frame_by_frame_asf_fk(skeleton, motion):
    """The kinematics kernel's arithmetic one frame at a time in plain Python (the kernel before it took a
    block's frames side by side, issue 35): the same layout arrays, the same sines and cosines
    (:func:`sincos` of the values times the unit's factor), each product and sum in the same order — so the
    kernel's lanes must equal it bit for bit, whatever the block (``naive_asf_fk`` checks the maths)."""
    from mocapdb.bodies.kinematics import _angle_factor, _layout, joint_node_indices
    from mocapdb.bodies.acclaim import INCH_TO_TOOLBOX
    lay = _layout(skeleton)
    rot_cols, root_cols, trans_cols = lay.columns_for(skeleton, motion)
    nodes_of_joints = joint_node_indices(skeleton)
    values = np.ascontiguousarray(motion.values, dtype=np.float64)
    sin, cos = sincos(values * _angle_factor(motion.angle_unit))
    n, nb = len(values), len(lay.order)

    def rotate(h, axis, c, s):   # h · R_axis(θ): two columns mix
        i, j = ((1, 2), (2, 0), (0, 1))[axis]
        for r in range(3):
            a, b = h[r][i], h[r][j]
            h[r][i] = c * a + s * b
            h[r][j] = c * b - s * a

    joints, root_rot = np.empty((n, len(nodes_of_joints), 3)), np.empty((n, 3, 3))
    for f in range(n):
        rr = [[1.0 if i == j else 0.0 for j in range(3)] for i in range(3)]
        h = [None] * (nb + 1)
        node = [None] * (nb + 1)
        h[0] = [[float(lay.orient[i, j]) for j in range(3)] for i in range(3)]
        for q in range(3):
            c = root_cols[q]
            if c >= 0:
                rotate(rr, 2 - q, float(cos[f, c]), float(sin[f, c]))
                rotate(h[0], 2 - q, float(cos[f, c]), float(sin[f, c]))
        node[0] = [((float(values[f, c]) if c >= 0 else 0.0) / float(skeleton.length_unit)) * INCH_TO_TOOLBOX
                   + float(skeleton.root_position[k]) for k, c in enumerate(trans_cols)]
        for b in lay.order:
            p, k = lay.parent[b], b + 1
            hp, d = h[p], lay.dmat[b]
            if lay.dident[b]:
                h[k] = [row[:] for row in hp]
            else:
                h[k] = [[hp[i][0] * d[0, j] + hp[i][1] * d[1, j] + hp[i][2] * d[2, j] for j in range(3)]
                        for i in range(3)]
            for ax in range(3):
                c = rot_cols[b, ax]
                if c >= 0:
                    rotate(h[k], 2 - ax, float(cos[f, c]), float(sin[f, c]))
            o = lay.offp[b]
            node[k] = [node[p][i] + (h[k][i][0] * o[0] + h[k][i][1] * o[1] + h[k][i][2] * o[2]) for i in range(3)]
        joints[f] = [node[j] for j in nodes_of_joints]
        root_rot[f] = rr
    return joints, root_rot


@pytest.mark.parametrize("frames", [1, 7, 63, 64, 65, 130, 300])
def test_fk_lanes_equal_the_frame_by_frame_kinematics_bit_for_bit(frames):
    """A block's frames side by side give each frame what the frame-by-frame kernel gave it, bit for bit
    (stored features must not move): the shipped take (every block length and a partial last block),
    then seeded random skeletons, angles and translations."""
    s = read_asf(SAMPLE_86_ASF)
    m = read_amc(SAMPLE_86_09, s)
    sub = replace(m, values=np.ascontiguousarray(m.values[:frames]))
    joints, rot = asf_forward_kinematics(s, sub)
    ref_joints, ref_rot = frame_by_frame_asf_fk(s, sub)
    assert np.array_equal(joints, ref_joints) and np.array_equal(rot, ref_rot)
    rng = np.random.default_rng(frames)
    text = SAMPLE_86_ASF.read_bytes().decode("latin-1")
    text = re.sub(r"axis -?[\d.e+-]+ -?[\d.e+-]+ -?[\d.e+-]+\s+XYZ",
                  lambda mo: "axis " + " ".join(repr(float(v)) for v in rng.uniform(-180, 180, 3)) + " XYZ", text)
    s2 = parse_asf(text)
    vals = rng.uniform(-180, 180, size=(frames, m.values.shape[1]))
    vals[:, :3] = rng.uniform(-50, 50, size=(frames, 3))   # the root's translation
    sub2 = replace(read_amc(SAMPLE_86_09, s2), values=vals)
    joints, rot = asf_forward_kinematics(s2, sub2)
    ref_joints, ref_rot = frame_by_frame_asf_fk(s2, sub2)
    assert np.array_equal(joints, ref_joints) and np.array_equal(rot, ref_rot)


@pytest.mark.shared
@pytest.mark.parametrize("amc", shared_cases(SAMPLE[:5]), ids=lambda p: p.stem)
def test_fk_lanes_equal_the_frame_by_frame_kinematics_on_real_takes(amc):
    s = read_asf(skeleton_path(amc))
    m = read_amc(amc, s)
    joints, rot = asf_forward_kinematics(s, m)
    ref_joints, ref_rot = frame_by_frame_asf_fk(s, m)
    assert np.array_equal(joints, ref_joints) and np.array_equal(rot, ref_rot)


@pytest.mark.shared
def test_root_rotation_is_the_amc_root_without_orientation():
    s = parse_asf(_perturbed_skeleton_text(5))
    m = parse_amc(SQUAT.read_bytes(), s)
    _, rot = asf_forward_kinematics(s, m)
    rx, ry, rz = (np.radians(m.values[:, m.column("root", d)]) for d in ("rx", "ry", "rz"))
    ref = euler_matrix(np.stack([rz, ry, rx], -1), "zyx")
    assert np.abs(rot - ref).max() < 1e-14
    o = np.radians(s.root_orientation)
    assert np.allclose(orientation_matrix(s), euler_matrix(o, "zxy"), atol=1e-15)


def test_sincos_within_one_ulp():
    rng = np.random.default_rng(0)
    real = np.radians(read_amc(SAMPLE_86_09, read_asf(SAMPLE_86_ASF)).values.ravel())
    for x in (real, rng.uniform(-10, 10, 100_000), rng.uniform(-9e4, 9e4, 100_000),
              np.array([0.0, -0.0, 1e-300, math.pi / 4, math.pi / 2, math.pi, 2e5, -3e7])):
        s, c = sincos(x)
        for got, ref in ((s, np.sin(x)), (c, np.cos(x))):
            ulp = np.spacing(np.abs(ref))
            assert np.all(np.abs(got - ref) <= ulp), np.abs(got - ref).max()


# ----------------------------------------------------------------------------
# edge cases from the text, derived from real files

def _to_radians(asf_text, amc_bytes):
    """The same skeleton/motion with every angle in radians (ASF and AMC)."""
    def rad(v):
        return repr(math.radians(float(v)))
    out = []
    for line in asf_text.split("\n"):
        t = line.split()
        if t and t[0] == "axis" and len(t) >= 4:
            line = f"     axis {rad(t[1])} {rad(t[2])} {rad(t[3])} {' '.join(t[4:])}"
        elif t[:2] == ["angle", "deg"]:
            line = "  angle rad"
        out.append(line)
    asf_rad = "\n".join(out)
    lines = []
    for raw in amc_bytes.decode("latin-1").split("\n"):
        t = raw.split()
        if t == [":DEGREES"]:
            raw = ":RADIANS"
        elif t and not t[0][0] in "#:0123456789":
            vals = t[1:]
            if t[0] == "root":
                vals = vals[:3] + [rad(v) for v in vals[3:]]
            else:
                vals = [rad(v) for v in vals]
            raw = " ".join([t[0]] + vals)
        lines.append(raw)
    return asf_rad, "\n".join(lines).encode("latin-1")


@pytest.mark.shared
def test_radians_give_the_same_positions():
    asf_text = (DATA / "cmu/02/02.asf").read_bytes().decode("latin-1")
    amc = (DATA / "cmu/02/02_01.amc").read_bytes()
    _, m_deg, (j_deg, r_deg) = fk(asf_text, amc)
    asf_rad, amc_rad = _to_radians(asf_text, amc)
    s, m_rad, (j_rad, r_rad) = fk(asf_rad, amc_rad)
    assert s.angle_unit == "rad" and m_rad.angle_unit == "rad" and m_deg.angle_unit == "deg"
    assert np.abs(j_rad - j_deg).max() <= 1e-12 * humerus(j_deg)
    assert np.abs(r_rad - r_deg).max() <= 1e-14
    # without :RADIANS in the AMC, the ASF's unit applies (toolbox behaviour)
    no_kw = amc_rad.replace(b":RADIANS", b"")
    _, m2, (j2, _) = fk(asf_rad, no_kw)
    assert m2.angle_unit == "rad" and np.array_equal(j2, j_rad)


@pytest.mark.shared
def test_samples_per_second():
    amc = SQUAT.read_bytes().replace(b":DEGREES", b":SAMPLES-PER-SECOND 60\r\n:DEGREES", 1)
    s = read_asf(DATA / "hdm05_cut/HDM_bd.asf")
    m = parse_amc(amc, s)
    assert m.fps == 60.0
    assert np.array_equal(m.values, read_amc(SQUAT, s).values)


@pytest.mark.shared
def test_root_position_and_orientation_are_applied():
    text = (DATA / "hdm05_cut/HDM_bd.asf").read_bytes().decode("latin-1")
    amc = SQUAT.read_bytes()
    _, _, (j0, r0) = fk(text, amc)
    moved = text.replace("position 0 0 0", "position 4.5 -9 13.5")
    s, _, (j1, r1) = fk(moved, amc)
    # position is scaled like a length (/0.45 * 2.54) and added to every joint
    shift = np.array([4.5, -9, 13.5]) / 0.45 * 2.54
    assert np.allclose(j1 - j0, shift, rtol=0, atol=1e-12)
    assert np.array_equal(r1, r0)
    turned = text.replace("orientation 0 0 0", "orientation 30 -20 45")
    s2, m2, (j2, r2) = fk(turned, amc)
    o = np.radians([30, -20, 45])
    O = euler_matrix(o, "zxy")  # Rz(o1)·Rx(o2)·Ry(o3), FEATURES.md §2.2
    root = j0[:, :1]
    # the whole body turns about the root by O; the root rotation ignores O
    assert np.allclose(j2 - root, (j0 - root) @ O.T, rtol=0, atol=1e-11)
    assert np.array_equal(r2, r0)


@pytest.mark.shared
def test_bone_with_zero_direction_sits_on_its_parent():
    text = (DATA / "hdm05_cut/HDM_bd.asf").read_bytes().decode("latin-1")
    text = re.sub(r"(name lhipjoint\s+direction)[^\r\n]*", r"\1 0 0 0", text)
    s, _, (j, _) = fk(text, SQUAT.read_bytes())
    assert np.array_equal(s.bone("lhipjoint").direction, np.zeros(3))
    assert np.array_equal(j[:, JOINT_INDEX["lhip"]], j[:, JOINT_INDEX["root"]])


@pytest.mark.shared
def test_dof_subset_equals_zero_for_the_missing_dof():
    text = (DATA / "hdm05_cut/HDM_bd.asf").read_bytes().decode("latin-1")
    # lfemur: "dof rx ry rz" -> "dof rx rz" (and two limits)
    text2 = re.sub(r"(name lfemur(?:.|\n)*?)dof rx ry rz(\s*)limits \(([^)]*)\)\s*\(([^)]*)\)",
                   r"\1dof rx rz\2limits (\3)\n           ", text, count=1)
    assert text2 != text
    amc = SQUAT.read_bytes()
    lines = []
    for raw in amc.split(b"\n"):
        t = raw.split()
        if t and t[0] == b"lfemur":
            raw = b" ".join([t[0], t[1], t[3]])
        lines.append(raw)
    s2, m2, (j2, _) = fk(text2, b"\n".join(lines))
    assert s2.bone("lfemur").dof == ("rx", "rz") and m2.dof_names["lfemur"] == ("rx", "rz")
    s = read_asf(DATA / "hdm05_cut/HDM_bd.asf")
    m = read_amc(SQUAT, s)
    vals = m.values.copy()
    vals[:, m.column("lfemur", "ry")] = 0
    j_ref, _ = asf_forward_kinematics(s, replace(m, values=vals))
    assert np.abs(j2 - j_ref).max() < 1e-12 * humerus(j_ref)
    assert np.abs(j_ref - asf_forward_kinematics(s, m)[0]).max() > 1e-3  # ry mattered


@pytest.mark.shared
def test_bone_order_line_endings_case_and_comments_do_not_matter():
    s = read_asf(DATA / "cmu/02/02.asf")
    data = (DATA / "cmu/02/02_01.amc").read_bytes()
    ref = parse_amc(data, s).values
    rng = np.random.default_rng(3)
    out, frame = [], []
    for raw in data.split(b"\n"):
        t = raw.split()
        if t and t[0][:1].isdigit():
            out += [frame[k] for k in rng.permutation(len(frame))]
            frame = []
            out.append(raw)
        elif t and t[0][:1] not in b"#:":
            frame.append(raw.upper() if rng.random() < 0.2 else raw)
        else:
            out.append(raw)
    out += [frame[k] for k in rng.permutation(len(frame))]
    shuffled = b"\n".join(out)
    assert shuffled != data
    assert np.array_equal(parse_amc(shuffled, s).values, ref)
    lf = shuffled.replace(b"\r\n", b"\n")
    assert lf != shuffled and np.array_equal(parse_amc(lf, s).values, ref)
    mixed = b"".join(x + (b"\r\n" if k % 3 else b"\n") for k, x in enumerate(lf.split(b"\n")))
    assert np.array_equal(parse_amc(mixed, s).values, ref)
    assert np.array_equal(parse_amc(b"\xef\xbb\xbf" + data, s).values, ref)  # UTF-8 BOM
    commented = re.sub(rb"\n2\r?\n", b"\n# a comment\n\n2\n", shuffled, count=1)
    assert commented != shuffled and np.array_equal(parse_amc(commented, s).values, ref)


def test_a_bone_absent_from_the_amc_reads_as_zero():
    s = read_asf(SAMPLE_86_ASF)
    data = lzma.decompress(SAMPLE_86_09.read_bytes())
    ref = parse_amc(data, s)
    cut = b"\n".join(x for x in data.split(b"\n") if not x.startswith(b"lthumb "))
    m = parse_amc(cut, s)
    assert np.all(m.dofs["lthumb"] == 0)
    keep = np.ones(m.values.shape[1], bool)
    keep[m.columns["lthumb"]] = False
    assert np.array_equal(m.values[:, keep], ref.values[:, keep])


def test_the_kernel_clears_every_row_it_reads_whatever_the_memory_held():
    # parse_amc hands the kernel an uninitialised array (np.empty: fresh pages are zero, reused ones are not),
    # so the zeros of a bone the file never lists must come from the kernel: here the array holds NaN first
    from mocapdb.readers import amc as amc_module
    s = read_asf(SAMPLE_86_ASF)
    data = lzma.decompress(SAMPLE_86_09.read_bytes())
    cut = b"\n".join(x for x in data.split(b"\n") if not x.startswith(b"lthumb "))
    want = parse_amc(cut, s)
    assert np.all(want.dofs["lthumb"] == 0)
    start = amc_module._parse_header(cut, "t.amc")[0]
    names, ndof, col_start, _, _, name_buf, name_start, name_len, _, _ = amc_module._kernel_layout(s)
    out = np.full((want.n_frames + 5, int(ndof.sum())), np.nan)
    fb = [np.zeros(1024, dtype=np.int64) for _ in range(3)]
    status = np.zeros(8, dtype=np.int64)
    amc_module._parse_amc_kernel(np.frombuffer(cut, dtype=np.uint8), start, name_buf, name_start, name_len, col_start,
                                 ndof, out, *fb, np.zeros(len(names), np.int8), np.zeros(len(names), np.int8), status)
    assert status[0] == 0 and status[7] == want.n_frames
    got = out[:want.n_frames]
    slow = fb[0][:status[6]]   # tokens left to float(): set as parse_amc sets them
    got.reshape(-1)[slow] = want.values.reshape(-1)[slow]
    assert np.array_equal(got.view(np.int64), want.values.view(np.int64))   # bit for bit, no NaN left
    assert np.isnan(out[want.n_frames:]).all()   # rows past the last frame untouched


@pytest.mark.shared
def test_motion_from_read_motion():
    m = read_motion(SQUAT)
    assert m.name == SQUAT.stem and m.skeleton == "HDM_bd" and m.source_format == "amc"
    assert m.meta["asf"].endswith("HDM_bd.asf") and m.fps == 120.0
    assert m.joints.shape == (m.n_frames, 24, 3) and m.root_rotation.shape == (m.n_frames, 3, 3)
    m13 = read_motion(DATA / "cmu/13/13_29.amc", asf=DATA / "cmu/02/02.asf")
    assert m13.skeleton == "02" and m13.n_frames > 1000


@pytest.mark.shared
def test_a_folders_only_asf_is_the_skeleton(tmp_path):
    # names that follow neither the CMU nor the HDM05 pattern
    (tmp_path / "subject.asf").write_bytes(MASS_KG.read_bytes())
    amc = tmp_path / "take 3.amc"
    amc.write_bytes(MASS_KG.with_suffix(".amc").read_bytes())
    assert find_skeleton(amc) == tmp_path / "subject.asf"
    (tmp_path / "other.asf").write_bytes(MASS_KG.read_bytes())
    assert find_skeleton(amc) is None  # two candidates: no guess


def test_longest_line_equals_its_definition_on_random_bytes():
    """The header check's one-pass line scan against the definition: line ends are LF or CR, the first
    line continues ``carry`` bytes, the last may be unfinished (issue 35 made it a kernel)."""
    rng = np.random.default_rng(35)
    for _ in range(5000):
        chunk = bytes(rng.choice([10, 13, 32, 65], size=int(rng.integers(0, 40)), p=[.15, .05, .3, .5])
                      .astype(np.uint8))
        carry = int(rng.integers(0, 5))
        text = "A" * carry + chunk.decode().replace("\r", "\n")
        lines = text.split("\n")
        assert longest_line(chunk, carry) == (max(len(x) for x in lines), len(lines[-1])), (chunk, carry)



def test_a_line_longer_than_a_limit_is_found_where_the_line_scan_finds_it():
    """The start check's window test (``bytes.find`` per window of limit/2 + 1 bytes) against the line scan:
    random texts of short and long lines, LF and CR ends or none, every limit from 1 to 40, lines of exactly
    the limit and one more."""
    rng = np.random.default_rng(36)
    for _ in range(3000):
        p_end = float(rng.choice([0.0, 0.02, 0.1, 0.3]))
        chunk = bytes(rng.choice([10, 13, 65], size=int(rng.integers(0, 120)), p=[p_end * .7, p_end * .3, 1 - p_end])
                      .astype(np.uint8))
        for limit in range(1, 41):
            assert has_line_longer(chunk, limit) == (longest_line(chunk)[0] > limit), (chunk, limit)
    for limit in (1, 2, 7, 16384):
        for n in (limit - 1, limit, limit + 1, 2 * limit + 3):
            for text in (b"x" * n, b"ab\n" + b"x" * n + b"\r\nz", b"\n" * 3 + b"x" * n):
                assert has_line_longer(text, limit) == (longest_line(text)[0] > limit), (text[:20], n, limit)

@pytest.mark.shared
def test_the_skeleton_rule_sees_a_new_asf_in_a_listed_folder(tmp_path):
    """The named candidates are checked against the folder's listing, kept while the folder is unchanged:
    an ASF added later (the folder's mtime moves) is found, one removed is not, and on a case-insensitive
    file system a differently cased name is still probed."""
    amc = tmp_path / "07_01.amc"
    shutil.copyfile(DATA / "cmu/02/02_01.amc", amc)
    shutil.copyfile(DATA / "cmu/02/02.asf", tmp_path / "07.asf")
    past = time.time() - 60
    os.utime(tmp_path, (past, past))   # an old folder: its listing is kept
    assert find_skeleton(amc) == tmp_path / "07.asf"
    shutil.copyfile(DATA / "cmu/02/02.asf", tmp_path / "07_01.asf")
    assert find_skeleton(amc) == tmp_path / "07_01.asf"
    (tmp_path / "07_01.asf").unlink()
    os.utime(tmp_path, (past + 1, past + 1))
    assert find_skeleton(amc) == tmp_path / "07.asf"
    (tmp_path / "07.asf").rename(tmp_path / "07.ASF")
    os.utime(tmp_path, (past + 2, past + 2))
    assert find_skeleton(amc) == tmp_path / "07.ASF"


def _min_frame_bytes_reference(data: bytes, start: int, ndof_of: dict) -> int:
    """The bound of issue 9 as it was written in Python (per line: lstrip, digit, comment, name → DOFs)."""
    pos = data.find(b"\n", start) + 1
    n = 2
    while 0 < pos < len(data):
        end = data.find(b"\n", pos)
        s = data[pos:end if end >= 0 else len(data)].lstrip()
        if s[:1].isdigit():
            break
        if s and not s.startswith(b"#"):
            name = s.split()[0]
            n += len(name) + 2 * ndof_of.get(name.decode("latin-1").lower(), 0) + 1
        if end < 0:
            break
        pos = end + 1
    return n


@pytest.mark.shared
def test_the_frame_size_bound_is_the_python_one():
    """Issue 35: the kernel bounding a take's frames (``_min_frame_bytes_kernel``, frame 1's bone lines)
    counts what the per-line Python did, on the shared takes and on seeded variants of their first
    frame (names in other cases and Latin-1 letters, unknown bones, comments, blank and CR lines, tabs,
    a text ending inside the frame)."""
    from mocapdb.readers.amc import _kernel_layout, _min_frame_bytes_kernel, _parse_header

    rng = np.random.default_rng(35)
    cases = 0
    for amc in sorted(DATA.rglob("*.amc"))[::7]:
        skel = read_asf(find_skeleton(amc))
        names, ndof, _, _, _, name_buf, name_start, name_len, _, _ = _kernel_layout(skel)
        ndof_of = {n.lower(): int(k) for n, k in zip(names, ndof)}
        data = amc.read_bytes()
        start = _parse_header(data, str(amc))[0]
        frame2 = re.search(rb"\n[ \t]*2[ \t]*\r?\n", data[start:])
        lines = data[start:start + frame2.start()].split(b"\n")
        variants = [data]
        for _ in range(12):
            out = [lines[0]]
            for line in lines[1:]:
                r = rng.random()
                if r < 0.15:
                    line = line.upper()
                elif r < 0.2:
                    line = b"\xc0" + line
                elif r < 0.25:
                    out.append(b"# a comment " + line)
                elif r < 0.3:
                    out.append(b"  \t\r")
                elif r < 0.35:
                    line = b"\t" + line.replace(b" ", b"\t")
                out.append(line)
            text = b"\n".join(out)
            variants.append(data[:start] + text + data[start + frame2.start():])
            variants.append(data[:start] + text[:int(rng.integers(0, len(text) + 1))])
        for v in variants:
            buf = np.frombuffer(v, dtype=np.uint8)
            assert (_min_frame_bytes_kernel(buf, start, name_buf, name_start, name_len, ndof)
                    == _min_frame_bytes_reference(v, start, ndof_of))
            cases += 1
    assert cases > 500
