"""Keyframe queries and the keyframe-chain search (KEYFRAMES.md §2-5, §8.1).

Oracle: ../shared/oracle/keyframes (the toolbox's index, queries and search
results over 77 documents); reference: tests/naive_keyframes.py (brute force
over frames, independent of the toolbox's pointer logic).
"""
import ast
import math
from pathlib import Path

import numpy as np
import pytest

from mocapdb.errors import ParameterError
from mocapdb.features import FEATURE_SETS
from mocapdb.keyframes import INDEX_PARTS, build_index
from mocapdb.keyframes.search_kernels import (_AUTO, _BITSET, _FORWARD, _HEAP, _chain_batch_kernel,
                                      _query_intervals_kernel)
from mocapdb.keyframes.search import _intervals, _plan, _search, _sub_arrays
from mocapdb.keyframes import (UNBOUNDED, KeyframeQuery,
                               annot_margins, choose_keyframes_equally_distributed,
                               keyframe_hit_documents, keyframe_intervals,
                               keyframe_mask_value, keyframe_postings, keyframe_search,
                               keyframe_search_batch, stiffness_bounds)
from naive_keyframes import (int_table, load_feat30_words, load_toolbox_query,
                             naive_choose_equally_distributed, naive_fuzzy_words,
                             naive_keyframe_search, naive_reachable_last, read_rows,
                             words_from_bits)

KF = "keyframes"
QUERIES = ["squat1Reps", "kickLFront1Reps", "hopBothLegs1hops", "rotateArmsBothBackward1Reps",
           "elbowToKnee1RepsLelbowStart", "synth1_nomatch", "synth2_stiffness0", "synth3_samepos",
           "extra4_loose"]
SETTINGS = ["annot", "zero"]


@pytest.fixture(scope="module")
def oracle_words(oracle_dir):
    rows = read_rows(oracle_dir / KF / "index" / "documents.csv")
    return [load_feat30_words(oracle_dir, Path(r["file"]).stem) for r in rows]


@pytest.fixture(scope="module")
def oracle_index(oracle_words):
    return build_index(oracle_words, feature_sets=INDEX_PARTS)


@pytest.fixture(scope="module")
def query_table(oracle_dir):
    return {r["query"]: r for r in read_rows(oracle_dir / KF / "queries" / "queries.csv")}


def toolbox_query(oracle_dir, name):
    vectors, sets, pos, stiffness, L = load_toolbox_query(oracle_dir, name)
    return KeyframeQuery.from_toolbox(vectors, sets, pos, stiffness, template_length=L)


def margins(query_table, name, setting):
    r = query_table[name]
    return (int(r["extendLeft"]), int(r["extendRight"])) if setting == "annot" else (0, 0)


def rows(segments, one_based=True):
    a = segments.as_array()
    return a + 1 if one_based else a


# ---- the oracle queries ---------------------------------------------------------


@pytest.mark.shared
@pytest.mark.parametrize("name", QUERIES)
def test_gap_bounds_and_margins_equal_oracle(oracle_dir, query_table, name):
    q = toolbox_query(oracle_dir, name)
    for path in (oracle_dir / KF / "queries" / f"{name}_gaps.csv",
                 oracle_dir / KF / "search" / name / "gaps.csv"):
        gaps = int_table(path, ["d_min", "d_max"])
        np.testing.assert_array_equal(q.d_min, gaps[:, 0])
        np.testing.assert_array_equal(q.d_max, np.where(gaps[:, 1] < 0, UNBOUNDED, gaps[:, 1]))
    assert annot_margins(q) == margins(query_table, name, "annot")
    assert q.template_length == int(query_table[name]["templateLength"])


