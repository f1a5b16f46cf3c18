"""The annotation chain (TEMPLATES.md §9.1, §10) against the toolbox and naive references."""
import numpy as np
import pytest

from mocapdb.annotation import (
    annotate, combine_by_label, extract_hits, form_segments, frame_labels)
from mocapdb.errors import ParameterError
from mocapdb.annotation.model import ClassModel, Model
from mocapdb.templates import mt_distance
from naive_dtw import naive_hits, naive_segments
from template_oracle import (
    ANNOTATION, CLASSES, COARSE, DOCS, TEMPLATES, csv_rows, csv_table, oracle_model,
    quantized_template, words)


def _same(got, ref):
    np.testing.assert_array_equal(np.isinf(got), np.isinf(ref))
    fin = np.isfinite(ref)
    assert np.abs(got[fin] - ref[fin]).max(initial=0.0) <= 1e-9


@pytest.fixture(scope="module")
def model():
    return oracle_model()


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("doc", DOCS)
def test_annotation_reproduces_toolbox(model, doc):
    folder = ANNOTATION / doc
    r = annotate(words(doc), model, keep_deltas=True)
    header, cdf = csv_table(folder / "classificationDelta_fine.csv")
    assert tuple(header) == model.class_names == r.class_names
    _same(r.classification_delta, cdf.T)
    _, delta = csv_table(folder / "delta_fine.csv")
    _same(r.delta, delta.T)
    header, cdc = csv_table(folder / "classificationDelta_coarse.csv")
    assert tuple(header) == model.labels == r.labels
    _same(r.label_delta, cdc.T)
    _, dc = csv_table(folder / "delta_coarse.csv")
    _same(combine_by_label(r.delta, model.label_index, len(model.labels)), dc.T)
    hits = csv_rows(folder / "hits_fine.csv")
    assert len(r.hits) == len(hits)
    assert [h["class"] for h in hits] == [r.class_names[k] for k in r.hits["class_id"]]
    np.testing.assert_array_equal([int(h["first_frame"]) - 1 for h in hits], r.hits["start"])
    np.testing.assert_array_equal([int(h["last_frame"]) - 1 for h in hits], r.hits["end"])
    _same(r.hits["cost"], np.array([float(h["cost"]) for h in hits]))
    assert (r.hits["doc"] == 0).all()
    segs = csv_rows(folder / "segments.csv")
    assert len(r.segments) == len(segs) > 0
    assert [s["label"] for s in segs] == list(r.segments["label"])
    np.testing.assert_array_equal([int(s["start_frame"]) - 1 for s in segs], r.segments["start"])
    np.testing.assert_array_equal([int(s["end_frame"]) - 1 for s in segs], r.segments["end"])
    _same(r.segments["cost"], np.array([float(s["cost"]) for s in segs]))


@pytest.mark.shared
def test_concatenated_documents_reproduce_toolbox(model):
    ws = [words(d) for d in DOCS]
    layout = csv_rows(ANNOTATION / "concat_layout.csv")
    assert [int(x["files_frame_length"]) for x in layout] == [len(w) for w in ws]
    r = annotate(np.concatenate(ws), model, doc_lengths=[len(w) for w in ws])
    ref = csv_rows(ANNOTATION / "segments_concat_check.csv")
    assert len(r.segments) == len(ref) == 19
    assert [s["label"] for s in ref] == list(r.segments["label"])
    assert [s["doc"] for s in ref] == [DOCS[d] for d in r.segments["doc"]]
    np.testing.assert_array_equal([int(s["start_frame"]) - 1 for s in ref], r.segments["start"])
    np.testing.assert_array_equal([int(s["end_frame"]) - 1 for s in ref], r.segments["end"])
    _same(r.segments["cost"], np.array([float(s["cost"]) for s in ref]))
    # frames in the database: document start (the toolbox's 1-based db frames
    # include two separator frames after every document)
    db = [int(x["files_frame_start"]) - 1 for x in layout]
    np.testing.assert_array_equal([int(s["start_frame_db"]) - 1 for s in ref],
                                  np.array(db)[r.segments["doc"]] + r.segments["start"])


def _archive():
    """The oracle documents, three times over (15 documents)."""
    ws = [words(d) for d in DOCS] * 3
    return np.concatenate(ws), [len(w) for w in ws]


