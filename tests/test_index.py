"""Inverted file index (KEYFRAMES.md §1, §3) against the toolbox oracle and naive references."""
from pathlib import Path

import numpy as np
import pytest

from mocapdb.errors import ParameterError
from mocapdb.keyframes import INDEX_PARTS, PART_BITS, Index, build_index, fuzzy_intervals, fuzzy_postings
from mocapdb.keyframes.index import _fuzzy
from naive_keyframes import (int_table, load_feat30_words, naive_fuzzy_words, naive_match,
                             naive_postings, naive_runs, naive_segments, naive_union, read_rows)

TOOLBOX_NAMES = {"upper": "AK_upper", "lower": "AK_lower", "mix": "AK_mix_avr"}


@pytest.fixture(scope="module")
def oracle_docs(oracle_dir):
    rows = read_rows(oracle_dir / "keyframes" / "index" / "documents.csv")
    return rows, [load_feat30_words(oracle_dir, Path(r["file"]).stem) for r in rows]


@pytest.fixture(scope="module")
def oracle_index(oracle_docs):
    return build_index(oracle_docs[1], feature_sets=INDEX_PARTS)


def random_docs(rng, n_docs, max_len, *, n_poses=6, empty=True):
    """Documents of runs of a few random 40-bit poses (some empty, some one frame)."""
    poses = rng.integers(0, 1 << 40, size=n_poses, dtype=np.uint64)
    docs = []
    for d in range(n_docs):
        n = 0 if (empty and d % 7 == 3) else (1 if d % 7 == 5 else int(rng.integers(1, max_len)))
        out = []
        while len(out) < n:
            w = poses[rng.integers(n_poses)] ^ (np.uint64(1) << np.uint64(rng.integers(40)))
            out.extend([w] * int(rng.integers(1, 6)))
        docs.append(np.array(out[:n], dtype=np.uint64))
    return docs


# ---- the toolbox's index over 77 documents --------------------------------


@pytest.mark.shared
@pytest.mark.parametrize("part", list(TOOLBOX_NAMES))
def test_segments_equal_oracle(oracle_index, oracle_dir, part):
    expected = int_table(oracle_dir / "keyframes" / "index" / f"{TOOLBOX_NAMES[part]}_segments.csv",
                         ["doc_id", "seg_id", "word", "start_frame", "n_frames"])
    cols = oracle_index.to_columns()
    sel = cols["feature_set"] == INDEX_PARTS.index(part)
    got = np.stack([cols["doc"][sel] + 1, cols["seg"][sel] + 1, cols["word"][sel].astype(np.int64),
                    cols["start_frame"][sel] + 1, cols["n_frames"][sel]], axis=1)
    np.testing.assert_array_equal(got, expected)


@pytest.mark.shared
@pytest.mark.parametrize("part", list(TOOLBOX_NAMES))
def test_posting_lists_equal_oracle(oracle_index, oracle_dir, part):
    lists = int_table(oracle_dir / "keyframes" / "index" / f"{TOOLBOX_NAMES[part]}_lists.csv",
                      ["word", "rank", "doc_id", "seg_id"])
    p = oracle_index.part_id(part)
    lo, hi = oracle_index.part_word_offset[p], oracle_index.part_word_offset[p + 1]
    words = oracle_index.words[lo:hi]
    np.testing.assert_array_equal(words.astype(np.int64), np.unique(lists[:, 0]))
    for w in np.unique(lists[:, 0]):
        rows = lists[lists[:, 0] == w]
        rows = rows[np.argsort(rows[:, 1])]
        doc, seg = oracle_index.posting_list(part, int(w))
        np.testing.assert_array_equal(np.stack([doc + 1, seg + 1], 1), rows[:, 2:])
    absent = next(w for w in range(1 << PART_BITS[part][1]) if w not in set(lists[:, 0].tolist()))
    assert oracle_index.posting_list(part, absent)[0].size == 0


@pytest.mark.shared
def test_document_table_equals_oracle(oracle_index, oracle_docs):
    rows = oracle_docs[0]
    np.testing.assert_array_equal(oracle_index.doc_lengths, [int(r["n_frames_30"]) for r in rows])
    for part, name in TOOLBOX_NAMES.items():
        p = oracle_index.part_id(part)
        np.testing.assert_array_equal(np.diff(oracle_index.doc_seg_offset[p]),
                                      [int(r[f"n_segments_{name}"]) for r in rows])