@pytest.mark.shared
@pytest.mark.parametrize("name", QUERIES)
def test_fuzzy_words_and_union_lists_equal_oracle(oracle_dir, oracle_index, name):
    q = toolbox_query(oracle_dir, name)
    words = int_table(oracle_dir / KF / "search" / name / "words.csv", ["k", "word", "list_length"])
    union = int_table(oracle_dir / KF / "search" / name / "union.csv", ["k", "doc_id", "seg_id"])
    postings = keyframe_postings(oracle_index, q, layout="sets")
    for k, post in enumerate(postings):
        mine = words[words[:, 0] == k + 1]
        # the toolbox enumerates all 2^w words; the index only knows those with postings
        first, n = FEATURE_SETS[q.feature_sets[k]]
        m, v = int(q.mask[k]) >> first, int(q.value[k]) >> first
        assert naive_fuzzy_words(m, v, n) == sorted(mine[:, 1].tolist())
        present = mine[mine[:, 2] > 0]
        np.testing.assert_array_equal(post.words.astype(np.int64), present[:, 1])
        np.testing.assert_array_equal(post.list_lengths, present[:, 2])
        expected = union[union[:, 0] == k + 1, 1:]
        np.testing.assert_array_equal(np.stack([post.doc + 1, post.seg + 1], 1).reshape(-1, 2),
                                      expected)


@pytest.mark.shared
@pytest.mark.parametrize("layout", ["sets", "full"])
@pytest.mark.parametrize("name", QUERIES)
def test_keyframe_intervals_equal_oracle(oracle_dir, oracle_index, name, layout):
    q = toolbox_query(oracle_dir, name)
    expected = int_table(oracle_dir / KF / "search" / name / "intervals.csv",
                         ["k", "doc_id", "start_frame", "end_frame"])
    got = keyframe_intervals(oracle_index, q, layout=layout)
    assert len(got) == q.n_keyframes
    for k, iv in enumerate(got):
        np.testing.assert_array_equal(rows(iv).reshape(-1, 3),
                                      expected[expected[:, 0] == k + 1, 1:])


@pytest.mark.shared
@pytest.mark.parametrize("layout", ["sets", "full"])
@pytest.mark.parametrize("setting", SETTINGS)
@pytest.mark.parametrize("name", QUERIES)
def test_search_equals_oracle(oracle_dir, oracle_index, query_table, name, setting, layout):
    q = toolbox_query(oracle_dir, name)
    el, er = margins(query_table, name, setting)
    segs, hits = keyframe_search(oracle_index, q, extend_left=el, extend_right=er,
                                 return_hits=True, layout=layout)
    base = oracle_dir / KF / "search" / name
    cols = ["doc_id", "start_frame", "end_frame"]
    expected = int_table(base / f"{setting}_segments_C.csv", cols)
    np.testing.assert_array_equal(rows(segs).reshape(-1, 3), expected)
    np.testing.assert_array_equal(expected,
                                  int_table(base / f"{setting}_segments_matlab.csv", cols))
    np.testing.assert_array_equal(rows(hits).reshape(-1, 3),
                                  int_table(base / f"{setting}_hits_matlab.csv",
                                            ["doc_id", "hit_start", "hit_end"]))
    timing = {(r["query"], r["setting"]): r
              for r in read_rows(oracle_dir / KF / "search" / "timing.csv")}
    assert segs.n_frames == int(timing[name, setting]["framesTotalNum"])
    assert len(segs) == int(timing[name, setting]["n_segments"])


@pytest.mark.shared
@pytest.mark.parametrize("name", QUERIES)
def test_brute_force_equals_search_on_oracle_documents(oracle_dir, oracle_words, oracle_index,
                                                       query_table, name):
    q = toolbox_query(oracle_dir, name)
    for setting in SETTINGS:
        el, er = margins(query_table, name, setting)
        expected = naive_keyframe_search(oracle_words, q.mask, q.value, q.d_min, q.d_max,
                                         extend_left=el, extend_right=er)
        got = keyframe_search(oracle_index, q, extend_left=el, extend_right=er)
        assert [tuple(r) for r in rows(got, False).tolist()] == expected


