"""Malformed input (DESIGN.md §6): every broken file raises ParseError naming the
file, the line (and frame/bone) and what was expected vs found. The broken files
are built from real ones; line numbers are located in the corrupted text.

Also: the skeleton-finding conventions of the data set.
"""
import re
import shutil
from dataclasses import replace

import pytest

from conftest import DATA
from mocapdb.readers.amc import read_amc
from mocapdb.readers.asf import read_asf
from mocapdb.readers import read_bvh
from mocapdb.writers import write_bvh
from mocapdb.errors import MocapdbError, ParseError
from mocapdb.readers import find_skeleton, read_motion

ASF = DATA / "hdm05_cut/HDM_bd.asf"
AMC = DATA / "hdm05_cut/squat1Reps/HDM_bd_squat1Reps_001_120.amc"


@pytest.fixture
def folder(tmp_path):
    """A take folder with the actor's skeleton (so read_motion finds it)."""
    shutil.copy(ASF, tmp_path / "HDM_bd.asf")
    return tmp_path


def lines_of(path):
    return path.read_bytes().split(b"\n")


def line_no(lines, k):
    return k + 1  # 0-based list index -> 1-based line number


def nth_line(lines, prefix, n=1):
    """Index of the n-th line starting with ``prefix``."""
    hits = [k for k, ln in enumerate(lines) if ln.startswith(prefix)]
    return hits[n - 1]


def write(folder, name, lines):
    p = folder / name
    p.write_bytes(b"\n".join(lines))
    return p


def raises(path, line, msg, frame=None):
    where = re.escape(f"{path}:{line}") + (rf" \(frame {frame}\)" if frame is not None else "")
    return pytest.raises(ParseError, match=where + ": " + msg)


# ----------------------------------------------------------------------------
# AMC

@pytest.mark.shared
def test_truncated_amc_last_frame_incomplete(folder):
    lines = lines_of(AMC)
    lines = lines[:-12]                 # drop the last 12 bone lines
    p = write(folder, "HDM_bd_cut_a.amc", lines)
    last = max(k for k, ln in enumerate(lines) if ln.strip())
    n_frames = sum(1 for ln in lines if ln.strip().isdigit())
    with raises(p, line_no(lines, last), r"every frame must list the bones of frame 1; "
                r"missing .*rtoes.* \(the file may be truncated\)", frame=n_frames):
        read_motion(p)


@pytest.mark.shared
def test_truncated_amc_mid_line(folder):
    data = AMC.read_bytes()
    cut = data[:data.rstrip().rfind(b" ")]     # last value of the last line cut off
    p = folder / "HDM_bd_cut_b.amc"
    p.write_bytes(cut)
    lines = cut.split(b"\n")
    bone = lines[-1].split()[0].decode()
    n_frames = sum(1 for ln in lines if ln.strip().isdigit())
    with raises(p, len(lines), rf"bone '{bone}': expected 1 value \(DOFs: rx\), found 0 "
                r"\(the last line is incomplete: the file may be truncated\)", frame=n_frames):
        read_motion(p)


@pytest.mark.shared
def test_amc_bone_not_in_the_asf(folder):
    lines = lines_of(AMC)
    k = nth_line(lines, b"lthumb", 5)
    lines[k] = lines[k].replace(b"lthumb", b"lpinky")
    p = write(folder, "HDM_bd_bone.amc", lines)
    with raises(p, line_no(lines, k), r"bone 'lpinky' is not in the skeleton HDM_bd\.asf "
                r"\(its bones: root, lhipjoint, .*\)", frame=5):
        read_motion(p)


@pytest.mark.shared
@pytest.mark.parametrize("change,expected", [
    (lambda v: v + [b"1.5"], r"expected 3 values \(DOFs: rx ry rz\), found 4"),
    (lambda v: v[:2], r"expected 3 values \(DOFs: rx ry rz\), found 2"),
])
def test_amc_wrong_number_of_values(folder, change, expected):
    lines = lines_of(AMC)
    k = nth_line(lines, b"rfemur", 7)
    t = lines[k].split()
    lines[k] = b" ".join([t[0]] + change(t[1:])) + b"\r"
    p = write(folder, "HDM_bd_count.amc", lines)
    with raises(p, line_no(lines, k), "bone 'rfemur': " + expected, frame=7):
        read_motion(p)