@pytest.mark.shared
@pytest.mark.parametrize("cells", [1, 1500 * 11, 4000 * 11])
def test_batched_annotation_equals_one_batch(model, monkeypatch, cells):
    import mocapdb.annotation.chain as ann
    w, lens = _archive()
    full = annotate(w, model, doc_lengths=lens, keep_deltas=True)  # keep_deltas: one batch
    # 1 cell: every document a batch of its own; then batches of 1-2 and 3-4 documents
    monkeypatch.setattr(ann, "BATCH_CELLS", cells)
    assert len(ann._batches(np.concatenate(([0], np.cumsum(lens))),
                            max(1, cells // len(model.classes)))) > 1
    small = annotate(w, model, doc_lengths=lens)
    np.testing.assert_array_equal(small.segments, full.segments)
    np.testing.assert_array_equal(small.hits, full.hits)
    # slices out of document order: hits stay in slice order across batches
    pre = {"kickLFront1Reps": [(len(w) - lens[-1], len(w) - 1), (500, 700), (650, 900)],
           "squat1Reps": [(len(w) - lens[-1], len(w) - 1), (0, lens[0] - 1)]}
    small = annotate(w, model, doc_lengths=lens, preselection=pre)
    full = annotate(w, model, doc_lengths=lens, preselection=pre, keep_deltas=True)
    assert (full.hits["doc"] == len(lens) - 1).any() and (full.hits["doc"] == 0).any()
    np.testing.assert_array_equal(small.segments, full.segments)
    np.testing.assert_array_equal(small.hits, full.hits)


def test_batches_cover_the_documents_in_order():
    from mocapdb.annotation.chain import _batches
    rng = np.random.default_rng(3)
    for _ in range(50):
        lens = rng.integers(0, 50, int(rng.integers(1, 30)))
        bounds = np.concatenate(([0], np.cumsum(lens)))
        size = int(rng.integers(1, 120))
        groups = _batches(bounds, size)
        assert groups[0][0] == 0 and groups[-1][1] == lens.size
        assert all(a < b for a, b in groups)
        assert all(b == c for (_, b), (c, _) in zip(groups[:-1], groups[1:]))
        # a batch holds at most `size` frames plus its last document
        assert all(bounds[b - 1] - bounds[a] < size for a, b in groups)
    assert _batches(np.zeros(1, np.int64), 10) == [(0, 0)]


@pytest.mark.shared
def test_keep_hits_false_gives_the_same_segments(model):
    w, lens = _archive()
    full = annotate(w, model, doc_lengths=lens)
    bare = annotate(w, model, doc_lengths=lens, keep_hits=False)
    assert len(full.hits) > 1000
    assert bare.hits.dtype == full.hits.dtype and bare.hits.size == 0
    np.testing.assert_array_equal(bare.segments, full.segments)
    with pytest.raises(ParameterError, match="match_num_max=5"):
        annotate(words("86_09"), model, match_num_max=5, keep_hits=False)


@pytest.mark.slow
@pytest.mark.shared
def test_hits_of_many_tasks_equal_one_task_at_a_time(model):
    """annotate extracts the hits of every (class, document) task in one parallel
    kernel whose threads reuse one scratch row across tasks (one thread: a
    single row for all 165); each must equal a fresh extraction of that task."""
    import numba
    w, lens = _archive()
    bounds = np.concatenate(([0], np.cumsum(lens)))
    old = numba.get_num_threads()
    try:
        for threads in {1, old}:
            numba.set_num_threads(threads)
            r = annotate(w, model, doc_lengths=lens)
            for c, cls in enumerate(model.classes):
                for d in range(len(lens)):
                    delta, starts = mt_distance(w[bounds[d]:bounds[d + 1]], cls.quantized,
                                                return_starts=True)
                    hits, _ = extract_hits(delta, starts, tau=cls.tau)
                    mine = r.hits[(r.hits["class_id"] == c) & (r.hits["doc"] == d)]
                    np.testing.assert_array_equal(mine["start"], hits["start"])
                    np.testing.assert_array_equal(mine["end"], hits["end"])
                    np.testing.assert_array_equal(mine["cost"], hits["cost"])
    finally:
        numba.set_num_threads(old)


# --- hit extraction ---------------------------------------------------------

@pytest.mark.shared
def test_extract_hits_matches_toolbox_loop_on_real_delta():
    d, s = mt_distance(words("86_09"), quantized_template(TEMPLATES / "kickLFront1Reps"),
                       return_starts=True)
    hits, cd = extract_hits(d, s, tau=0.13)
    ref, cdn = naive_hits(d, s, 0.13)
    assert len(hits) == len(ref) > 100
    np.testing.assert_array_equal(np.array([(a, b) for a, b, _ in ref]),
                                  np.stack([hits["start"], hits["end"]], 1))
    np.testing.assert_array_equal(hits["cost"], [c for _, _, c in ref])
    np.testing.assert_array_equal(cd, cdn)


def test_extract_hits_matches_toolbox_loop_on_random_ties():
    rng = np.random.default_rng(4)
    for trial in range(100):
        n = int(rng.integers(1, 60 if trial % 4 else 700))
        d = rng.integers(0, 6, n) / 20.0
        d[rng.random(n) < 0.2] = np.inf
        s = np.maximum(0, np.arange(n) - rng.integers(0, 8, n))
        tau = float(rng.choice([0.0, 0.1, 0.13, 1.0]))
        hits, cd = extract_hits(d, s, tau=tau, match_num_max=None)
        ref, cdn = naive_hits(d, s, tau)
        assert [tuple(h) for h in hits.tolist()] == [(a, b, c) for a, b, c in ref]
        np.testing.assert_array_equal(cd, cdn)


@pytest.mark.shared
def test_match_num_max_raises():
    d = np.zeros(10)
    s = np.arange(10)
    assert len(extract_hits(d, s, match_num_max=11)[0]) == 10
    with pytest.raises(ParameterError, match="match_num_max=10"):
        extract_hits(d, s, match_num_max=10)
    model = Model("m", [ClassModel("kick", "kick", quantized=quantized_template(
        TEMPLATES / "kickLFront1Reps"))])
    with pytest.raises(ParameterError, match=r"'kick'.*match_num_max=5.*doc_lengths\[0\].*match_num_max=None") as e:
        annotate(words("86_09"), model, match_num_max=5)
    assert "document 0" not in str(e.value)
    # the default has no limit: the same hits as the toolbox's loop without one
    hits = annotate(words("86_09"), model).hits
    assert len(hits) > 5


def test_sort_kernel_equals_stable_argsort():
    from mocapdb.annotation.chain import _sort_by_key
    rng = np.random.default_rng(6)
    for n in [0, 1, 2, 15, 16, 17, 31, 33, 64, 100, 257, 1000]:
        key = np.concatenate([rng.random(5), rng.integers(0, 7, n + 3) / 7.0])
        key[5:][rng.random(n + 3) < 0.1] = -np.inf
        idx = rng.permutation(n + 3)[:n].astype(np.int64)  # any indices, here unordered
        ref = idx[np.argsort(key[5 + idx], kind="stable")]
        got = idx.copy()
        _sort_by_key(got, np.full(n, -7, np.int64), n, key, 5)
        np.testing.assert_array_equal(got, ref)


# --- segments ---------------------------------------------------------------

def test_form_segments_matches_toolbox_algorithm_on_random_data():
    rng = np.random.default_rng(9)
    labels = ("a", "b", "c")
    for _ in range(60):
        lens = [int(x) for x in rng.integers(1, 40, int(rng.integers(1, 4)))]
        docs = []
        for n in lens:
            c = rng.integers(0, 5, (3, n)) / 10.0
            c[rng.random((3, n)) < 0.4] = np.inf
            docs.append(c)
        got = form_segments(np.concatenate(docs, axis=1), doc_lengths=lens, labels=labels)
        ref = naive_segments(docs, labels)
        assert [tuple(x)[:5] for x in got.tolist()] == [
            (lab, d, s, e, c) for lab, d, s, e, c in ref]


def test_frame_labels_ties_go_to_the_first_label():
    cd = np.array([[0.1, np.inf, 0.2, np.inf],
                   [0.1, 0.05, 0.2, np.inf]])
    dmin, arg = frame_labels(cd)
    np.testing.assert_array_equal(arg, [0, 1, 0, -1])
    np.testing.assert_array_equal(dmin, [0.1, 0.05, 0.2, np.inf])


# --- keyframe preselection (§10.1) ------------------------------------------

@pytest.mark.shared
def test_preselection_limits_delta_to_slices(model):
    w = words("86_09")
    full = annotate(w, model, keep_deltas=True)
    whole = [[(0, len(w) - 1)]] * len(model.classes)
    same = annotate(w, model, preselection=whole, keep_deltas=True)
    np.testing.assert_array_equal(same.classification_delta, full.classification_delta)
    np.testing.assert_array_equal(same.segments, full.segments)
    k = model.class_names.index("kickLFront1Reps")
    pre = {"kickLFront1Reps": [(500, 700), (650, 900)], "squat1Reps": []}
    r = annotate(w, model, preselection=pre, keep_deltas=True)
    assert np.isinf(r.delta[k, :500]).all() and np.isinf(r.delta[k, 901:]).all()
    # the later slice overwrites the overlap, as annotationScript.m does
    np.testing.assert_array_equal(r.delta[k, 500:650], mt_distance(w[500:701],
                                  model.classes[k].quantized)[:150])
    np.testing.assert_array_equal(r.delta[k, 650:901], mt_distance(w[650:901],
                                  model.classes[k].quantized))
    assert np.isinf(r.delta[model.class_names.index("squat1Reps")]).all()
    other = model.class_names.index("throwBasketball")
    np.testing.assert_array_equal(r.delta[other], full.delta[other])


@pytest.mark.shared
def test_preselection_slices_must_stay_in_one_document(model):
    ws = [words(d) for d in DOCS[:2]]
    with pytest.raises(ParameterError, match="crosses a document boundary"):
        annotate(np.concatenate(ws), model, doc_lengths=[len(x) for x in ws],
                 preselection={"squat1Reps": [(1190, 1210)]})
    with pytest.raises(ParameterError, match="unknown classes"):
        annotate(ws[0], model, preselection={"walk": []})


# --- model ------------------------------------------------------------------

@pytest.mark.shared
def test_model_validation():
    q = quantized_template(TEMPLATES / "squat1Reps")
    with pytest.raises(ParameterError, match="unique"):
        Model("m", [ClassModel("a", "x", quantized=q), ClassModel("a", "y", quantized=q)])
    with pytest.raises(ParameterError, match="lacks the class labels"):
        Model("m", [ClassModel("a", "x", quantized=q)], labels=("y",))
    with pytest.raises(ParameterError, match="needs a template"):
        ClassModel("a", "x")
    m = Model("m", [ClassModel("a", "x", quantized=q), ClassModel("b", "w", quantized=q),
                    ClassModel("c", "x", quantized=q)])
    assert m.labels == ("x", "w")
    np.testing.assert_array_equal(m.label_index, [0, 1, 0])
    assert set(CLASSES) == {c for cs in COARSE.values() for c in cs}


def test_won_frames_equals_naive_on_random_label_deltas():
    """The won-frames filter (annotation.postprocess) against a plain loop: a segment keeps its
    label's frames where that label is the first minimal finite cd, and is dropped below the need."""
    from mocapdb.annotation import SEGMENT_DTYPE, form_segments
    from mocapdb.annotation.postprocess import drop_unwon_segments, won_frames

    rng = np.random.default_rng(11)
    labels = ("a", "b", "c", "d")
    for _ in range(20):
        lengths = rng.integers(4, 120, size=3)   # short documents too: their need is capped
        cd = np.round(rng.uniform(0, 0.2, size=(4, lengths.sum())), 2)
        cd[rng.random(cd.shape) < 0.4] = np.inf
        bounds = np.concatenate(([0], np.cumsum(lengths)))
        seg = form_segments(cd, doc_lengths=lengths, labels=labels)
        want = []
        for x in seg:
            a, b = bounds[x["doc"]] + x["start"], bounds[x["doc"]] + x["end"]
            n = 0
            for f in range(a, b + 1):
                col = cd[:, f]
                if np.isfinite(col).any() and labels[int(np.argmin(col))] == x["label"]:
                    n += 1
            want.append(n)
        np.testing.assert_array_equal(won_frames(seg, cd, bounds, labels), want)
        need = rng.integers(0, 6, size=4)
        kept = drop_unwon_segments(seg, cd, bounds, labels, need)
        # in a document of n frames a label needs at most a third of ⌈n/2⌉ (postprocess.document_minimum)
        cap = [int(np.ceil(((lengths[x["doc"]] + 1) // 2) / 3 - 1e-9)) for x in seg]
        mask = np.array([w >= min(need[labels.index(x["label"])], c) for w, x, c in zip(want, seg, cap)], dtype=bool)
        np.testing.assert_array_equal(kept, seg[mask] if seg.size else seg)
        assert kept.dtype == SEGMENT_DTYPE


def test_margin_equals_naive_on_random_label_deltas():
    """The margin filter (annotation.postprocess) against a plain loop: a frame whose best label beats
    the second best by less than the margin loses every label; single finite labels stay."""
    from mocapdb.annotation.postprocess import apply_margin

    rng = np.random.default_rng(7)
    for _ in range(20):
        cd = np.round(rng.uniform(0, 0.2, size=(5, 200)), 2)
        cd[rng.random(cd.shape) < 0.5] = np.inf
        margin = float(rng.choice([0.0, 0.01, 0.03]))
        want = cd.copy()
        for f in range(cd.shape[1]):
            col = np.sort(cd[:, f])
            if np.isfinite(col[0]) and col[1] - col[0] < margin:
                want[:, f] = np.inf
        np.testing.assert_array_equal(apply_margin(np.ascontiguousarray(cd.copy()), margin), want)