@pytest.mark.shared
@pytest.mark.parametrize("testset", ["testset1", "testset3"])
def test_extra_testsets(oracle_dir, testset):
    """The hand-made cases in the comments of keyframeSearch.m, as 3-bit documents."""
    base = oracle_dir / KF / "extra_testsets"
    bits = np.loadtxt(base / f"{testset}_features.csv", delimiter=",", skiprows=1, dtype=np.int64)
    words = words_from_bits(bits)  # b1..b3 -> features 1..3 (bits 0..2 of the upper set)
    summary = {r["testset"]: r for r in read_rows(base / "summary.csv")}[testset]
    pos = ast.literal_eval(summary["positions"].replace(" ", ","))
    q = KeyframeQuery.from_stiffness([1, 2, 4], [1, 2, 4], np.array(pos) - 1,
                                     float(summary["stiffness"]), template_length=max(pos),
                                     feature_sets=("upper",) * 3)
    gaps = int_table(base / f"{testset}_gaps.csv", ["d_min", "d_max"])
    np.testing.assert_array_equal(q.d_min, gaps[:, 0])
    np.testing.assert_array_equal(q.d_max, np.where(gaps[:, 1] < 0, UNBOUNDED, gaps[:, 1]))
    index = build_index([words], feature_sets=INDEX_PARTS)
    cols = index.to_columns()
    sel = cols["feature_set"] == 0
    np.testing.assert_array_equal(
        np.stack([cols["doc"][sel] + 1, cols["seg"][sel] + 1, cols["word"][sel].astype(np.int64),
                  cols["start_frame"][sel] + 1, cols["n_frames"][sel]], 1),
        int_table(base / f"{testset}_segments.csv",
                  ["doc_id", "seg_id", "word", "start_frame", "n_frames"]))
    ivs = int_table(base / f"{testset}_intervals.csv", ["k", "doc_id", "start_frame", "end_frame"])
    for k, iv in enumerate(keyframe_intervals(index, q)):
        np.testing.assert_array_equal(rows(iv).reshape(-1, 3), ivs[ivs[:, 0] == k + 1, 1:])
    el, er = int(summary["extendLeft"]), int(summary["extendRight"])
    for layout in ("sets", "full"):
        segs, hits = keyframe_search(index, q, extend_left=el, extend_right=er, return_hits=True,
                                     layout=layout)
        np.testing.assert_array_equal(rows(hits), int_table(base / f"{testset}_hits_matlab.csv",
                                                            ["doc_id", "hit_start", "hit_end"]))
        expected = int_table(base / f"{testset}_segments_C.csv",
                             ["doc_id", "start_frame", "end_frame"])
        np.testing.assert_array_equal(rows(segs), expected)
        comment = ast.literal_eval(summary["expected_in_comment"].replace(" ", ","))
        assert rows(segs).tolist() == [comment]


# ---- brute force on seeded random documents and queries ---------------------------


def _random_case(rng, *, cross_sets):
    """Documents made of runs of a few poses, and a query whose keyframes match some frames."""
    bits = (np.array([0, 1, 2, 14, 15, 26, 27, 39]) if cross_sets else np.arange(5))
    n_docs = int(rng.integers(1, 6))
    docs = []
    for d in range(n_docs):
        n = 0 if rng.random() < 0.1 else int(rng.integers(1, 90))
        out = []
        while len(out) < n:
            w = 0
            for b in bits:
                if rng.random() < 0.5:
                    w |= 1 << int(b)
            out.extend([w] * int(rng.integers(1, 7)))
        docs.append(np.array(out[:n], dtype=np.uint64))
    K = int(rng.integers(1, 6))
    mask, value = [], []
    for _ in range(K):
        chosen = rng.choice(bits, size=int(rng.integers(0, 4)), replace=False)
        m = sum(1 << int(b) for b in chosen)
        v = int(rng.integers(0, 1 << 40)) & m
        if rng.random() < 0.05:  # a keyframe that cannot match (bit never set)
            m |= 1 << 20
            v |= 1 << 20
        mask.append(m)
        value.append(v)
    d_min, d_max = [], []
    for _ in range(K - 1):
        r = rng.random()
        if r < 0.15:  # same template position: [0, 0]
            lo, hi = 0, 0
        elif r < 0.3:  # stiffness 0: [0, inf]
            lo, hi = 0, UNBOUNDED
        else:
            lo = int(rng.integers(0, 6))
            hi = lo + int(rng.integers(0, 10))
        d_min.append(lo)
        d_max.append(hi)
    q = KeyframeQuery(np.array(mask, np.uint64), np.array(value, np.uint64), np.arange(K),
                      d_min, d_max, K)
    return docs, q, int(rng.integers(0, 5)), int(rng.integers(0, 5))


