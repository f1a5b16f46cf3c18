"""The distance function Δ (TEMPLATES.md §9, §12) against the toolbox, naive DP and librosa."""
import numba
import numpy as np
import pytest

from mocapdb.errors import ParameterError
from mocapdb.templates import (
    ANNOTATION_STEPS, RETRIEVAL_STEPS, cost_table, mt_distance, mt_distance_slices,
    subsequence_dtw)
from mocapdb.templates import QuantizedTemplate
from naive_dtw import naive_cost_matrix, naive_subsequence_dtw
from template_oracle import (
    ANNOTATION, DOCS, SQUAT, TEMPLATES, csv_matrix, csv_table, features, quantized_template,
    words)


def _assert_delta(got, ref):
    """Same +inf positions, finite values within 1e-9."""
    np.testing.assert_array_equal(np.isinf(got), np.isinf(ref))
    fin = np.isfinite(ref)
    assert np.abs(got[fin] - ref[fin]).max(initial=0.0) <= 1e-9


@pytest.mark.shared
def test_squat_delta_on_86_09_reproduces_toolbox():
    ref = csv_matrix(SQUAT / "delta_86_09.csv").ravel()
    got = mt_distance(words("86_09"), quantized_template(SQUAT))
    assert got.shape == ref.shape == (1199,)
    _assert_delta(got, ref)
    assert np.isinf(got[:21]).all() and np.isfinite(got[21:]).all()


@pytest.mark.shared
@pytest.mark.parametrize("doc", DOCS)
def test_all_classes_delta_reproduces_toolbox(doc):
    header, ref = csv_table(ANNOTATION / doc / "delta_fine.csv")
    got = mt_distance(words(doc), [quantized_template(TEMPLATES / c) for c in header])
    assert got.shape == ref.T.shape
    _assert_delta(got, ref.T)


# --- kernel vs naive --------------------------------------------------------

def _random_template(rng, K):
    mask = rng.integers(0, 1 << 40, K, dtype=np.uint64)
    # sparse masks and all-wildcard columns
    mask &= rng.integers(0, 1 << 40, K, dtype=np.uint64)
    mask[rng.random(K) < 0.2] = 0
    value = mask & rng.integers(0, 1 << 40, K, dtype=np.uint64)
    return QuantizedTemplate(mask, value, rng.choice([.75, .875, 1.0, 1.25, 1.4], K))


def _random_words(rng, m):
    # few distinct words: many exact ties in C and D
    pool = rng.integers(0, 1 << 40, 4, dtype=np.uint64)
    return pool[rng.integers(0, 4, m)]


def _naive(q, w, steps, rule):
    from mocapdb.features import unpack_words
    C = naive_cost_matrix(q.dense(), q.weights, unpack_words(w))
    return naive_subsequence_dtw(C, steps, rule)


@pytest.mark.slow
@pytest.mark.parametrize("rule", ["toolbox", "textbook"])
@pytest.mark.parametrize("steps", [ANNOTATION_STEPS, RETRIEVAL_STEPS,
                                   ((1, 1, 1.0), (2, 3, 0.5), (1, 2, 3.0), (3, 1, 1.5)),
                                   # 1 and 2 steps run the 3-step path, padded
                                   ((1, 1, 1.0),), ((1, 2, 1.0), (0, 1, 0.5)),
                                   # dj = 0 twice, dj up to 3: the ring's other shapes
                                   ((1, 0, 1.0), (1, 1, 2.0), (2, 0, 0.5)),
                                   ((1, 3, 1.0), (1, 1, 1.0), (2, 1, 2.0))])
def test_kernel_matches_naive_on_random_data(rule, steps):
    rng = np.random.default_rng([len(rule), len(steps), int(sum(s[1] for s in steps))])
    for trial in range(40):
        K = int(rng.choice([1, 2, 3, 5, 8, 13]))
        m = int(rng.integers(0, 40))  # includes documents shorter than the template
        q = _random_template(rng, K)
        w = _random_words(rng, m)
        d, s = mt_distance(w, q, steps=steps, rule=rule, return_starts=True, chunk_size=7)
        dn, sn, _ = _naive(q, w, steps, rule)
        np.testing.assert_array_equal(d, dn)
        np.testing.assert_array_equal(s, sn)


@pytest.mark.shared
@pytest.mark.parametrize("rule", ["toolbox", "textbook"])
def test_kernel_matches_naive_on_real_data(rule):
    w = words("02_04")
    for cls in ("squat1Reps", "hopBothLegs1hops", "kickLFront1Reps"):
        q = quantized_template(TEMPLATES / cls)
        d, s = mt_distance(w, q, rule=rule, return_starts=True)
        dn, sn, _ = _naive(q, w, ANNOTATION_STEPS, rule)
        np.testing.assert_array_equal(d, dn)
        np.testing.assert_array_equal(s, sn)


@pytest.mark.shared
def test_cost_table_matches_naive_cost():
    q = quantized_template(TEMPLATES / "kickLFront1Reps")
    w = words("02_01")
    C = naive_cost_matrix(q.dense(), q.weights, features("02_01"))
    T = cost_table(q)
    pc = np.bitwise_count((q.value[:, None] ^ w[None, :]) & q.mask[:, None])
    np.testing.assert_array_equal(T[np.arange(len(q))[:, None], pc], C)
    assert (T[:, 0] == 0).all()


# --- chunking, threads, documents -------------------------------------------