@pytest.mark.shared
@pytest.mark.parametrize("token,expected", [
    (b"abc", r"expected a number, found 'abc'"),
    (b"1.2.3", r"expected a number, found '1\.2\.3'"),
    (b"12,5", r"expected a number, found '12,5'"),
    (b"nan", r"expected a finite number, found 'nan' \(NaN/inf values are not allowed\)"),
    (b"-inf", r"expected a finite number, found '-inf'"),
    (b"1e999", r"expected a finite number, found '1e999'"),
])
def test_amc_non_numeric_and_non_finite_values(folder, token, expected):
    lines = lines_of(AMC)
    k = nth_line(lines, b"lhumerus", 11)
    t = lines[k].split()
    lines[k] = b" ".join([t[0], t[1], token, t[3]])
    p = write(folder, "HDM_bd_value.amc", lines)
    with raises(p, line_no(lines, k), "bone 'lhumerus': " + expected, frame=11):
        read_motion(p)


@pytest.mark.shared
def test_amc_zero_frames(folder):
    lines = lines_of(AMC)
    header = lines[:nth_line(lines, b"1")]
    p = write(folder, "HDM_bd_empty.amc", header)
    with raises(p, len(header), r"no frames \(expected a frame number line"):
        read_motion(p)


@pytest.mark.shared
def test_amc_frame_numbers_out_of_sequence(folder):
    lines = lines_of(AMC)
    k = next(i for i, ln in enumerate(lines) if ln.strip() == b"9")
    lines[k] = b"10"
    p = write(folder, "HDM_bd_seq.amc", lines)
    with raises(p, line_no(lines, k), "expected frame number 9, found 10"):
        read_motion(p)


@pytest.mark.shared
def test_amc_bone_twice_in_a_frame(folder):
    lines = lines_of(AMC)
    k = nth_line(lines, b"head", 3)
    lines.insert(k + 1, lines[k])
    p = write(folder, "HDM_bd_dup.amc", lines)
    with raises(p, line_no(lines, k + 1), "bone 'head' appears twice in one frame", frame=3):
        read_motion(p)


@pytest.mark.shared
def test_amc_bone_line_before_the_first_frame(folder):
    lines = lines_of(AMC)
    k = nth_line(lines, b":DEGREES")
    lines.insert(k + 1, b"root 1 2 3 4 5 6")
    p = write(folder, "HDM_bd_hdr.amc", lines)
    with raises(p, line_no(lines, k + 1), "expected a frame number before the first bone line"):
        read_motion(p)


# ----------------------------------------------------------------------------
# ASF

@pytest.mark.shared
@pytest.mark.parametrize("old,new,expected", [
    (b"angle deg", b"angle grad", r"units angle: expected 'deg' or 'rad', found 'grad'"),
    # a named or unknown unit reads (other writers' dialects: test_asf_amc); a missing one does not
    (b"length 0.45", b"length", r"units length: expected a number or a unit name, found nothing"),
    (b"length 0.45", b"length -1", r"units length: expected a positive number, found '-1'"),
    (b"order TX TY TZ RX RY RZ", b"order TX TY TZ RX RY RW",
     r"root order: unknown token 'RW' \(expected TX TY TZ RX RY RZ\)"),
    (b"axis XYZ", b"axis ZYX", r"root axis: unsupported rotation order 'ZYX'"),
    (b"dof rx ry rz", b"dof rx rw rz", r"dof: unknown token 'rw' \(expected rx, ry, rz\)"),
    (b"dof rx ry rz", b"dof tx ry rz", r"dof: unsupported translation/length DOF 'tx'"),
    (b"axis 0 0 20  XYZ", b"axis 0 0 20  ZXY", r"bone axis: unsupported rotation order 'ZXY'"),
    (b"length 7.34031", b"length 7.34o31", r"bone length: expected a number, found '7\.34o31'"),
    (b"direction 0.567149 -0.783011 0.255413", b"direction 0.567149 nan 0.255413",
     r"bone direction: expected a finite number, found 'nan'"),
])
def test_asf_bad_units_tokens_and_numbers(tmp_path, old, new, expected):
    data = ASF.read_bytes()
    assert old in data
    bad = data.replace(old, new, 1)
    lines = bad.split(b"\n")
    k = next(i for i, ln in enumerate(lines) if new in ln)
    p = tmp_path / "broken.asf"
    p.write_bytes(bad)
    with raises(p, line_no(lines, k), expected):
        read_asf(p)


