"""Where recordings come from, and what ingest says about what it cannot read (issue 18 item 1,
issue 22 items 7 and 9).

Compressed files (.gz, .bz2, .xz) and zip archives (a folder inside, as the CMU and Bandai downloads
come) are read in place: the motion's source_path runs through the archive, an AMC finds its ASF in
the same archive, re-ingest is a no-op, the viewer re-reads the member. FIFOs and devices are named as
such; special and unreadable folder entries get a line; an unreadable ASF is reported under its own
name; control characters never reach the terminal raw. Hashing streams; the BVH parse holds the
channel values, not the text as well; many sibling joints parse in linear time.
"""
import bz2
import gzip
import lzma
import os
import shutil
import socket
import tracemalloc
import zipfile

import numpy as np
import pytest

import mocapdb
import mocapdb.readers.bvh as bvh_module
from mocapdb.features import motion_features
from mocapdb.readers import read_motion
from mocapdb.readers.sources import sha256
from mocapdb.storage.motions import source_motion

from conftest import DATA, run

pytestmark = pytest.mark.shared

CMU = DATA / "cmu" / "02"
WALK = DATA / "foreign" / "bvh" / "pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh"
DG = DATA / "hdm05_full" / "HDM_dg_06-03_03_120.c3d"
KICK = DATA / "hdm05_cut" / "kickLFront1Reps" / "HDM_bd_kickLFront1Reps_001_120.amc"


@pytest.fixture
def archive(tmp_path):
    """A CMU-style download: a zip holding subjects/02/ (its ASF and two takes) and a BVH elsewhere."""
    path = tmp_path / "cmu.zip"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.write(CMU / "02.asf", "subjects/02/02.asf")
        z.write(CMU / "02_01.amc", "subjects/02/02_01.amc")
        z.write(CMU / "02_02.amc", "subjects/02/02_02.amc")
        z.write(WALK, "other/walk.bvh")
        z.writestr("__MACOSX/subjects/02/._02_01.amc", b"resource fork")
        z.writestr("subjects/README.txt", b"not a motion")
    return path


def words_of(con, name):
    return con.execute("SELECT bits FROM features JOIN motions USING (motion_id) WHERE name = ? ORDER BY frame",
                       [name]).fetchnumpy()["bits"]


def test_a_zip_archive_is_read_in_place_and_re_ingest_is_a_no_op(archive, tmp_path):
    with mocapdb.connect(tmp_path / "z.duckdb") as con:
        report = mocapdb.ingest(con, [archive])
        assert sorted(p for p, *_ in report.ingested) == [str(archive / "other/walk.bvh"),
                                                          str(archive / "subjects/02/02_01.amc"),
                                                          str(archive / "subjects/02/02_02.amc")]
        assert sorted(p for p, _ in report.unsupported) == [str(archive / "subjects/02/02.asf"),
                                                            str(archive / "subjects/README.txt")]
        rows = con.execute("SELECT name, source_path, skeleton_path FROM motions ORDER BY name").fetchall()
        assert rows[0] == ("02_01", str(archive / "subjects/02/02_01.amc"), str(archive / "subjects/02/02.asf"))
        np.testing.assert_array_equal(words_of(con, "02_01"), motion_features(read_motion(CMU / "02_01.amc")))
        np.testing.assert_array_equal(words_of(con, "walk"), motion_features(read_motion(WALK)))
        # the viewer re-reads the member
        mid = con.execute("SELECT motion_id FROM motions WHERE name = '02_02'").fetchall()[0][0]
        np.testing.assert_array_equal(source_motion(con, mid).joints, read_motion(CMU / "02_02.amc").joints)
        # macOS's metadata folder is passed over, and said so (issue 33)
        assert report.skipped == [(str(archive / "__MACOSX"), "macOS zip metadata (__MACOSX): not read; name it on "
                                                               "the command line to read it")]
        again = mocapdb.ingest(con, [archive])
        assert not again.ingested and len(again.skipped) == 4
        # the same take outside the archive has the same bytes: stored once
        plain = mocapdb.ingest(con, [CMU / "02_01.amc"])
        mid = dict(con.execute('SELECT name, motion_id FROM motions').fetchall())['02_01']
        [(path, why)] = plain.skipped
        assert path == str(CMU / "02_01.amc") and why.startswith(f"already ingested as motion {mid} ")
        # a folder inside the archive, named directly
        inner = mocapdb.ingest(con, [archive / "subjects" / "02"])
        assert sorted(p for p, _ in inner.skipped) == [str(archive / "subjects/02/02_01.amc"),
                                                       str(archive / "subjects/02/02_02.amc")]
    db = tmp_path / "cli.duckdb"
    r = run(db, "ingest", archive / "subjects" / "02", "--silent")
    assert "2 ingested, 0 skipped, 0 failed, 1 not motion files" in r.output
    r = run(db, "ingest", archive / "subjects" / "03", "--silent", code=1)
    assert r.output.strip() == (f"Error: paths: '{archive / 'subjects' / '03'}' does not "
                                f"exist (no such member in {archive})")


