"""Calibrated confidence (issue 32 item 4): per label a monotone step map from a score of the raw score and the
segment's length to the share of right segments on held-out recordings, stored with the model and applied after
the raw score."""
import dataclasses

import numpy as np
import pyarrow as pa
import pytest

import mocapdb
from mocapdb.annotation import ConfidenceMap
from mocapdb.annotation import postprocess
from mocapdb.annotation.model import STEP_ORDER
from mocapdb.annotation.postprocess import calibrate_confidence
from mocapdb.errors import ParameterError, SchemaError
from mocapdb.annotation import SEGMENT_DTYPE
from mocapdb.learning.confidence_maps import (CAUTION, FULL_LENGTH, MIN_STEP, PRIOR_SEGMENTS, RIDGE,
                                             MAX_LENGTH_WEIGHT, _logistic, fit_confidence_maps, length_weight)
from mocapdb.storage.model_store import fingerprint, load_model, model_from_tables, model_tables, save_model


@pytest.fixture(scope="module")
def default():
    with mocapdb.connect() as con:
        return load_model(con, "default"), load_model(con, "toolbox")


def _segments(labels, lengths):
    out = np.zeros(len(labels), dtype=SEGMENT_DTYPE)
    out["label"] = labels
    out["start"] = 10
    out["end"] = 10 + np.asarray(lengths) - 1
    return out


def test_a_map_is_a_rising_step_function_per_length():
    short = ConfidenceMap("move", (0.0, 0.4, 0.8), (0.5, 0.7, 0.95))
    long = ConfidenceMap("move", (0.0, 0.5), (0.8, 0.99), min_length=45)
    segs = _segments(["move", "move", "move", "move", "kick", "move", "move"], [10, 10, 44, 10, 100, 45, 200])
    got = calibrate_confidence(segs, np.array([0.0, 0.39, 0.4, 1.0, 0.33, 0.2, 0.5]), [long, short])
    # a step's value, plus STEP_ORDER of the way to the next one (1 after the last) as far as the raw score lies
    # towards the next cut (1); a label without a map keeps its raw score
    want = [0.5, 0.5 + STEP_ORDER * 0.2 * (0.39 / 0.4), 0.7, 0.95 + STEP_ORDER * 0.05, 0.33,
            0.8 + STEP_ORDER * 0.19 * (0.2 / 0.5), 0.99]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    # within a step the raw score orders, and no segment reaches the next step's value
    within = calibrate_confidence(_segments(["move"] * 5, [10] * 5), np.array([0.4, 0.5, 0.6, 0.79, 0.8]), [short])
    assert 0.7 == within[0] < within[1] < within[2] < within[3] < 0.7 + STEP_ORDER * 0.25 < within[4] == 0.95
    # nothing is added where the next value is no higher: a stored -0.0 stays -0.0
    flat = calibrate_confidence(_segments(["move"] * 2, [10, 10]), np.array([0.1, 0.3]),
                                [ConfidenceMap("move", (0.0, 0.5), (-0.0, 0.0))])
    assert [np.signbit(x) for x in flat] == [True, True]
    # below the first cut: the first step; shorter than every map: the raw score
    assert calibrate_confidence(_segments(["move", "move"], [50, 30]), np.array([0.1, 0.1]),
                                [ConfidenceMap("move", (0.2,), (0.6,), min_length=40)]).tolist() == [0.6, 0.1]
    for cuts, values in (((0.5, 0.4), (0.1, 0.2)), ((0.1, 0.2), (0.3, 0.2)), ((0.1,), (1.2,)), ((), ()),
                         ((0.1, 0.2), (0.3,)), ((float("nan"),), (0.5,))):
        with pytest.raises(ParameterError, match="confidence map of 'move'"):
            ConfidenceMap("move", cuts, values)
    with pytest.raises(ParameterError, match="min_length"):
        ConfidenceMap("move", (0.0,), (0.5,), min_length=-1)
    for bad in ({"length_weight": -0.5}, {"length_weight": float("nan")}, {"length_weight": float("inf")},
                {"full_length": 0}, {"full_length": 2.5}, {"full_length": True}, {"length_product": 1},
                {"length_product": "yes"}):
        with pytest.raises(ParameterError, match="length_weight|full_length|length_product"):
            ConfidenceMap("move", (0.0,), (0.5,), **bad)