@pytest.mark.shared
def test_asf_bone_missing_from_the_hierarchy(tmp_path):
    lines = lines_of(ASF)
    k = next(i for i, ln in enumerate(lines) if ln.strip() == b"lhand lfingers")
    del lines[k]
    h = next(i for i, ln in enumerate(lines) if ln.startswith(b":hierarchy"))
    p = write(tmp_path, "nohier.asf", lines)
    with raises(p, line_no(lines, h), r"hierarchy: bone 'lfingers' \(line \d+\) is not the "
                r"child of any bone or of root"):
        read_asf(p)


@pytest.mark.shared
def test_amc_read_with_a_skeleton_lacking_its_bones(tmp_path):
    # an HDM05 take with a skeleton whose thumb bones were renamed
    data = ASF.read_bytes().replace(b"lthumb", b"lthumb1")
    p = tmp_path / "other.asf"
    p.write_bytes(data)
    lines = lines_of(AMC)
    k = nth_line(lines, b"lthumb")
    with raises(AMC, line_no(lines, k), r"bone 'lthumb' is not in the skeleton other\.asf",
                frame=1):
        read_amc(AMC, read_asf(p))


# ----------------------------------------------------------------------------
# BVH

@pytest.fixture(scope="module")
def bvh_lines(tmp_path_factory):
    s = read_asf(ASF)
    m = read_amc(AMC, s)
    p = write_bvh(tmp_path_factory.mktemp("bvh") / "ok.bvh", s, replace(m, values=m.values[:30]),
                  precision=9)
    return lines_of(p)


def motion_line(lines, frame):
    return lines.index(b"MOTION") + 2 + frame  # 0-based index of a frame's line (1-based frame)


@pytest.mark.shared
@pytest.mark.parametrize("edit,found", [(lambda t: t + [b"1.5"], 97),
                                        (lambda t: t[:-3], 93)])
def test_bvh_motion_line_with_wrong_channel_count(tmp_path, bvh_lines, edit, found):
    lines = list(bvh_lines)
    k = motion_line(lines, 12)
    lines[k] = b" ".join(edit(lines[k].split()))
    p = write(tmp_path, "walk.bvh", lines)
    with raises(p, line_no(lines, k), f"expected 96 channel values, found {found}", frame=12):
        read_bvh(p)


@pytest.mark.shared
def test_bvh_unknown_channel_name(tmp_path, bvh_lines):
    lines = list(bvh_lines)
    k = next(i for i, ln in enumerate(lines) if b"JOINT lfemur" in ln) + 3
    assert b"CHANNELS 3 Zrotation Yrotation Xrotation" in lines[k]
    lines[k] = lines[k].replace(b"Yrotation", b"Wrotation")
    p = write(tmp_path, "chan.bvh", lines)
    with raises(p, line_no(lines, k), r"joint 'lfemur': unknown channel 'Wrotation' "
                r"\(expected Xposition, .*Zrotation\)"):
        read_bvh(p)


@pytest.mark.shared
def test_bvh_channel_count_disagrees_with_names(tmp_path, bvh_lines):
    lines = list(bvh_lines)
    k = next(i for i, ln in enumerate(lines) if b"CHANNELS 3" in ln)
    lines[k] = lines[k].replace(b"CHANNELS 3", b"CHANNELS 4")
    p = write(tmp_path, "count.bvh", lines)
    with raises(p, line_no(lines, k), r"joint 'lhipjoint': CHANNELS 4 but 3 channel names"):
        read_bvh(p)


