"""Refusals that say what was measured (issue 33 item 3).

A take whose poses fold the trunk was refused as "not a human skeleton: trunk 0.11 × the leg length" while
files with a byte-identical hierarchy were accepted: the distance root → neck is measured over the take's
frames, so it is the pose that failed. The skeleton's own proportions (its rest pose) now tell the two apart.
"""
import gzip

import pytest

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


def test_an_animal_is_still_not_a_human_skeleton():
    with pytest.raises(ParseError, match="not a human skeleton: it stands upright .* trunk 1.21 × the leg length"):
        read_motion(DATA / "foreign2" / "bvh" / "dog_D1_007_KAN01_001.bvh")
