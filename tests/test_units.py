"""Joints in true metres whatever unit a BVH file is in (issue 33 item 1), and `export-joints` over many
motions into a folder it creates (item 2).

A BVH file declares no unit. `export-joints` used to pick among m/cm/mm/inch by the legs' length, and a
CMU-converted BVH (unit 1/0.45 inch) came out 2.2× too small as "inch". Here real files of every BVH family
at hand (foreign, foreign2, Bandai, ACCAD; CMU takes written in the CMU unit from their AMC) are read, the
unit decided, said in ingest_log's notes and in every export, and a take exports the same joints as its
twins scaled to metres, millimetres, inches and CMU units (within 1 %).
"""
import gzip
import json
import numpy as np
import pytest

import mocapdb
from mocapdb.cli.options import UNIT_NAMES
from mocapdb.errors import ParameterError
from mocapdb.readers import read_motion
from mocapdb.bodies.joints import JOINT_INDEX
from mocapdb.writers.joints_write import _write_bvh
from mocapdb.bodies.units import UNITS, bvh_unit, leg_length, metres_per_unit

from bvh_edit import edit_bvh
from conftest import DATA, run

pytestmark = pytest.mark.shared

BANDAI = DATA / "bandai2_dev" / "dataset-2_walk_normal_001.bvh.gz"
ACCAD = DATA / "accad_dev" / "Male1_B3_Walk.bvh.gz"
#: file → the unit it is in (the data README: Bandai and ACCAD centimetres; Mixamo exports centimetres;
#: fairmotion's PFNN skeleton metres; a Kinect v1 BVH centimetres)
KNOWN = {DATA / "foreign" / "bvh" / "mixamo_freebvh.bvh": "cm",
         DATA / "foreign" / "bvh" / "fairmotion_pfnn_hierarchy.bvh": "m",
         DATA / "foreign2" / "bvh" / "kinect_clap_nan.bvh": "cm",
         BANDAI: "cm", ACCAD: "cm"}


def scaled_bvh(data: bytes, factor: float) -> bytes:
    """A BVH file's bytes with every length times ``factor`` (the take in another unit)."""
    return edit_bvh(data, factor=factor)


def cmu_unit_bvh(path):
    """CMU take 86_09 as the CMU BVH conversions write it: ASF bone names, lengths in 1/0.45 inch."""
    m = read_motion(DATA / "cmu" / "86" / "86_09.amc")
    _write_bvh(path, m.joints * 0.01 / UNITS["cmu"], m.fps, m.root_rotation)
    return path


def test_the_unit_names_of_the_cli_are_the_readers():
    assert UNIT_NAMES == tuple(UNITS)


@pytest.mark.parametrize("path", sorted(KNOWN), ids=lambda p: p.name)
def test_every_family_gets_its_unit_and_a_human_leg(path):
    m = read_motion(path)
    factor, how = metres_per_unit(m)
    assert m.meta["unit"] == KNOWN[path] and factor == UNITS[KNOWN[path]], how
    assert how.startswith(f"{KNOWN[path]}: the only unit") and m.meta["notes"][-1] == f"unit {how}"
    assert 0.5 <= leg_length(m.joints) * factor <= 1.1


def test_a_cmu_unit_bvh_is_in_cmu_units_not_inches(tmp_path):
    """The probe's case: 27 of 37 CMU BVH motions came out with the pelvis at 0.41–0.46 m."""
    m = read_motion(cmu_unit_bvh(tmp_path / "86_09.bvh"))
    factor, how = metres_per_unit(m)
    assert m.meta["unit"] == "cmu" and factor == pytest.approx(0.0254 / 0.45), how
    pelvis = np.median(m.joints[:, JOINT_INDEX["root"], 1] - m.joints[:, JOINT_INDEX["ltoes"], 1]) * factor
    assert 0.8 < pelvis < 1.2
    # a child's legs (no unit fits): the CMU bone names decide
    unit, reason = bvh_unit(m.joints * 0.5, ["Hips", "LHipJoint", "RHipJoint", "LowerBack"])
    assert unit == "cmu" and "bone names" in reason
    unit, reason = bvh_unit(m.joints * 0.5, ["Hips", "LeftUpLeg"])
    assert "guessed" in reason and "--unit" in reason