@pytest.mark.slow
@pytest.mark.parametrize("cross_sets", [False, True])
def test_brute_force_equals_search_random(cross_sets):
    rng = np.random.default_rng(2024 + cross_sets)
    for case in range(400):
        docs, q, el, er = _random_case(rng, cross_sets=cross_sets)
        expected, path_hits = naive_keyframe_search(docs, q.mask, q.value, q.d_min, q.d_max,
                                                    extend_left=el, extend_right=er,
                                                    return_hits=True)
        reachable = naive_reachable_last(docs, q.mask, q.value, q.d_min, q.d_max)
        first_hits = None
        for parts in (("upper", "lower", "mix"), ("full",), INDEX_PARTS):
            index = build_index(docs, feature_sets=parts)
            segs, hits = keyframe_search(index, q, extend_left=el, extend_right=er,
                                         return_hits=True)
            got = [tuple(r) for r in rows(segs, False).tolist()]
            assert got == expected, f"case {case}, parts {parts}"
            # every raw hit is the hit of a path of matching runs, ordered per document
            h = rows(hits, False)
            assert {tuple(r) for r in h.tolist()} <= set(path_hits)
            for d in np.unique(h[:, 0]):
                hd = h[h[:, 0] == d]
                assert (np.diff(hd[:, 1]) >= 0).all() and (np.diff(hd[:, 2]) >= 0).all()
            # the raw hits do not depend on the layout either
            first_hits = h.tolist() if first_hits is None else first_hits
            assert h.tolist() == first_hits
            # every frame of the last keyframe on an admissible chain is covered
            for d, t in reachable:
                assert any(sd == d and s <= t <= e for sd, s, e in got)
            # parallel document ranges give the same result
            s3, h3 = keyframe_search(index, q, extend_left=el, extend_right=er, return_hits=True,
                                     n_threads=3)
            assert s3.as_array().tolist() == segs.as_array().tolist()
            assert h3.as_array().tolist() == hits.as_array().tolist()
            hit_docs = keyframe_hit_documents(index, [q])[0]
            assert np.flatnonzero(hit_docs).tolist() == sorted({r[0] for r in got})


@pytest.mark.slow
def test_batch_and_cache_equal_single_searches():
    rng = np.random.default_rng(7)
    docs = []
    for _ in range(6):
        d, _, _, _ = _random_case(rng, cross_sets=True)
        docs.extend(d)
    queries = [_random_case(rng, cross_sets=True)[1] for _ in range(30)]
    queries += queries[:5]  # repeated queries share keyframes
    ext = rng.integers(0, 4, size=len(queries))
    for parts in (("upper", "lower", "mix"), ("full",)):
        index = build_index(docs, feature_sets=parts)
        single = [keyframe_search(index, q, extend_left=int(e), extend_right=int(e) + 1)
                  for q, e in zip(queries, ext)]
        cache = {}
        for use_cache in (None, cache, cache):
            batch = keyframe_search_batch(index, queries, extend_left=ext, extend_right=ext + 1,
                                          cache=use_cache)
            for a, b in zip(single, batch):
                assert a.as_array().tolist() == b.as_array().tolist()
            hit = keyframe_hit_documents(index, queries, cache=use_cache)
            for row, s in zip(hit, single):
                assert np.flatnonzero(row).tolist() == sorted(set(s.doc.tolist()))
        assert cache  # filled


