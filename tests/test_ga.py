"""Genetic learning of keyframe queries (paper Sect. 6, KEYFRAMES.md §8.2).

Real clips: four classes of ../shared/data/hdm05_cut (two similar locomotion
classes, a jump and a kick).  Small populations and few generations keep the
file fast; the full-size figures are in benchmarks/bench_ga.py.
"""
import numpy as np
import pytest

from mocapdb import learning as ga
from mocapdb.learning import ga_operators
from mocapdb.errors import ParameterError
from mocapdb.features import N_FEATURES
from mocapdb.keyframes import build_index
from mocapdb.keyframes import KeyframeQuery, keyframe_search
from mocapdb.templates import learn_template
from mocapdb.learning.class_templates import clips_from_folders

CLASSES = ["hopBothLegs1hops", "jogLeftCircle4StepsRstart", "kickLFront1Reps",
           "sneak2StepsLStart"]
SMALL = {"population_size": 16, "generations": 12}


@pytest.fixture(scope="module")
def clips(data_dir):
    return {c: [w for _, w in v]
            for c, v in clips_from_folders(data_dir / "hdm05_cut", classes=CLASSES).items()}


@pytest.fixture(scope="module")
def train(clips):
    """(index, labels, templates) over all clips of CLASSES, in class order."""
    words = [w for c in CLASSES for w in clips[c]]
    labels = np.array([i for i, c in enumerate(CLASSES) for _ in clips[c]])
    templates = {c: learn_template(clips[c]) for c in CLASSES}
    return ga.training_index(words), labels, templates


def evolve(train, cls, *, seed, **params):
    index, labels, templates = train
    ci = CLASSES.index(cls)
    return ga.evolve_keyframes(np.flatnonzero(labels == ci), np.flatnonzero(labels != ci),
                               template=templates[cls], index=index, random_state=seed,
                               **{**SMALL, **params})


def query_state(q):
    return [a.tolist() for a in (q.mask, q.value, q.positions, q.d_min, q.d_max)]


def stats_state(s):
    return [getattr(s, f).tolist() for f in ga.GAStatistics.__dataclass_fields__]


def check_valid(q, L):
    """Invariants every individual must keep."""
    assert isinstance(q, KeyframeQuery)
    K = q.n_keyframes
    assert K >= 1
    assert q.feature_sets == (None,) * K
    assert q.template_length == L
    assert (np.diff(q.positions) >= 0).all()
    assert q.positions.min() >= 0 and q.positions.max() < L
    assert len(q.d_min) == len(q.d_max) == K - 1
    assert (q.d_min >= 0).all() and (q.d_min <= q.d_max).all()
    assert (q.mask < np.uint64(1 << N_FEATURES)).all()
    assert not (q.value & ~q.mask).any()


# --------------------------------------------------------------------------
# whole runs


@pytest.mark.slow
@pytest.mark.shared
def test_reproducible_from_seed(train):
    a = evolve(train, "kickLFront1Reps", seed=7)
    b = evolve(train, "kickLFront1Reps", seed=7)
    c = evolve(train, "kickLFront1Reps", seed=8)
    assert query_state(a.query) == query_state(b.query)
    assert stats_state(a.statistics) == stats_state(b.statistics)
    assert [query_state(q) for q in a.population] == [query_state(q) for q in b.population]
    assert a.population_fitness.tolist() == b.population_fitness.tolist()
    # another seed gives another run
    assert [query_state(q) for q in a.population] != [query_state(q) for q in c.population]
    assert stats_state(a.statistics) != stats_state(c.statistics)


@pytest.mark.shared
@pytest.mark.parametrize("ties", ["fewest_fixed", "offspring"])
def test_elitist_survival_and_rising_precision(train, ties):
    r = evolve(train, "kickLFront1Reps", seed=3, generations=25, ties=ties)
    s = r.statistics
    assert s.generations == 25
    assert len(s.mean_precision) == 26
    # elitist (M + λ) survival: the best and every rank never get worse
    assert (np.diff(s.best_fitness) >= 0).all()
    assert (np.diff(s.mean_fitness) >= -1e-12).all()
    # from the wildcard-rich δ = 0 template columns to discriminative queries
    assert s.mean_precision[-1] > s.mean_precision[0] + 0.1
    assert s.best_fitness[-1] == r.fitness == r.population_fitness.max()
    assert r.n_evaluations == 16 + 25 * 10
    assert (np.diff(r.population_fitness) <= 0).all()