@pytest.mark.shared
def test_chunked_and_parallel_equal_serial():
    w = np.concatenate([words(d) for d in DOCS])
    qs = [quantized_template(TEMPLATES / c)
          for c in ("lieDownFloor", "rotateArmsBothBackward1Reps", "throwBasketball")]
    ref_d, ref_s = mt_distance(w, qs, return_starts=True, chunk_size=len(w))
    old = numba.get_num_threads()
    try:
        for threads in {1, old}:
            numba.set_num_threads(threads)
            for chunk in (2, 17, 333):
                d, s = mt_distance(w, qs, return_starts=True, chunk_size=chunk)
                np.testing.assert_array_equal(d, ref_d)
                np.testing.assert_array_equal(s, ref_s)
    finally:
        numba.set_num_threads(old)


@pytest.mark.shared
def test_documents_are_independent():
    ws = [words(d) for d in DOCS]
    qs = [quantized_template(TEMPLATES / c) for c in ("sneak2StepsLStart", "hopBothLegs1hops")]
    d, s = mt_distance(np.concatenate(ws), qs, doc_lengths=[len(x) for x in ws],
                       return_starts=True, chunk_size=50)
    pos = 0
    for x in ws:
        dd, ss = mt_distance(x, qs, return_starts=True)
        np.testing.assert_array_equal(d[:, pos:pos + len(x)], dd)
        np.testing.assert_array_equal(s[:, pos:pos + len(x)], np.where(ss >= 0, ss + pos, -1))
        pos += len(x)


@pytest.mark.shared
def test_slices_equal_separate_documents():
    w = words("86_09")
    q = quantized_template(TEMPLATES / "grabHighR")
    delta, off, starts = mt_distance_slices(w, [q], [0, 0, 0], [100, 400, 390], [500, 460, 1199],
                                            return_starts=True, chunk_size=64)
    for k, (a, b) in enumerate([(100, 500), (400, 460), (390, 1199)]):
        d, s = mt_distance(w[a:b], q, return_starts=True)
        np.testing.assert_array_equal(delta[off[k]:off[k + 1]], d)
        np.testing.assert_array_equal(starts[off[k]:off[k + 1]], np.where(s >= 0, s + a, -1))


# --- the two rules ----------------------------------------------------------

@pytest.mark.shared
def test_textbook_is_never_above_toolbox_and_equal_for_equal_weights():
    w = words("86_09")
    q = quantized_template(SQUAT)
    tool = mt_distance(w, q)
    text = mt_distance(w, q, rule="textbook")
    fin = np.isfinite(tool)
    assert (text[fin] <= tool[fin]).all() and (text[fin] < tool[fin]).mean() > 0.9
    eq = ((1, 1, 1.0), (1, 2, 1.0), (2, 1, 1.0))
    np.testing.assert_array_equal(mt_distance(w, q, steps=eq),
                                  mt_distance(w, q, steps=eq, rule="textbook"))


@pytest.mark.slow
@pytest.mark.shared
def test_textbook_rule_equals_librosa():
    import librosa
    sigma = np.array([[1, 1], [1, 2], [2, 1]])
    wmul = np.array([1.0, 1.0, 2.0])
    rng = np.random.default_rng(2)
    cases = [(quantized_template(SQUAT), words("86_09")),
             (quantized_template(TEMPLATES / "depositFloorR"), words("02_06"))]
    cases += [(_random_template(rng, int(k)), _random_words(rng, 60)) for k in (1, 2, 7)]
    for q, w in cases:
        C = naive_cost_matrix(q.dense(), q.weights, features_of(w))
        D, steps = librosa.sequence.dtw(C=C, subseq=True, step_sizes_sigma=sigma,
                                        weights_mul=wmul, backtrack=False, return_steps=True)
        d, s = mt_distance(w, q, rule="textbook", return_starts=True)
        np.testing.assert_array_equal(d, D[-1])
        np.testing.assert_array_equal(subsequence_dtw(C, rule="textbook"), D[-1])
        for e in np.flatnonzero(np.isfinite(d))[::37]:
            wp = librosa.sequence.dtw_backtracking(steps, step_sizes_sigma=sigma, subseq=True,
                                                   start=int(e))
            assert s[e] == wp[-1][1]


def features_of(w):
    from mocapdb.features import unpack_words
    return unpack_words(w)


@pytest.mark.shared
def test_dense_and_packed_kernels_agree():
    q = quantized_template(TEMPLATES / "jogLeftCircle4StepsRstart")
    w = words("02_06")
    C = naive_cost_matrix(q.dense(), q.weights, features("02_06"))
    for rule in ("toolbox", "textbook"):
        d, s = subsequence_dtw(C, rule=rule, return_starts=True)
        d2, s2 = mt_distance(w, q, rule=rule, return_starts=True)
        np.testing.assert_array_equal(d, d2)
        np.testing.assert_array_equal(s, s2)


# --- validation -------------------------------------------------------------

@pytest.mark.shared
def test_bad_input_raises_parameter_errors():
    q = quantized_template(SQUAT)
    w = words("02_01")
    with pytest.raises(ParameterError, match="rule"):
        mt_distance(w, q, rule="fast")
    with pytest.raises(ParameterError, match="not both 0"):
        mt_distance(w, q, steps=((0, 0, 1.0),))
    with pytest.raises(ParameterError, match="positive"):
        mt_distance(w, q, steps=((1, 1, 0.0),))
    with pytest.raises(ParameterError, match="doc_lengths"):
        mt_distance(w, q, doc_lengths=[10, 10])
    with pytest.raises(ParameterError, match="QuantizedTemplate"):
        mt_distance(w, [q, "squat"])
    with pytest.raises(ParameterError, match="words"):
        mt_distance(np.zeros((3, 40)), q)
    with pytest.raises(ParameterError, match="slices"):
        mt_distance_slices(w, [q], [0], [5], [len(w) + 1])
    with pytest.raises(ParameterError, match="NaN"):
        subsequence_dtw(np.array([[np.nan, 1.0]]))
