"""Every file of ../shared/data/foreign2 (and foreign/) through the CLI's ingest, each with its expected
outcome and notes (issue 19 item 7) in the ingest_log table and the --report CSV, and one terminal line
per failed file (issue 26 item 4). Credits: see ../shared/data/README.md (keenon/
nimblephysics, AnyBody/ammr, kjangsy/DHNKinect, Digital-Humans-23/motion-matching, vtan05/Anytop_fork,
UomoCaffeLatte/PyAsfAmc; foreign/: pyomeca/ezc3d-testFiles, 20tab/bvh-python, omimo/PyMO,
Wasserwecken/bvhio, facebookresearch/fairmotion)."""
import csv
import json

import numpy as np
import pytest

from mocapdb.readers import read_asf, read_amc
from mocapdb.bodies import asf_forward_kinematics, node_positions
from mocapdb.bodies.asf_humanoid import asf_humanoid_joints
from mocapdb.features import downsample, relational_features
from mocapdb.storage.motions import source_motion

from conftest import DATA, run

pytestmark = pytest.mark.shared

#: file -> "ingested" with the notes its ingest_log row must hold, or "failed" with its reason's start
FOREIGN2 = {
    "amc/test_mass_kg.amc": ("ingested", ["ASF units mass 'kg' kept as written",
                                          "rate 30 Hz from the ASF's :documentation (the AMC has no "
                                          ":SAMPLES-PER-SECOND)",
                                          "skeleton test_mass_kg.asf read by its shape and bone names "
                                          "(not the CMU names)"]),
    "bvh/kinect_clap_nan.bvh": ("ingested", ["lost tracking (NaN, infinite or absurd values) interpolated in "
                                             "97 frames", "unit cm: the only unit giving the legs"]),
    "bvh/dog_D1_007_KAN01_001.bvh": ("failed", "not a human skeleton: it stands upright"),
    "bvh/chicken_walk.bvh": ("failed", "not a humanoid skeleton mocapdb can map: cannot find the joints of an arm"),
    "c3d/vicon53_freeform.c3d": ("ingested", ["rebuilt Nick01:RBWT in 37 of the 37 frames",
                                              "interpolated 790 missing marker samples"]),
    "c3d/cortex_dotted_trial1.c3d": ("ingested", ["kept frames 844–1286 of 1526",
                                                  "neck placed between the shoulders",
                                                  "head and headtop placed from the neck and the trunk's axis"]),
    "c3d/isb_walk_2014001_C1_01.c3d": ("ingested", ["head and headtop placed from the neck and the trunk's axis "
                                                    "(no head markers)"]),
}
FOREIGN = {
    "amc/11_01.amc": "ingested", "bvh/bvhio_example.bvh": "ingested",
    "bvh/fairmotion_pfnn_hierarchy.bvh": "ingested", "bvh/mixamo_freebvh.bvh": "ingested",
    "bvh/pymo_AV_8Walk_Meredith_HVHA_Rep1.bvh": "ingested",
    "bvh/fairmotion_sinusoidal.bvh": "not a humanoid skeleton mocapdb can map: 4 points",
    "c3d/ezc3d_Qualisys.c3d": "ingested",
    "c3d/ezc3d_BTS.c3d": "no full-body marker set: cannot place lelbow, lwrist, relbow, rwrist",
    "c3d/ezc3d_FP_Type1.c3d": "no full-body marker set: cannot place lelbow, lwrist, relbow, rwrist",
    "c3d/ezc3d_Optotrak.c3d": "no full-body marker set: cannot place root, lhip",
    "c3d/ezc3d_read_NOTworking2.c3d": "no full-body marker set: cannot place root, lhip, lknee, lankle, ltoes, rhip",
}


@pytest.fixture(scope="module")
def ingested(tmp_path_factory):
    folder = tmp_path_factory.mktemp("foreign2")
    db, report = folder / "f.duckdb", folder / "report.csv"
    r = run(db, "ingest", DATA / "foreign", DATA / "foreign2", "--silent", "--report", report, code=None)
    return db, r, report


def test_the_folders_hold_what_the_tests_expect():
    assert sorted(str(p.relative_to(DATA / "foreign2")) for p in (DATA / "foreign2").rglob("*.*")
                  if p.suffix != ".asf") == sorted(FOREIGN2)
    assert sorted(str(p.relative_to(DATA / "foreign")) for p in (DATA / "foreign").rglob("*.*")
                  if p.suffix != ".asf") == sorted(FOREIGN)


