"""AMASS and SMPL-family .npz motions (issue 26 item 1; READERS.md §9).

AMASS's licence forbids redistributing its files, so these tests write their own: the shipped
CMU take 86_09 (and HDM05 takes of ../shared) re-expressed on the SMPL tree
(`lab.amass_write`), in the SMPL-H, SMPL-X and SMPL layouts. Read back, they give
the take's features again. Body models are made up here too: random vertices around a rest
skeleton, a regressor averaging them, random shape directions — arrays of the shape of an SMPL-H
or SMPL-X model.npz, none of its numbers.
"""
import gzip
import json
import shutil
import zipfile

import numpy as np
import pytest

import mocapdb
from mocapdb.errors import ParseError
from mocapdb.features import N_BITS, motion_features, unpack_words
from mocapdb.readers import ReaderOptions, read_amc, read_asf, read_motion
from lab.amass_write import write_amass
from mocapdb.readers.body_model import load_body_model
from mocapdb.bodies.humanoid import Z_UP_TO_Y_UP
from mocapdb.bodies.joints import JOINT_INDEX
from mocapdb.bodies.smpl import FAMILIES, canonical_weights, smpl_forward_kinematics
from mocapdb.readers.generic_body import generic_rest
from mocapdb.storage.motions import source_motion

from conftest import DATA, SAMPLE_86_09, SAMPLE_86_ASF, run, shared_cases
from amass_files import make_body_model, rewrite
from naive_kinematics import naive_smpl_fk


@pytest.fixture(scope="module")
def take():
    """86_09 as ASF/AMC: the skeleton, the AMC values and the ASF reading (the reference)."""
    skel = read_asf(SAMPLE_86_ASF)
    return skel, read_amc(SAMPLE_86_09, skel), read_motion(SAMPLE_86_09, asf=SAMPLE_86_ASF)


def bits(motion):
    return unpack_words(motion_features(motion), N_BITS)


def agreement(a, b):
    """The fraction of feature bits (the 40 and feature 41, per 30 Hz frame) two readings of a take share."""
    x, y = bits(a), bits(b)
    assert x.shape == y.shape
    return float((x == y).mean())


# --------------------------------------------------------------------------
# forward kinematics: the kernel against its naive twin

@pytest.mark.slow
def test_the_kernel_agrees_with_its_naive_twin_on_random_poses():
    rng = np.random.default_rng(7)
    rest = generic_rest()
    pose = rng.normal(scale=1.2, size=(40, 22, 3))
    pose[0] = 0.0                                  # the rest pose
    pose[1, 5] = [np.pi, 0.0, 0.0]                 # half a turn
    pose[2, :] = [0.0, 1e-9, 0.0]                  # nearly nothing
    trans = rng.normal(size=(40, 3))
    joints, pelvis = smpl_forward_kinematics(rest, pose, trans)
    want, want_pelvis = naive_smpl_fk(rest.joints, rest.ends, pose, trans)
    assert np.abs(joints - want).max() < 1e-12
    assert np.abs(pelvis - want_pelvis).max() < 1e-12
    # at rest the canonical joints are the rest skeleton's
    assert np.allclose(joints[0, JOINT_INDEX["lknee"]], rest.joints[4] + trans[0])
    assert np.allclose(joints[0, JOINT_INDEX["headtop"]], rest.ends[2] + trans[0])


def test_one_frame_and_the_spine_points():
    rest = generic_rest()
    joints, _ = smpl_forward_kinematics(rest, np.zeros((1, 22, 3)), np.zeros((1, 3)))
    w = canonical_weights(rest)
    assert np.allclose(w.sum(axis=1), 1.0)
    spine = [rest.joints[k] for k in (0, 3, 6, 9, 12)]
    length = sum(np.linalg.norm(b - a) for a, b in zip(spine, spine[1:]))
    # belly at a third of the spine's length from the pelvis (along the polyline)
    from_pelvis = np.linalg.norm(joints[0, JOINT_INDEX["belly"]] - spine[0])
    assert abs(from_pelvis - length / 3) < 0.01 * length


# --------------------------------------------------------------------------
# a real take written as AMASS reads back as its ASF reading