@pytest.mark.shared
def test_segments_accessor(oracle_index, oracle_docs):
    words = oracle_docs[1][75]  # 86_09, the longest document
    for part in INDEX_PARTS:
        start, length, word = oracle_index.segments(part, 75)
        first, n = PART_BITS[part]
        expected = naive_segments(words, first, n)
        assert [tuple(x) for x in zip(word.tolist(), start.tolist(), length.tolist())] == expected


# ---- build vs. naive, columns round trip ------------------------------------


@pytest.mark.parametrize("seed", range(4))
def test_build_equals_naive(seed):
    rng = np.random.default_rng(seed)
    docs = random_docs(rng, 15, 60)
    index = build_index(docs, feature_sets=INDEX_PARTS)
    for part in INDEX_PARTS:
        first, n = PART_BITS[part]
        segs = [naive_segments(w, first, n) for w in docs]
        for d, expected in enumerate(segs):
            start, length, word = index.segments(part, d)
            assert list(zip(word.tolist(), start.tolist(), length.tolist())) == expected
        lists = naive_postings(segs)
        p = index.part_id(part)
        words = index.words[index.part_word_offset[p]:index.part_word_offset[p + 1]]
        assert sorted(lists) == words.tolist()
        for w, postings in lists.items():
            doc, seg = index.posting_list(part, w)
            assert list(zip(doc.tolist(), seg.tolist())) == postings


def test_flat_input_equals_list_input():
    docs = random_docs(np.random.default_rng(9), 12, 40)
    a = build_index(docs, feature_sets=INDEX_PARTS)
    b = build_index(np.concatenate(docs), doc_lengths=[len(d) for d in docs],
                    feature_sets=INDEX_PARTS)
    for f in Index.__dataclass_fields__:
        if f != "parts":
            np.testing.assert_array_equal(getattr(a, f), getattr(b, f), err_msg=f)


@pytest.mark.parametrize("names", [False, True])
@pytest.mark.parametrize("order", ["sorted", "shuffled"])
def test_columns_round_trip_any_order(names, order):
    docs = random_docs(np.random.default_rng(5), 20, 50)
    index = build_index(docs, feature_sets=("upper", "mix", "full"))
    cols = index.to_columns()
    perm = np.random.default_rng(1).permutation(len(cols["doc"]))
    shuffled = {k: v[perm] if order == "shuffled" else v for k, v in cols.items()}
    if names:  # part names instead of codes
        shuffled["feature_set"] = np.array([INDEX_PARTS[c] for c in shuffled["feature_set"]],
                                           dtype=object)
    back = Index.from_columns(**shuffled, doc_lengths=index.doc_lengths)
    assert back.parts == ("upper", "mix", "full")
    for f in Index.__dataclass_fields__:
        if f != "parts":
            np.testing.assert_array_equal(getattr(index, f), getattr(back, f), err_msg=f)


def test_from_columns_rejects_inconsistent_tables():
    docs = random_docs(np.random.default_rng(2), 6, 30, empty=False)
    index = build_index(docs, feature_sets=("lower",))
    cols = index.to_columns()
    lengths = index.doc_lengths

    def without(i):
        return {k: np.delete(v, i) for k, v in cols.items()}

    with pytest.raises(ParameterError, match="tile|seg"):
        Index.from_columns(**without(3), doc_lengths=lengths)
    twice = {k: v.copy() for k, v in cols.items()}
    twice["seg"][4] = twice["seg"][3]  # a seg number twice, one missing
    with pytest.raises(ParameterError, match="tile|seg"):
        Index.from_columns(**twice, doc_lengths=lengths)
    bad = {k: v.copy() for k, v in cols.items()}
    bad["n_frames"][0] += 1
    bad["start_frame"][1:int(np.diff(index.doc_seg_offset[0])[0])] += 1  # shifted, too long
    with pytest.raises(ParameterError, match="tile"):
        Index.from_columns(**bad, doc_lengths=lengths)
    bad = {k: v.copy() for k, v in cols.items()}
    bad["start_frame"][2] += 1
    with pytest.raises(ParameterError, match="tile"):
        Index.from_columns(**bad, doc_lengths=lengths)
    with pytest.raises(ParameterError, match="doc ids"):
        Index.from_columns(**cols, doc_lengths=lengths[:-1])
    bad = dict(cols, feature_set=np.array(["legs"] * len(cols["doc"])))
    with pytest.raises(ParameterError, match="unknown part"):
        Index.from_columns(**bad, doc_lengths=lengths)
    bad = dict(cols, word=cols["word"][:-1])
    with pytest.raises(ParameterError, match="column word"):
        Index.from_columns(**bad, doc_lengths=lengths)


