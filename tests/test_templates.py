"""Motion template learning and quantization (TEMPLATES.md §3–§8) against the toolbox."""
import numpy as np
import pytest

from mocapdb.errors import ParameterError
from mocapdb.features import pack_words
from mocapdb.templates import (
    MotionTemplate, QuantizedTemplate, average_step, balance_weighted, contract_weighted,
    expand_weighted, learn_template, quantize, weighted_dtw)
from naive_dtw import naive_average_step, naive_contract, naive_weighted_dtw
from template_oracle import (
    CLASSES, SQUAT, TEMPLATES, csv_matrix, features, quantized_template, real_template, stats,
    training_clips)

# bit-identity is the target; 1e-12 still catches every tie-breaking slip
# (a wrong tie moves entries of the learned template by ~0.06)
EXACT = 1e-12


def _assert_template(mt, folder, st):
    real, weights = real_template(folder)
    assert mt.real.shape == real.shape
    assert np.abs(mt.real - real).max() <= EXACT
    assert np.abs(mt.weights - weights).max() <= EXACT
    assert mt.iterations == int(st["iter_num"][0])
    for key, ours in (("iter_error_max", mt.error_max), ("iter_error_mean", mt.error_mean),
                      ("iter_error_std", mt.error_std)):
        ref = np.array(st[key], dtype=float)
        assert ours.shape == ref.shape
        np.testing.assert_allclose(ours, ref, rtol=1e-12, atol=0, err_msg=key)


def _assert_quantized(q, folder):
    ref = quantized_template(folder)
    assert len(q) == len(ref)
    np.testing.assert_array_equal(q.mask, ref.mask)
    np.testing.assert_array_equal(q.value, ref.value)
    np.testing.assert_array_equal(q.weights, ref.weights)
    np.testing.assert_array_equal(q.dense(), csv_matrix(folder / "template_quantized_0.05.csv").T)


@pytest.mark.shared
def test_squat_template_reproduces_toolbox():
    st = stats(SQUAT / "template_stats.txt")
    clips = [features(s) for s in st["training_files(order)"]]
    assert len(clips) == 40
    mt = learn_template(clips)
    assert mt.n_clips == 40
    _assert_template(mt, SQUAT, st)
    _assert_quantized(mt.quantize(0.05), SQUAT)


@pytest.mark.slow
@pytest.mark.shared
@pytest.mark.parametrize("cls", CLASSES)
def test_class_templates_reproduce_toolbox(cls):
    folder = TEMPLATES / cls
    mt = learn_template([features(s) for s in training_clips(cls)])
    _assert_template(mt, folder, stats(folder / "template_stats.txt"))
    _assert_quantized(mt.quantize(0.05), folder)


@pytest.mark.shared
def test_packed_words_and_bool_clips_learn_the_same_template():
    clips = [features(s) for s in training_clips("rotateArmsBothBackward1Reps")]
    a = learn_template(clips)
    b = learn_template([pack_words(c) for c in clips])
    np.testing.assert_array_equal(a.real, b.real)
    np.testing.assert_array_equal(a.weights, b.weights)


# --- §6 balancing: worked examples from the text ---------------------------

def test_contraction_worked_example():
    X, w = contract_weighted(np.ones((7, 1)), [1, .5, .125, .125, 1, .25, .4])
    np.testing.assert_array_equal(w, [1, .75, 1.65])
    np.testing.assert_array_equal(X, np.ones((3, 1)))


def test_contraction_right_border_drops_earlier_group_members():
    # [1 | .5 .5 | .3]: the last column is too light, so it joins the last input
    # column of the previous output (.5); that group replaces the previous output
    # column [.5 .5] and the first .5 (value 10) is lost.
    X = np.array([[1.0], [10.0], [20.0], [30.0]])
    Xo, wo = contract_weighted(X, [1, .5, .5, .3])
    np.testing.assert_array_equal(wo, [1, .3 + .5])
    np.testing.assert_array_equal(Xo[:, 0], [1.0, (.5 * 20 + .3 * 30) / (.3 + .5)])


def test_contraction_border_at_first_column_emits_one_column():
    Xo, wo = contract_weighted(np.array([[1.0], [0.0]]), [.2, .3])
    np.testing.assert_array_equal(wo, [.5])
    np.testing.assert_array_equal(Xo[:, 0], [.2 / .5])