def test_the_length_enters_the_score():
    """With ℓ = min(n, F) / F the score raw · (1 + w · ℓ) / (1 + w) (``length_product``; maps fitted before it:
    (raw + w · ℓ) / (1 + w)): a longer segment, up to F frames, scores higher at the same raw score — multiplied,
    a match of raw score 0 stays 0 however long; w = 0 is the raw score itself, bit for bit, either way."""
    segs = _segments(["move"] * 5, [30, 60, 120, 30, 120])
    raw = np.array([0.4, 0.4, 0.4, 1.0, 0.0])
    ell = np.array([0.5, 1.0, 1.0, 0.5, 1.0])
    for product, score in ((False, (raw + ell) / 2), (True, raw * (1 + ell) / 2)):
        m = ConfidenceMap("move", (0.0, 0.5), (0.3, 0.9), length_weight=1.0, full_length=60, length_product=product)
        got = calibrate_confidence(segs, raw, [m])
        want = np.where(score < 0.5, 0.3 + STEP_ORDER * 0.6 * score / 0.5,
                        0.9 + STEP_ORDER * 0.1 * (score - 0.5) / 0.5)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
        assert got[0] < got[1] == got[2] and got[3] > got[0]
        np.testing.assert_array_equal(postprocess.length_score(raw, [30, 60, 120, 30, 120], 1.0, 60, product), score)
    assert got[4] == 0.3                                   # multiplied: no match, no lift for the length
    rng = np.random.default_rng(3)
    raw = rng.random(200)
    segs = _segments(["move"] * 200, rng.integers(1, 300, 200))
    plain = ConfidenceMap("move", (0.0, 0.2, 0.7), (0.1, 0.4, 0.8))
    for product in (False, True):
        zero = ConfidenceMap("move", (0.0, 0.2, 0.7), (0.1, 0.4, 0.8), length_weight=-0.0, full_length=7,
                             length_product=product)
        assert zero.length_weight == 0.0 and not np.signbit(zero.length_weight)
        assert calibrate_confidence(segs, raw, [plain]).tobytes() == calibrate_confidence(segs, raw, [zero]).tobytes()


def test_fitted_maps_rise_and_follow_the_share_right(monkeypatch):
    """One map of the length-weighted score per label, a cautious share right per step: rising, within [0, 1],
    below the share right of the segments it was fitted to but not far; every label of the model gets it."""
    rng = np.random.default_rng(0)
    raw = rng.random(400)
    lengths = rng.integers(10, 200, 400)
    right = rng.random(400) < 0.1 + 0.5 * raw + 0.3 * (lengths >= 90)   # higher raw score, longer: more often right
    segs = _segments(np.where(np.arange(400) < 300, "move", "kick"), lengths)
    maps = fit_confidence_maps(("move", "kick", "turn"), segs, raw, right)
    assert [m.label for m in maps] == ["move", "kick", "turn"] and {m.min_length for m in maps} == {0}
    assert len({(m.cuts, m.values, m.length_weight, m.full_length, m.length_product) for m in maps}) == 1
    w = maps[0].length_weight
    assert w == length_weight(raw, lengths, right) > 0 and maps[0].full_length == FULL_LENGTH
    assert maps[0].length_product
    for m in maps:
        assert all(b >= a for a, b in zip(m.values, m.values[1:])) and 0 <= m.values[0] <= m.values[-1] <= 1
    got = calibrate_confidence(segs, raw, maps)
    monkeypatch.setattr(postprocess, "STEP_ORDER", 0.0)
    steps = calibrate_confidence(segs, raw, maps)           # the steps' own values
    score = raw * (1 + w * np.minimum(lengths, FULL_LENGTH) / FULL_LENGTH) / (1 + w)
    # the score moves a segment at most a hundredth of the way to 1 above its step, in the score's order
    assert ((got >= steps) & (got - steps <= STEP_ORDER * (1 - steps) + 1e-15)).all()
    same = steps[:, None] == steps[None, :]
    assert not (same & (score[:, None] < score[None, :]) & (got[:, None] > got[None, :])).any()
    # one rising map of the score: a segment better in raw score and no shorter never ranks lower
    better = (raw[:, None] >= raw[None, :]) & (np.minimum(lengths, FULL_LENGTH)[:, None]
                                               >= np.minimum(lengths, FULL_LENGTH)[None, :])
    assert not (better & (got[:, None] < got[None, :])).any()
    got = steps
    # cautious on what it was fitted to: each step a user trusts (≥ 0.5) below its segments' share right,
    # not by much overall
    for v in np.unique(got[got >= 0.5]):
        assert right[got == v].mean() >= v
    assert 0 < right.mean() - got.mean() < 0.1
    longer = lengths >= 90
    assert got[longer & (raw > 0.7)].mean() > 0.7 > 0.3 > got[~longer & (raw < 0.3)].mean()
    with pytest.raises(ParameterError, match="held-out segments"):
        fit_confidence_maps(("move",), segs[:0], raw[:0], right[:0])
    with pytest.raises(ParameterError, match="end at or after"):
        fit_confidence_maps(("move",), _segments(["move"] * 2, [0, 5]), raw[:2], right[:2])
    assert PRIOR_SEGMENTS > 0 and MIN_STEP > 1 and CAUTION > 0


