"""The paper's P1/R1/F1 and P2/R2/F2 (Eq. (5)–(8)) and the τ sweep."""
import numpy as np
import pytest

from mocapdb.annotation import annotate
from mocapdb.errors import ParameterError
from mocapdb.annotation.labels import label_rows, segments_to_rows
from mocapdb.evaluation.metrics import (
    annotate_sweep, evaluate_annotation, evaluate_by_label, f_measure, frame_measures,
    segment_measures, parse_tau_grid, sweep_tau, tau_grid)
from naive_metrics import naive_frame_measures, naive_segment_measures
from template_oracle import DOCS, oracle_model, words


def _random_rows(rng, n, docs=("a", "b", "c"), labels=("move", "kick", "jump", "sit")):
    s = rng.integers(0, 300, n)
    e = s + rng.integers(0, 60, n)
    return [(str(rng.choice(docs)), str(rng.choice(labels)), int(a), int(b))
            for a, b in zip(s, e)]


@pytest.mark.parametrize("seed", range(40))
def test_measures_equal_naive_sets_on_random_segments(seed):
    rng = np.random.default_rng(seed)
    truth = _random_rows(rng, int(rng.integers(0, 25)))
    auto = _random_rows(rng, int(rng.integers(0, 25)))
    p1, r1, f1, c1 = frame_measures(truth, auto)
    n = naive_frame_measures(truth, auto)
    assert c1 == n[3]
    np.testing.assert_allclose((p1, r1, f1), n[:3], rtol=0, atol=1e-15)
    p2, r2, f2, c2 = segment_measures(truth, auto)
    n = naive_segment_measures(truth, auto)
    assert c2 == n[3]
    np.testing.assert_allclose((p2, r2, f2), n[:3], rtol=0, atol=1e-15)
    s = evaluate_annotation(label_rows(*zip(*truth)) if truth else truth, auto)
    assert (s.p1, s.r1, s.f1, s.p2, s.r2, s.f2) == (p1, r1, f1, p2, r2, f2)
    assert (s.truth_frames, s.auto_frames, s.common_frames) == c1


def test_hand_computed_example():
    # M = {(d,a,0..9)}; A = {(d,a,5..14)} ∪ {(d,b,0..4)}: |M|=10, |A|=15, |M∩A|=5
    truth = [("d", "a", 0, 9)]
    auto = [("d", "a", 5, 14), ("d", "b", 0, 4)]
    s = evaluate_annotation(truth, auto)
    assert (s.truth_frames, s.auto_frames, s.common_frames) == (10, 15, 5)
    assert s.p1 == pytest.approx(1 / 3) and s.r1 == 0.5 and s.f1 == pytest.approx(0.4)
    # segments: 1 of 2 automatic segments overlaps a same-label manual one; the manual one is found
    assert (s.p2, s.r2) == (0.5, 1.0) and s.f2 == pytest.approx(2 / 3)


def test_overlapping_labels_all_count_and_same_label_overlaps_once():
    # a frame carries every label covering it; the same label twice counts once
    truth = [("d", "a", 0, 9), ("d", "b", 0, 9)]
    auto = [("d", "a", 0, 4), ("d", "a", 3, 9), ("d", "b", 5, 9)]
    s = evaluate_annotation(truth, auto)
    assert (s.truth_frames, s.auto_frames, s.common_frames) == (20, 15, 15)
    assert (s.p1, s.r1) == (1.0, 0.75)
    assert (s.auto_correct, s.truth_found) == (3, 2)


def test_touching_segments_do_not_overlap_and_documents_are_separate():
    s = evaluate_annotation([("d", "a", 0, 9)], [("d", "a", 10, 19), ("e", "a", 0, 9)])
    assert (s.common_frames, s.p2, s.r2, s.f1, s.f2) == (0, 0.0, 0.0, 0.0, 0.0)


def test_perfect_disjoint_and_empty():
    rng = np.random.default_rng(7)
    truth = _random_rows(rng, 30)
    s = evaluate_annotation(truth, truth)
    assert (s.p1, s.r1, s.f1, s.p2, s.r2, s.f2) == (1.0,) * 6
    other = [(d, "nothing", a, b) for d, _, a, b in truth]
    s = evaluate_annotation(truth, other)
    assert (s.p1, s.r1, s.f1, s.p2, s.r2, s.f2) == (0.0,) * 6
    # a denominator of 0 gives 0 (documented convention), never NaN
    s = evaluate_annotation(truth, [])
    assert (s.p1, s.r1, s.f1, s.p2, s.r2, s.f2) == (0.0,) * 6 and s.auto_frames == 0
    s = evaluate_annotation([], truth)
    assert (s.p1, s.r1, s.f1) == (0.0,) * 3 and s.truth_frames == 0
    assert f_measure(0, 0) == 0.0 and f_measure(1, 0.5) == pytest.approx(2 / 3)