def test_contraction_matches_naive_on_random_weights():
    rng = np.random.default_rng(7)
    for _ in range(200):
        n = int(rng.integers(1, 12))
        w = rng.choice([.05, .125, .25, .3, .5, .7, .75, 1.0, 1.4], size=n)
        X = rng.random((n, 3))
        Xo, wo = contract_weighted(X, w)
        Xn, wn = naive_contract(X, w)
        np.testing.assert_array_equal(wo, wn)
        np.testing.assert_array_equal(Xo, Xn)


def test_expand_uses_matlab_rounding():
    X = np.arange(5.0)[:, None]
    w = np.array([0.4, 1.5, 2.5, 2.49, 0.5])
    Xo, wo = expand_weighted(X, w)
    # max(1, round): 1, 2, 3 (banker's rounding would give 2), 2, 1
    np.testing.assert_array_equal(Xo[:, 0], [0, 1, 1, 2, 2, 2, 3, 3, 4])
    np.testing.assert_array_equal(wo, [0.4, .75, .75, 2.5 / 3, 2.5 / 3, 2.5 / 3, 1.245, 1.245, .5])


def test_balance_keeps_weights_in_range():
    rng = np.random.default_rng(3)
    for _ in range(50):
        n = int(rng.integers(2, 30))
        w = rng.uniform(0.05, 3.0, n)
        _, wo = balance_weighted(rng.random((n, 2)), w)
        # except the degenerate border case, weights lie in [0.75, 1.5)
        if wo.size > 1:
            assert ((wo >= 0.75) & (wo < 1.5)).all()


# --- §7 stopping rule -------------------------------------------------------

def _stop_reason(mt, iter_max, iter_thresh):
    e = mt.error_max
    if e[-1] <= iter_thresh:
        return "threshold"
    if len(e) >= 2 and e[-1] == e[-2]:
        return "unchanged"
    return "iter_max" if mt.iterations == iter_max else "?"


@pytest.mark.slow
def test_stop_when_error_unchanged():
    # Three clips that are not mutually alignable at zero cost: the templates
    # reach a fixed point with a positive error, which then repeats exactly.
    rng = np.random.default_rng(11)
    found = False
    for _ in range(20):
        clips = [rng.random((int(rng.integers(4, 9)), 40)) < 0.5 for _ in range(3)]
        mt = learn_template(clips, iter_max=30, iter_thresh=0.0)
        e = mt.error_max
        assert mt.iterations == len(e)
        # the loop never continues past a threshold hit or a repeated error
        assert all(e[k] > 0.0 for k in range(len(e) - 1))
        assert all(e[k] != e[k - 1] for k in range(1, len(e) - 1))
        if _stop_reason(mt, 30, 0.0) == "unchanged" and mt.iterations < 30:
            found = True
    assert found, "no seeded example stopped on an unchanged error"


@pytest.mark.shared
def test_stop_on_threshold_and_iter_max():
    clips = [features(s) for s in training_clips("rotateArmsBothBackward1Reps")]
    mt = learn_template(clips, iter_max=2)
    assert mt.iterations == 2 and mt.error_max[-1] > 0.005
    same = [features(training_clips("squat1Reps")[0])] * 3
    mt = learn_template(same)
    assert mt.iterations == 1 and mt.error_max[0] == 0.0
    np.testing.assert_array_equal(mt.real, same[0].astype(float))


# --- kernels vs naive -------------------------------------------------------

def test_weighted_dtw_matches_naive():
    rng = np.random.default_rng(5)
    for _ in range(30):
        n, m = int(rng.integers(1, 9)), int(rng.integers(1, 9))
        # quarter steps make exact ties frequent
        V = rng.integers(0, 5, (n, 40)) / 4
        W = rng.integers(0, 5, (m, 40)) / 4
        wV = rng.choice([.75, 1.0, 1.25], n)
        wW = rng.choice([.75, 1.0, 1.25], m)
        got = weighted_dtw(V, W, v_weights=wV, w_weights=wW)
        ref = naive_weighted_dtw(V, W, wV, wW)
        np.testing.assert_array_equal(got[0], ref[0])
        np.testing.assert_array_equal(got[1], ref[1])
        assert got[2] == ref[2]