def test_build_rejects_bad_input():
    with pytest.raises(ParameterError, match="feature_sets"):
        build_index([np.zeros(3, np.uint64)], feature_sets=("arms",))
    with pytest.raises(ParameterError, match="doc_lengths sum"):
        build_index(np.zeros(5, np.uint64), doc_lengths=[2, 2])
    with pytest.raises(ParameterError, match="negative"):
        build_index([np.array([1, -1])])
    with pytest.raises(ParameterError, match="uint64"):
        build_index([np.array([0.5, 1.0])])
    with pytest.raises(ParameterError, match="part"):
        build_index([np.zeros(3, np.uint64)]).part_id("full")


# ---- fuzzy keyframes against one part ---------------------------------------


@pytest.mark.parametrize("seed", range(3))
def test_fuzzy_postings_equal_wildcard_enumeration(seed):
    """Word matching == the toolbox's 2^w enumeration; both union strategies agree."""
    rng = np.random.default_rng(seed)
    docs = random_docs(rng, 25, 80, n_poses=10)
    index = build_index(docs, feature_sets=INDEX_PARTS)
    for part in INDEX_PARTS:
        first, n = PART_BITS[part]
        segs = [naive_segments(w, first, n) for w in docs]
        lists = naive_postings(segs)
        for _ in range(12):
            n_wild = int(rng.integers(0, min(n, 12) + 1))
            mask = ((1 << n) - 1) & ~sum(1 << int(b) for b in rng.choice(n, n_wild, replace=False))
            # value from a word of the index so that matches exist, or random
            some = int(rng.choice(list(lists))) if rng.random() < 0.7 else int(rng.integers(1 << n))
            value = some & mask
            if part == "full":
                words = sorted(w for w in lists if (w & mask) == value)
            else:
                words = [w for w in naive_fuzzy_words(mask, value, n) if w in lists]
            expected_union = naive_union(lists, words)
            for strategy in (1, 2):
                w_idx, doc, start, end, u_doc, u_seg = _fuzzy(index, part, mask, value, True,
                                                              strategy)
                assert index.words[w_idx].tolist() == words
                assert list(zip(u_doc.tolist(), u_seg.tolist())) == expected_union
                expected_iv = [(d, s, e) for d, wd in enumerate(docs)
                               for s, e in naive_runs(naive_match(
                                   [(int(x) >> first) & ((1 << n) - 1) for x in wd], mask, value))]
                assert list(zip(doc.tolist(), start.tolist(), end.tolist())) == expected_iv
            post = fuzzy_postings(index, part, mask, value)
            assert post.words.tolist() == words
            assert post.list_lengths.tolist() == [len(lists[w]) for w in words]
            iv = fuzzy_intervals(index, part, mask, value)
            assert list(zip(iv.doc.tolist(), iv.start.tolist(), iv.end.tolist())) == expected_iv


@pytest.mark.shared
def test_fuzzy_rejects_words_outside_the_part(oracle_index):
    with pytest.raises(ParameterError, match="local"):
        fuzzy_postings(oracle_index, "lower", 1 << 12, 0)
    with pytest.raises(ParameterError, match="value bits"):
        fuzzy_intervals(oracle_index, "upper", 0b01, 0b11)


@pytest.mark.shared
@pytest.mark.parametrize("part", INDEX_PARTS)
def test_union_strategies_on_oracle_documents(oracle_docs, oracle_index, part):
    """Heap merge and bitset sweep give the naive union on real data."""
    rng = np.random.default_rng(11)
    words_per_doc = oracle_docs[1]
    first, n = PART_BITS[part]
    lists = naive_postings([naive_segments(w, first, n) for w in words_per_doc])
    known = sorted(lists)
    for _ in range(25):
        n_wild = int(rng.integers(0, n - 2))
        mask = ((1 << n) - 1) & ~sum(1 << int(b) for b in rng.choice(n, n_wild, replace=False))
        value = known[int(rng.integers(len(known)))] & mask
        words = [w for w in known if (w & mask) == value]
        expected = naive_union(lists, words)
        for strategy in (1, 2):
            w_idx, _, _, _, u_doc, u_seg = _fuzzy(oracle_index, part, mask, value, True, strategy)
            assert oracle_index.words[w_idx].tolist() == words
            assert list(zip(u_doc.tolist(), u_seg.tolist())) == expected
