"""Query by example on arrays (mocapdb.retrieval): kernels against naive twins, the search's invariants
on real clips, and retrieval quality on held-out actors."""
import numpy as np
import pytest

from mocapdb.errors import ParameterError
from lab.retrieval import class_scores, loao_retrieval, precision_at, r_precision, relevance
from mocapdb.features import FEATURE_NAMES, FEATURE_SETS, mirror_words, unpack_words
from mocapdb.keyframes import build_index, keyframe_search
from mocapdb.learning import read_clip
from mocapdb.retrieval import (RESULT_DTYPE, archive_sample, chance_cost, clip_template, examples_template,
                               feature_frequencies, feature_mask, information_weights, mirror_template, plan_query,
                               preselect, rank_slices, sample_step, search_documents, select_hits)
from mocapdb.retrieval.archive import index_sample, index_words
from mocapdb.templates import QuantizedTemplate, mt_distance, subsequence_dtw, weighted_cost_tables

from conftest import DATA
from naive_retrieval import naive_select_hits, naive_weighted_costs, naive_words_of_runs

CLASSES = ("kickLFront1Reps", "rotateArmsBothBackward1Reps", "hopBothLegs1hops", "squat1Reps")


# ---------------------------------------------------------------------------
# kernels against their naive twins (random data: no ../shared needed)


def _random_delta(rng, n_tasks=6, n_max=120, K=9):
    lengths = rng.integers(0, n_max, n_tasks)
    offsets = np.concatenate(([0], np.cumsum(lengths)))
    first = offsets[:-1] + 1000 * np.arange(n_tasks)  # word indices of each task's first frame
    delta = rng.uniform(0.0, 0.5, offsets[-1])
    delta[rng.random(offsets[-1]) < 0.2] = np.inf
    delta[rng.random(offsets[-1]) < 0.2] = 0.25  # ties
    local = np.concatenate([np.arange(n) for n in lengths]) if offsets[-1] else np.zeros(0, int)
    span = rng.integers(0, K, offsets[-1])
    starts = np.repeat(first, lengths) + np.maximum(0, local - span)
    return delta, starts, offsets, first


@pytest.mark.parametrize("seed", range(8))
def test_select_hits_equals_naive(seed):
    rng = np.random.default_rng(seed)
    delta, starts, offsets, first = _random_delta(rng)
    taken = rng.random(delta.size) < 0.05
    for tau, limit, minima in ((0.3, 4, False), (1.0, 1000, False), (0.1, 2, False), (1.0, 1000, True),
                               (0.3, 3, True)):
        got = select_hits(delta, starts, offsets, first, tau=tau, limit=limit, taken=taken, minima=minima)
        want = naive_select_hits(delta, starts, offsets, first, tau, limit, taken, minima)
        assert [tuple(h) for h in got.tolist()] == want


def test_select_hits_never_overlap_and_respect_taken():
    rng = np.random.default_rng(99)
    delta, starts, offsets, first = _random_delta(rng, n_tasks=3, n_max=400, K=30)
    taken = np.zeros(delta.size, bool)
    taken[offsets[0]:offsets[0] + 50] = True
    hits = select_hits(delta, starts, offsets, first, tau=1.0, limit=10_000, taken=taken)
    for q in range(3):
        h = np.sort(hits[hits["task"] == q], order="start")
        assert (h["start"][1:] > h["end"][:-1]).all()
        assert not taken[offsets[q] + h["start"]].any() and not taken[offsets[q] + h["end"]].any()
        assert (h["end"] - h["start"] < 30).all()


def test_select_hits_bad_input():
    d, s, off, first = np.zeros(3), np.zeros(3, np.int64), np.array([0, 3]), np.array([0])
    with pytest.raises(ParameterError, match="tau"):
        select_hits(d, s, off, first, tau=-1, limit=3)
    with pytest.raises(ParameterError, match="limit"):
        select_hits(d, s, off, first, tau=1, limit=0)
    with pytest.raises(ParameterError, match="starts"):
        select_hits(d, np.array([0, 5, 1]), off, first, tau=1, limit=3)
    with pytest.raises(ParameterError, match="NaN"):
        select_hits(np.array([0, np.nan, 1]), s, off, first, tau=1, limit=3)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4))