@pytest.mark.shared
def test_bvh_non_numeric_motion_values(tmp_path, bvh_lines):
    """A token that is no number is an error; NaN, inf and their C-runtime spellings are lost tracking
    (tests/test_bvh_tracking.py), read as a gap."""
    lines = list(bvh_lines)
    k = motion_line(lines, 20)
    t = lines[k].split()
    t[40] = b"x1"
    lines[k] = b" ".join(t)
    p = write(tmp_path, "nan.bvh", lines)
    with raises(p, line_no(lines, k), "expected a number, found 'x1'", frame=20):
        read_bvh(p)
    for tok in (b"NaN", b"-nan", b"inf", b"-Infinity", b"1.#QNAN", b"-1.#IND", b"1e999"):
        t[40] = tok
        lines[k] = b" ".join(t)
        motion = read_bvh(write(tmp_path, "nan.bvh", lines))
        assert motion.n_frames == 30 and motion.meta["notes"][0].startswith(
            "lost tracking (NaN, infinite or absurd values) interpolated in 1 frames"), tok


@pytest.mark.shared
def test_bvh_truncated_and_overlong(tmp_path, bvh_lines):
    lines = list(bvh_lines)
    frames_line = lines.index(b"MOTION") + 1
    p = write(tmp_path, "short.bvh", lines[:-6])
    with raises(p, line_no(lines, frames_line), r"'Frames: 30' but only 25 motion lines follow"):
        read_bvh(p)
    extra = list(lines)
    extra[frames_line] = b"Frames: 29"
    p = write(tmp_path, "long.bvh", extra)
    with raises(p, line_no(extra, motion_line(extra, 30)), "more motion lines than the 29 "
                "announced", frame=30):
        read_bvh(p)


@pytest.mark.shared
def test_bvh_bad_offset(tmp_path, bvh_lines):
    lines = list(bvh_lines)
    k = next(i for i, ln in enumerate(lines) if ln.strip().startswith(b"OFFSET"))
    lines[k] = lines[k].rsplit(b" ", 1)[0]
    p = write(tmp_path, "offset.bvh", lines)
    with raises(p, line_no(lines, k), r"joint 'root': OFFSET: expected 3 numbers, found 2"):
        read_bvh(p)


# ----------------------------------------------------------------------------
# dispatch and skeleton conventions

@pytest.mark.shared
def test_find_skeleton_conventions(tmp_path):
    assert find_skeleton(DATA / "cmu/02/02_01.amc") == DATA / "cmu/02/02.asf"
    assert find_skeleton(AMC) == ASF
    assert (find_skeleton(DATA / "hdm05_full/HDM_dg_06-03_03_120.amc")
            == DATA / "hdm05_full/HDM_dg.asf")
    assert find_skeleton(DATA / "cmu/13/13_29.amc") is None
    # the same stem wins over the subject's skeleton
    (tmp_path / "07_01.amc").write_bytes(b"")
    (tmp_path / "07.asf").write_bytes(b"")
    assert find_skeleton(tmp_path / "07_01.amc") == tmp_path / "07.asf"
    (tmp_path / "07_01.asf").write_bytes(b"")
    assert find_skeleton(tmp_path / "07_01.amc") == tmp_path / "07_01.asf"


@pytest.mark.shared
def test_amc_without_a_skeleton_says_how_to_pass_one():
    p = DATA / "cmu/13/13_29.amc"
    with pytest.raises(ParseError, match=re.escape(f"{p}: no ASF skeleton found") +
                       r".*give the skeleton: --asf FILE \(command line\) or asf=FILE \(Python\)\. A CMU take "
                       r"without its subject's ASF reads with any CMU subject's ASF") as err:
        read_motion(p)
    # it speaks of the user's files, not of this repository's test folders
    assert "cmu/02" not in str(err.value) and "read_motion(" not in str(err.value)
    assert read_motion(p, asf=DATA / "cmu/02/02.asf").n_frames > 0


