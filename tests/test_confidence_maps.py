"""Calibrated confidence (issue 32 item 4): per label a monotone step map from the raw score to the share of
right segments on held-out recordings, stored with the model and applied after the raw score."""
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
from mocapdb.learning.confidence_maps import CAUTION, LENGTH_EDGES, MIN_STEP, PRIOR_SEGMENTS, fit_confidence_maps
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


def test_fitted_maps_rise_and_follow_the_share_right(monkeypatch):
    """Isotonic steps per length band, each a cautious share right: rising, within [0, 1], below the share right
    of the segments it was fitted to but not far; every label of the model gets them."""
    rng = np.random.default_rng(0)
    raw = rng.random(400)
    lengths = rng.integers(10, 200, 400)
    right = rng.random(400) < 0.1 + 0.5 * raw + 0.3 * (lengths >= 90)   # higher raw score, longer: more often right
    segs = _segments(np.where(np.arange(400) < 300, "move", "kick"), lengths)
    maps = fit_confidence_maps(("move", "kick", "turn"), segs, raw, right)
    assert {(m.label, m.min_length) for m in maps} == {(lab, lo) for lab in ("move", "kick", "turn")
                                                       for lo in LENGTH_EDGES}
    for m in maps:
        assert all(b >= a for a, b in zip(m.values, m.values[1:])) and 0 <= m.values[0] <= m.values[-1] <= 1
    got = calibrate_confidence(segs, raw, maps)
    monkeypatch.setattr(postprocess, "STEP_ORDER", 0.0)
    steps = calibrate_confidence(segs, raw, maps)           # the steps' own values
    # the raw score moves a segment at most a hundredth of the way to 1 above its step, in the raw score's order
    assert ((got >= steps) & (got - steps <= STEP_ORDER * (1 - steps) + 1e-15)).all()
    same = steps[:, None] == steps[None, :]
    assert not (same & (raw[:, None] < raw[None, :]) & (got[:, None] > got[None, :])).any()
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
    with pytest.raises(ParameterError, match="length_edges"):
        fit_confidence_maps(("move",), segs, raw, right, length_edges=(10, 5))
    assert PRIOR_SEGMENTS > 0 and MIN_STEP > 1 and CAUTION > 0


def test_the_maps_are_stored_and_change_the_fingerprint(default, tmp_path):
    model, toolbox = default
    assert toolbox.confidence_maps == ()                      # the reference mode keeps the raw score
    maps = tuple(ConfidenceMap(lab, (0.0, 0.5), (0.25, 0.75), min_length=lo) for lab in model.labels[::-1]
                 for lo in (40, 0))
    cal = dataclasses.replace(model, name="cal", confidence_maps=maps)
    assert fingerprint(cal) != fingerprint(dataclasses.replace(cal, confidence_maps=()))
    with mocapdb.connect(tmp_path / "a.duckdb") as con:
        fp = save_model(con, cal)
        back = load_model(con, "cal")
    assert fingerprint(back) == fp
    assert ({(m.label, m.min_length, m.cuts, m.values) for m in back.confidence_maps}
            == {(m.label, m.min_length, m.cuts, m.values) for m in maps})
    tables = model_tables(cal)
    rows = tables["confidence_maps"]
    tables["confidence_maps"] = rows.set_column(1, "label", pa.array(["nolabel"] * rows.num_rows))
    with pytest.raises(SchemaError, match="confidence maps of labels it lacks"):
        model_from_tables(tables)


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
    maps = tuple(ConfidenceMap(lab, (0.0, 0.3, 0.9), (0.1 + k / 100, 0.5, 0.9 + lo / 1000), min_length=lo)
                 for k, lab in enumerate(model.labels) for lo in (0, 60))
    raw = mocapdb.annotation.annotate(w, raw_model, doc_lengths=lengths).segments
    cal = mocapdb.annotation.annotate(w, dataclasses.replace(model, confidence_maps=maps), doc_lengths=lengths).segments
    assert raw.size > 3 and np.array_equal(raw[["label", "doc", "start", "end"]], cal[["label", "doc", "start", "end"]])
    want = calibrate_confidence(raw, raw["confidence"], maps)
    assert cal["confidence"].tolist() == want.tolist()
    assert len(set(want.tolist())) > 1