@pytest.mark.slow
@pytest.mark.parametrize("family", ["smplh", "smplx", "smpl"])
def test_86_09_as_amass_has_the_features_of_its_asf_reading(take, tmp_path, family):
    skel, amc, ref = take
    path = write_amass(tmp_path / f"86_09_{family}.npz", skel, amc, family=family)
    with np.load(path) as z:
        assert z["poses"].shape == (amc.n_frames, FAMILIES[family][1])
    m = read_motion(path)
    assert (m.n_frames, m.fps, m.source_format) == (ref.n_frames, 120.0, "amass")
    assert "generic rest skeleton" in m.meta["notes"][0]
    assert m.root_rotation is not None
    # metres, against the ASF's centimetres: the generic skeleton is 86's, so the joints come back
    assert np.abs(m.joints - ref.joints * 0.01).max() < 0.01
    assert agreement(m, ref) >= 0.99


#: one clip of each of the 11 HDM05 classes (the actors take turns)
HDM05_TAKES = shared_cases([sorted(d.glob(f"HDM_{('bd', 'bk', 'dg', 'mm')[k % 4]}_*_120.amc"))[0]
                            for k, d in enumerate(sorted(p for p in (DATA / "hdm05_cut").iterdir() if p.is_dir()))]
                           if (DATA / "hdm05_cut").is_dir() else [])


@pytest.mark.shared
@pytest.mark.parametrize("amc", HDM05_TAKES, ids=lambda p: getattr(p, "stem", str(p)))
def test_hdm05_takes_as_amass_read_with_the_generic_skeleton(amc, tmp_path):
    """Another actor's rotations on 86's proportions: the features stay those of the take."""
    asf = DATA / "hdm05_cut" / f"HDM_{amc.stem.split('_')[1]}.asf"
    skel = read_asf(asf)
    path = write_amass(tmp_path / "take.npz", skel, read_amc(amc, skel))
    assert agreement(read_motion(path), read_motion(amc, asf=asf)) >= 0.95


# --------------------------------------------------------------------------
# what a file may hold

@pytest.fixture(scope="module")
def small(take, tmp_path_factory):
    """The first 600 frames of 86_09 as an SMPL-H AMASS file (gender female, as bytes)."""
    skel, amc, _ = take
    from dataclasses import replace
    short = replace(amc, values=amc.values[:600])
    return write_amass(tmp_path_factory.mktemp("small") / "86_09_short.npz", skel, short, gender=b"female")


@pytest.mark.parametrize("gender", [b"female", "female", np.array([b"female"]), np.array(["female"])])
def test_gender_as_bytes_or_text_reads_the_same(small, tmp_path, gender):
    m = read_motion(rewrite(small, tmp_path / "g.npz", gender=np.array(gender)))
    assert m.meta["gender"] == "female"
    assert np.array_equal(m.joints, read_motion(small).joints)


@pytest.mark.parametrize("key,value,fps", [("mocap_framerate", 120.00004577, 120.0),
                                           ("mocap_frame_rate", 120.0, 120.0),
                                           ("mocap_frame_rate", 59.94, 59.94),
                                           ("mocap_framerate", 100.00001, 100.0)])
def test_frame_rate_keys_and_snapping(small, tmp_path, key, value, fps):
    path = rewrite(small, tmp_path / "r.npz", **{"mocap_framerate": None, key: np.array(value)})
    m = read_motion(path)
    assert m.fps == fps and m.meta["rate_key"] == key


