"""The development evaluation: LOAO documents, CMU ground truth, the whole run."""
import numpy as np
import pytest

from mocapdb.annotation import annotate
from mocapdb.errors import ParameterError
from lab.documents import CLIPS_PER_DOCUMENT, cmu86_documents, concatenate_motions, loao_documents, mocap6_documents
from lab.development import development_data, development_evaluation
from mocapdb.annotation.labels import class_labels
from mocapdb.evaluation.metrics import evaluate_by_label
from mocapdb.features.heading import heading_degrees
from mocapdb.readers import read_motion
from mocapdb.learning.class_templates import clip_files

from conftest import DATA, amc_frame_count

pytestmark = pytest.mark.shared

CUT = DATA / "hdm05_cut"


@pytest.fixture(scope="module")
def dg_docs():
    return loao_documents(CUT, "dg", seed=0)


def test_joined_clips_have_continuous_roots():
    paths = [p for ps in clip_files(CUT, classes=["kickLFront1Reps", "jogLeftCircle4StepsRstart"],
                                    actors=["bk"]).values() for p in ps]
    clips = [read_motion(p) for p in paths]
    doc, lengths = concatenate_motions(clips, name="d", heading="kept")
    assert doc.n_frames == lengths.sum() == sum(c.n_frames for c in clips)
    ends = np.cumsum(lengths)
    root = doc.joints[:, 0, :]
    # first-frame root of clip k+1 = last-frame root of clip k, in the floor plane
    np.testing.assert_allclose(root[ends[:-1], [0]], root[ends[:-1] - 1, [0]], atol=1e-9)
    np.testing.assert_allclose(root[ends[:-1], [2]], root[ends[:-1] - 1, [2]], atol=1e-9)
    for k, c in enumerate(clips):
        part = doc.joints[ends[k] - lengths[k]:ends[k]]
        shift = part - c.joints                       # a pure floor-plane translation
        np.testing.assert_allclose(shift[..., 1], 0.0, atol=0)
        np.testing.assert_allclose(shift, np.broadcast_to(shift[0, 0], shift.shape), atol=1e-9)
        np.testing.assert_array_equal(doc.root_rotation[ends[k] - lengths[k]:ends[k]],
                                      c.root_rotation)
    np.testing.assert_array_equal(doc.joints[:lengths[0]], clips[0].joints)
    assert doc.meta["clips"] == [c.name for c in clips]
    with pytest.raises(ParameterError, match="at least one clip"):
        concatenate_motions([])


def test_joined_clips_continue_the_last_ones_heading():
    """Each clip turned about the vertical to start facing where the last ended: no turn at a join."""
    paths = [p for ps in clip_files(CUT, classes=["kickLFront1Reps", "jogLeftCircle4StepsRstart"],
                                    actors=["bk"]).values() for p in ps]
    clips = [read_motion(p) for p in paths]
    doc, lengths = concatenate_motions(clips, name="d")
    ends = np.cumsum(lengths)
    h = heading_degrees(doc.joints, doc.root_rotation)
    np.testing.assert_allclose(h[ends[:-1]], h[ends[:-1] - 1], atol=1e-6)      # the heading runs on
    root = doc.joints[:, 0, :]
    np.testing.assert_allclose(root[ends[:-1]][:, [0, 2]], root[ends[:-1] - 1][:, [0, 2]], atol=1e-9)
    kept = [heading_degrees(c.joints, c.root_rotation) for c in clips]
    assert max(abs(((k[0] - kept[i - 1][-1]) + 180) % 360 - 180) for i, k in enumerate(kept) if i) > 20
    for k, c in enumerate(clips):
        part = doc.joints[ends[k] - lengths[k]:ends[k]]
        np.testing.assert_allclose(part[..., 1], c.joints[..., 1], atol=1e-9)      # heights kept
        # a rigid turn and shift in the floor plane: every distance between joints is kept
        np.testing.assert_allclose(np.linalg.norm(part[:, 1] - part[:, 0], axis=1),
                                   np.linalg.norm(c.joints[:, 1] - c.joints[:, 0], axis=1), atol=1e-9)
        np.testing.assert_allclose(np.diff(heading_degrees(part, doc.root_rotation[ends[k] - lengths[k]:ends[k]])),
                                   np.diff(kept[k]), atol=1e-6)                   # the clip's own turns kept
    np.testing.assert_array_equal(doc.joints[:lengths[0]], clips[0].joints)


