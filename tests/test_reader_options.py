"""One value for the reader options (issue 26 item 5): ReaderOptions, checked once, frozen, carried
whole from the CLI and the API through storage and distributed to the readers.

On the recordings shipped with mocapdb (a bare clone runs them). That ingest and ray-annotate read a
C3D with --marker-rules alike is in test_ray.py.
"""
import dataclasses
import inspect
import json
import os
import pickle

import pytest

import mocapdb
from mocapdb.cli import main
from mocapdb.distributed import MotionWorker, ray_annotate
from mocapdb.errors import ParameterError
from mocapdb.readers import READER_OPTIONS, ReaderOptions, read_motion
from mocapdb.storage.ingest import ingest_files
from mocapdb.storage.ingest_read import compute_motion, prepare_file
from mocapdb.storage.motions import source_motion

from conftest import SAMPLE_86_ASF, SAMPLE_86_09, SAMPLE_BVH, SAMPLE_C3D

#: the reader keywords that used to be repeated in storage and distributed
KEYWORDS = {"asf", "joint_map", "marker_map", "marker_rules", "max_decompressed", "maps"}


def test_checked_once_frozen_and_one_value_for_threads_and_workers(tmp_path):
    toml = tmp_path / "map.toml"
    toml.write_text('root = "Hips"\nneck = ["Neck", "Neck1"]\n', encoding="utf-8")
    a = ReaderOptions(joint_map=toml, marker_rules="anatomical", max_decompressed="2GiB", asf="86.asf")
    b = ReaderOptions(joint_map={"root": "Hips", "neck": ["Neck", "Neck1"]}, marker_rules="anatomical",
                      max_decompressed=2 << 30, asf=os.path.abspath("86.asf"))
    assert a == b and hash(a) == hash(b) and pickle.loads(pickle.dumps(a)) == a   # Ray pickles it
    assert a.mapping("joint_map") == {"root": "Hips", "neck": ["Neck", "Neck1"]} and a.max_decompressed == 2 << 30
    assert a.asf.startswith("/")   # absolute: workers have their own working directory
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.marker_rules = "toolbox"
    for bad, message in [({"marker_rules": "vicon"}, "marker_rules must be one of 'toolbox', 'anatomical'"),
                         ({"joint_map": {"knee": "Knee"}}, "joint_map: 'knee' is not a canonical joint"),
                         ({"marker_map": tmp_path / "none.toml"}, "marker_map .*none.toml: cannot read it"),
                         ({"max_decompressed": "lots"}, "max_decompressed: 'lots' is not a size"),
                         ({"body_model": tmp_path / "model.npz"}, "body_model: .*model.npz' does not exist")]:
        with pytest.raises(ParameterError, match=message):
            ReaderOptions(**bad)
    # the API checks them before any file is read
    with pytest.raises(ParameterError, match="marker_rules"):
        mocapdb.ingest(mocapdb.connect(), [tmp_path / "nowhere.c3d"], marker_rules="vicon")


def test_each_file_stores_the_options_of_its_type():
    options = ReaderOptions(joint_map={"root": "Hips"}, marker_map={"root": ["LASI", "RASI"]},
                            marker_rules="anatomical", max_decompressed="1GiB")
    assert options.for_file("walk.bvh.gz") == {"joint_map": {"root": "Hips"}}
    assert json.loads(options.stored("x.zip/take.c3d")) == {"marker_map": {"root": ["LASI", "RASI"]},
                                                           "marker_rules": "anatomical"}
    assert options.stored("02_01.amc") is None and ReaderOptions().stored("take.c3d") is None
    # the default rules are not stored: a motion read as before stores what it stored before
    assert ReaderOptions(marker_rules="toolbox").for_file("take.c3d") == {}
    stored = '{"marker_rules": "anatomical", "notes": ["a note"], "source_frames": [1, 9]}'
    assert ReaderOptions.from_stored(stored, asf=None) == ReaderOptions(marker_rules="anatomical")
    assert set(READER_OPTIONS) == {"joint_map", "marker_map", "marker_rules", "body_model"}


def test_read_motion_takes_the_value_or_its_keywords():
    by_value = read_motion(SAMPLE_86_09, ReaderOptions(asf=SAMPLE_86_ASF))
    by_keyword = read_motion(SAMPLE_86_09, asf=SAMPLE_86_ASF)
    assert (by_value.joints == by_keyword.joints).all()
    with pytest.raises(ParameterError, match="give options or the keywords"):
        read_motion(SAMPLE_86_09, ReaderOptions(), asf=SAMPLE_86_ASF)


@pytest.mark.slow
def test_ingest_stores_and_the_viewer_rereads_with_the_same_value(open_db):
    """The options a motion was stored with come back whole when its source is re-read."""
    con = open_db()
    mocapdb.ingest(con, [SAMPLE_C3D], marker_rules="anatomical")
    (mid, stored), = con.execute("SELECT motion_id, reader_options FROM motions").fetchall()
    assert json.loads(stored) == {"marker_rules": "anatomical"}
    again = source_motion(con, mid)
    assert (again.joints == read_motion(SAMPLE_C3D, marker_rules="anatomical").joints).all()
    prep = compute_motion(prepare_file(SAMPLE_C3D, ReaderOptions(marker_rules="anatomical")))
    assert prep.reader_options == stored and (prep.motion.joints == again.joints).all()


def test_storage_and_distributed_take_the_value_not_its_keywords():
    for fn in (ingest_files, prepare_file, ray_annotate, MotionWorker.__init__):
        params = set(inspect.signature(fn).parameters)
        assert "options" in params and not params & KEYWORDS, fn.__qualname__
    # the CLI: ingest and ray-annotate have one set of reader options (marker rules included)
    reader = {p.name for p in main.commands["ingest"].params} & {p.name for p in main.commands["ray-annotate"].params}
    assert {"asf", "joint_map", "marker_map", "marker_rules", "max_decompressed"} <= reader


def test_a_bvh_joint_map_reaches_the_reader_through_ingest(tmp_path, open_db):
    """A joint map given to ingest (a dict) is the map the BVH reader uses and the one stored."""
    con = open_db()
    mapping = {"head": "Head", "neck": ["LeftShoulder", "RightShoulder"]}
    mocapdb.ingest(con, [SAMPLE_BVH], joint_map=mapping)
    stored, = con.execute("SELECT reader_options FROM motions").fetchall()[0]
    assert json.loads(stored)["joint_map"] == mapping
    assert (source_motion(con, 1).joints == read_motion(SAMPLE_BVH, joint_map=mapping).joints).all()