def test_vocabulary_drops_and_reports_unproducible_truth():
    truth = [("86_09", "move", 0, 219), ("86_09", "look_around", 261, 514),
             ("86_09", "clap", 542, 705), ("86_09", "move", 924, 1198)]
    auto = [("86_09", "move", 0, 230), ("86_09", "kick", 300, 320)]
    vocab = ("move", "kick", "jump")
    s = evaluate_annotation(truth, auto, labels=vocab)
    assert s.dropped_truth == {"clap": 1, "look_around": 1} and s.dropped_auto == {}
    assert s.truth_segments == 2 and s.truth_frames == 220 + 275
    full = evaluate_annotation(truth, auto)
    assert full.r1 < s.r1 and full.p1 == s.p1
    by = evaluate_by_label(truth, auto, labels=vocab)
    assert by["move"].r2 == 0.5 and by["kick"].p1 == 0.0 and by["jump"].f1 == 0.0


@pytest.mark.shared
def test_annotation_segments_are_accepted_directly():
    model = oracle_model()
    w = words("86_09")
    ann = annotate(w, model)
    rows = segments_to_rows(ann.segments, ["86_09"])
    s1 = evaluate_annotation(rows, rows)
    s2 = evaluate_annotation(ann.segments, ann.segments)   # doc indices as document keys
    assert s1 == s2 and s1.f1 == 1.0 and s1.auto_segments == len(ann.segments) == 10


def test_bad_rows_are_rejected():
    with pytest.raises(ParameterError, match=r"truth\[0\].*0 <= start <= end"):
        evaluate_annotation([("d", "a", 5, 4)], [])
    with pytest.raises(ParameterError, match=r"auto\[1\] must be \(document, label, start, end\)"):
        evaluate_annotation([], [("d", "a", 0, 4), ("d", 1, 2)])


# --- τ sweep -----------------------------------------------------------------

def test_tau_grid():
    g = tau_grid(0.05, 0.25, 0.01)
    assert g.size == 21 and g[0] == 0.05 and g[-1] == 0.25 and g[8] == 0.13
    with pytest.raises(ParameterError, match="step > 0"):
        tau_grid(0.1, 0.2, 0)
    np.testing.assert_array_equal(parse_tau_grid("0.05:0.25:0.01"), g)
    with pytest.raises(ParameterError, match="start:stop:step"):
        parse_tau_grid("0.05-0.25")


@pytest.fixture(scope="module")
def five_docs():
    ws = [words(d) for d in DOCS]
    return np.concatenate(ws), np.array([len(w) for w in ws])


@pytest.mark.shared
def test_sweep_equals_annotate_per_tau(five_docs):
    w, lens = five_docs
    model = oracle_model()
    taus = [0.02, 0.08, 0.13, 0.2, 0.3]
    segs = annotate_sweep(w, model, taus, doc_lengths=lens)
    for t, s in zip(taus, segs):
        ref = annotate(w, model, doc_lengths=lens, tau=t).segments
        np.testing.assert_array_equal(s, ref)
    assert len(segs[0]) < len(segs[-1])


@pytest.mark.shared
def test_sweep_with_preselection_equals_annotate(five_docs):
    w, lens = five_docs
    model = oracle_model()
    # a preselection: the second half of every document, per class
    b = np.concatenate(([0], np.cumsum(lens)))
    pre = [[(int(b[d] + lens[d] // 2), int(b[d + 1] - 1)) for d in range(len(lens))]
           for _ in model.classes]
    segs = annotate_sweep(w, model, [0.1, 0.2], doc_lengths=lens, preselection=pre)
    for t, s in zip([0.1, 0.2], segs):
        np.testing.assert_array_equal(
            s, annotate(w, model, doc_lengths=lens, preselection=pre, tau=t).segments)


@pytest.mark.shared
def test_sweep_tau_scores(five_docs):
    w, lens = five_docs
    model = oracle_model()
    truth = segments_to_rows(annotate(w, model, doc_lengths=lens, tau=0.13).segments, DOCS)
    out = sweep_tau(w, model, truth, [0.05, 0.13, 0.25], documents=DOCS, doc_lengths=lens)
    assert [t for t, _ in out] == [0.05, 0.13, 0.25]
    assert out[1][1].f1 == 1.0 and out[1][1].f2 == 1.0
    # a stricter τ keeps fewer frames: precision stays 1 against the τ=0.13 result
    assert out[0][1].p1 == 1.0 and out[0][1].r1 < 1.0
