"""Training a model from labelled clips (TEMPLATES.md §1, §7, §8)."""
import numpy as np
import pytest

from mocapdb.annotation import annotate
from mocapdb.errors import ParameterError
from mocapdb.annotation.labels import class_labels, label_rows
from mocapdb.learning.class_templates import (
    clip_actor, clip_files, clips_from_folders, clips_from_segments, train_model)
from template_oracle import (
    ANNOTATION, COARSE, SQUAT, TEMPLATES, csv_rows, quantized_template, real_template, stats,
    training_clips, words)

from conftest import DATA

pytestmark = pytest.mark.shared

CUT = DATA / "hdm05_cut"


@pytest.fixture(scope="module")
def all_clips():
    return clips_from_folders(CUT)


def test_squat_folder_reproduces_the_oracle_template():
    clips = clips_from_folders(CUT, classes=["squat1Reps"])
    assert [n for n, _ in clips["squat1Reps"]] == training_clips("squat1Reps")
    model = train_model(clips, name="squat", labels=class_labels("hdm05"))
    (c,) = model.classes
    assert (c.name, c.label, c.delta, c.tau) == ("squat1Reps", "exercise", 0.05, 0.13)
    assert model.labels == ("exercise",)
    real, weights = real_template(TEMPLATES / "squat1Reps")
    np.testing.assert_array_equal(c.template.real, real)
    np.testing.assert_array_equal(c.template.weights, weights)
    assert c.template.n_clips == 40
    assert c.template.iterations == int(stats(SQUAT / "template_stats.txt")["iter_num"][0])
    ref = quantized_template(TEMPLATES / "squat1Reps")
    np.testing.assert_array_equal(c.quantized.mask, ref.mask)
    np.testing.assert_array_equal(c.quantized.value, ref.value)
    np.testing.assert_array_equal(c.quantized.weights, ref.weights)


@pytest.mark.slow
def test_all_actors_model_annotates_like_the_oracle(all_clips):
    """Files → features → 11 templates → annotation equals the toolbox's segments."""
    for cls, cl in all_clips.items():
        assert [n for n, _ in cl] == training_clips(cls)
    model = train_model(all_clips, name="all", labels=class_labels("hdm05"))
    assert model.labels == tuple(COARSE)
    assert model.class_names == tuple(sorted(all_clips))
    ann = annotate(words("86_09"), model)
    segs = csv_rows(ANNOTATION / "86_09" / "segments.csv")
    assert list(ann.segments["label"]) == [s["label"] for s in segs]
    np.testing.assert_array_equal(ann.segments["start"], [int(s["start_frame"]) - 1 for s in segs])
    np.testing.assert_array_equal(ann.segments["end"], [int(s["end_frame"]) - 1 for s in segs])


def test_leave_one_actor_out_selection():
    every = clip_files(CUT)
    without_mm = clip_files(CUT, actors=["bd", "bk", "dg"])
    only_mm = clip_files(CUT, actors=["mm"])
    assert sum(map(len, every.values())) == 232
    for cls, paths in every.items():
        assert [p for p in paths if clip_actor(p.stem) != "mm"] == without_mm[cls]
        assert [p for p in paths if clip_actor(p.stem) == "mm"] == only_mm.get(cls, [])
        assert paths == sorted(paths, key=lambda p: p.name)
    assert clip_actor("HDM_bd_squat1Reps_001_120") == "bd" and clip_actor("86_09") is None
    with pytest.raises(ParameterError, match=r"classes \['nope'\] have no folder"):
        clip_files(CUT, classes=["nope"])
    with pytest.raises(ParameterError, match="root must be a folder"):
        clip_files(CUT / "missing")


def test_default_labels_order_and_progress(all_clips):
    sub = {c: all_clips[c][:3] for c in ("squat1Reps", "hopBothLegs1hops", "kickLFront1Reps")}
    seen = []
    model = train_model(sub, name="m", progress=lambda k, n, c: seen.append((k, n, c)))
    assert model.class_names == model.labels == tuple(sub)
    assert seen == [(1, 3, "squat1Reps"), (2, 3, "hopBothLegs1hops"), (3, 3, "kickLFront1Reps")]
    assert all(c.template.n_clips == 3 for c in model.classes)
    # (name, words) pairs and bare word arrays train the same template
    bare = train_model({"squat1Reps": [w for _, w in sub["squat1Reps"]]}, name="b")
    np.testing.assert_array_equal(bare.classes[0].template.real, model.classes[0].template.real)
    # label order follows the mapping's order, not the class order
    m2 = train_model(sub, name="m2", labels={"kickLFront1Reps": "kick", "squat1Reps": "exercise",
                                             "hopBothLegs1hops": "jump"})
    assert m2.labels == ("kick", "exercise", "jump")


def test_bad_training_input(all_clips):
    with pytest.raises(ParameterError, match="non-empty mapping"):
        train_model({}, name="x")
    with pytest.raises(ParameterError, match=r"class 'a' has no clips"):
        train_model({"a": []}, name="x")
    with pytest.raises(ParameterError, match=r"labels lacks the classes \['squat1Reps'\]"):
        train_model({"squat1Reps": all_clips["squat1Reps"][:2]}, name="x", labels={"b": "c"})
    with pytest.raises(ParameterError, match=r"clips\['a'\]\[0\] must be a 1-D uint64"):
        train_model({"a": [np.zeros((5, 40), bool)]}, name="x")


def test_clips_from_segments_cut_documents():
    w = words("86_09")
    rows = label_rows("86_09", ["move", "other", "move"], [0, 300, 924], [219, 400, 1198])
    clips = clips_from_segments({"86_09": w}, rows)
    assert list(clips) == ["move", "other"]
    assert [n for n, _ in clips["move"]] == ["86_09[0:219]", "86_09[924:1198]"]
    np.testing.assert_array_equal(clips["move"][1][1], w[924:1199])
    model = train_model(clips, name="cut")
    assert [c.template.n_clips for c in model.classes] == [2, 1]
    with pytest.raises(ParameterError, match=r"outside the document's 1199 frames"):
        clips_from_segments({"86_09": w}, [("86_09", "move", 1000, 1199)])
    with pytest.raises(ParameterError, match="not in words_by_document"):
        clips_from_segments({"86_09": w}, [("x", "move", 0, 1)])