def test_weighted_delta_equals_naive_dense_dtw(seed):
    rng = np.random.default_rng(seed)
    K, n = 11, 90
    mask = rng.integers(0, 1 << 40, K, dtype=np.uint64)
    mask[3] = 0  # an all-wildcard column costs nothing
    t = QuantizedTemplate(mask, mask & rng.integers(0, 1 << 40, K, dtype=np.uint64), rng.uniform(0.6, 1.4, K))
    words = rng.integers(0, 1 << 40, n, dtype=np.uint64)
    words[10:20] = words[10]  # runs: the kernel reuses a word's costs
    W = rng.uniform(0.0, 4.0, (K, 40))
    W[5, :] = 0.0  # a column whose features weigh nothing costs nothing
    delta, starts = mt_distance(words, t, feature_weights=[W], return_starts=True)
    C = naive_weighted_costs(t.dense(), t.weights, W, unpack_words(words).astype(float))
    want, want_starts = subsequence_dtw(C, return_starts=True)
    np.testing.assert_allclose(delta, want, rtol=1e-12, atol=1e-15)
    assert np.array_equal(starts, want_starts)
    np.testing.assert_allclose(weighted_cost_tables(t, W).sum(axis=1)[:, 0], C[:, 0] * 0 + naive_weighted_costs(
        t.dense(), t.weights, W, np.zeros((1, 40)))[:, 0], rtol=1e-12, atol=1e-15)


def test_equal_feature_weights_give_the_papers_delta():
    rng = np.random.default_rng(5)
    mask = rng.integers(0, 1 << 40, 15, dtype=np.uint64)
    t = QuantizedTemplate(mask, mask & rng.integers(0, 1 << 40, 15, dtype=np.uint64), rng.uniform(0.6, 1.4, 15))
    words = rng.integers(0, 1 << 40, 400, dtype=np.uint64)
    plain = mt_distance(words, t)
    weighted = mt_distance(words, t, feature_weights=[np.full((15, 40), 2.5)])
    assert np.array_equal(np.isfinite(plain), np.isfinite(weighted))
    np.testing.assert_allclose(weighted[np.isfinite(plain)], plain[np.isfinite(plain)], rtol=1e-12)
    with pytest.raises(ParameterError, match="feature_weights"):
        mt_distance(words, t, feature_weights=[np.ones((14, 40))])
    with pytest.raises(ParameterError, match="feature_weights"):
        mt_distance(words, t, feature_weights=[-np.ones((15, 40))])