BAD = {
    "shape only": ({"poses": None, "trans": None, "mocap_framerate": None},
                   "an AMASS body shape file (betas and gender), not a motion"),
    "other arrays": ({"poses": None, "betas": None}, "not an AMASS motion: no poses array (it holds"),
    "poses width": ({"poses": np.zeros((600, 100))}, "poses has shape (600, 100); expected n × 72"),
    "no trans": ({"trans": None}, "no trans array"),
    "trans shape": ({"trans": np.zeros((599, 3))}, "trans has shape (599, 3); expected (600, 3)"),
    "no rate": ({"mocap_framerate": None}, "no frame rate (mocap_framerate or mocap_frame_rate)"),
    "zero rate": ({"mocap_framerate": np.array(0.0)}, "frame rate 0.0 Hz"),
    "no frames": ({"poses": np.zeros((0, 156)), "trans": np.zeros((0, 3))}, "no frames"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_files_that_are_not_amass_motions_are_refused_with_the_reason(small, tmp_path, case):
    changes, message = BAD[case]
    path = rewrite(small, tmp_path / "bad.npz", **changes)
    with pytest.raises(ParseError) as e:
        read_motion(path)
    assert str(e.value).startswith(str(path)) and message in str(e.value)


def test_broken_npz_files_name_the_file_and_frame(small, tmp_path):
    with np.load(small) as z:
        poses = z["poses"].copy()
    poses[41, 7] = np.nan
    with pytest.raises(ParseError, match=r"bad\.npz \(frame 42\): non-finite pose"):
        read_motion(rewrite(small, tmp_path / "bad.npz", poses=poses))
    (tmp_path / "text.npz").write_text("poses")
    with pytest.raises(ParseError, match="not an .npz archive"):
        read_motion(tmp_path / "text.npz")
    np.save(tmp_path / "one.npy", np.zeros(3))
    shutil.move(tmp_path / "one.npy", tmp_path / "one.npz")
    with pytest.raises(ParseError, match="a single .npy array"):
        read_motion(tmp_path / "one.npz")
    objects = rewrite(small, tmp_path / "objects.npz")
    with np.load(objects) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["gender"] = np.array([{"who": "female"}], dtype=object)
    np.savez(objects, **arrays)
    with pytest.raises(ParseError, match="'gender' holds Python objects"):
        read_motion(objects)


def test_a_body_standing_along_y_is_not_turned(small, tmp_path):
    """Other SMPL tools write Y up: the body is read as it stands (noted)."""
    with np.load(small) as z:
        poses, trans = z["poses"].copy(), z["trans"]
    # turn the whole take by +90° about x: Z-up becomes Y-up
    from mocapdb.bodies.smpl import axis_angle_matrices, rotation_vectors
    root = Z_UP_TO_Y_UP @ axis_angle_matrices(poses[:, :3])
    poses[:, :3] = rotation_vectors(root)
    m = read_motion(rewrite(small, tmp_path / "y.npz", poses=poses, trans=trans @ Z_UP_TO_Y_UP.T))
    assert m.meta["up"] == "+Y" and any("stands along +Y" in n for n in m.meta["notes"])
    ref = read_motion(small)
    assert np.abs((m.joints - m.joints[:1, :1]) - (ref.joints - ref.joints[:1, :1])).max() < 1e-9


# --------------------------------------------------------------------------
# body models

def standing_rest_frame(path, out, betas):
    """The take's file with its first frame at rest, standing (AMASS's +90° about x), at the origin."""
    with np.load(path) as z:
        poses, trans = z["poses"].copy(), z["trans"].copy()
    poses[0] = 0.0
    poses[0, 0] = np.pi / 2
    trans[0] = 0.0
    return rewrite(path, out, poses=poses, trans=trans, betas=np.asarray(betas, float))


def test_a_body_model_gives_the_rest_joints_of_the_takes_betas(small, tmp_path):
    arrays = make_body_model(tmp_path / "smplh" / "female" / "model.npz", generic_rest())
    betas = np.random.default_rng(3).normal(size=16)
    path = standing_rest_frame(small, tmp_path / "take.npz", betas)
    m = read_motion(path, body_model=tmp_path / "smplh" / "female" / "model.npz")
    # J = J_regressor · (v_template + shapedirs · β), computed here, not by the library
    shaped = arrays["v_template"] + arrays["shapedirs"] @ betas
    want = arrays["J_regressor"] @ shaped
    # standing at rest: the joints are where the model puts them, around the pelvis; the pelvis is
    # at its rest position plus trans (0) in AMASS's Z-up world, here turned to Y up
    frame = m.joints[0] - m.joints[0, 0]
    assert np.allclose(m.joints[0, 0], Z_UP_TO_Y_UP @ want[0], atol=1e-9)
    for joint, k in (("lknee", 4), ("rankle", 8), ("neck", 12), ("lelbow", 18), ("rwrist", 21),
                     ("lfingers", 25), ("rfingers", 40)):
        assert np.allclose(frame[JOINT_INDEX[joint]], want[k] - want[0], atol=1e-9), joint
    # the end points are the shaped toe-tip and head-top vertices
    n = len(arrays["v_template"])
    assert np.allclose(frame[JOINT_INDEX["ltoes"]], shaped[n - 3] - want[0], atol=1e-9)
    assert np.allclose(frame[JOINT_INDEX["headtop"]], shaped[n - 1] - want[0], atol=1e-9)
    assert m.meta["notes"][0].startswith("rest skeleton: the body model ") and "16 of the take's 16 betas" in \
        m.meta["notes"][0]


def test_a_body_model_folder_is_chosen_by_family_and_gender(take, tmp_path):
    skel, amc, ref = take
    models = tmp_path / "body_models"
    rest = generic_rest()
    for gender, seed in (("male", 1), ("female", 2), ("neutral", 3)):
        make_body_model(models / "smplh" / gender / "model.npz", rest, seed=seed)
    make_body_model(models / "smplx" / "SMPLX_NEUTRAL.npz", rest, family="smplx", seed=4)
    betas = np.linspace(-1.0, 1.0, 16)
    for family, gender, used in (("smplh", "male", "smplh/male/model.npz"),
                                 ("smplh", "female", "smplh/female/model.npz"),
                                 ("smplx", "female", "smplx/SMPLX_NEUTRAL.npz")):
        model = load_body_model(models / used)
        path = write_amass(tmp_path / f"{family}_{gender}.npz", skel, amc, family=family,
                           rest=model.rest(betas), gender=gender, betas=betas)
        m = read_motion(path, body_model=models)
        assert str(models / used) in m.meta["notes"][0]
        if family == "smplx":
            assert any("no female SMPL-X body model" in n and "neutral one used" in n for n in m.meta["notes"])
            assert model.n_shape == 300   # its 100 expression directions are not shape
        assert agreement(m, ref) >= 0.95


def test_a_body_model_of_another_family_or_a_missing_one_is_refused(small, tmp_path):
    make_body_model(tmp_path / "smplx" / "SMPLX_FEMALE.npz", generic_rest(), family="smplx")
    with pytest.raises(ParseError, match=r"86_09_short\.npz: the body model .*SMPLX_FEMALE\.npz is SMPL-X "
                                         r"\(55 joints\) and this take is SMPL-H"):
        read_motion(small, body_model=tmp_path / "smplx" / "SMPLX_FEMALE.npz")
    with pytest.raises(ParseError, match=r"no SMPL-H body model for gender 'female' \(nor a neutral one\)"):
        read_motion(small, body_model=tmp_path)
    (tmp_path / "broken.npz").write_bytes(b"PK\x03\x04 not really")
    with pytest.raises(ParseError, match=r"broken\.npz: not a body model \.npz file"):
        read_motion(small, body_model=tmp_path / "broken.npz")


def test_a_male_model_for_a_female_take_is_used_as_given_and_noted(small, tmp_path):
    make_body_model(tmp_path / "smplh" / "male" / "model.npz", generic_rest())
    m = read_motion(small, body_model=tmp_path / "smplh" / "male" / "model.npz")
    assert any("the take is female; the body model" in n and "is male: used as given" in n
               for n in m.meta["notes"])


# --------------------------------------------------------------------------
# ingest: folders, archives, compressed files, the re-read, the CLI

@pytest.mark.slow
def test_ingest_reads_amass_in_folders_archives_and_compressed(small, tmp_path):
    folder = tmp_path / "AMASS" / "CMU" / "86"
    folder.mkdir(parents=True)
    shutil.copy(small, folder / "86_09_poses.npz")
    np.savez(folder / "shape.npz", betas=np.zeros(16), gender=np.array("female"))
    zipped = tmp_path / "amass.zip"
    with zipfile.ZipFile(zipped, "w") as z:
        z.write(small, "CMU/86/86_09_stored.npz")
    rewrite(small, tmp_path / "moved.npz", trans=np.load(small)["trans"] + 1.0)
    with gzip.open(tmp_path / "86_09_moved.npz.gz", "wb") as g:
        g.write((tmp_path / "moved.npz").read_bytes())
    with mocapdb.connect(tmp_path / "a.duckdb") as con:
        report = mocapdb.ingest(con, [tmp_path / "AMASS", zipped, tmp_path / "86_09_moved.npz.gz"])
        assert not report.failed
        assert [r for r in report.unsupported if "shape.npz" in r[0]][0][1].startswith(
            "an AMASS body shape file (betas and gender, no motion)")
        # the folder's file and the zip member are the same bytes: one motion; the moved take another
        assert len(report.ingested) == 2 and len(report.skipped) == 1
        rows = con.execute("SELECT name, format, source_fps, reader_options FROM motions ORDER BY name").fetchall()
        assert [(r[0], r[1], r[2]) for r in rows] == [("86_09_moved", "amass", 120.0),
                                                       ("86_09_poses", "amass", 120.0)]
        assert "generic rest skeleton" in json.loads(rows[0][3])["notes"][0]
        again = mocapdb.ingest(con, [tmp_path / "AMASS", zipped, tmp_path / "86_09_moved.npz.gz"])
        assert not again.ingested and len(again.skipped) == 3
        for mid, in con.execute("SELECT motion_id FROM motions").fetchall():
            assert source_motion(con, mid).n_frames == 600


def test_ingest_with_a_body_model_stores_it_and_re_reads_with_it(small, tmp_path):
    models = tmp_path / "models"
    make_body_model(models / "smplh" / "female" / "model.npz", generic_rest(), seed=5)
    take = standing_rest_frame(small, tmp_path / "take.npz", np.ones(16))
    db = tmp_path / "b.duckdb"
    run(db, "ingest", take, "--body-model", models)
    with mocapdb.connect(db) as con:
        (options,) = con.execute("SELECT reader_options FROM motions").fetchone()
        assert json.loads(options)["body_model"] == str(models)
        (notes,) = con.execute("SELECT notes FROM ingest_log WHERE outcome = 'ingested'").fetchone()
        assert notes.startswith(f"rest skeleton: the body model {models / 'smplh' / 'female' / 'model.npz'}")
        again = source_motion(con, 1)
    direct = read_motion(take, body_model=models)
    assert np.array_equal(again.joints, direct.joints)
    assert not np.allclose(direct.joints, read_motion(take).joints)   # not the generic skeleton
    r = run(db, "ingest", take, "--body-model", tmp_path / "nowhere", code=2)
    assert "does not exist" in r.output


def test_mutated_npz_files_raise_only_mocapdb_errors(small, tmp_path):
    """Seeded byte mutations (tests/fuzzing.py) of a plain and a deflated AMASS file — of the whole
    file (the zip's checksums catch those), and of one array's .npy bytes inside a sound zip
    (headers, shapes, values) — are read to finite joints or refused with a ParseError naming the
    file; nothing else escapes."""
    from fuzzing import mutate

    with np.load(small) as z:
        arrays = {k: z[k][:60] if z[k].ndim == 2 else z[k] for k in z.files}
    np.savez(tmp_path / "plain.npz", **arrays)
    np.savez_compressed(tmp_path / "deflated.npz", **arrays)
    rng = np.random.default_rng(26)
    outcomes = {"read": 0, "refused": 0}
    for k in range(240):
        source = tmp_path / ("plain.npz", "deflated.npz")[k % 2]
        case = tmp_path / f"case_{k}.npz"
        if k % 4 < 2:
            case.write_bytes(mutate(source.read_bytes(), rng))
        else:
            with zipfile.ZipFile(source) as zin, zipfile.ZipFile(case, "w", zin.infolist()[0].compress_type) as zout:
                names = zin.namelist()
                hit = names[int(rng.integers(0, len(names)))]
                for name in names:
                    data = zin.read(name)
                    zout.writestr(name, mutate(data, rng) if name == hit else data)
        try:
            m = read_motion(case)
        except ParseError as exc:
            assert str(exc).startswith(str(case)), exc
            outcomes["refused"] += 1
            continue
        assert np.isfinite(m.joints).all()
        outcomes["read"] += 1
    assert outcomes["read"] > 0 and outcomes["refused"] > 0, outcomes


def test_deflated_arrays_are_held_to_the_decompression_cap(small, tmp_path):
    """An .npz of np.savez_compressed is a zip of deflated arrays: like any compressed recording it may
    decompress to at most the cap (--max-decompressed), judged before an array is read; stored
    (np.savez) arrays are read as they lie on disk."""
    with np.load(small) as z:
        arrays = {k: z[k] for k in z.files}
    np.savez_compressed(tmp_path / "deflated.npz", **arrays)
    assert read_motion(tmp_path / "deflated.npz").n_frames == 600
    with pytest.raises(ParseError, match=r"deflated\.npz: its compressed arrays decompress to .* more than 100 KiB"):
        read_motion(tmp_path / "deflated.npz", ReaderOptions(max_decompressed="100KiB"))
    assert read_motion(small, ReaderOptions(max_decompressed="100KiB")).n_frames == 600   # stored, not inflated