def test_unsupported_extension(tmp_path):
    p = tmp_path / "take.c3x"
    p.write_bytes(b"")
    with pytest.raises(ParseError, match=re.escape(f"{p}: unsupported file type '.c3x'")):
        read_motion(p)
    assert issubclass(ParseError, MocapdbError)


@pytest.mark.shared
def test_a_start_checked_once_is_checked_again_when_the_file_changes(tmp_path, monkeypatch):
    """Ingest checks a take's first bytes before hashing it and again before reading it; the second
    check of an unchanged file is remembered, not read again (issue 35) — but a file rewritten since,
    or changed within the last two seconds, is read again and refused when its start says so."""
    import os
    import time

    import mocapdb.readers.files as files

    amc = tmp_path / "take.amc"
    shutil.copyfile(AMC, amc)
    past = time.time() - 60
    os.utime(amc, (past, past))
    opened = []
    real = files.open_stream
    monkeypatch.setattr(files, "open_stream", lambda p: opened.append(p) or real(p))
    files.check_start(amc)
    files.check_start(amc)
    assert len(opened) == 1   # the unchanged file's start is remembered
    amc.write_bytes(b"1\n" + b"x" * (1 << 15) + b"\n")   # rewritten: one line longer than any AMC line
    with pytest.raises(ParseError, match="a line longer than"):
        files.check_start(amc)
    os.utime(amc, (past, past))   # an old mtime again: a failed start is never remembered
    with pytest.raises(ParseError, match="a line longer than"):
        files.check_start(amc)
    recent = tmp_path / "recent.amc"
    shutil.copyfile(AMC, recent)   # just written: checked each time
    opened.clear()
    files.check_start(recent)
    files.check_start(recent)
    assert len(opened) == 2


def _old_check_finite_motion(joints):
    """check_finite_motion's decision as NumPy steps (before its one kernel call, issue 35): None (accepted),
    "nan" or "far"."""
    import numpy as np
    first = joints[0]
    size = float(np.ptp(first, axis=0).max()) or 1.0
    centre = first.mean(axis=0)
    if not np.isfinite(joints).all():
        return "nan"
    return "far" if (np.abs(joints - centre) > 1e6 * size).any() else None


def test_the_finite_and_extent_check_decides_as_numpy():
    """The one-call check (size and centre of the first frame, every coordinate's finiteness and distance)
    accepts and refuses exactly what its NumPy steps did: random bodies, a flat one (size 0 → 1), values
    at and beyond 10^6 body sizes, NaN and inf anywhere; the size and centre are NumPy's bit for bit."""
    import numpy as np
    from mocapdb.bodies.motion import _extent_kernel, check_finite_motion
    rng = np.random.default_rng(35)
    for trial in range(400):
        n = int(rng.integers(1, 40))
        j = rng.normal(0, 10.0 ** rng.integers(-3, 4), size=(n, 24, 3))
        if trial % 7 == 0:
            j[0] = j[0, :1]   # a flat first frame: size 0 → 1
        size = float(np.ptp(j[0], axis=0).max()) or 1.0
        out = np.empty(3)
        _extent_kernel(j.reshape(-1, 3), 24, out)
        assert out[2] == size
        assert out[1] == np.abs(j.reshape(-1, 3) - j[0].mean(axis=0)).max()
        kind = trial % 5
        if kind == 1:   # exactly at the bound (accepted), or just beyond it (refused)
            f, k, c = (int(rng.integers(0, s)) for s in (n, 24, 3))
            if f:
                j[f, k, c] = j[0].mean(axis=0)[c] + 1e6 * size * (1.0 if trial % 2 else 1.0 + 1e-9)
        elif kind == 2:
            j[tuple(int(rng.integers(0, s)) for s in (n, 24, 3))] = rng.choice([np.nan, np.inf, -np.inf])
        elif kind == 3:
            j[-1, -1, -1] = 1e300
        expected = _old_check_finite_motion(j)
        try:
            check_finite_motion(j, "x.bvh")
            got = None
        except ParseError as exc:
            got = "nan" if "non-finite" in str(exc) else "far"
        assert got == expected, (trial, got, expected)