def test_empty_documents_and_no_match():
    index = build_index([np.zeros(0, np.uint64)] * 3 + [np.full(5, 3, np.uint64)])
    q = KeyframeQuery([1, 2], [1, 2], [0, 1], [0], [4], 2)
    segs = keyframe_search(index, q, extend_left=9, extend_right=9)
    assert segs.as_array().tolist() == [[3, 0, 4]]
    none = KeyframeQuery([1 << 5], [1 << 5], [0], [], [], 1)
    assert len(keyframe_search(index, none)) == 0
    assert not keyframe_hit_documents(index, [none]).any()


@pytest.mark.shared
def test_single_keyframe_hits_are_its_intervals(oracle_dir, oracle_index):
    q = toolbox_query(oracle_dir, "rotateArmsBothBackward1Reps")
    one = KeyframeQuery(q.mask[:1], q.value[:1], q.positions[:1], [], [], q.template_length,
                        q.feature_sets[:1])
    segs, hits = keyframe_search(oracle_index, one, return_hits=True)
    iv = keyframe_intervals(oracle_index, one)[0]
    assert hits.as_array().tolist() == iv.as_array().tolist()
    assert segs.as_array().tolist() == iv.as_array().tolist()  # runs never overlap


# ---- the document filter (keyframes from the fewest postings up) -------------------

STRATEGIES = (_AUTO, _HEAP, _BITSET, _FORWARD)


def _unfiltered(index, q, el, er, layout=None):
    """Segments and raw hits from every keyframe's intervals in every document (no filter)."""
    keys, q_kf, q_kf_offset, d_min, d_max = _plan(index, [q], layout)
    segs, _, hits, _ = _chain_batch_kernel(*_intervals(index, keys), q_kf, q_kf_offset, d_min,
                                           d_max, index.doc_lengths, np.array([el]),
                                           np.array([er]), True)
    return segs.tolist(), hits.tolist()


def check_document_filter(index, q, el, er, layout=None):
    """The filtered search equals the unfiltered one, for every method and document split.

    Also checks the invariant behind it: each keyframe's filtered intervals are
    its full intervals in a set of documents that contains every document
    where all keyframes match -- exactly those when every keyframe is answered
    by one index part (else a keyframe's parts are filtered one by one).
    Returns (#documents where some keyframe matches, #documents where all do).
    """
    segs, hits = _unfiltered(index, q, el, er, layout)
    keys, *_ = _plan(index, [q], layout)
    full = keyframe_intervals(index, q, layout=layout)
    both = set(range(index.n_docs))
    for iv in full:
        both &= set(iv.doc.tolist())
    kf_ids = np.arange(len(keys))
    for strategy in STRATEGIES:
        for n_threads in (1, 3):
            s, h = _search(index, [q], np.array([el]), np.array([er]), True, layout, n_threads,
                           strategy=strategy)
            assert s[0].tolist() == segs and h[0].tolist() == hits, (strategy, n_threads)
        doc, start, end, off = _query_intervals_kernel(*index.kernel_arrays(), *_sub_arrays(keys),
                                                       kf_ids, 0, index.n_docs, strategy)
        _, q_kf, _, _, _ = _plan(index, [q], layout)
        for k, iv in enumerate(full):
            a, b = off[q_kf[k]], off[q_kf[k] + 1]
            kept = set(doc[a:b].tolist())
            if all(len(subs) == 1 for subs in keys):
                assert kept == both
            keep = np.isin(iv.doc, list(both | kept))
            np.testing.assert_array_equal(
                np.stack([doc[a:b], start[a:b], end[a:b]]),
                np.stack([iv.doc[keep], iv.start[keep], iv.end[keep]]))
    assert keyframe_hit_documents(index, [q], layout=layout)[0].tolist() == \
        [d in {r[0] for r in segs} for d in range(index.n_docs)]
    some = set()
    for iv in full:
        some |= set(iv.doc.tolist())
    return len(some), len(both)