def test_the_length_weight_is_the_ratio_of_the_logistic_slopes():
    """The Newton steps reach the penalized maximum likelihood (no move of the coefficients, in random
    directions near and far, does better), length_weight is the ratio of its slopes — of raw · ℓ to raw, or (the
    maps before it, ``product=False``) of ℓ to raw —, and the weight follows what decides being right: the
    length with the raw score (> 0), the raw score alone (about 0), the raw score ranking the wrong way or not at
    all (the length alone, capped; or nothing where the length does not help)."""
    rng = np.random.default_rng(5)
    n = 600
    raw = rng.random(n)
    lengths = rng.integers(5, 240, n)
    ell = np.minimum(lengths, FULL_LENGTH) / FULL_LENGTH
    added = rng.random(n) < 1 / (1 + np.exp(-(-2.0 + 2.0 * raw + 3.0 * ell)))
    b = _logistic(np.column_stack([np.ones(n), raw, ell]), added.astype(float), RIDGE)
    assert length_weight(raw, lengths, added, product=False) == b[2] / b[1]
    right = rng.random(n) < 1 / (1 + np.exp(-(-2.0 + 2.0 * raw + 3.0 * raw * ell)))
    x, y = np.column_stack([np.ones(n), raw, raw * ell]), right.astype(float)

    def objective(b):
        z = x @ b
        return float((y * z - np.logaddexp(0.0, z)).sum() - RIDGE / 2 * (b[1:] ** 2).sum())

    b = _logistic(x, y, RIDGE)
    top = objective(b)
    for scale in (1e-3, 0.05, 0.5, 3.0):
        for _ in range(200):
            assert objective(b + rng.normal(0, scale, 3)) <= top + 1e-9
    w = length_weight(raw, lengths, right)
    assert w == b[2] / b[1] and 0.8 < w < 3.0            # the generating ratio 3 / 2, shrunk by the ridge
    # the raw score alone: small (raw · ℓ carries much of the raw score, so the ridge leaves it a little)
    assert length_weight(raw, lengths, rng.random(n) < 0.1 + 0.8 * raw) < 0.4
    # the raw score ranking the wrong way: no ratio through it — the length alone where it helps, else nothing
    assert length_weight(raw, lengths, rng.random(n) < 0.6 - 0.5 * raw + 0.4 * raw * ell) == MAX_LENGTH_WEIGHT
    assert length_weight(raw, lengths, rng.random(n) < 0.9 - 0.4 * raw - 0.4 * raw * ell) == 0.0
    assert length_weight(raw, lengths, np.ones(n, dtype=bool)) >= 0.0
    # raw scores all alike (designed classes' 1s): their slope is rounding, the length decides, capped
    w = length_weight(np.ones(n), lengths, right)
    assert w == MAX_LENGTH_WEIGHT
    maps = fit_confidence_maps(("move",), _segments(["move"] * n, lengths), np.ones(n), right)
    got = calibrate_confidence(_segments(["move"] * n, lengths), np.ones(n), maps)
    assert np.isfinite(got).all() and not (((ell[:, None] > ell[None, :]) & (got[:, None] < got[None, :])).any())