@pytest.mark.shared
def test_population_is_valid_and_scores_equal_brute_force(train, clips):
    """Every individual is a valid query; its P/R/Fit equal a per-clip search."""
    index, labels, templates = train
    cls = "hopBothLegs1hops"
    r = evolve(train, cls, seed=11)
    words = [w for c in CLASSES for w in clips[c]]
    L = len(templates[cls])
    one_clip = [build_index([w]) for w in words]  # the toolbox's per-set layout
    positive = labels == CLASSES.index(cls)
    for q, p, rc, f in zip(r.population, r.population_precision, r.population_recall,
                           r.population_fitness):
        check_valid(q, L)
        hit = np.array([len(keyframe_search(ix, q)) > 0 for ix in one_clip])
        tp = int((hit & positive).sum())
        P = tp / hit.sum() if hit.any() else 0.0
        R = tp / positive.sum()
        F = 5 * P * R / (4 * P + R) if P + R > 0 else 0.0
        assert p == pytest.approx(P, abs=1e-12)
        assert rc == pytest.approx(R, abs=1e-12)
        assert f == pytest.approx(F, abs=1e-12)


@pytest.mark.shared
def test_clips_instead_of_index(clips, train):
    """Clip lists (T+, T-) build their own index and template: same run."""
    cls = "sneak2StepsLStart"
    neg = [w for c in CLASSES if c != cls for w in clips[c]]
    a = ga.evolve_keyframes(clips[cls], neg, random_state=5, **SMALL)
    b = ga.evolve_keyframes(clips[cls], neg, template=train[2][cls], random_state=5, **SMALL)
    assert query_state(a.query) == query_state(b.query)
    # the index over positive + negative in that order equals the shared one on T
    index, labels, templates = train
    order = np.concatenate([np.flatnonzero(labels == CLASSES.index(cls)),
                            np.flatnonzero(labels != CLASSES.index(cls))])
    c = ga.evolve_keyframes(order[:len(clips[cls])], order[len(clips[cls]):],
                            template=templates[cls], index=index, random_state=5, **SMALL)
    assert stats_state(a.statistics) == stats_state(c.statistics)


@pytest.mark.slow
@pytest.mark.shared
def test_learn_queries_progress_seeds_and_jobs(clips):
    calls = []
    params = {"population_size": 8, "generations": 3}
    res = ga.learn_keyframe_queries(clips, runs=3, random_state=1, n_jobs=1,
                                    progress=lambda *a: calls.append(a), **params)
    assert list(res) == CLASSES
    assert sorted(calls) == sorted((c, k, 3) for c in CLASSES for k in (1, 2, 3))
    for c, lq in res.items():
        assert len(lq.runs) == 3 and lq.consensus.shape == (3,)
        assert lq.query is lq.runs[lq.best_run].query
        assert lq.best_run == ga.consensus_pick([r.query for r in lq.runs],
                                                [r.fitness for r in lq.runs])
    # a class's runs do not depend on the other classes learned, nor on n_jobs
    one = ga.learn_keyframe_queries(clips, classes=["kickLFront1Reps"], runs=3, random_state=1,
                                    n_jobs=2, **params)
    assert list(one) == ["kickLFront1Reps"]
    for a, b in zip(one["kickLFront1Reps"].runs, res["kickLFront1Reps"].runs):
        assert query_state(a.query) == query_state(b.query)
        assert stats_state(a.statistics) == stats_state(b.statistics)
    assert ga.average_statistics(res.values()).generations == 3


@pytest.mark.shared
def test_learn_query_runs_are_independent_children(train):
    index, labels, templates = train
    pos, neg = np.flatnonzero(labels == 0), np.flatnonzero(labels != 0)
    lq = ga.learn_keyframe_query(pos, neg, template=templates[CLASSES[0]], index=index, runs=2,
                                 random_state=4, n_jobs=1, **SMALL)
    child = np.random.default_rng(4).spawn(2)[1]
    r1 = ga.evolve_keyframes(pos, neg, template=templates[CLASSES[0]], index=index,
                             random_state=child, **SMALL)
    assert stats_state(lq.runs[1].statistics) == stats_state(r1.statistics)
    assert stats_state(lq.runs[0].statistics) != stats_state(r1.statistics)