@pytest.mark.parametrize("twin", ["m", "mm", "inch", "cmu"])
def test_a_take_and_its_scaled_twin_export_the_same_joints(tmp_path, twin):
    data = gzip.decompress(BANDAI.read_bytes())
    (tmp_path / "take.bvh").write_bytes(data)
    (tmp_path / f"take_{twin}.bvh").write_bytes(scaled_bvh(data, UNITS["cm"] / UNITS[twin]))
    with mocapdb.connect(tmp_path / "t.duckdb") as con:
        report = mocapdb.ingest(con, [tmp_path / "take.bvh", tmp_path / f"take_{twin}.bvh"])
        assert len(report.ingested) == 2
        notes = dict(con.execute("SELECT regexp_extract(path, '[^/]+$'), notes FROM ingest_log").fetchall())
        assert "unit cm: the only unit" in notes["take.bvh"] and f"unit {twin}: the only" in notes[f"take_{twin}.bvh"]
        out = mocapdb.export_joints(con, None, tmp_path / "out", all=True)
    a, b = (np.load(tmp_path / "out" / f"{s}.npz") for s in ("take", f"take_{twin}"))
    assert str(b["source_unit"]).startswith(f"{twin}: ") and float(b["metres_per_source_unit"]) == UNITS[twin]
    scale = np.abs(a["joints"]).max()
    assert np.abs(a["joints"] - b["joints"]).max() < 0.01 * scale
    units = json.loads((tmp_path / "out" / "units.json").read_text())
    assert units["unit"] == "m" and {f["file"]: f["source_unit"].split(":")[0] for f in units["files"]} == {
        "take.npz": "cm", f"take_{twin}.npz": twin} and len(out.written) == 2


def test_unit_and_scale_override_the_decision(tmp_path):
    data = gzip.decompress(BANDAI.read_bytes())
    (tmp_path / "take.bvh").write_bytes(data)
    db = tmp_path / "t.duckdb"
    run(db, "ingest", tmp_path / "take.bvh", "--silent")
    r = run(db, "export-joints", "take", "--unit", "mm", "--format", "csv", "--out", tmp_path / "a" / "mm.csv")
    assert "source unit mm (given)" in r.output
    r = run(db, "export-joints", "--all", "--scale", "0.02", "--out", tmp_path / "b.npz")
    with np.load(tmp_path / "b.npz") as z, mocapdb.connect(db, read_only=True) as con:
        assert float(z["metres_per_source_unit"]) == 0.02 and str(z["source_unit"]) == "0.02 m per unit (given)"
        mm = np.loadtxt(tmp_path / "a" / "mm.csv", delimiter=",", skiprows=1)[:, 2:].reshape(-1, 24, 3)
        assert np.allclose(z["joints"], mm * 20, rtol=1e-6, atol=1e-6)
        for bad in ({"unit": "furlong"}, {"scale": 0}, {"scale": "1e400"}, {"unit": "m", "scale": 1}):
            with pytest.raises(ParameterError):
                mocapdb.export_joints(con, ["take"], tmp_path / "c.npz", **bad)
    r = run(db, "export-joints", "take", "--scale", "-1", "--out", tmp_path / "c.npz", code=1)
    assert r.output.startswith("Error: scale must be a positive number")


def test_export_selects_by_where_and_label_into_a_folder_it_creates(tmp_path):
    takes = tmp_path / "takes"
    takes.mkdir()
    for src in (BANDAI, ACCAD, DATA / "bandai2_dev" / "dataset-2_wave-right-hand_normal_001.bvh.gz"):
        (takes / src.name).write_bytes(src.read_bytes())
    db = tmp_path / "t.duckdb"
    run(db, "ingest", takes, "--silent")
    run(db, "annotate", "--silent", "--format", "csv", "--out", tmp_path / "seg.csv")
    out = tmp_path / "missing" / "deeper"
    r = run(db, "export-joints", "--where", "name LIKE 'dataset-2_%'", "--format", "bvh", "--out", out)
    assert sorted(p.name for p in out.iterdir()) == ["dataset-2_walk_normal_001.bvh",
                                                     "dataset-2_wave-right-hand_normal_001.bvh", "units.json"]
    assert r.output.count("source unit cm: the only unit") == 2
    r = run(db, "export-joints", "--label", "move", "--format", "csv", "--out", tmp_path / "moves")
    names = sorted(p.stem for p in (tmp_path / "moves").glob("*.csv"))
    assert names == ["Male1_B3_Walk", "dataset-2_walk_normal_001"], r.output
    r = run(db, "export-joints", "--label", "nosuch", "--out", tmp_path / "x", code=1)
    assert r.output.startswith("Error: label 'nosuch': no stored segment of it") and "move" in r.output
    for where in ("1 = 1; DROP TABLE motions", "no_such_column = 1", ""):
        r = run(db, "export-joints", "--where", where, "--out", tmp_path / "x", code=None)
        assert r.exit_code != 0 and r.output.count("\n") <= 2 and "internal error" not in r.output, r.output
    r = run(db, "export-joints", "--out", tmp_path / "x", code=2)
    assert "--all, --where SQL or --label LABEL" in r.output
    with mocapdb.connect(db, read_only=True) as con:
        assert con.execute("SELECT count(*) FROM motions").fetchone()[0] == 3