@pytest.mark.slow
@pytest.mark.parametrize("suffix, module", [(".gz", gzip), (".bz2", bz2), (".xz", lzma)])
def test_compressed_files_read_as_their_content(tmp_path, suffix, module):
    folder = tmp_path / "takes"
    folder.mkdir()
    for src in (WALK, DG, KICK):
        (folder / (src.name + suffix)).write_bytes(module.compress(src.read_bytes()))
    shutil.copy(DATA / "hdm05_cut" / "HDM_bd.asf", folder)
    with mocapdb.connect(tmp_path / "c.duckdb") as con:
        report = mocapdb.ingest(con, [folder])
        assert len(report.ingested) == 3 and not report.failed
        for src in (WALK, DG, KICK):
            stem = src.name.split(".")[0]
            np.testing.assert_array_equal(words_of(con, stem), motion_features(read_motion(src)))
        sha = dict(con.execute("SELECT name, sha256 FROM motions").fetchall())
        assert sha[WALK.stem] == sha256(WALK)   # the recording's bytes, whatever the packing
        assert mocapdb.ingest(con, [WALK]).skipped
    broken = tmp_path / "cut.bvh.gz"
    broken.write_bytes(gzip.compress(WALK.read_bytes())[:5000])
    with mocapdb.connect(tmp_path / "b.duckdb") as con:
        (path, reason), = mocapdb.ingest(con, [broken]).failed
        assert path == str(broken) and reason.startswith(f"{broken}: cannot read it (corrupt compressed data")


def test_fifos_and_sockets_are_named_as_such(tmp_path):
    folder = tmp_path / "takes"
    folder.mkdir()
    shutil.copy(WALK, folder / "walk.bvh")
    os.mkfifo(folder / "pipe.bvh")
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(folder / "sock.bvh"))
    try:
        db = tmp_path / "f.duckdb"
        r = run(db, "ingest", folder, "--silent")
        assert "1 ingested, 0 skipped, 0 failed, 2 not motion files" in r.output
        assert "pipe.bvh" not in r.output   # the terminal names failed files; every file is in ingest_log
        with mocapdb.connect(db, read_only=True) as con:
            assert con.execute("SELECT path, outcome, reason FROM ingest_log WHERE outcome <> 'ingested' "
                               "ORDER BY path").fetchall() == [
                (str(folder / "pipe.bvh"), "not a motion file", "a FIFO (named pipe), not a regular file"),
                (str(folder / "sock.bvh"), "not a motion file", "a socket, not a regular file")]
        r = run(db, "ingest", folder / "pipe.bvh", "--silent", code=1)
        assert "does not exist" not in r.output
        assert f"failed  {folder / 'pipe.bvh'}: a FIFO (named pipe), not a motion file" in r.output
    finally:
        sock.close()


def test_an_unreadable_folder_gets_a_line(tmp_path, monkeypatch):
    folder = tmp_path / "takes"
    (folder / "locked").mkdir(parents=True)
    shutil.copy(WALK, folder / "walk.bvh")
    real = os.scandir

    def scandir(path="."):
        if str(path).endswith("locked"):
            raise PermissionError(13, "Permission denied", str(path))
        return real(path)
    monkeypatch.setattr(os, "scandir", scandir)
    r = run(tmp_path / "u.duckdb", "ingest", folder, "--silent", code=None)
    assert f"unreadable {folder / 'locked'}: unreadable folder (Permission denied)" in r.output
    assert "1 ingested, 0 skipped, 0 failed, 1 unreadable" in r.output
    with mocapdb.connect(tmp_path / "u.duckdb", read_only=True) as con:   # logged as a failure to read
        assert con.execute("SELECT path, outcome, reason FROM ingest_log WHERE outcome <> 'ingested'").fetchall() \
            == [(str(folder / "locked"), "failed", "unreadable folder (Permission denied)")]