@pytest.mark.shared
def test_parameter_errors(train, clips):
    index, labels, templates = train
    t = templates[CLASSES[0]]
    with pytest.raises(ParameterError, match="population_size"):
        ga.evolve_keyframes([0], [1], template=t, index=index, population_size=0)
    with pytest.raises(ParameterError, match="n_parents"):
        ga.evolve_keyframes([0], [1], template=t, index=index, n_parents=1)
    with pytest.raises(ParameterError, match="tolerance"):
        ga.evolve_keyframes([0], [1], template=t, index=index, tolerance=(1.0, 0.2))
    with pytest.raises(ParameterError, match="ties"):
        ga.evolve_keyframes([0], [1], template=t, index=index, ties="random")
    with pytest.raises(ParameterError, match="template="):
        ga.evolve_keyframes([0], [1], index=index)
    with pytest.raises(ParameterError, match="disjoint"):
        ga.evolve_keyframes([0, 1], [1], template=t, index=index)
    with pytest.raises(ParameterError, match="outside"):
        ga.evolve_keyframes([0], [10**6], template=t, index=index)
    with pytest.raises(ParameterError, match="uint64"):
        ga.evolve_keyframes([np.zeros(5)], [], template=t)
    with pytest.raises(ParameterError, match="unknown GA parameter"):
        ga.learn_keyframe_query([0], [1], template=t, index=index, generation=3)
    with pytest.raises(ParameterError, match="runs"):
        ga.learn_keyframe_query([0], [1], template=t, index=index, runs=0)
    with pytest.raises(ParameterError, match="not in clips_by_class"):
        ga.learn_keyframe_queries(clips, classes=["nope"])


# --------------------------------------------------------------------------
# fitness


def test_f_beta_and_document_fitness():
    assert ga.f_beta(0.5, 1.0) == pytest.approx(5 * 0.5 / (4 * 0.5 + 1))
    assert ga.f_beta(1.0, 0.5, beta=1.0) == pytest.approx(2 / 3)
    assert ga.f_beta(0.0, 0.0) == 0.0
    relevant = np.array([1, 1, 1, 0, 0, 0, 0], bool)
    hits = np.array([[1, 1, 0, 1, 0, 0, 0],    # P 2/3, R 2/3
                     [0, 0, 0, 0, 0, 0, 0],    # nothing hit: 0
                     [0, 0, 0, 1, 1, 0, 0],    # only negatives: 0
                     [1, 1, 1, 1, 1, 1, 1]],   # everything
                    bool)
    P, R, F = ga.fitness_from_hits(hits, relevant)
    assert P.tolist() == pytest.approx([2 / 3, 0, 0, 3 / 7])
    assert R.tolist() == pytest.approx([2 / 3, 0, 0, 1])
    assert F.tolist() == pytest.approx([2 / 3, 0, 0, 5 * 3 / 7 / (4 * 3 / 7 + 1)])
    # documents outside T are ignored
    docs = np.array([1, 1, 1, 0, 1, 1, 1], bool)
    P, R, F = ga.fitness_from_hits(hits[:1], relevant, documents=docs)
    assert P[0] == 1.0 and R[0] == pytest.approx(2 / 3)


# --------------------------------------------------------------------------
# selection


def test_sus_selects_proportionally():
    f = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 0.5, 7.5])
    n = 6
    expected = n * f / f.sum()
    rng = np.random.default_rng(2024)
    draws = 20000
    counts = np.zeros((draws, len(f)), np.int64)
    for t in range(draws):
        idx = ga.stochastic_universal_sampling(f, n, random_state=rng)
        assert len(idx) == n and (np.diff(idx) >= 0).all()
        counts[t] = np.bincount(idx, minlength=len(f))
    # SUS's minimal spread: every individual floor or ceil of its expectation
    assert (counts >= np.floor(expected)).all() and (counts <= np.ceil(expected)).all()
    # and unbiased: the mean count is the expectation (sd of the mean < 0.004)
    assert counts.mean(axis=0) == pytest.approx(expected, abs=0.02)
    assert counts[:, 0].sum() == 0  # zero fitness is never selected


def test_sus_all_zero_is_uniform():
    rng = np.random.default_rng(5)
    counts = sum(np.bincount(ga.stochastic_universal_sampling(np.zeros(4), 2,
                                                              random_state=rng),
                             minlength=4) for _ in range(4000))
    assert counts / counts.sum() == pytest.approx([0.25] * 4, abs=0.02)
    with pytest.raises(ParameterError, match="fitness"):
        ga.stochastic_universal_sampling([1.0, -1.0], 2)


# --------------------------------------------------------------------------
# operators


@pytest.fixture(scope="module")
def quantized(train):
    t = train[2]["kickLFront1Reps"]
    return t.quantize(0.0), t.quantize(0.05)


def keyframes(q):
    return list(zip(q.positions.tolist(), q.mask.tolist(), q.value.tolist()))