def test_every_reference_of_an_iteration_matches_naive():
    # one iteration runs each pair's DP once and reads it in both orientations;
    # quarter values and equal weights make ties in both orientations frequent
    from mocapdb.templates.averaging import _averaging_iteration, _pack_sequences
    rng = np.random.default_rng(13)
    for _ in range(6):
        seqs = [rng.integers(0, 3, (int(rng.integers(1, 8)), 40)) / 2 for _ in range(4)]
        ws = [rng.choice([.75, 1.0], len(x)) for x in seqs]
        X, w, off = _pack_sequences(seqs, ws)
        T, wT, costs = _averaging_iteration(X, w, off)
        for r in range(4):
            order = [r] + [k for k in range(4) if k != r]
            Tn, wn, cn = naive_average_step([seqs[k] for k in order], [ws[k] for k in order])
            np.testing.assert_array_equal(T[off[r]:off[r + 1]], Tn)
            np.testing.assert_array_equal(wT[off[r]:off[r + 1]], wn)
            np.testing.assert_array_equal(costs[:, r], cn)


@pytest.mark.slow
@pytest.mark.shared
def test_average_step_matches_naive_on_real_clips():
    clips = [features(s).astype(float) for s in training_clips("hopBothLegs1hops")[:5]]
    ws = [np.ones(len(c)) for c in clips]
    T, wT, c = average_step(clips, ws)
    Tn, wn, cn = naive_average_step(clips, ws)
    np.testing.assert_array_equal(T, Tn)
    np.testing.assert_array_equal(wT, wn)
    np.testing.assert_array_equal(c, cn)


# --- quantization -----------------------------------------------------------

def test_quantize_thresholds_and_packing():
    real = np.zeros((3, 40))
    real[0, :4] = [0.05, 0.95, 0.050001, 0.949999]
    real[1, :] = 1.0
    real[2, :] = 0.5
    q = quantize(real, np.ones(3), delta=0.05)
    d = q.dense()
    np.testing.assert_array_equal(d[0, :4], [0, 1, .5, .5])
    assert (d[1] == 1).all() and (d[2] == .5).all()
    assert q.mask[2] == 0 and q.value[2] == 0
    assert q.mask[1] == (1 << 40) - 1 == q.value[1]
    assert int(q.value[0]) & ~int(q.mask[0]) == 0
    assert q.wildcard_fraction == pytest.approx((2 + 40) / 120)
    # δ = 0: only exact 0 / 1 stay fixed
    d0 = quantize(real, np.ones(3), delta=0).dense()
    np.testing.assert_array_equal(d0[0, :4], [.5, .5, .5, .5])


def test_quantized_expand_repeats_heavy_columns():
    q = QuantizedTemplate(np.array([1, 3], np.uint64), np.array([1, 2], np.uint64),
                          np.array([1.2, 2.5]))
    e = q.expand()
    np.testing.assert_array_equal(e.mask, [1, 3, 3, 3])
    np.testing.assert_array_equal(e.weights, [1.2, 2.5 / 3, 2.5 / 3, 2.5 / 3])
    r = QuantizedTemplate.from_dense(e.dense(), e.weights)
    np.testing.assert_array_equal(r.value, e.value)


# --- validation -------------------------------------------------------------

def test_bad_input_raises_parameter_errors():
    with pytest.raises(ParameterError, match="at least one clip"):
        learn_template([])
    with pytest.raises(ParameterError, match=r"shape \(n_frames, 40\)"):
        learn_template([np.zeros((5, 39), bool)])
    with pytest.raises(ParameterError, match="no frames"):
        learn_template([np.zeros((0, 40), bool)])
    with pytest.raises(ParameterError, match="iter_max"):
        learn_template([np.zeros((5, 40), bool)], iter_max=0)
    with pytest.raises(ParameterError, match="delta"):
        quantize(np.zeros((2, 40)), np.ones(2), delta=0.5)
    with pytest.raises(ParameterError, match="subset of mask"):
        QuantizedTemplate(np.array([1], np.uint64), np.array([2], np.uint64), np.ones(1))
    with pytest.raises(ParameterError, match="only 0, 1 and 0.5"):
        QuantizedTemplate.from_dense(np.full((1, 40), 0.3), np.ones(1))
    with pytest.raises(ParameterError, match="weights"):
        MotionTemplate(np.zeros((2, 40)), np.array([1.0, -1.0]))