def test_index_words_rebuild_the_documents():
    rng = np.random.default_rng(3)
    lengths = np.array([0, 57, 300, 1, 120])
    words = rng.integers(0, 4, lengths.sum(), dtype=np.uint64) << np.uint64(37)  # long runs
    index = build_index(words, doc_lengths=lengths, feature_sets=("upper", "full"))
    base = np.concatenate(([0], np.cumsum(lengths)))
    for d in range(lengths.size):
        s, n, w = index.segments("full", d)
        assert np.array_equal(naive_words_of_runs(s, n, w, lengths[d]), words[base[d]:base[d + 1]])
    doc = rng.integers(1, lengths.size, 50)
    a = (rng.random(50) * lengths[doc]).astype(int)
    b = np.minimum(lengths[doc], a + rng.integers(0, 80, 50))
    want = np.concatenate([words[base[d] + x:base[d] + y] for d, x, y in zip(doc, a, b)])
    assert np.array_equal(index_words(index, doc, a, b), want)
    assert np.array_equal(index_sample(index, 7), archive_sample(words, lengths, lengths.sum() // 7))
    with pytest.raises(ParameterError, match="within"):
        index_words(index, [1], [0], [58])


def test_feature_masks():
    assert feature_mask("all") == (1 << 40) - 1
    assert feature_mask("upper") == (1 << 14) - 1
    first, n = FEATURE_SETS["lower"]
    assert feature_mask("lower") == ((1 << n) - 1) << first
    names = f"{FEATURE_NAMES[16]}, {FEATURE_NAMES[39]}"
    assert feature_mask(names) == feature_mask([FEATURE_NAMES[16], FEATURE_NAMES[39]]) == (1 << 16) | (1 << 39)
    with pytest.raises(ParameterError, match="did you mean .*foot_left_raised_rel_y_body_min"):
        feature_mask("foot_left_raised")
    with pytest.raises(ParameterError, match="features must be"):
        feature_mask(" , ")


def test_weights_and_chance_level():
    rng = np.random.default_rng(1)
    sample = rng.integers(0, 1 << 40, 500, dtype=np.uint64) & np.uint64((1 << 40) - 2)  # feature 1 never on
    p = feature_frequencies(sample)
    assert p[0] == 1 / 502 and ((p > 0) & (p < 1)).all()
    words = np.array([0, 1, 3], np.uint64)
    t = clip_template(words, features="upper")
    w = information_weights(t, p)
    assert w.shape == (3, 40) and (w[:, 14:] == 0).all()
    assert w[1, 0] == pytest.approx(-np.log2(1 / 502)) and w[0, 0] == pytest.approx(-np.log2(501 / 502))
    assert 0 < chance_cost(t, p) < 1
    assert chance_cost(QuantizedTemplate(np.zeros(2, np.uint64), np.zeros(2, np.uint64), np.ones(2)), p) == 0


# ---------------------------------------------------------------------------
# the search on real clips


@pytest.fixture(scope="module")
def clips():
    out = {}
    for c in CLASSES:
        for p in sorted((DATA / "hdm05_cut" / c).glob("*.amc")):
            out[p.stem] = (c, read_clip(p))
    return out


@pytest.fixture(scope="module")
def archive(clips):
    """Documents of 6 clips each (as joined takes), their words and index."""
    names = list(clips)
    docs = [names[k:k + 6] for k in range(0, len(names), 6)]
    words = [np.concatenate([clips[n][1] for n in d]) for d in docs]
    lengths = np.array([len(w) for w in words])
    w = np.concatenate(words)
    return docs, w, lengths, build_index(w, doc_lengths=lengths, feature_sets=("full",))


@pytest.mark.shared
def test_results_rank_distinct_places_and_avoid_the_query(archive):
    docs, words, lengths, index = archive
    base = np.concatenate(([0], np.cumsum(lengths)))
    d, s, e = 2, 40, 95
    query = plan_query([words[base[d] + s:base[d] + e + 1]], archive_sample(words, lengths))
    hits = search_documents(words, lengths, query, limit=40, exclude=[(d, s, e)])
    assert hits.dtype == RESULT_DTYPE and 10 <= hits.size <= 40
    assert (np.diff(hits["cost"]) >= 0).all() and (hits["cost"] <= query.tau).all()
    for k in range(lengths.size):
        h = np.sort(hits[hits["doc"] == k], order="start")
        assert (h["start"][1:] > h["end"][:-1]).all() and (h["end"] < lengths[k]).all()
    mine = hits[hits["doc"] == d]
    assert not ((mine["start"] <= e) & (mine["end"] >= s)).any()
    # a match spans ½ to 2 times the query (the steps of Δ)
    n = hits["end"] - hits["start"] + 1
    assert (n >= (e - s + 1) // 2).all() and (n <= 2 * (e - s + 1)).all()
    # without the exclusion the query finds itself, at cost 0
    self_hit = search_documents(words, lengths, query, limit=1)[0]
    assert (self_hit["doc"], self_hit["start"], self_hit["end"]) == (d, s, e) and self_hit["cost"] < 1e-12


@pytest.mark.shared
def test_search_is_deterministic_and_independent_of_batching_and_coarse_pass(archive):
    docs, words, lengths, index = archive
    base = np.concatenate(([0], np.cumsum(lengths)))
    query = plan_query([words[base[1]:base[1] + 60]], archive_sample(words, lengths))
    a = search_documents(words, lengths, query, limit=15, exclude=[(1, 0, 59)])
    b = search_documents(words, lengths, query, limit=15, exclude=[(1, 0, 59)], batch_frames=500)
    c = search_documents(words, lengths, query, limit=15, exclude=[(1, 0, 59)])
    assert np.array_equal(a, b) and np.array_equal(a, c)
    # coarse to fine finds what one full-resolution pass finds, on these clips
    ta, tb = base[:-1], base[1:]
    taken = np.zeros(words.size, bool)
    taken[base[1]:base[1] + 60] = True
    fine = rank_slices(words, query, ta, tb, limit=15, taken=taken, coarse=False)
    coarse = rank_slices(words, query, ta, tb, limit=15, taken=taken)
    assert np.array_equal(fine, coarse)


@pytest.mark.shared
def test_keyframes_of_a_query_find_the_query_itself(archive, clips):
    """Whatever level, a query's own stretch lies in its preselection (its keyframes hold in it)."""
    docs, words, lengths, index = archive
    base = np.concatenate(([0], np.cumsum(lengths)))
    sample = archive_sample(words, lengths)
    for d in range(0, lengths.size, 3):
        s, e = 5, min(lengths[d] - 1, 85)
        query = plan_query([words[base[d] + s:base[d] + e + 1]], sample)
        assert query.keyframes, "no keyframes for a real clip"
        for kq in query.keyframes:
            segs = keyframe_search(index, kq, extend_left=2 * int(kq.positions[0]),
                                   extend_right=2 * (kq.template_length - 1 - int(kq.positions[-1])))
            inside = (segs.doc == d) & (segs.start <= s) & (segs.end >= e)
            assert inside.any(), (d, kq)
        segs = preselect(index, query, budget=0)  # the strictest level
        assert segs.n_frames < words.size


@pytest.mark.shared
def test_templates_from_examples_and_mirror_images(clips):
    kicks = [w for c, w in clips.values() if c == "kickLFront1Reps"][:3]
    t = examples_template(kicks)
    assert 0.05 < t.wildcard_fraction < 0.9  # shared features fixed, the rest free
    m = mirror_template(kicks[0])
    # a template of a stretch and its mirror image matches the mirror image as well as the stretch
    assert mt_distance(kicks[0], m).min() == pytest.approx(mt_distance(mirror_words(kicks[0]), m).min(), abs=1e-12)
    assert sample_step(10, 3) == 3 and sample_step(2, 16) == 1
    with pytest.raises(ParameterError, match="two or more"):
        examples_template(kicks[:1])


# ---------------------------------------------------------------------------
# quality: R-precision on held-out actors


def test_relevance_counts_each_true_segment_once():
    from mocapdb.annotation.labels import label_rows

    truth = label_rows(["a", "a", "b"], ["kick", "jump", "kick"], [0, 100, 0], [49, 199, 59])  # 0-based here
    res = np.array([(0, 0, 40, 0.1), (0, 10, 45, 0.2), (0, 120, 180, 0.3), (1, 30, 59, 0.4), (1, 0, 80, 0.5)],
                   RESULT_DTYPE)
    rel = relevance(res, truth, "kick", ["a", "b"])
    assert rel == [True, False, False, True, False]
    assert r_precision(rel, 2) == 0.5 and precision_at(rel, 5) == 0.4 and precision_at(rel, 10) == 0.2


@pytest.mark.slow
@pytest.mark.shared
def test_r_precision_on_held_out_actors(tmp_path):
    """Kicks and arm rotations of one actor find the other three actors' (the LOAO documents)."""
    from lab.documents import DocumentSet, loao_documents

    docs = DocumentSet.concat(loao_documents(DATA / "hdm05_cut", a, classes=list(CLASSES), class_labels={})
                              for a in ("bd", "bk", "dg", "mm"))
    results = loao_retrieval(docs, labels=["kickLFront1Reps", "rotateArmsBothBackward1Reps"])
    scores = {c.label: c for c in class_scores(results)}
    assert scores["kickLFront1Reps"].n_queries == 24 and scores["rotateArmsBothBackward1Reps"].n_queries == 13
    assert scores["rotateArmsBothBackward1Reps"].r_precision >= 0.9
    assert scores["kickLFront1Reps"].r_precision >= 0.7
    assert all(c.precision_at[1] >= 0.9 for c in scores.values())
