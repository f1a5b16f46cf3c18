"""Refusals that say what was measured (issue 33 item 3).

A take whose poses fold the trunk was refused as "not a human skeleton: trunk 0.11 × the leg length" while
files with a byte-identical hierarchy were accepted: the distance root → neck is measured over the take's
frames, so it is the pose that failed. The skeleton's own proportions (its rest pose) now tell the two apart.
A human's skeleton whose take keeps a human's proportions but never stands (crawling, lying) is read.
"""
import gzip

import numpy as np
import pytest

from mocapdb.bodies import JOINT_INDEX

from mocapdb.errors import ParseError
from mocapdb.readers import read_motion

from bvh_edit import channel, edit_bvh
from conftest import DATA

pytestmark = pytest.mark.shared

WALK = DATA / "accad_dev" / "Male1_B3_Walk.bvh.gz"


def test_a_folded_pose_is_named_the_pose_not_the_skeleton(tmp_path):
    data = gzip.decompress(WALK.read_bytes())

    def fold(values, hier):   # the upper spine bent back on itself in every frame
        values[:, channel(hier, "Spine1", "Zrotation")] += 170.0

    folded = tmp_path / "contorsion.bvh"
    folded.write_bytes(edit_bvh(data, values=fold))
    assert folded.read_bytes().split(b"MOTION")[0] == data.split(b"MOTION")[0]   # the same hierarchy, byte for byte
    assert read_motion(WALK).n_frames > 100   # which is a human's
    with pytest.raises(ParseError) as info:
        read_motion(folded)
    why = info.value.reason
    assert why.startswith("not a human pose: ") and "not a human skeleton" not in why
    assert "trunk 0.07 × the leg length over the take's frames, 0.56 in its rest pose" in why
    assert why.endswith("the skeleton has a human's proportions at rest: it is the take's poses")


def test_a_human_who_never_stands_is_read():
    """Crawling on all fours and a crouch that ends lying never stand upright (two legs to the floor, arms off
    it): the skeleton and every frame keep a human's proportions, so it is a human lying or crawling, read as
    such (refused as "not a human pose" before). The dog keeps failing on its trunk, the folded take on its
    poses (the tests beside)."""
    for name in ("Male1_A11_CrawlForward", "Male1_A12_CrawlBackward", "Male1_A8_CrouchToLie"):
        m = read_motion(DATA / "accad_dev" / f"{name}.bvh.gz")
        assert m.n_frames > 150
        j = m.joints
        # never upright indeed: the head is never a trunk's length above the hips
        head_over_root = j[:, JOINT_INDEX["head"], 1] - j[:, JOINT_INDEX["root"], 1]
        trunk = np.linalg.norm(j[:, JOINT_INDEX["neck"]] - j[:, JOINT_INDEX["root"]], axis=1)
        assert (head_over_root < trunk).mean() > 0.4, name


def test_an_animal_is_still_not_a_human_skeleton():
    with pytest.raises(ParseError, match="not a human skeleton: it stands upright .* trunk 1.21 × the leg length"):
        read_motion(DATA / "foreign2" / "bvh" / "dog_D1_007_KAN01_001.bvh")