@pytest.mark.shared
def test_random_query_comes_from_the_strict_template(quantized):
    strict, _ = quantized
    L = len(strict)
    rng = np.random.default_rng(0)
    sizes = []
    for _ in range(500):
        q = ga.random_query(strict, random_state=rng)
        check_valid(q, L)
        assert (np.diff(q.positions) > 0).all()  # distinct columns
        assert (q.mask == strict.mask[q.positions]).all()
        assert (q.value == strict.value[q.positions]).all()
        delta = np.diff(q.positions)
        assert (q.d_min <= np.floor(0.8 * delta)).all()
        assert (q.d_max >= np.ceil(1.2 * delta)).all() and (q.d_max <= 2 * delta).all()
        sizes.append(q.n_keyframes)
    assert 1 <= min(sizes) and max(sizes) <= 8
    assert np.mean(sizes) == pytest.approx(3.0, abs=0.15)


def test_gap_bounds_formula():
    pos = [0, 10, 10, 30]
    lo, hi = ga.gap_bounds(pos, random_state=3)
    u = np.random.default_rng(3).random(3) * 0.8 + 0.2
    delta = np.diff(pos)
    assert lo.tolist() == np.floor(delta * (1 - u)).astype(int).tolist()
    assert hi.tolist() == np.ceil(delta * (1 + u)).astype(int).tolist()
    assert lo[1] == hi[1] == 0  # same column: distance 0


@pytest.mark.shared
def test_recombine_merges_parent_keyframes(quantized):
    strict, _ = quantized
    L = len(strict)
    rng = np.random.default_rng(1)
    for _ in range(300):
        a = ga.random_query(strict, random_state=rng)
        b = ga.random_query(strict, random_state=rng)
        child = ga.recombine(a, b, random_state=rng)
        check_valid(child, L)
        kf = keyframes(child)
        assert set(kf) <= set(keyframes(a)) | set(keyframes(b))
        assert len(kf) == len(set(kf))  # no keyframe twice
        delta = np.diff(child.positions)  # gap bounds recomputed as in the initialisation
        assert (child.d_min <= np.floor(0.8 * delta)).all()
        assert (child.d_max >= np.ceil(1.2 * delta)).all() and (child.d_max <= 2 * delta).all()
    # a parent with itself only yields subsets of its keyframes
    a = ga.random_query(strict, random_state=9, mean_keyframes=6)
    for s in range(50):
        assert set(keyframes(ga.recombine(a, a, random_state=s))) <= set(keyframes(a))


@pytest.mark.shared
def test_mutations_keep_invariants_and_do_one_thing(quantized):
    strict, loose = quantized
    L = len(strict)
    rng = np.random.default_rng(2)
    seen = set()
    for _ in range(400):
        q = ga.random_query(strict, random_state=rng)
        m = ga.mutate(q, strict, loose, random_state=rng)
        check_valid(m, L)
        for op in ga_operators._applicable(ga_operators._genome(q)):
            m = ga.mutate(q, strict, loose, random_state=rng, operation=op)
            check_valid(m, L)
            seen.add(op)
            kq, km = keyframes(q), keyframes(m)
            if op == "add":
                # one new strict-template column inserted at k; gaps not touching
                # it unchanged
                assert m.n_keyframes == q.n_keyframes + 1
                ok = False
                for k in range(m.n_keyframes):
                    p, mk, vk = km[k]
                    if km[:k] + km[k + 1:] != kq or (mk, vk) != (int(strict.mask[p]),
                                                              int(strict.value[p])):
                        continue
                    keep_m = [g for g in range(m.n_keyframes - 1) if g not in (k - 1, k)]
                    keep_q = [g for g in range(q.n_keyframes - 1) if g != k - 1]
                    ok |= (m.d_min[keep_m].tolist() == q.d_min[keep_q].tolist()
                           and m.d_max[keep_m].tolist() == q.d_max[keep_q].tolist())
                assert ok
            elif op == "remove":
                (k,) = [k for k in range(q.n_keyframes) if kq[:k] + kq[k + 1:] == km]
                lo, hi = q.d_min.tolist(), q.d_max.tolist()
                if 0 < k < q.n_keyframes - 1:  # inner keyframe: its two gaps add up
                    lo[k - 1:k + 1] = [lo[k - 1] + lo[k]]
                    hi[k - 1:k + 1] = [hi[k - 1] + hi[k]]
                else:
                    del lo[min(k, len(lo) - 1)], hi[min(k, len(hi) - 1)]
                assert m.d_min.tolist() == lo and m.d_max.tolist() == hi
            elif op in ("specialise", "generalise"):
                assert (m.positions == q.positions).all() and (m.d_min == q.d_min).all()
                changed = np.flatnonzero(m.mask != q.mask)
                assert len(changed) == 1
                k = changed[0]
                diff = int(m.mask[k]) ^ int(q.mask[k])
                assert diff.bit_count() == 1
                if op == "specialise":
                    assert int(m.mask[k]) & diff
                    lm, lv = int(loose.mask[q.positions[k]]), int(loose.value[q.positions[k]])
                    if lm & diff:  # the δ = 0.05 template's value where it has one
                        assert int(m.value[k]) & diff == lv & diff
                else:
                    assert not int(m.mask[k]) & diff and not int(m.value[k]) & diff
                assert int(m.value[k]) & ~diff == int(q.value[k]) & ~diff
            elif op == "gap":
                assert keyframes(m) == keyframes(q)
                changes = (m.d_min != q.d_min).sum() + (m.d_max != q.d_max).sum()
                assert changes <= 1  # (0 when clamped at a bound)
    assert seen == set(ga.MUTATIONS)


