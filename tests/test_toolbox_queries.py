"""The toolbox keyframe queries of a model (mocapdb.learning.toolbox_queries).

Oracle: ../shared/oracle/keyframes (hand-made queries, their gap bounds and
search results over the toolbox's 77-document index); the heuristic queries
are checked on the default model's 11 templates and the 232 HDM05 clips of
../shared/oracle/features.
"""
import csv
from pathlib import Path

import numpy as np
import pytest

import mocapdb
from mocapdb.errors import ParameterError, ParseError
from mocapdb.keyframes import INDEX_PARTS, build_index
from mocapdb.keyframes import (UNBOUNDED, annot_margins, choose_keyframes_equally_distributed,
                               keyframe_hit_documents, keyframe_search)
from mocapdb.storage.model_store import load_model
from mocapdb.learning.toolbox_queries import has_toolbox_query, read_toolbox_query, toolbox_keyframe_queries
from naive_keyframes import int_table, load_feat30_words, load_toolbox_query, read_rows

pytestmark = pytest.mark.shared

HAND_MADE = ["squat1Reps", "kickLFront1Reps", "hopBothLegs1hops", "rotateArmsBothBackward1Reps",
             "elbowToKnee1RepsLelbowStart"]


@pytest.fixture(scope="module")
def queries_dir(oracle_dir):
    return oracle_dir / "keyframes" / "queries"


@pytest.fixture(scope="module")
def default_model():
    """The toolbox's 11 templates (the shipped model ``toolbox``), which the toolbox's queries belong to."""
    with mocapdb.connect() as con:
        return load_model(con, "toolbox")


@pytest.fixture(scope="module")
def toolbox_model(default_model, queries_dir):
    return toolbox_keyframe_queries(default_model, queries_dir=queries_dir)


@pytest.mark.parametrize("name", HAND_MADE)
def test_hand_made_query_equals_oracle(oracle_dir, queries_dir, name):
    q = read_toolbox_query(queries_dir, name)
    gaps = int_table(queries_dir / f"{name}_gaps.csv", ["d_min", "d_max"])
    np.testing.assert_array_equal(q.d_min, gaps[:, 0])
    np.testing.assert_array_equal(q.d_max, np.where(gaps[:, 1] < 0, UNBOUNDED, gaps[:, 1]))
    vectors, sets, pos, _, length = load_toolbox_query(oracle_dir, name)
    assert q.positions.tolist() == [p - 1 for p in pos]
    assert q.template_length == length
    assert q.feature_sets == tuple(("upper", "lower", "mix")[s - 1] for s in sets)
    table = {r["query"]: r for r in read_rows(queries_dir / "queries.csv")}
    assert annot_margins(q) == (int(table[name]["extendLeft"]), int(table[name]["extendRight"]))


def test_squat_query_search_reproduces_oracle(oracle_dir, queries_dir):
    docs = read_rows(oracle_dir / "keyframes" / "index" / "documents.csv")
    index = build_index([load_feat30_words(oracle_dir, Path(r["file"]).stem) for r in docs],
                        feature_sets=INDEX_PARTS)
    q = read_toolbox_query(queries_dir, "squat1Reps")
    el, er = annot_margins(q)
    got = keyframe_search(index, q, extend_left=el, extend_right=er).as_array() + 1
    expected = int_table(oracle_dir / "keyframes" / "search" / "squat1Reps" / "annot_segments_C.csv",
                         ["doc_id", "start_frame", "end_frame"])
    assert len(expected) > 0
    np.testing.assert_array_equal(got.reshape(-1, 3), expected)


def test_model_gets_hand_made_or_heuristic_queries(default_model, toolbox_model, queries_dir):
    assert len(default_model.classes) == 11
    assert toolbox_model is not default_model  # a copy: the input keeps its own queries
    assert toolbox_model.class_names == default_model.class_names
    assert toolbox_model.labels == default_model.labels
    n_hand = 0
    for c, orig in zip(toolbox_model.classes, default_model.classes):
        assert c.quantized is orig.quantized and c.tau == orig.tau and c.label == orig.label
        q = c.keyframe_query
        if has_toolbox_query(queries_dir, c.name):
            n_hand += 1
            ref = read_toolbox_query(queries_dir, c.name)
        else:
            ref = choose_keyframes_equally_distributed(orig.quantized.mask, orig.quantized.value)
            # the heuristic takes whole template columns as 40-bit keyframes
            assert q.template_length == len(orig.quantized)
            assert q.mask.tolist() == orig.quantized.mask[q.positions].tolist()
            assert q.value.tolist() == orig.quantized.value[q.positions].tolist()
            assert q.feature_sets == (None,) * q.n_keyframes
        for field in ("mask", "value", "positions", "d_min", "d_max"):
            np.testing.assert_array_equal(getattr(q, field), getattr(ref, field))
        assert q.template_length == ref.template_length and q.feature_sets == ref.feature_sets
    assert n_hand == len(HAND_MADE)


def test_heuristic_queries_find_their_class(oracle_dir, toolbox_model, queries_dir):
    """Every query hits most clips of its own class and few of the others."""
    manifest = [r for r in read_rows(oracle_dir / "features" / "manifest.csv") if r["kind"] == "clip"]
    index = build_index([load_feat30_words(oracle_dir, r["stem"]) for r in manifest],
                        feature_sets=INDEX_PARTS)
    hit = keyframe_hit_documents(index, [c.keyframe_query for c in toolbox_model.classes])
    for c, h in zip(toolbox_model.classes, hit):
        own = np.array([f"_{c.name}_" in r["stem"] for r in manifest])
        assert own.sum() >= 10, c.name
        assert h[own].mean() >= 0.5, (c.name, h[own].sum(), own.sum())
        assert h[own].sum() > 2 * h[~own].sum(), (c.name, h[own].sum(), h[~own].sum())


def test_errors(tmp_path, queries_dir, default_model):
    with pytest.raises(ParameterError, match="no hand-made query for class 'walk'"):
        read_toolbox_query(queries_dir, "walk")
    with pytest.raises(ParameterError, match="is not a folder"):
        toolbox_keyframe_queries(default_model, queries_dir=tmp_path / "missing")
    # a gaps file with the wrong number of rows
    for suffix in ("keyframes", "gaps"):
        (tmp_path / f"x_{suffix}.csv").write_text((queries_dir / f"squat1Reps_{suffix}.csv").read_text())
    with open(tmp_path / "x_gaps.csv") as f:
        lines = f.read().splitlines()
    (tmp_path / "x_gaps.csv").write_text("\n".join(lines[:-1]) + "\n")
    with pytest.raises(ParseError, match="2 gap rows for 4 keyframes"):
        read_toolbox_query(tmp_path, "x")
    # an entry the toolbox rejects (checkKeyframes.m)
    rows = list(csv.reader(open(queries_dir / "squat1Reps_keyframes.csv")))
    rows[1][6] = "0.3"
    with open(tmp_path / "y_keyframes.csv", "w", newline="") as f:
        csv.writer(f).writerows(rows)
    (tmp_path / "y_gaps.csv").write_text((queries_dir / "squat1Reps_gaps.csv").read_text())
    with pytest.raises(ParameterError, match="entries must be 0, 1 or 0.5"):
        read_toolbox_query(tmp_path, "y")