def _rare_case(rng):
    """Many documents; one keyframe needs a bit that only a few documents have."""
    bits = np.array([0, 1, 2, 14, 15, 26, 27, 39])
    rare = 1 << 20
    n_docs = int(rng.integers(20, 60))
    rare_docs = set(rng.choice(n_docs, size=int(rng.integers(0, 4)), replace=False).tolist())
    docs = []
    for d in range(n_docs):
        n = int(rng.integers(0, 70))
        out = []
        while len(out) < n:
            w = sum(1 << int(b) for b in bits if rng.random() < 0.5)
            if d in rare_docs and rng.random() < 0.4:
                w |= rare
            out.extend([w] * int(rng.integers(1, 6)))
        docs.append(np.array(out[:n], dtype=np.uint64))
    K = int(rng.integers(2, 6))
    mask, value = [], []
    for _ in range(K):
        chosen = rng.choice(bits, size=int(rng.integers(0, 3)), replace=False)
        m = sum(1 << int(b) for b in chosen)
        mask.append(m)
        value.append(int(rng.integers(0, 1 << 40)) & m)
    r = int(rng.integers(K))
    mask[r] |= rare
    value[r] |= rare
    d_min = [int(x) for x in rng.integers(0, 4, K - 1)]
    d_max = [lo + int(rng.integers(0, 12)) if rng.random() < 0.8 else UNBOUNDED for lo in d_min]
    q = KeyframeQuery(np.array(mask, np.uint64), np.array(value, np.uint64), np.arange(K),
                      d_min, d_max, K)
    return docs, q, int(rng.integers(0, 4)), int(rng.integers(0, 4))


@pytest.mark.slow
def test_document_filter_changes_nothing_random():
    rng = np.random.default_rng(31)
    removed = 0
    for case in range(60):
        docs, q, el, er = _rare_case(rng)
        expected, path_hits = naive_keyframe_search(docs, q.mask, q.value, q.d_min, q.d_max,
                                                    extend_left=el, extend_right=er,
                                                    return_hits=True)
        for parts in (("upper", "lower", "mix"), ("full",)):
            index = build_index(docs, feature_sets=parts)
            some, kept = check_document_filter(index, q, el, er)
            removed += some - kept
            got = keyframe_search(index, q, extend_left=el, extend_right=er)
            assert [tuple(r) for r in rows(got, False).tolist()] == expected, case
    assert removed > 500  # the filter did remove documents


