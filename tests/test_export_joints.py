"""The canonical joints out: `mocapdb export-joints` and `mocapdb.api.export_joints` (issue 26 item 3).

On the recordings that ship with mocapdb (an ASF/AMC take, a BVH of another tool, an HDM05 C3D
document) and an AMASS-format file written from the first: npz and csv hold the joints the
readers give, at the source rate, in metres, Y up; the BVH skeleton ingests back with the same
features (≥ 98 % of the bits; measured 99.9–100 %).
"""
import csv
import shutil

import numpy as np
import pytest

import mocapdb
from mocapdb.errors import ParameterError, SchemaError
from mocapdb.features import N_BITS, motion_features, unpack_words
from mocapdb.bodies import JOINT_NAMES
from mocapdb.readers import read_amc, read_asf, read_motion
from lab.amass_write import write_amass
from mocapdb.bodies.joints import JOINT_INDEX
from mocapdb.writers.joints_write import metres_per_unit
from mocapdb.storage.motions import source_motion

from conftest import SAMPLE_86_09, SAMPLE_86_ASF, SAMPLE_BVH, SAMPLE_C3D, run

NAMES = {"amc": "86_09", "bvh": "pymo_AV_8Walk_Meredith_HVHA_Rep1", "c3d": "HDM_mm_01-02_03_120"}


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    """A database file with the three shipped recordings and 86_09 as AMASS under another name."""
    d = tmp_path_factory.mktemp("export")
    sample = d / "sample"
    sample.mkdir()
    for f in (SAMPLE_86_ASF, SAMPLE_86_09, SAMPLE_BVH, SAMPLE_C3D):
        shutil.copy(f, sample)
    skel = read_asf(SAMPLE_86_ASF)
    write_amass(sample / "86_09_amass.npz", skel, read_amc(SAMPLE_86_09, skel))
    path = d / "e.duckdb"
    with mocapdb.connect(path) as con:
        report = mocapdb.ingest(con, [sample])
        assert len(report.ingested) == 4 and not report.failed
    return path, sample


def ids_by_format(con):
    return dict(con.execute("SELECT format, motion_id FROM motions").fetchall())


@pytest.mark.slow
def test_npz_holds_the_joints_in_metres_at_the_source_rate(db, tmp_path):
    path, _ = db
    with mocapdb.connect(path, read_only=True) as con:
        ids = ids_by_format(con)
        report = mocapdb.export_joints(con, list(ids.values()), tmp_path / "out")
        assert not report.failed and len(report.written) == 4
        for fmt, mid in ids.items():
            motion = source_motion(con, mid)
            (file,) = [p for m, _, p, _ in report.written if m == mid]
            with np.load(file) as z:
                assert list(z["joint_names"]) == list(JOINT_NAMES)
                assert float(z["fps"]) == motion.fps == con.execute(
                    "SELECT source_fps FROM motions WHERE motion_id = ?", [mid]).fetchone()[0]
                joints = z["joints"]
            assert joints.shape == (motion.n_frames, 24, 3)
            assert np.allclose(joints, motion.joints * metres_per_unit(motion)[0], rtol=0, atol=1e-12)
            # metres: a human's legs; Y up: the head above the ankles
            leg = np.linalg.norm(joints[:, JOINT_INDEX["lhip"]] - joints[:, JOINT_INDEX["lknee"]], axis=1) + \
                np.linalg.norm(joints[:, JOINT_INDEX["lknee"]] - joints[:, JOINT_INDEX["lankle"]], axis=1)
            assert 0.6 < np.median(leg) < 1.1, fmt
            assert np.mean(joints[:, JOINT_INDEX["head"], 1] > joints[:, JOINT_INDEX["lankle"], 1]) > 0.9, fmt


@pytest.mark.slow
def test_csv_has_a_row_per_frame_with_its_time(db, tmp_path):
    path, _ = db
    with mocapdb.connect(path, read_only=True) as con:
        mid = ids_by_format(con)["c3d"]
        mocapdb.export_joints(con, [NAMES["c3d"]], tmp_path / "one.npz")
        mocapdb.export_joints(con, [mid], tmp_path / "one.csv", format="csv")
    with (tmp_path / "one.csv").open() as fh:
        rows = list(csv.reader(fh))
    head = rows[0]
    assert head[:5] == ["frame", "time", "root_x", "root_y", "root_z"] and head[-1] == "rfingers_z"
    assert len(head) == 2 + 72
    table = np.array(rows[1:], dtype=float)
    with np.load(tmp_path / "one.npz") as z:
        joints, fps = z["joints"], float(z["fps"])
    assert len(table) == len(joints)
    assert np.array_equal(table[:, 0], np.arange(1, len(joints) + 1))
    assert np.allclose(table[:, 1], np.arange(len(joints)) / fps)
    assert np.allclose(table[:, 2:], joints.reshape(len(joints), -1), rtol=1e-8, atol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["amc", "bvh", "c3d", "amass"])