@pytest.mark.shared
def test_mutation_errors_and_single_keyframe(quantized):
    strict, loose = quantized
    q = KeyframeQuery([strict.mask[3]], [strict.value[3]], [3], [], [], len(strict))
    with pytest.raises(ParameterError, match="not applicable"):
        ga.mutate(q, strict, loose, operation="remove")
    with pytest.raises(ParameterError, match="not applicable"):
        ga.mutate(q, strict, loose, operation="gap")
    rng = np.random.default_rng(0)
    ops = set()
    for _ in range(200):
        m = ga.mutate(q, strict, loose, random_state=rng)
        check_valid(m, len(strict))
        ops.add("add" if m.n_keyframes == 2 else "bit")
    assert ops == {"add", "bit"}


# --------------------------------------------------------------------------
# consensus


def kq(words, positions=None):
    n = len(words)
    pos = list(range(n)) if positions is None else positions
    return KeyframeQuery(np.array([m for m, _ in words], np.uint64),
                         np.array([v for _, v in words], np.uint64), pos,
                         [0] * (n - 1), [5] * (n - 1), 20)


def test_consensus_pick_hand_made():
    w1, w2, w3, w4 = (0b111, 0b101), (0b11, 0b1), (0b1, 0b0), (0b110, 0b110)
    w1_other_value = (0b111, 0b100)
    results = [kq([w1, w2]),             # w1 in 2 others, w2 in 1: mean 1.5
               kq([w1, w3]),             # w1: 2, w3: 0 -> 1.0
               kq([w2, w1], [4, 9]),     # same words at other positions: 1.5
               kq([w4]),                 # unique: 0
               kq([w1_other_value])]     # another value is another keyframe: 0
    scores = ga.consensus_scores(results)
    assert scores.tolist() == [1.5, 1.0, 1.5, 0.0, 0.0]
    # ties -> higher fitness; the fittest result alone does not win
    assert ga.consensus_pick(results, [0.7, 0.9, 0.8, 1.0, 1.0]) == 2
    assert ga.consensus_pick(results, [0.8, 0.9, 0.8, 1.0, 1.0]) == 0  # full tie: earlier
    assert ga.consensus_pick([kq([w4])], [0.1]) == 0
    with pytest.raises(ParameterError, match="one entry per query"):
        ga.consensus_pick(results, [1.0])


# --------------------------------------------------------------------------
# Fig. 5


@pytest.mark.shared
def test_average_statistics_and_plot(train, tmp_path):
    a = evolve(train, "sneak2StepsLStart", seed=1)
    b = evolve(train, "hopBothLegs1hops", seed=2)
    st = ga.average_statistics([a, b.statistics])
    assert st.mean_precision.tolist() == pytest.approx(
        ((a.statistics.mean_precision + b.statistics.mean_precision) / 2).tolist())
    with pytest.raises(ParameterError, match="generations"):
        ga.average_statistics([a, evolve(train, "sneak2StepsLStart", seed=1, generations=3)])
    import matplotlib  # noqa: F401  (the test extra installs it)
    from mocapdb.evaluation.figures import plot_ga_statistics

    out = tmp_path / "fig5.png"
    fig = plot_ga_statistics(st, out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert [line.get_label() for line in fig.axes[0].lines][:3] == [
        "precision", "recall", "fitness (F$_2$)"]
    with pytest.raises(ParameterError, match="GAStatistics"):
        plot_ga_statistics(a, out)