def test_every_file_gets_its_outcome_and_its_notes(ingested, open_db):
    db, r, report = ingested
    # every file has its verdict; the failed ones make the exit status 1 (README: ingest)
    assert r.exit_code == 1 and "Traceback" not in r.output
    con = open_db(db, read_only=True)
    log = {path: (outcome, reason, notes) for path, outcome, reason, notes in con.execute(
        "SELECT path, outcome, reason, notes FROM ingest_log WHERE run_id = 1 AND member IS NULL").fetchall()}
    expected = {str(DATA / "foreign2" / name): outcome for name, (outcome, _) in FOREIGN2.items()}
    expected |= {str(DATA / "foreign" / name): "ingested" if outcome == "ingested" else "failed"
                 for name, outcome in FOREIGN.items()}
    expected |= {str(p): "not a motion file" for p in DATA.glob("foreign*/amc/*.asf")}
    assert {path: row[0] for path, row in log.items()} == expected
    for name, (outcome, wanted) in FOREIGN2.items():
        _, reason, notes = log[str(DATA / "foreign2" / name)]
        if outcome == "failed":
            assert reason.startswith(f"{DATA / 'foreign2' / name}: {wanted}"), name
        else:
            for note in wanted:
                assert any(n.startswith(note) for n in notes.split("\n")), (name, note, notes)
    for name, outcome in FOREIGN.items():
        if outcome != "ingested":
            assert log[str(DATA / "foreign" / name)][1].startswith(f"{DATA / 'foreign' / name}: {outcome}"), name
    # stored motions, and only they, have a motion id: the motion whose row it is
    stored = dict(con.execute("SELECT source_path, motion_id FROM motions").fetchall())
    assert dict(con.execute("SELECT path, motion_id FROM ingest_log WHERE outcome = 'ingested'").fetchall()) == stored
    assert con.execute("SELECT count(*) FROM ingest_log WHERE outcome <> 'ingested' AND motion_id IS NOT NULL"
                       ).fetchall() == [(0,)]
    # the terminal: a line per failed file, the summary, where the rest is
    lines = r.output.splitlines()
    failed = sorted(p for p, (outcome, _, _) in log.items() if outcome == "failed")
    assert sorted(ln.split(": ", 1)[0][len("failed  "):] for ln in lines if ln.startswith("failed  ")) == failed
    assert len(lines) == len(failed) + 2 and not any(ln.startswith("note") for ln in lines)
    assert lines[-2].startswith("11 ingested, 0 skipped, 7 failed, 2 not motion files; 9 read with notes (")
    assert lines[-1] == f"every file's outcome, reason and notes: ingest_log run 1, and {report}"
    # --report: the same rows as CSV
    with report.open(newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(log) and {r["path"]: (r["outcome"], r["reason"], r["notes"]) for r in rows} == {
        path: (outcome, reason or "", notes or "") for path, (outcome, reason, notes) in log.items()}


def test_notes_are_stored_with_the_motion_and_the_source_rereads(ingested, open_db):
    """The notes live in motions.reader_options under "notes" (with "source_frames"), which the re-read
    path passes over: the viewer's source_motion gives the stored motion's frames again."""
    db, _, _ = ingested
    con = open_db(db, read_only=True)
    rows = dict(con.execute("SELECT name, reader_options FROM motions").fetchall())
    cortex = json.loads(rows["cortex_dotted_trial1"])
    assert cortex["source_frames"] == [844, 1286] and cortex["notes"][0].startswith("kept frames 844–1286")
    # a BVH's only note: the unit its lengths were taken in (issue 33 item 1)
    assert json.loads(rows["mixamo_freebvh"])["notes"] == ["unit cm: the only unit giving the legs an adult's "
                                                           "length (0.83 m)"]
    for name in ("cortex_dotted_trial1", "kinect_clap_nan", "test_mass_kg"):
        mid, n = con.execute("SELECT motion_id, n_source_frames FROM motions WHERE name = ?", [name]).fetchall()[0]
        assert source_motion(con, mid).n_frames == n


def test_a_cmu_skeleton_through_the_humanoid_mapper_agrees_with_its_bone_names():
    """The mapper that reads non-CMU ASFs (the foreign2 pair) reads the CMU 86 skeleton nearly as its
    bone names do: the differences are where the names define the point otherwise (the neck at the
    lower neck's tip, the wrist at the radius's tip)."""
    skeleton = read_asf(DATA / "cmu" / "86" / "86.asf")
    amc = read_amc(DATA / "cmu" / "86" / "86_09.amc", skeleton)
    named, rot = asf_forward_kinematics(skeleton, amc)
    nodes, node_rot = node_positions(skeleton, amc)
    mapped, mapped_rot, _, problem = asf_humanoid_joints(skeleton, nodes, node_rot)
    assert problem is None and mapped_rot is not None
    a = downsample(relational_features(named, rot, amc.fps))
    b = downsample(relational_features(mapped, mapped_rot, amc.fps))
    assert np.mean(a == b) > 0.98