def test_the_bvh_ingests_back_with_the_same_features(db, tmp_path, fmt):
    path, _ = db
    with mocapdb.connect(path, read_only=True) as con:
        mid = ids_by_format(con)[fmt]
        source = source_motion(con, mid)
        (_, _, file, _), = mocapdb.export_joints(con, [mid], tmp_path / "take.bvh", format="bvh").written
    back = read_motion(file)
    a, b = unpack_words(motion_features(source), N_BITS), unpack_words(motion_features(back), N_BITS)
    assert a.shape == b.shape
    assert (a == b).mean() >= 0.98
    # the joints of the file, in metres, within a few centimetres (the BVH's bones have one length)
    scale = metres_per_unit(source)[0]
    assert np.median(np.linalg.norm(back.joints - source.joints * scale, axis=2)) < 0.005
    assert back.root_rotation is not None   # feature #40 reads the root as the source's did
    with mocapdb.connect(tmp_path / "back.duckdb") as con:
        assert len(mocapdb.ingest(con, [file]).ingested) == 1


def test_several_motions_go_to_a_directory_named_by_motion(db, tmp_path):
    path, sample = db
    shutil.copy(path, tmp_path / "twin.duckdb")
    skel = read_asf(SAMPLE_86_ASF)   # another motion named 86_09 (other bytes)
    write_amass(tmp_path / "86_09.npz", skel, read_amc(SAMPLE_86_09, skel), gender="male")
    with mocapdb.connect(tmp_path / "twin.duckdb") as con:
        mocapdb.ingest(con, [tmp_path / "86_09.npz"])
        report = mocapdb.export_joints(con, ["86_09", NAMES["bvh"]], tmp_path / "dir", format="csv")
        ids = [r[0] for r in con.execute("SELECT motion_id FROM motions WHERE name = '86_09' ORDER BY 1").fetchall()]
    names = sorted(p.name for _, _, p, _ in report.written)
    assert names == sorted([f"86_09_{ids[0]}.csv", f"86_09_{ids[1]}.csv", f"{NAMES['bvh']}.csv"])
    assert all(p.parent == tmp_path / "dir" for _, _, p, _ in report.written)


@pytest.mark.slow
def test_errors_name_the_motion_and_the_others_are_written(db, tmp_path):
    path, sample = db
    moved = tmp_path / "copy.duckdb"
    shutil.copy(path, moved)
    with mocapdb.connect(moved) as con:
        gone = ids_by_format(con)["bvh"]
        con.execute("UPDATE motions SET source_path = ? WHERE motion_id = ?", [str(tmp_path / "gone.bvh.xz"), gone])
        with pytest.raises(SchemaError, match="no motion 'nothing'"):
            mocapdb.export_joints(con, ["nothing"], tmp_path / "x")
        with pytest.raises(ParameterError, match="2 motions give one file each; give a directory"):
            mocapdb.export_joints(con, [1, 2], tmp_path / "x.npz")
        with pytest.raises(ParameterError, match="format must be one of npz, csv, bvh"):
            mocapdb.export_joints(con, [1], tmp_path / "x", format="fbx")
        report = mocapdb.export_joints(con, [1, 2, 3, 4], tmp_path / "out")
    assert len(report.written) == 3
    (mid, name, reason), = report.failed
    assert mid == gone and reason.startswith(f"motion {gone} ({NAMES['bvh']}): ") and "gone.bvh.xz is gone" in reason
    r = run(moved, "export-joints", 1, 2, 3, 4, "--format", "bvh", "--out", tmp_path / "cli", code=1)
    assert f"failed  motion {gone} ({NAMES['bvh']})" in r.output and r.output.count("wrote ") == 3
    r = run(moved, "export-joints", "nothing", "--out", tmp_path / "cli", code=1)
    assert r.output.startswith("Error: no motion 'nothing'")
