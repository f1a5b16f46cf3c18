"""The shipped default model: the paper's 15 labels, built by its recipe, and what the development
evaluation (benchmarks/eval_quality.py, figures in benchmarks/eval_quality.json) says of it."""
import json

import numpy as np
import pytest

import mocapdb
from conftest import REPO
from mocapdb.evaluation import development_data
from mocapdb.learning.recipe import DEFAULT_MIRRORS, DEFAULT_REVERSALS, PAPER_LABELS, build_model, default_recipe
from mocapdb.storage.models import load_model

FIGURES = REPO / "benchmarks" / "eval_quality.json"


@pytest.fixture(scope="module")
def shipped():
    con = mocapdb.connect()
    try:
        return load_model(con, "default"), load_model(con, "toolbox")
    finally:
        con.close()


def test_the_default_model_knows_the_paper_s_15_labels(shipped):
    model, toolbox = shipped
    assert model.labels == PAPER_LABELS
    for lab in PAPER_LABELS:
        assert any(c.label == lab for c in model.classes), lab
    names = set(model.class_names)
    assert set(DEFAULT_MIRRORS.values()) <= names and {n for n, _ in DEFAULT_REVERSALS.values()} <= names
    assert {"kickRFront1Reps", "punchLFront1Reps", "turnAround", "standStill", "tpose1000",
            "cmuWalk2Steps"} <= names
    assert set(toolbox.class_names) <= names                     # the 11 HDM05 classes are in it
    assert all(0 < c.tau <= 0.13 for c in model.classes)         # τ per class, never above the paper's
    assert len({c.tau for c in model.classes}) > 3
    assert all(c.min_frames > 0 for c in model.classes) and model.margin == 0
    queried = [c for c in model.classes if c.keyframe_query is not None]
    assert 0 < len(queried) < len(model.classes)


def test_the_shipped_templates_are_the_recipe_s(shipped, data_dir):
    """benchmarks/train_default_model.py's templates, rebuilt here (learning is deterministic)."""
    model, _ = shipped
    clips = development_data(data_dir).clips()
    fresh = build_model(clips, default_recipe(), name="default")
    assert fresh.class_names == model.class_names and fresh.labels == model.labels
    for a, b in zip(fresh.classes, model.classes):
        for x in ("mask", "value", "weights"):
            np.testing.assert_array_equal(getattr(a.quantized, x), getattr(b.quantized, x), err_msg=a.name)


def test_the_development_figures_belong_to_the_shipped_model(shipped):
    model, _ = shipped
    figures = json.loads(FIGURES.read_text())
    # the evaluation's model of all folds' data is the shipped one (same recipe, seed and GA runs)
    with_query = {c for c, src in figures["queries"].items()
                  if src.startswith(("ga", "class definition", "keyframe definition"))}
    assert with_query == {c.name for c in model.classes if c.keyframe_query is not None
                          and not any(c.name == m for m in DEFAULT_MIRRORS.values())
                          and c.name not in {n for n, _ in DEFAULT_REVERSALS.values()}}
    assert figures["parameters"] == {"seed": 0, "runs": 20, "generations": 100, "inner_runs": 3, "ga": False,
                                     "inner_generations": 50}


def test_the_new_default_beats_the_reference_on_every_setting():
    """Stored figures of benchmarks/eval_quality.py (RESULTS.md, issue 11): the new default's F1 beats
    the reference mode's on every setting, and its F2 on every setting but the leave-one-actor-out clip
    documents, where it is within one segment in a hundred (their truth has 8 of the 15 labels: a
    stand, a turn or a punch inside a clip counts as an error)."""
    s = json.loads(FIGURES.read_text())["settings"]
    new, ref = s["new default"], s["reference"]
    for setting in ("loao", "loao_mirrored", "cmu86_09", "mocap6", "cmu", "all"):
        assert new[setting]["f1"] > ref[setting]["f1"], setting
        if setting != "loao":
            assert new[setting]["f2"] >= ref[setting]["f2"], setting
    assert new["loao"]["f2"] >= ref["loao"]["f2"] - 0.01
    # the previous default lost recall on new actors; the new default keeps it
    assert new["loao"]["r1"] > s["previous default"]["loao"]["r1"]


def test_the_kicks_are_preselected_by_their_designed_keyframe(shipped):
    """mocapdb/models/classes/kick.toml: both kick classes carry the stretched-leg keyframe (the right
    kick's mirrored), and the kick segments of the development evaluation are all found."""
    model, _ = shipped
    by = {c.name: c for c in model.classes}
    left, right = by["kickLFront1Reps"].keyframe_query, by["kickRFront1Reps"].keyframe_query
    assert left is not None and left.n_keyframes == 1
    mirrored = left.mirrored()
    assert (right.mask, right.value, right.positions) == (mirrored.mask, mirrored.value, mirrored.positions)
    figures = json.loads(FIGURES.read_text())
    assert figures["queries"]["kickLFront1Reps"] == "keyframe definition"
    kick = figures["per_label"]["loao"]["new default"]["kick"]
    assert kick["r2"] == 1.0 and kick["f1"] > figures["per_label"]["loao"]["reference"]["kick"]["f1"]
