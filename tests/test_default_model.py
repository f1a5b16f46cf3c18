"""The shipped default model: the paper's 15 labels, built by its recipe, and what the development
evaluation (benchmarks/eval_quality.py, figures in benchmarks/eval_quality.json) says of it."""
import json

import numpy as np
import pytest

import mocapdb
from conftest import REPO
from lab.development import development_data
from lab.recipe import DEFAULT_MIRRORS, DEFAULT_REVERSALS, PAPER_LABELS, build_model, default_recipe
from lab.development import LABS
from mocapdb.storage.model_store import fingerprint, load_model

FIGURES = REPO / "benchmarks" / "eval_quality.json"


@pytest.fixture(scope="module")
def shipped():
    with mocapdb.connect() as con:
        return load_model(con, "default"), load_model(con, "toolbox")


def test_the_default_model_knows_the_paper_s_15_labels(shipped):
    model, toolbox = shipped
    assert model.labels == PAPER_LABELS
    for lab in PAPER_LABELS:
        assert any(c.label == lab for c in model.classes), lab
    names = set(model.class_names)
    assert set(DEFAULT_MIRRORS.values()) <= names and {n for n, _ in DEFAULT_REVERSALS.values()} <= names
    assert {"kickRFront1Reps", "punchLFront1Reps", "turnHeading", "standStill", "tpose1000",
            "cmuWalk2Steps", "bandaiWalk2Steps", "bandaiRun2Steps"} <= names
    assert model.concurrent_labels == ("turn",)                  # a walker who turns is still walking
    assert set(toolbox.class_names) <= names                     # the 11 HDM05 classes are in it
    assert all(0 < c.tau <= 0.13 for c in model.classes)         # τ per class, never above the paper's
    assert len({c.tau for c in model.classes}) > 3
    assert all(c.min_frames > 0 for c in model.classes) and model.margin == 0
    # every class preselected (issue 20) but the turn, which reads feature 41 (not in the keyframe index)
    assert [c.name for c in model.classes if c.keyframe_query is None] == ["turnHeading"]


@pytest.mark.slow
@pytest.mark.shared
def test_the_shipped_templates_are_the_recipe_s(shipped, data_dir):
    """benchmarks/train_default_model.py's templates, rebuilt here (learning is deterministic)."""
    model, _ = shipped
    clips = development_data(data_dir).clips()
    fresh = build_model(clips, default_recipe(), name="default")
    assert fresh.class_names == model.class_names and fresh.labels == model.labels
    for a, b in zip(fresh.classes, model.classes):
        for x in ("mask", "value", "weights"):
            np.testing.assert_array_equal(getattr(a.quantized, x), getattr(b.quantized, x), err_msg=a.name)


def test_the_development_figures_are_the_shipped_recipe_s(shipped):
    """benchmarks/eval_quality.py's figures (RESULTS.md, issue 25): the new recipe, every set held out,
    beside the previous default's recipe and the reference mode."""
    figures = json.loads(FIGURES.read_text())
    assert figures["parameters"]["previous"] == "a7c2d94" and figures["parameters"]["seed"] == 0
    assert figures["parameters"]["fingerprint"] == fingerprint(shipped[0]), \
        "the shipped model changed: run benchmarks/eval_quality.py again in the same commit"
    cols = figures["columns"]
    assert set(cols) == {"reference", "previous kf", "previous no-kf", "new kf", "new no-kf"}
    for col in cols.values():
        assert {"loao", "loao_mirrored", "cmu86_09", "mocap6", "cmu", "all", "bandai2"} <= set(col)


def test_the_new_default_holds_every_set_and_travels_to_the_studio():
    """Stored figures: with keyframes the new recipe keeps every HDM05 and CMU set within 0.01 of the previous
    default's (held out), and on the studio's clips it labels locomotion move, finds the turns, stays off
    straight walks and (mostly) off gestures; keyframes never cost move recall."""
    figures = json.loads(FIGURES.read_text())
    new, prev, ref = figures["columns"]["new kf"], figures["columns"]["previous kf"], figures["columns"]["reference"]
    for s in ("loao", "loao_mirrored", "cmu86_09", "mocap6", "cmu", "all"):
        assert new[s]["f1"] >= prev[s]["f1"] - 0.01, s
        assert new[s]["f1"] > ref[s]["f1"], s
    st, old = figures["studio"]["new kf"], figures["studio"]["previous kf"]
    assert st["move_share"] >= 0.90 > old["move_share"]
    assert st["turning_with_turn"] >= 36 > old["turning_with_turn"]
    assert st["straight_with_turn"] <= 1
    assert st["gesture_wrong"] < old["gesture_wrong"]
    assert st["move_share"] >= figures["studio"]["new no-kf"]["move_share"] - 0.01