def test_loao_documents_truth_is_the_clip_boundaries(dg_docs):
    files = {p.stem: (cls, p) for cls, ps in clip_files(CUT, actors=["dg"]).items() for p in ps}
    docs = dg_docs
    used = [c for doc in docs.clips for c in doc]
    assert sorted(used) == sorted(files)                      # every clip exactly once
    assert len(docs.names) == -(-len(files) // CLIPS_PER_DOCUMENT)
    labels = class_labels("hdm05")
    for d, (name, clips) in enumerate(zip(docs.names, docs.clips)):
        t = docs.truth_native[docs.truth_native["document"] == name]
        lengths = [amc_frame_count(files[c][1]) for c in clips]   # counted independently
        np.testing.assert_array_equal(t["end"] - t["start"] + 1, lengths)
        np.testing.assert_array_equal(t["start"][1:], t["end"][:-1] + 1)
        assert t["start"][0] == 1 and t["end"][-1] == docs.native_lengths[d] == sum(lengths)
        assert list(t["label"]) == [labels[files[c][0]] for c in clips]
        assert docs.doc_lengths[d] == -(-docs.native_lengths[d] // 4)
    assert docs.words.size == docs.doc_lengths.sum()
    g = docs.truth
    np.testing.assert_array_equal(g["start"], (docs.truth_native["start"] - 1) // 4)
    np.testing.assert_array_equal(g["end"], (docs.truth_native["end"] - 1) // 4)


def test_loao_documents_are_seeded(dg_docs):
    again = loao_documents(CUT, "dg", seed=0)
    assert again.clips == dg_docs.clips
    np.testing.assert_array_equal(again.words, dg_docs.words)
    other = loao_documents(CUT, "dg", seed=1)
    assert other.clips != dg_docs.clips
    assert sorted(c for d in other.clips for c in d) == sorted(c for d in dg_docs.clips for c in d)


def test_cmu86_truth():
    docs = cmu86_documents(DATA)
    assert docs.names == ("86_09",) and docs.native_lengths[0] == 4794
    assert docs.doc_lengths[0] == docs.words.size == 1199
    assert list(docs.truth["label"]) == ["move", "look_around", "clap", "stand_and_clap", "move"]
    assert (docs.truth["start"][0], docs.truth["end"][0]) == (0, 219)
    assert docs.truth["end"][-1] == 1198


def test_mocap6_truth_blocks():
    docs = mocap6_documents(DATA, trials=("13_30", "14_20"))
    assert docs.names == ("13_30", "14_20")
    for d, name in enumerate(docs.names):
        ids = np.array((DATA / "labels" / "cmu_mocap6" / f"{name}.txt").read_text().split(), int)
        t = docs.truth_native[docs.truth_native["document"] == name]
        n = docs.native_lengths[d]
        assert t["start"][0] == 1 and t["end"][-1] == min(n, 12 * ids.size)
        np.testing.assert_array_equal(t["start"][1:], t["end"][:-1] + 1)
        assert ((t["start"] - 1) % 12 == 0).all()
        # each row is one run of equal block labels
        runs = np.flatnonzero(np.diff(ids[:-(-n // 12)])) + 1
        assert len(t) == runs.size + 1
    g = docs.truth[docs.truth["document"] == "13_30"]
    assert ((g["start"]) % 3 == 0).all()                    # 12 native frames = 3 at 30 Hz
    assert set(docs.truth["label"]) >= {"exercise", "move", "jump"}   # Squat/KneeRaise, Jog, JumpJack
    assert "Twist" in set(docs.truth["label"])              # unmapped ("others"): kept, dropped at scoring


@pytest.mark.slow
def test_small_development_evaluation_finds_held_out_squats():
    classes = ["squat1Reps", "hopBothLegs1hops", "jogLeftCircle4StepsRstart", "kickLFront1Reps"]
    calls = []

    def whole_documents(model, words, doc_lengths):
        # a "preselection" of every whole document must change nothing
        calls.append((model.name, words.size))
        b = np.concatenate(([0], np.cumsum(doc_lengths)))
        return [[(int(b[d]), int(b[d + 1] - 1)) for d in range(len(doc_lengths))]
                for _ in model.classes]

    res = development_evaluation(DATA, held_out=["bk"], classes=classes, real_documents=False, studio=False,
                                 sweep_taus=[0.08, 0.13])
    s = res.scores["loao"]
    for v in (s.p1, s.r1, s.f1, s.p2, s.r2, s.f2):
        assert 0.0 <= v <= 1.0
    assert set(res.scores) == {"loao", "all"} and res.scores["all"] == s
    assert res.models["without_bk"].labels == ("move", "jump", "kick", "exercise")
    assert all(c.template.n_clips == sum(1 for p in ps if "_bk_" not in p.name)
               for c, ps in zip(res.models["without_bk"].classes,
                                clip_files(CUT, classes=classes).values()))
    by = evaluate_by_label(res.truth["loao"], res.auto["loao"])
    assert by["exercise"].r1 > 0.5 and by["exercise"].r2 > 0.5
    assert res.sweep[1][1] == s
    pre = development_evaluation(DATA, held_out=["bk"], classes=classes, real_documents=False, studio=False,
                                 preselection=whole_documents)
    assert calls == [("without_bk", res.documents["loao"].words.size)]
    np.testing.assert_array_equal(pre.auto["loao"], res.auto["loao"])
    with pytest.raises(ParameterError, match=r"held_out actors \['zz'\]"):
        development_evaluation(DATA, held_out=["zz"], classes=classes[:1], real_documents=False, studio=False)


def test_real_documents_annotated_with_the_full_model():
    res = development_evaluation(DATA, held_out=[], studio=False, classes=["jogLeftCircle4StepsRstart",
                                                             "sneak2StepsLStart"])
    assert set(res.scores) == {"cmu86_09", "mocap6", "cmu", "all"}
    s = res.scores["cmu86_09"]
    assert s.dropped_truth == {"clap": 1, "look_around": 1, "stand_and_clap": 1}
    assert s.truth_segments == 2                            # the two walks (move)
    ann = annotate(res.documents["cmu86_09"].words, res.models["all"])
    assert len(res.auto["cmu86_09"]) == len(ann.segments)
    assert res.scores["cmu"].truth_segments == (res.scores["cmu86_09"].truth_segments
                                                + res.scores["mocap6"].truth_segments)


@pytest.mark.slow
def test_cmu_documents_are_annotated_by_models_that_never_saw_them(data_dir):
    """Leave-one-document-out: a CMU document whose stretches train templates is annotated by a model
    built without them; modes annotate every fold's model several ways; mirrored LOAO documents."""
    from lab.recipe import PAPER_LABELS, Recipe, build_model

    recipe = Recipe(labels={"squat1Reps": "exercise", "cmuJumpingJack1Reps": "jump", "cmuWalk2Steps": "move"})
    seen = {}

    def build(clips, name):
        seen[name] = {x.document for v in clips.values() for x in v}
        return build_model(clips, recipe, name=name)

    data = development_data(data_dir, classes=["squat1Reps"], studio=False)
    res = development_evaluation(data_dir, data=data, held_out=["bk"], build=build, mirrored=True,
                                 vocabulary=PAPER_LABELS,
                                 modes={"plain": {}, "tau 0.05": {"tau": 0.05}, "margin": {"margin": 0.02}})
    assert set(res) == {"plain", "tau 0.05", "margin"}
    for name in ("86_09", "13_29", "13_30", "13_31", "14_14", "14_20"):
        assert f"without_{name}" in seen and name not in seen[f"without_{name}"]
        assert name in seen["all"]
    assert not any(d.startswith("HDM_bk_") for d in seen["without_bk"])
    plain = res["plain"]
    assert set(plain.scores) == {"loao", "loao_mirrored", "cmu86_09", "mocap6", "cmu", "all"}
    # turn is never in these truths: not scored there (UNSCORED)
    assert plain.vocabulary["cmu"] == tuple(lab for lab in PAPER_LABELS if lab != "turn")
    assert (res["tau 0.05"].scores["mocap6"].auto_frames <= plain.scores["mocap6"].auto_frames)
    assert res["margin"].scores["all"].auto_frames <= plain.scores["all"].auto_frames
    # the mirrored documents drop the right-handed truth (left-handed motions no label covers)
    assert "grabDepR" not in set(plain.truth["loao_mirrored"]["label"])
    assert len(plain.documents["loao_mirrored"].names) == len(plain.documents["loao"].names)
    # preselected rows: without keyframe queries every class is matched on whole documents
    pre = plain.preselected["mocap6"]
    assert set(pre["label"]) == {"exercise", "jump", "move"}