def test_the_maps_are_stored_and_change_the_fingerprint(default, tmp_path):
    model, toolbox = default
    assert toolbox.confidence_maps == ()                      # the reference mode keeps the raw score
    maps = tuple(ConfidenceMap(lab, (0.0, 0.5), (0.25, 0.75), min_length=lo, length_weight=lo / 80,
                               full_length=60 + lo, length_product=k % 2 == 0)
                 for k, lab in enumerate(model.labels[::-1]) for lo in (40, 0))
    cal = dataclasses.replace(model, name="cal", confidence_maps=maps)
    assert fingerprint(cal) != fingerprint(dataclasses.replace(cal, confidence_maps=()))
    heavier = tuple(dataclasses.replace(m, length_weight=m.length_weight * 2) for m in maps)
    assert fingerprint(cal) != fingerprint(dataclasses.replace(cal, confidence_maps=heavier))
    added = tuple(dataclasses.replace(m, length_product=False) for m in maps)
    assert fingerprint(cal) != fingerprint(dataclasses.replace(cal, confidence_maps=added))
    # maps without a length weight keep their fingerprints whatever their rule
    flat = tuple(dataclasses.replace(m, length_weight=0.0) for m in maps)
    assert fingerprint(dataclasses.replace(cal, confidence_maps=flat)) == fingerprint(
        dataclasses.replace(cal, confidence_maps=tuple(dataclasses.replace(m, length_product=False) for m in flat)))
    with mocapdb.connect(tmp_path / "a.duckdb") as con:
        fp = save_model(con, cal)
        back = load_model(con, "cal")
    assert fingerprint(back) == fp
    def rows(ms):
        return {(m.label, m.min_length, m.cuts, m.values, m.length_weight, m.full_length, m.length_product)
                for m in ms}

    assert rows(back.confidence_maps) == rows(maps)
    # maps stored before the length entered the score: the raw score alone
    tables = model_tables(cal)
    old = tables["confidence_maps"].drop_columns(["length_weight", "full_length", "length_product"])
    back = model_from_tables(tables | {"confidence_maps": old}).confidence_maps
    assert rows(back) == rows(dataclasses.replace(m, length_weight=0.0, full_length=90, length_product=False)
                              for m in maps)
    # maps stored before the length multiplied the match: added
    old = tables["confidence_maps"].drop_columns(["length_product"])
    back = model_from_tables(tables | {"confidence_maps": old}).confidence_maps
    assert rows(back) == rows(dataclasses.replace(m, length_product=False) for m in maps)
    # the steps of one map disagreeing on its score is damage, not a choice
    mixed = tables["confidence_maps"]
    weights = mixed.column("length_weight").to_numpy().copy()
    weights[mixed.column("k").to_numpy() == 2] += 1
    with pytest.raises(SchemaError, match="disagree on its length_weight"):
        model_from_tables(tables | {"confidence_maps": mixed.set_column(
            mixed.schema.get_field_index("length_weight"), "length_weight", pa.array(weights))})
    flags = mixed.column("length_product").to_numpy(zero_copy_only=False).copy()
    flags[mixed.column("k").to_numpy() == 2] ^= True
    with pytest.raises(SchemaError, match="length_product"):
        model_from_tables(tables | {"confidence_maps": mixed.set_column(
            mixed.schema.get_field_index("length_product"), "length_product", pa.array(flags))})
    rows = tables["confidence_maps"]
    tables["confidence_maps"] = rows.set_column(1, "label", pa.array(["nolabel"] * rows.num_rows))
    with pytest.raises(SchemaError, match="confidence maps of labels it lacks"):
        model_from_tables(tables)


def test_an_archive_from_before_the_length_multiplied_reads_its_maps_as_added(default, tmp_path):
    """An archive whose confidence_maps has no column length_product (made before it), opened by mocapdb:
    the column is added, false on the rows there were, and the stored maps read as they were made — the
    length added to the raw score."""
    import duckdb

    model, _ = default
    maps = tuple(ConfidenceMap(lab, (0.0, 0.5), (0.25, 0.75), length_weight=0.5, length_product=True)
                 for lab in model.labels)
    db = tmp_path / "old.duckdb"
    with mocapdb.connect(db) as con:
        save_model(con, dataclasses.replace(model, name="mine", confidence_maps=maps))
    with duckdb.connect(str(db)) as raw:
        raw.execute("ALTER TABLE confidence_maps DROP COLUMN length_product")
    with mocapdb.connect(db) as con:
        assert con.execute("SELECT count(*), bool_or(length_product) FROM confidence_maps "
                           "WHERE model = 'mine'").fetchone() == (2 * len(maps), False)
        back = load_model(con, "mine").confidence_maps
    assert [(m.label, m.length_weight, m.length_product) for m in back] == [(m.label, 0.5, False) for m in maps]


def test_annotation_gives_the_map_s_values(default):
    """The shipped sample annotated by the default model and by a copy with maps: every segment's confidence
    is its label's step at its raw score."""
    model, _ = default
    with mocapdb.connect() as con:
        mocapdb.ingest(con, sample=True)
        words = con.execute("SELECT list(bits ORDER BY frame) FROM features GROUP BY motion_id "
                            "ORDER BY motion_id").fetchall()
    w = np.concatenate([np.asarray(x, dtype=np.uint64) for x, in words])
    lengths = [len(x) for x, in words]
    raw_model = dataclasses.replace(model, confidence_maps=())
    maps = tuple(ConfidenceMap(lab, (0.0, 0.3, 0.9), (0.1 + k / 100, 0.5, 0.9 + lo / 1000), min_length=lo,
                               length_weight=k / 10, full_length=45 + lo, length_product=bool(k % 2))
                 for k, lab in enumerate(model.labels) for lo in (0, 60))
    raw = mocapdb.annotation.annotate(w, raw_model, doc_lengths=lengths).segments
    cal = mocapdb.annotation.annotate(w, dataclasses.replace(model, confidence_maps=maps), doc_lengths=lengths).segments
    assert raw.size > 3 and np.array_equal(raw[["label", "doc", "start", "end"]], cal[["label", "doc", "start", "end"]])
    want = calibrate_confidence(raw, raw["confidence"], maps)
    assert cal["confidence"].tolist() == want.tolist()
    assert len(set(want.tolist())) > 1