def test_the_stored_figures_leave_every_lab_out():
    """eval_quality.py's leave-one-lab-out: every lab, both modes, per fold and inside it; the third lab's clips
    and the confidence judged per held-out set."""
    figures = json.loads(FIGURES.read_text())
    for mode in ("keyframes", "no keyframes"):
        folds = figures["lolo"][mode]
        assert set(folds) == set(LABS)
        assert len(folds["hdm05"]["per actor"]) == 4 and len(folds["bandai2"]["per style"]) == 5
        assert len(folds["cmu"]["per document"]) == 6
        assert all(0 <= f["move"] <= 1 for f in folds.values())
        assert {"loao", "bandai2", "accad", "pooled"} <= set(figures["lolo_calibration"][mode])
    assert {"new kf", "previous kf", "reference"} <= set(figures["lab"])
    assert figures["lab"]["new kf"]["clips"] == 69


def test_the_confidence_is_calibrated_on_labs_left_out(shipped):
    """The shipped model carries one confidence map per label, of a score weighing the segment's length (the
    toolbox none), and the stored leave-one-lab-out figures (each lab's segments through maps fitted on the other
    labs') meet issue 32's targets pooled: segments with confidence >= 0.5 right >= 0.90, AUC >= 0.85; the raw
    score's as many most trusted segments right no more often (the two compared at the same coverage: the raw
    score trusts fewer at 0.5), and the raw score ranks worse pooled; on the sets with most segments the ranking
    holds (AUC >= 0.85). Not asserted: mocap6 (23 segments; CMU's jumping jacks as throws, RESULTS.md issue 32)."""
    from mocapdb.learning.confidence_maps import FULL_LENGTH

    model, toolbox = shipped
    assert [m.label for m in model.confidence_maps] == list(model.labels)
    assert {(m.min_length, m.full_length) for m in model.confidence_maps} == {(0, FULL_LENGTH)}
    assert len({m.length_weight for m in model.confidence_maps}) == 1 and model.confidence_maps[0].length_weight > 0
    assert toolbox.confidence_maps == ()
    figures = json.loads(FIGURES.read_text())
    cal = figures["lolo_calibrated"]["keyframes"]
    assert cal["pooled"]["confident_right"] >= 0.90
    assert cal["pooled"]["confident_right"] >= figures["lolo_raw_at_calibrated_count"]["keyframes"]["pooled"]
    assert cal["pooled"]["auc"] >= 0.85
    assert cal["pooled"]["auc"] > figures["lolo_calibration"]["keyframes"]["pooled"]["auc"]
    for s in ("loao", "loao_mirrored", "bandai2", "accad"):
        assert cal[s]["auc"] >= 0.85, s


@pytest.mark.shared
def test_a_clip_of_one_gait_cycle_gets_move(shipped, data_dir, monkeypatch):
    """0.7 s of a walk or run (one gait cycle: CMU 02's walks and jog, ACCAD's clips of locomotion), each a
    document of its own as a file of that length is: the shipped model labels most of them `move` and nothing
    but `move` and `turn`. Without the short-document rule none, as before it: `move`'s minimum length (26
    frames) is longer than the clip (21 frames)."""
    from lab.lab_clips import lab_clip_files
    from lab.short_clips import gait_cycle
    from mocapdb.annotation import annotate, preselection_for
    from mocapdb.annotation import postprocess
    from mocapdb.readers import read_motion

    model = shipped[0]
    cmu = data_dir / "cmu" / "02"
    motions = [read_motion(cmu / f"{d}.amc", asf=cmu / "02.asf") for d in ("02_01", "02_02", "02_03")]
    motions += [read_motion(p) for p, truth, _ in lab_clip_files(data_dir) if truth.locomotion]
    words = [gait_cycle(m, 0.7) for m in motions]
    lengths = np.array([w.size for w in words])
    assert len(words) >= 30 and (lengths <= 22).all()

    def labels():
        flat = np.concatenate(words)
        segs = annotate(flat, model, doc_lengths=lengths, preselection=preselection_for(flat, lengths, model)).segments
        return {int(d) for d, lab in zip(segs["doc"], segs["label"]) if lab == "move"}, set(segs["label"].tolist())

    with_move, found = labels()
    assert len(with_move) >= 0.5 * len(words) and found <= {"move", "turn"}, (len(with_move), found)
    monkeypatch.setattr(postprocess, "document_minimum", lambda n: np.full(np.shape(n), 1 << 40, np.int64))
    assert labels()[0] == set()
