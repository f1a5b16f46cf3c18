"""Concurrent labels and per-segment confidence (beyond the paper, issue 25).

A concurrent label (``Model.concurrent_labels``) is segmented on its own and
takes no frame from the others; every segment carries a confidence, 1 − the
best Δ̄^τ/τ over its frames. Worked examples on words made by hand, a
brute-force twin of the confidence kernel, and both through every output
(SQL, CSV, ELAN) on the shipped sample.
"""
import csv

import numpy as np
import pytest

import mocapdb
from conftest import SAMPLE_86_09, SAMPLE_86_ASF, open_db, run  # noqa: F401
from mocapdb.annotation import ClassModel, Model, annotate
from mocapdb.annotation.chain_kernels import _segment_min_kernel
from mocapdb.annotation.elan import CONFIDENCE_TIER, read_eaf
from mocapdb.errors import ParameterError
from mocapdb.templates import QuantizedTemplate


def cls(name, label, bit, tau=0.1, columns=6, extra=0):
    """A class whose template asks for feature ``bit`` on (and ``extra`` more features off) in every column."""
    mask = np.full(columns, (1 << bit) | extra, np.uint64)
    value = np.full(columns, 1 << bit, np.uint64)
    return ClassModel(name, label, quantized=QuantizedTemplate(mask, value, np.ones(columns)), tau=tau)


def words(n, spans):
    w = np.zeros(n, np.uint64)
    for bit, (a, b) in spans:
        w[a:b + 1] |= np.uint64(1 << bit)
    return w


def segs(ann):
    return sorted((str(s["label"]), int(s["start"]), int(s["end"])) for s in ann.segments)


def test_a_concurrent_label_takes_no_frame_from_the_others():
    # a walk over 10..69 that turns over 25..44
    w = words(100, [(0, (10, 69)), (1, (25, 44))])
    classes = (cls("A", "walk", 0), cls("B", "turn", 1))
    plain = annotate(w, Model("m", classes))
    both = annotate(w, Model("m", classes, concurrent_labels=("turn",)))
    # the paper's segmenter: one label per frame, ties to the first label: the turn never wins a frame
    assert segs(plain) == [("walk", 10, 69)]
    # concurrent: the turn where it holds, beside the walk
    assert segs(both) == [("turn", 25, 44), ("walk", 10, 69)]
    # without it the model is the paper's: the same model without the setting gives the same segments
    assert segs(annotate(w, Model("m", classes, concurrent_labels=()))) == segs(plain)


def test_a_short_document_keeps_a_label_over_half_of_it_but_not_a_short_turn():
    """A label's minimum length drops leftovers between labels; in a document shorter than twice it (a clip
    of one gait cycle) a segment over half the document is kept — not a concurrent label's, whose minimum
    is its own duration (a lasting turn)."""
    import dataclasses

    walk, turn = (dataclasses.replace(c, min_frames=26) for c in (cls("A", "walk", 0), cls("B", "turn", 1)))
    model = Model("m", (walk, turn), concurrent_labels=("turn",))
    short = words(21, [(0, (3, 16)), (1, (2, 19))])          # 0.7 s: a walk of 14 frames, a turn of 18
    assert segs(annotate(short, model)) == [("walk", 3, 16)]
    # the same walk inside a long document is a leftover: dropped
    long_doc = words(60, [(0, (3, 16))])
    assert segs(annotate(long_doc, model)) == []
    # documents annotated together keep their own lengths: the short one keeps its walk
    both = annotate(np.concatenate([long_doc, short]), model, doc_lengths=[60, 21])
    assert sorted((int(s["doc"]), str(s["label"])) for s in both.segments) == [(1, "walk")]
    # under half of the short document: dropped (⌈21/2⌉ = 11 > 9 frames)
    assert segs(annotate(words(21, [(0, (3, 11))]), model)) == []


def test_concurrent_labels_must_be_labels_of_the_model():
    with pytest.raises(ParameterError, match="not labels of the model"):
        Model("m", (cls("A", "walk", 0),), concurrent_labels=("turn",))
    with pytest.raises(ParameterError, match="sequence of labels"):
        Model("m", (cls("A", "walk", 0),), concurrent_labels="walk")