def test_an_unreadable_skeleton_is_reported_under_its_own_name(tmp_path, open_db):
    take = tmp_path / "02_01.amc"
    shutil.copy(CMU / "02_01.amc", take)
    skeleton = tmp_path / "not_a_file.asf"
    skeleton.mkdir()   # a folder where the skeleton should be: unreadable, even for root
    con = open_db(tmp_path / "s.duckdb")
    (path, reason), = mocapdb.ingest(con, [take], asf=skeleton).failed
    assert path == str(take)
    assert reason.startswith(f"{skeleton}: cannot read this skeleton of {take} (")


def test_control_characters_never_reach_the_terminal_raw(tmp_path):
    folder = tmp_path / "takes"
    folder.mkdir()
    rng = np.random.default_rng(3)
    junk = bytes(rng.integers(0, 32, 4000, dtype=np.uint8))   # control characters only
    for name in ("evil\x1b[2Jname.bvh", "bell\x07.amc", "x.c3d", "hier.bvh"):
        (folder / name).write_bytes(junk)
    (folder / "hier.bvh").write_bytes(b"HIERARCHY\nROOT \x1b]0;owned\x07\n{\nOFFSET 0 0 0\n}\n")
    r = run(tmp_path / "c.duckdb", "ingest", folder, "--silent", code=None)
    assert "4 failed" in r.output
    assert not any(ch in r.output for ch in "\x1b\x07\x00\x01\x08"), r.output
    assert "\\x1b" in r.output


def test_hashing_streams_the_file(tmp_path):
    """The hash of a file read in chunks equals hashlib's of its bytes, and memory stays far below the
    file's size."""
    import hashlib
    big = tmp_path / "big.bvh"
    big.write_bytes(WALK.read_bytes() * 8)   # ~4.8 MB
    tracemalloc.start()
    digest = sha256(big)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert digest == hashlib.sha256(big.read_bytes()).hexdigest()
    assert peak < 0.5 * big.stat().st_size


def test_the_bvh_parse_holds_the_values_not_the_text(tmp_path, monkeypatch):
    """The motion lines are parsed block by block (64 KiB here) and forward kinematics runs in blocks:
    reading holds the channel values and the joints, not the text and every joint's path as well."""
    head, _, body = WALK.read_bytes().partition(b"MOTION")
    lines = [ln for ln in body.split(b"\n")[3:] if ln.strip()]
    frame_time = body.split(b"\n")[2]
    path = tmp_path / "long.bvh"
    path.write_bytes(head + b"MOTION\nFrames: %d\n" % (8 * len(lines)) + frame_time + b"\n"
                     + b"\n".join(lines * 8) + b"\n")
    monkeypatch.setattr(bvh_module, "_READ_BLOCK", 1 << 16)
    monkeypatch.setattr(bvh_module, "_FK_POINTS", 1 << 14)
    read_motion(path)   # warm: compile, cache the hierarchy
    tracemalloc.start()
    motion = read_motion(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    values = 8 * len(lines) * len(lines[0].split()) * 8
    assert motion.n_frames == 8 * len(lines)
    assert peak < values + motion.joints.nbytes + 4 * (1 << 16) + (1 << 22)


def test_sibling_joints_are_numbered_in_one_pass(tmp_path, monkeypatch):
    """100,000 siblings took 222 s: every joint's line was counted from the file's start. Lines are now
    counted once for the whole hierarchy."""
    calls = []
    real = bvh_module.line_of
    monkeypatch.setattr(bvh_module, "line_of", lambda data, pos: calls.append(pos) or real(data, pos))
    rows = ["HIERARCHY", "ROOT Hips", "{", "OFFSET 0 0 0", "CHANNELS 3 Xposition Yposition Zposition"]
    for k in range(2000):
        rows += [f"JOINT J{k}", "{", f"OFFSET {k} 1 0", "End Site", "{", "OFFSET 0 1 0", "}", "}"]
    rows += ["}", "MOTION", "Frames: 1", "Frame Time: 0.0333333", "0 0 0"]
    data = parse = bvh_module.parse_bvh("\n".join(rows).encode() + b"\n", path="siblings.bvh")
    assert len(parse.hierarchy.joints) == 2001 and data.hierarchy.joints[-1].line == 5 + 8 * 1999 + 1
    assert len(calls) <= 2