@pytest.mark.shared
@pytest.mark.parametrize("name", QUERIES)
def test_document_filter_changes_nothing_on_oracle_documents(oracle_dir, oracle_index,
                                                             query_table, name):
    """Toolbox queries as they are, and with one keyframe narrowed to the exact set word of a
    hit's first frame (it then matches in few documents, and that hit survives)."""
    q = toolbox_query(oracle_dir, name)
    el, er = margins(query_table, name, "annot")
    for layout in (None, "full"):
        check_document_filter(oracle_index, q, el, er, layout)
    _, hits = keyframe_search(oracle_index, q, return_hits=True)
    for i in range(0, len(hits), max(1, len(hits) // 3)):
        d, t = int(hits.doc[i]), int(hits.start[i])
        first, n = FEATURE_SETS[q.feature_sets[0]]
        sel = ((1 << n) - 1) << first
        word = int(oracle_index.segments("full", d)[2][
            np.searchsorted(oracle_index.segments("full", d)[0], t, side="right") - 1])
        mask, value = q.mask.copy(), q.value.copy()
        mask[0], value[0] = sel, word & sel
        rare = KeyframeQuery(mask, value, q.positions, q.d_min, q.d_max, q.template_length,
                             q.feature_sets)
        for layout in (None, "full"):
            some, kept = check_document_filter(oracle_index, rare, el, er, layout)
            assert 1 <= kept < oracle_index.n_docs
        segs = keyframe_search(oracle_index, rare, extend_left=el, extend_right=er)
        assert d in segs.doc


# ---- building queries -----------------------------------------------------------


@pytest.mark.parametrize("delta, s, expected", [
    (5, 0.0, (0, UNBOUNDED)),      # stiffness 0: unbounded
    (0, 0.0, (0, UNBOUNDED)),      # 0 * inf = NaN -> inf
    (4, 1.0, (4, 4)),              # stiff: exactly the template distance
    (0, 0.6, (0, 0)),              # same template position
    (10, 0.7, (7, 14)),
    (5, 0.8, (4, 6)),
    (2, 0.5, (1, 4)),
    (7, 0.4, (3, 17)),
])
def test_stiffness_to_gap_bounds(delta, s, expected):
    q = KeyframeQuery.from_stiffness([1, 1], [1, 1], [3, 3 + delta], s, template_length=20 + delta)
    assert (int(q.d_min[0]), int(q.d_max[0])) == expected
    assert stiffness_bounds([float(delta)], [s])[1][0] == expected[1]


def test_stiffness_errors():
    with pytest.raises(ParameterError, match="stiffness"):
        KeyframeQuery.from_stiffness([1, 1], [1, 1], [0, 4], 1.2, template_length=5)
    with pytest.raises(ParameterError, match="stiffness"):
        KeyframeQuery.from_stiffness([1, 1, 1], [1, 1, 1], [0, 4, 5], [0.5], template_length=6)
    with pytest.raises(ParameterError, match="stiffness"):
        KeyframeQuery.from_stiffness([1, 1], [1, 1], [0, 4], float("nan"), template_length=5)
    with pytest.raises(ParameterError, match="ascending"):
        KeyframeQuery.from_stiffness([1, 1], [1, 1], [4, 0], 0.5, template_length=5)
    with pytest.raises(ParameterError, match="d_max"):  # only reachable with fractional distances
        stiffness_bounds([0.5], [0.9])


def test_query_validation():
    ok = dict(mask=[3, 1], value=[1, 1], positions=[0, 2], d_min=[1], d_max=[3], template_length=4)
    KeyframeQuery(**ok)
    for change, pattern in [({"value": [4, 1]}, "outside mask"),
                            ({"mask": [1 << 40, 1], "value": [0, 1]}, "bit 39"),
                            ({"positions": [2, 0]}, "non-decreasing"),
                            ({"d_min": [4]}, "d_max"),
                            ({"d_min": [-1]}, "negative"),
                            ({"d_max": [math.nan]}, "NaN"),
                            ({"d_max": [3, 4]}, "entries"),
                            ({"template_length": 2}, "template_length"),
                            ({"mask": [1 << 20, 1], "value": [0, 1],
                              "feature_sets": ("upper", None)}, "outside that set")]:
        with pytest.raises(ParameterError, match=pattern):
            KeyframeQuery(**{**ok, **change})
    q = KeyframeQuery(**{**ok, "d_max": [math.inf]})
    assert q.d_max[0] == UNBOUNDED


def test_toolbox_vectors():
    v = [1, 0, 0.5, 1, 0.5, 0, 0, 0, 0, 0, 0, 0]
    m, val = keyframe_mask_value(v, feature_set="lower")
    assert m == 0b111111101011 << 14 and val == 0b1001 << 14
    q = KeyframeQuery.from_toolbox([v, v], [2, 2], [3, 7], 0.5, template_length=9)
    np.testing.assert_array_equal(q.to_vectors()[0, 14:26], v)
    assert q.to_vectors()[0, :14].tolist() == [0.5] * 14
    assert q.positions.tolist() == [2, 6] and annot_margins(q) == (4, 4)
    with pytest.raises(ParameterError, match="0, 1 or 0.5"):
        keyframe_mask_value([0.3] * 12, feature_set="lower")
    with pytest.raises(ParameterError, match="needs 14"):
        KeyframeQuery.from_toolbox([[0] * 12], [1], [1], [], template_length=1)
    with pytest.raises(ParameterError, match="set_index"):
        KeyframeQuery.from_toolbox([[0] * 12], [4], [1], [], template_length=1)
    short = [1] * 13  # a stale 39-feature vector for the 14-bit mix set
    with pytest.raises(ParameterError, match="needs 14"):
        KeyframeQuery.from_toolbox([short], [3], [1], [], template_length=1)
    padded = KeyframeQuery.from_toolbox([short], [3], [1], [], template_length=1,
                                        pad_short_mix=True)
    assert padded.to_vectors()[0, 26:].tolist() == [1] * 13 + [0.5]


@pytest.mark.shared
def test_search_parameter_errors(oracle_index, oracle_dir):
    q = toolbox_query(oracle_dir, "squat1Reps")
    with pytest.raises(ParameterError, match="extend_left"):
        keyframe_search(oracle_index, q, extend_left=-1)
    with pytest.raises(ParameterError, match="layout"):
        keyframe_search(oracle_index, q, layout="legs")
    with pytest.raises(ParameterError, match="n_threads"):
        keyframe_search(oracle_index, q, n_threads=0)
    with pytest.raises(ParameterError, match="KeyframeQuery"):
        keyframe_search_batch(oracle_index, [q, "squat"])
    cross = KeyframeQuery([1 | 1 << 20], [1], [0], [], [], 1)
    with pytest.raises(ParameterError, match="several feature sets"):
        keyframe_postings(oracle_index, cross, layout="sets")
    with pytest.raises(ParameterError, match="no part"):
        keyframe_search(build_index([np.zeros(4, np.uint64)], feature_sets=("upper",)), cross)


# ---- heuristic chooser (§8.1) -----------------------------------------------------


def _templates(oracle_dir):
    for d in sorted((oracle_dir / "templates").iterdir()):
        yield d.name, np.loadtxt(d / "template_quantized_0.05.csv", delimiter=",", ndmin=2)


@pytest.mark.shared
@pytest.mark.parametrize("feature_set", [None, "upper", "lower", "mix"])
def test_chooser_equals_toolbox_rule(oracle_dir, feature_set):
    for name, dense in _templates(oracle_dir):  # (40, L) of 0 / 1 / 0.5
        mask = words_from_bits((dense != 0.5).T.astype(np.int64))
        value = words_from_bits((dense == 1).T.astype(np.int64))
        first, n = FEATURE_SETS[feature_set] if feature_set else (0, 40)
        for k in (1, 2, 3, 4):
            q = choose_keyframes_equally_distributed(mask, value, n_keyframes=k,
                                                     feature_set=feature_set)
            expected = naive_choose_equally_distributed(dense[first:first + n], k)
            assert q.positions.tolist() == [p - 1 for p in expected], name
            sel = sum(1 << b for b in range(first, first + n))
            assert q.mask.tolist() == [int(mask[p]) & sel for p in q.positions]
            assert q.value.tolist() == [int(value[p]) & sel for p in q.positions]
            assert q.template_length == dense.shape[1]
            lo, hi = stiffness_bounds(np.diff(q.positions), np.full(k - 1, 0.5))
            assert q.d_min.tolist() == lo.tolist() and q.d_max.tolist() == hi.tolist()


def test_chooser_rejects_short_templates():
    with pytest.raises(ParameterError, match="too short"):
        choose_keyframes_equally_distributed(np.zeros(5, np.uint64), np.zeros(5, np.uint64),
                                             n_keyframes=4)