def test_confidence_is_how_far_the_best_match_lies_below_tau():
    """Per segment: 1 − the smallest Δ̄^τ/τ of its label's classes over its frames."""
    rng = np.random.default_rng(11)
    w = words(300, [(0, (10, 79)), (2, (120, 199)), (3, (150, 260))])
    w |= (rng.random(300) < 0.2).astype(np.uint64) << np.uint64(5)  # noise on a feature classes C and D ask off
    model = Model("m", (cls("A", "walk", 0, tau=0.1), cls("C", "kick", 2, tau=0.3, extra=(1 << 5) | (1 << 6)),
                        cls("D", "kick", 3, tau=0.2, extra=1 << 5)))
    ann = annotate(w, model, keep_deltas=True)
    assert len(ann.segments) >= 2
    taus = np.array([c.tau for c in model.classes])
    ratio = ann.classification_delta / taus[:, None]
    for seg in ann.segments:
        rows = [k for k, c in enumerate(model.classes) if c.label == seg["label"]]
        best = ratio[rows, seg["start"]:seg["end"] + 1].min()
        assert seg["confidence"] == pytest.approx(max(0.0, 1 - best))
    by = {str(s["label"]): s for s in ann.segments}
    assert by["walk"]["confidence"] == pytest.approx(1.0)            # a perfect match
    assert ((ann.segments["confidence"] >= 0) & (ann.segments["confidence"] <= 1)).all()
    # at τ = 0 only perfect matches are hits: their confidence is 1, not 0/0
    exact = annotate(w, Model("m", (cls("A", "walk", 0, tau=0.0),)))
    assert len(exact.segments) and (exact.segments["confidence"] == 1.0).all()


def test_segment_min_kernel_matches_brute_force():
    rng = np.random.default_rng(3)
    x = rng.random((4, 300))
    x[rng.random(x.shape) < 0.3] = np.inf
    lab = rng.integers(0, 4, 50)
    first = rng.integers(0, 290, 50)
    last = np.minimum(first + rng.integers(0, 40, 50), 299)
    out = np.empty(50)
    _segment_min_kernel(x, lab, first, last, out)
    np.testing.assert_array_equal(out, [x[l, a:b + 1].min() for l, a, b in zip(lab, first, last)])


@pytest.fixture(scope="module")
def sample_db(tmp_path_factory):
    db = tmp_path_factory.mktemp("conf") / "s.duckdb"
    with mocapdb.connect(db) as con:
        mocapdb.ingest(con, [SAMPLE_86_09], asf=SAMPLE_86_ASF)
    return db


@pytest.mark.slow
def test_confidence_in_sql_csv_and_elan(sample_db, tmp_path):
    with mocapdb.connect(sample_db) as con:
        rows = con.sql("SELECT s.label, s.confidence, s.cost FROM motions m, "
                       "LATERAL (SELECT unnest(annotate(m.motion_id), recursive := true)) s").fetchall()
    assert rows and all(0 <= c <= 1 for _, c, _ in rows)
    assert any(c > 0 for _, c, _ in rows)
    out = tmp_path / "a.csv"
    run(sample_db, "annotate", "--format", "csv", "--out", str(out))
    table = list(csv.DictReader(out.open()))
    assert [r["label"] for r in table] and all(0 <= float(r["confidence"]) <= 1 for r in table)
    eaf = tmp_path / "a.eaf"
    run(sample_db, "annotate", "--format", "eaf", "--out", str(eaf))
    text = eaf.read_text()
    assert CONFIDENCE_TIER.strip() in text
    # the confidence tiers are references: the file reads back onto the same segments as the CSV
    back = read_eaf(eaf, fps=120.0)
    assert len(back) == len(table)
    with mocapdb.connect(sample_db) as con:
        stored = con.sql("SELECT count(*), min(confidence), max(confidence) FROM annotations").fetchall()[0]
    assert stored[0] == len(table) and 0 <= stored[1] <= stored[2] <= 1
