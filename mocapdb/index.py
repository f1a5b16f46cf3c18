"""Inverted file index over packed feature words (KEYFRAMES.md §1, §3).

A document is a sequence of packed 30 Hz feature words (``uint64``, bit k-1 =
feature k).  The index stores, per *part*, the maximal runs of constant word
("segments") of every document and one posting list per distinct word.  A part
is one of the toolbox's feature sets (``"upper"``, ``"lower"``, ``"mix"``: the
word restricted to the set's bits, shifted so that feature 1 of the set is
bit 0, exactly as the toolbox's per-set indexes) or ``"full"`` (the whole
40-bit word).  Both layouts answer the same keyframe queries with the same
frame intervals; they differ in size and speed
(``benchmarks/bench_keyframes_search.py``).

Storage (all parts in one set of flat arrays, part after part, within a part
document after document):

* the segment table -- per segment its first frame, length and word id; it
  maps 1:1 onto ``postings(motion_id, feature_set, seg, word, start_frame,
  n_frames)`` (:meth:`Index.to_columns`, :meth:`Index.from_columns`);
* the posting lists -- per distinct word the (doc, seg) pairs in the toolbox's
  order, each carrying the segment's first and last frame, so that a query
  reads its lists sequentially and never touches the segment table.

A fuzzy keyframe ``(mask, value)`` is answered without enumerating the 2^w
wildcard words: the index's distinct words are tested with
``word & mask == value``.  Its frame intervals come from the union of the
matching posting lists (heap merge or bitset) or, in a few documents, from
a forward scan of their segments (the keyframe search's document filter,
mocapdb.keyframes); all give the same intervals.

Building (and loading from the ``postings`` table) is O(segments): word ids
by hashing, posting lists by a counting sort -- no sort of the segments.

Public functions
----------------
build_index        words of many documents -> :class:`Index`
segment_runs       maximal runs of constant (restricted) word, many documents
fuzzy_postings     distinct words matching a keyframe + union of their lists
fuzzy_intervals    the union converted to frame intervals (§3)

Frame numbers are 0-based with inclusive ends; document ids are 0-based
positions in the order the documents were given.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba.cpython.unsafe.numbers import trailing_zeros  # count-trailing-zeros intrinsic

from mocapdb._numba import jit
from mocapdb.errors import ParameterError
from mocapdb.features import FEATURE_SETS, N_FEATURES

#: index parts in canonical order; the integer code of a part is its position
INDEX_PARTS = ("upper", "lower", "mix", "full")
#: (first bit, n bits) of every part
PART_BITS = {**FEATURE_SETS, "full": (0, N_FEATURES)}
#: the toolbox layout: one index per feature set (KEYFRAMES.md §1)
SET_PARTS = ("upper", "lower", "mix")

_I32_MAX = 2**31 - 1


class Segments(NamedTuple):
    """Frame ranges ``(doc, start, end)`` (0-based, inclusive), each ``(n,) int64``."""

    doc: np.ndarray
    start: np.ndarray
    end: np.ndarray

    @property
    def n_frames(self) -> int:
        """Total number of frames covered (the toolbox's ``framesTotalNum``)."""
        return int(np.sum(self.end - self.start + 1))

    def __len__(self) -> int:  # number of ranges, not of fields
        return len(self.doc)

    def as_array(self) -> np.ndarray:
        """``(n, 3) int64`` rows (doc, start, end)."""
        return np.stack([self.doc, self.start, self.end], axis=1)


class Postings(NamedTuple):
    """One fuzzy keyframe against one index part (KEYFRAMES.md §3).

    ``words`` (W,) uint64: the distinct index words matching the keyframe,
    ascending (words without postings do not exist in the index);
    ``list_lengths`` (W,) int64; ``doc``, ``seg`` (P,) int64: the union of
    their posting lists in (doc, seg) order, without duplicates.
    """

    words: np.ndarray
    list_lengths: np.ndarray
    doc: np.ndarray
    seg: np.ndarray


# --------------------------------------------------------------------------
# kernels


@jit
def _count_runs_kernel(words, doc_offset, shift, mask, out_count):  # pragma: no cover
    """Number of maximal runs of constant ``(word >> shift) & mask`` per document."""
    for d in range(len(doc_offset) - 1):
        lo = doc_offset[d]
        hi = doc_offset[d + 1]
        if hi <= lo:
            out_count[d] = 0
            continue
        n = 1
        prev = (words[lo] >> shift) & mask
        for t in range(lo + 1, hi):
            w = (words[t] >> shift) & mask
            if w != prev:
                n += 1
                prev = w
        out_count[d] = n


@jit
def _fill_runs_kernel(words, doc_offset, shift, mask, seg_offset,
                      out_start, out_len, out_word):  # pragma: no cover
    """Write the runs counted by :func:`_count_runs_kernel` (runs_find_constant.m)."""
    for d in range(len(doc_offset) - 1):
        lo = doc_offset[d]
        hi = doc_offset[d + 1]
        if hi <= lo:
            continue
        s = seg_offset[d]
        prev = (words[lo] >> shift) & mask
        start = lo
        for t in range(lo + 1, hi + 1):
            w = prev
            if t < hi:
                w = (words[t] >> shift) & mask
            if t == hi or w != prev:
                out_start[s] = start - lo
                out_len[s] = t - start
                out_word[s] = prev
                s += 1
                start = t
                prev = w


@jit
def _match_words_kernel(words, lo, hi, mask, value, out_idx):  # pragma: no cover
    """Indices i in [lo, hi) with ``(words[i] & mask) == value``; returns the count.

    Replaces the toolbox's enumeration of all 2^w wildcard combinations
    (indicesFixedBits.m): only words that occur in the index are tested.
    """
    n = 0
    for i in range(lo, hi):
        if (words[i] & mask) == value:
            out_idx[n] = i
            n += 1
    return n


@jit
def _sift_down(hkey, hsrc, n, i):  # pragma: no cover
    """Restore the min-heap property of ``hkey[:n]`` below node i (hsrc moves along)."""
    while True:
        c = 2 * i + 1
        if c >= n:
            return
        if c + 1 < n and hkey[c + 1] < hkey[c]:
            c += 1
        if hkey[c] >= hkey[i]:
            return
        hkey[i], hkey[c] = hkey[c], hkey[i]
        hsrc[i], hsrc[c] = hsrc[c], hsrc[i]
        i = c


@jit
def _union_intervals_kernel(list_doc, list_seg, list_start, list_end, lst_lo, lst_hi, n_words,
                            alive, hkey, hsrc, hpos, out_doc, out_start, out_end,
                            want_union, u_doc, u_seg):  # pragma: no cover
    """Union of posting lists and its frame intervals (§3).

    List i is the range ``lst_lo[i]:lst_hi[i]`` of the ``list_*`` arrays (a
    whole posting list or the part of it within a document range).

    The lists are merged in (doc, seg) order with a binary heap (the toolbox's
    k-way merge C_union_presorted_2xn.cpp; lists of different words are
    disjoint, so nothing needs de-duplicating).  Each posting carries its
    frames, so the re-segmentation (convertKeyframeList) runs on the fly: a
    posting that continues the previous one (same doc, seg + 1) extends the
    last interval.  A non-empty ``alive`` (uint8 per document) drops the
    postings of documents d with ``alive[d] == 0`` (they cannot end a
    continuation: a document is all alive or all dropped).  ``hkey``/``hsrc``/
    ``hpos`` are scratch of length >= n_words; ``out_*`` and (with
    ``want_union``) ``u_doc``/``u_seg`` need room for all postings.  Returns
    (#intervals, #postings kept).
    """
    filtered = len(alive) > 0
    n = 0
    for i in range(n_words):
        a = lst_lo[i]
        hpos[i] = a
        if a < lst_hi[i]:
            hkey[n] = (np.int64(list_doc[a]) << 32) | np.int64(list_seg[a])
            hsrc[n] = i
            n += 1
    for i in range(n // 2 - 1, -1, -1):
        _sift_down(hkey, hsrc, n, i)
    n_iv = 0
    n_u = 0
    last_doc = -1
    last_seg = -2
    while n > 0:
        i = hsrc[0]
        j = hpos[i]
        stop = lst_hi[i]
        # with one list left, drain it without heap work
        j_end = stop if n == 1 else j + 1
        while j < j_end:
            d = list_doc[j]
            if filtered and alive[d] == 0:
                j += 1
                continue
            sg = list_seg[j]
            if d == last_doc and sg == last_seg + 1:
                out_end[n_iv - 1] = list_end[j]
            else:
                out_doc[n_iv] = d
                out_start[n_iv] = list_start[j]
                out_end[n_iv] = list_end[j]
                n_iv += 1
            last_doc = d
            last_seg = sg
            if want_union:
                u_doc[n_u] = d
                u_seg[n_u] = sg
            n_u += 1
            j += 1
        hpos[i] = j
        if j < stop:
            hkey[0] = (np.int64(list_doc[j]) << 32) | np.int64(list_seg[j])
        else:
            n -= 1
            hkey[0] = hkey[n]
            hsrc[0] = hsrc[n]
        _sift_down(hkey, hsrc, n, 0)
    return n_iv, n_u


@jit
def _bitset_intervals_kernel(list_doc, list_seg, lst_lo, lst_hi, n_words, seg_start, seg_len,
                             doc_seg_offset, d0, d1, alive, bitset, out_doc, out_start, out_end,
                             want_union, u_doc, u_seg):  # pragma: no cover
    """Same result as :func:`_union_intervals_kernel`, for many lists.

    Marks the postings' global segment ids in ``bitset`` (zeroed, one bit per
    segment of documents d0 <= d < d1 of the part; ``doc_seg_offset``: the
    part's row), then sweeps it in (doc, seg) order: O(postings + segments/64
    + documents) whatever the number of lists.  ``alive`` as there.  Returns
    (#intervals, #postings kept).
    """
    filtered = len(alive) > 0
    g0 = doc_seg_offset[d0]
    for i in range(n_words):
        for j in range(lst_lo[i], lst_hi[i]):
            dj = list_doc[j]
            if filtered and alive[dj] == 0:
                continue
            g = doc_seg_offset[dj] + list_seg[j] - g0
            bitset[g >> 6] |= np.uint64(1) << np.uint64(g & 63)
    n_iv = 0
    n_u = 0
    d = d0
    prev = np.int64(-2)
    for blk in range(len(bitset)):
        x = bitset[blk]
        while x != 0:
            g = g0 + (blk << 6) + np.int64(trailing_zeros(x))
            x &= x - np.uint64(1)
            while doc_seg_offset[d + 1] <= g:
                d += 1
            end = seg_start[g] + seg_len[g] - 1
            if g == prev + 1 and g != doc_seg_offset[d]:  # next segment of the same document
                out_end[n_iv - 1] = end
            else:
                out_doc[n_iv] = d
                out_start[n_iv] = seg_start[g]
                out_end[n_iv] = end
                n_iv += 1
            if want_union:
                u_doc[n_u] = d
                u_seg[n_u] = g - doc_seg_offset[d]
            n_u += 1
            prev = g
    return n_iv, n_u


@jit
def _forward_intervals_kernel(seg_start, seg_len, seg_wid, doc_seg_offset, match, docs, n_docs,
                              out_doc, out_start, out_end):  # pragma: no cover
    """Intervals of a fuzzy keyframe in the documents ``docs[:n_docs]``, from the segment table.

    The forward twin of the posting-list union: walks each document's
    segments and tests their word (``match[seg_wid[g]]``, one flag per
    part-local word id); consecutive matching segments form one interval,
    exactly the re-segmentation of the union list.  O(segments of those
    documents), independent of the number of postings.  Returns #intervals.
    """
    n_iv = 0
    for i in range(n_docs):
        d = docs[i]
        prev = False
        for g in range(doc_seg_offset[d], doc_seg_offset[d + 1]):
            if match[seg_wid[g]]:
                end = seg_start[g] + seg_len[g] - 1
                if prev:
                    out_end[n_iv - 1] = end
                else:
                    out_doc[n_iv] = d
                    out_start[n_iv] = seg_start[g]
                    out_end[n_iv] = end
                    n_iv += 1
                prev = True
            else:
                prev = False
    return n_iv


@jit
def _match_lists_kernel(words, list_offset, list_doc, part_word_offset, n_docs, part, mask, value,
                        d0, d1, out_idx, out_lo, out_hi):  # pragma: no cover
    """Index words of ``part`` matching ``(mask, value)`` and their lists cut to d0 <= d < d1.

    Writes the word indices and each list's range ``out_lo[i]:out_hi[i]``
    (room for all words of the part).  Returns (#words, total postings).
    """
    word_lo = part_word_offset[part]
    nw = _match_words_kernel(words, word_lo, part_word_offset[part + 1], mask, value, out_idx)
    total = 0
    for i in range(nw):
        a = list_offset[out_idx[i]]
        b = list_offset[out_idx[i] + 1]
        if d0 > 0:  # lists are sorted by doc: cut them to the document range
            a += np.searchsorted(list_doc[a:b], d0)
        if d1 < n_docs:
            b = a + np.searchsorted(list_doc[a:b], d1)
        out_lo[i] = a
        out_hi[i] = b
        total += b - a
    return nw, total


@jit
def _heap_cost(n_postings, n_lists):  # pragma: no cover
    """Cost (ns, measured on 100 h) of the heap merge: ~4 per posting + ~6 per heap level."""
    log_nw = 0
    while (1 << log_nw) < n_lists:
        log_nw += 1
    return n_postings * (4 + 6 * max(log_nw - 1, 0))


@jit
def _bitset_cost(n_postings, n_segs, n_docs):  # pragma: no cover
    """Cost (ns, measured on 100 h) of the bitset union: ~5 per posting + the sweep."""
    return 5 * n_postings + n_segs // 16 + 3 * n_docs


@jit
def _union_kernel(list_doc, list_seg, list_start, list_end, seg_start, seg_len, offsets,
                  lst_lo, lst_hi, total, d0, d1, alive, want_union, strategy):  # pragma: no cover
    """Union + intervals of the cut lists (``offsets``: the part's doc_seg_offset row).

    ``strategy``: 0 = by the cost model, 1 = heap, 2 = bitset (same result).
    Allocates outputs sized to the postings (data dependent).  Returns
    (intervals doc/start/end, union doc/seg).
    """
    nw = len(lst_lo)
    o_doc = np.empty(total, np.int64)
    o_s = np.empty(total, np.int64)
    o_e = np.empty(total, np.int64)
    nu = total if want_union else 0
    u_doc = np.empty(nu, np.int64)
    u_seg = np.empty(nu, np.int64)
    n_segs = offsets[d1] - offsets[d0]
    if strategy == 0:
        strategy = 2 if _bitset_cost(total, n_segs, d1 - d0) < _heap_cost(total, nw) else 1
    if strategy == 2:
        bitset = np.zeros((n_segs >> 6) + 1, np.uint64)
        n_iv, n_u = _bitset_intervals_kernel(list_doc, list_seg, lst_lo, lst_hi, nw, seg_start,
                                             seg_len, offsets, d0, d1, alive, bitset, o_doc, o_s,
                                             o_e, want_union, u_doc, u_seg)
    else:
        hkey = np.empty(nw, np.int64)
        hsrc = np.empty(nw, np.int64)
        hpos = np.empty(nw, np.int64)
        n_iv, n_u = _union_intervals_kernel(list_doc, list_seg, list_start, list_end, lst_lo,
                                            lst_hi, nw, alive, hkey, hsrc, hpos, o_doc, o_s, o_e,
                                            want_union, u_doc, u_seg)
    return o_doc[:n_iv], o_s[:n_iv], o_e[:n_iv], u_doc[:n_u], u_seg[:n_u]


@jit
def _fuzzy_kernel(words, list_offset, list_doc, list_seg, list_start, list_end,
                  seg_start, seg_len, seg_wid, part_word_offset, doc_seg_offset,
                  part, mask, value, d0, d1, want_union, strategy):  # pragma: no cover
    """Fuzzy keyframe ``(mask, value)`` on one part, documents ``d0 <= d < d1``.

    Matches the part's distinct words, then merges their posting lists with
    a heap (:func:`_union_intervals_kernel`) or, when the lists are many,
    through a bitset over the part's segments (:func:`_bitset_intervals_kernel`);
    both give the same result.  ``strategy``: 0 = by the cost model, 1 = heap,
    2 = bitset.  Returns (word_idx, intervals doc/start/end, union doc/seg).
    """
    offsets = doc_seg_offset[part]
    n_words = part_word_offset[part + 1] - part_word_offset[part]
    idx = np.empty(n_words, np.int64)
    lst_lo = np.empty(n_words, np.int64)
    lst_hi = np.empty(n_words, np.int64)
    nw, total = _match_lists_kernel(words, list_offset, list_doc, part_word_offset,
                                    len(offsets) - 1, part, mask, value, d0, d1, idx, lst_lo,
                                    lst_hi)
    o_doc, o_s, o_e, u_doc, u_seg = _union_kernel(list_doc, list_seg, list_start, list_end,
                                                  seg_start, seg_len, offsets, lst_lo[:nw],
                                                  lst_hi[:nw], total, d0, d1,
                                                  np.zeros(0, np.uint8), want_union, strategy)
    return idx[:nw], o_doc, o_s, o_e, u_doc, u_seg


_FIB = 0x9E3779B97F4A7C15  # 2^64 / golden ratio: multiplicative (Fibonacci) hashing


@jit
def _hash_words_kernel(word, i, lo, hi, keys, ids, distinct, counts, nd, bits,
                       out_id):  # pragma: no cover
    """Insert/look up ``word[i:hi]`` in an open-addressing table of ``2^bits`` slots.

    Writes ``out_id[i - lo]`` (first-seen id) and counts; stops early, before a
    new word would push the load factor above 1/2.  Returns (next i, #distinct).
    A separate kernel because arrays re-bound inside a hot loop cost numba a
    reference count per iteration (20x slower).
    """
    mask = len(keys) - 1
    shift = np.uint64(64 - bits)
    limit = len(keys) // 2
    while i < hi:
        w = word[i]
        h = np.int64((w * np.uint64(_FIB)) >> shift)
        j = ids[h]
        while j >= 0 and keys[h] != w:
            h = (h + 1) & mask
            j = ids[h]
        if j < 0:
            if nd >= limit:
                return i, nd
            j = nd
            keys[h] = w
            ids[h] = j
            distinct[j] = w
            nd += 1
        out_id[i - lo] = j
        counts[j] += 1
        i += 1
    return i, nd


@jit
def _distinct_words_kernel(word, lo, hi, out_id):  # pragma: no cover
    """Distinct words of ``word[lo:hi]`` in first-seen order (hashing, O(n)).

    Writes ``out_id[i - lo]`` = first-seen id of ``word[i]``; returns the
    distinct words and their counts in first-seen order.  Replaces a sort of
    millions of 40-bit words; the table doubles when half full.
    """
    bits = 10
    nd = 0
    i = lo
    distinct = np.empty(0, np.uint64)
    counts = np.zeros(0, np.int64)
    while True:
        cap = 1 << bits
        keys = np.empty(cap, np.uint64)
        ids = np.full(cap, -1, np.int64)
        grown = np.empty(cap // 2, np.uint64)
        grown[:nd] = distinct[:nd]
        distinct = grown
        grown_counts = np.zeros(cap // 2, np.int64)
        grown_counts[:nd] = counts[:nd]
        counts = grown_counts
        shift = np.uint64(64 - bits)
        for t in range(nd):  # re-insert the words seen so far
            x = distinct[t]
            h = np.int64((x * np.uint64(_FIB)) >> shift)
            while ids[h] >= 0:
                h = (h + 1) & (cap - 1)
            keys[h] = x
            ids[h] = t
        i, nd = _hash_words_kernel(word, i, lo, hi, keys, ids, distinct, counts, nd, bits,
                                   out_id)
        if i == hi:
            return distinct[:nd], counts[:nd]
        bits += 1


@jit
def _fill_postings_kernel(seg_wid, doc_seg_offset, seg_start, seg_len, cursor,
                          list_doc, list_seg, list_start, list_end):  # pragma: no cover
    """Scatter one part's segments into its posting lists (counting sort by word id).

    Segments are visited in (doc, seg) order, so every list comes out in the
    toolbox's order.  ``cursor[w]`` = next free entry of word w's list (advanced).
    """
    for d in range(len(doc_seg_offset) - 1):
        a = doc_seg_offset[d]
        for g in range(a, doc_seg_offset[d + 1]):
            w = seg_wid[g]
            j = cursor[w]
            cursor[w] = j + 1
            list_doc[j] = d
            list_seg[j] = g - a
            list_start[j] = seg_start[g]
            list_end[j] = seg_start[g] + seg_len[g] - 1


@jit
def _group_count_kernel(part_pos, fs, doc, n_docs, out_count):  # pragma: no cover
    """Rows per (part, document) group: ``out_count[part_pos[fs]·n_docs + doc + 1] += 1``."""
    for i in range(len(fs)):
        out_count[part_pos[fs[i]] * n_docs + doc[i] + 1] += 1


@jit
def _scatter_rows_kernel(part_pos, fs, doc, seg, start, length, word, n_docs, group_offset,
                         filled, out_start, out_len, out_word):  # pragma: no cover
    """Put table rows in (part, doc, seg) order: row -> group offset + seg.

    Returns False at a seg number outside its group or used twice (then the
    rows do not number each group's segments 0, 1, ...).
    """
    for i in range(len(fs)):
        g = part_pos[fs[i]] * n_docs + doc[i]
        s = seg[i]
        if s < 0 or s >= group_offset[g + 1] - group_offset[g]:
            return False
        j = group_offset[g] + s
        if filled[j]:
            return False
        filled[j] = True
        out_start[j] = start[i]
        out_len[j] = length[i]
        out_word[j] = word[i]
    return True


@jit
def _tiling_error_kernel(doc_seg_offset, seg_start, seg_len, doc_lengths):  # pragma: no cover
    """First document whose segments do not tile ``0..doc_lengths[d]-1`` in order, or -1."""
    for d in range(len(doc_seg_offset) - 1):
        t = 0
        for g in range(doc_seg_offset[d], doc_seg_offset[d + 1]):
            if seg_start[g] != t or seg_len[g] <= 0:
                return d
            t += seg_len[g]
        if t != doc_lengths[d]:
            return d
    return -1


# --------------------------------------------------------------------------
# building


def _as_u64(x, name):
    a = np.asarray(x)
    if a.dtype != np.uint64:
        if a.dtype.kind not in "iu":
            raise ParameterError(f"{name} must hold packed uint64 feature words, "
                                 f"got dtype {a.dtype}")
        if a.size and a.min() < 0:
            raise ParameterError(f"{name} holds negative words; pass packed uint64 feature words")
        a = a.astype(np.uint64)
    return np.ascontiguousarray(a)


def _as_int(x, name):
    """A 1-D integer column, kept in its dtype when it is a signed or small one."""
    a = np.asarray(x)
    if a.dtype.kind == "f" and a.size and not np.all(a == np.floor(a)):
        raise ParameterError(f"column {name} must hold integers, got dtype {a.dtype}")
    if a.dtype.kind not in "iu" or a.dtype == np.uint64:  # uint64 + int64 would be float
        a = a.astype(np.int64)
    return np.ascontiguousarray(a.ravel())


def _part_names(feature_sets) -> tuple:
    if isinstance(feature_sets, str):
        feature_sets = (feature_sets,)
    names = tuple(feature_sets)
    if not names:
        raise ParameterError("feature_sets is empty; pass e.g. ('upper', 'lower', 'mix') "
                             "or ('full',)")
    for n in names:
        if n not in INDEX_PARTS:
            raise ParameterError(f"feature_sets contains {n!r}; allowed: {', '.join(INDEX_PARTS)}")
    if len(set(names)) != len(names):
        raise ParameterError(f"feature_sets={names!r} repeats a part")
    return tuple(n for n in INDEX_PARTS if n in names)  # canonical order


def _doc_lengths(doc_lengths, n_frames=None):
    lengths = np.asarray(doc_lengths)
    if lengths.ndim != 1 or lengths.dtype.kind not in "iu":
        raise ParameterError("doc_lengths must be a 1-D integer array (frames per document)")
    lengths = lengths.astype(np.int64)
    if lengths.size and (lengths.min() < 0 or lengths.max() > _I32_MAX):
        raise ParameterError(f"doc_lengths must be in 0..{_I32_MAX}")
    if n_frames is not None and int(lengths.sum()) != n_frames:
        raise ParameterError(f"doc_lengths sum to {int(lengths.sum())} but words has "
                             f"{n_frames} frames")
    return lengths


def segment_runs(words, doc_lengths, *, feature_set="full"):
    """Maximal runs of constant word in many documents (runs_find_constant.m).

    Parameters
    ----------
    words : (n_frames,) uint64
        Packed words of all documents, concatenated.
    doc_lengths : (n_docs,) int
        Frames per document (zero allowed).
    feature_set : {'upper', 'lower', 'mix', 'full'}, default 'full'
        Restrict the word to this set's bits, shifted so feature 1 of the set
        is bit 0 (KEYFRAMES.md §1.2), or keep all 40 bits.

    Returns
    -------
    start, length : (n_segs,) int64
        First frame (0-based, within its document) and length of each run.
    word : (n_segs,) uint64
        The (restricted) word of the run.
    seg_offset : (n_docs + 1,) int64
        Runs of document d are ``seg_offset[d]:seg_offset[d+1]``.
    """
    words = _as_u64(words, "words")
    lengths = _doc_lengths(doc_lengths, len(words))
    if feature_set not in PART_BITS:
        raise ParameterError(f"feature_set={feature_set!r}; allowed: {', '.join(INDEX_PARTS)}")
    first, nbits = PART_BITS[feature_set]
    shift, mask = np.uint64(first), np.uint64((1 << nbits) - 1)
    doc_offset = np.zeros(len(lengths) + 1, np.int64)
    np.cumsum(lengths, out=doc_offset[1:])
    count = np.empty(len(lengths), np.int64)
    _count_runs_kernel(words, doc_offset, shift, mask, count)
    seg_offset = np.zeros(len(lengths) + 1, np.int64)
    np.cumsum(count, out=seg_offset[1:])
    n = int(seg_offset[-1])
    start = np.empty(n, np.int64)
    length = np.empty(n, np.int64)
    word = np.empty(n, np.uint64)
    _fill_runs_kernel(words, doc_offset, shift, mask, seg_offset, start, length, word)
    return start, length, word, seg_offset


@dataclass(frozen=True, eq=False)
class Index:
    """Inverted file index of one or more parts over the same documents.

    Attributes
    ----------
    parts : tuple of str
        Parts present, canonical order (subset of :data:`INDEX_PARTS`).
    doc_lengths : (n_docs,) int64
        Frames per document (the toolbox's ``files_frame_length``).
    part_seg_offset : (n_parts + 1,) int64
        Segments of part p are ``part_seg_offset[p]:part_seg_offset[p+1]``.
    doc_seg_offset : (n_parts, n_docs + 1) int64
        Segments of document d in part p are
        ``doc_seg_offset[p, d]:doc_seg_offset[p, d+1]`` (global ids).
    seg_start, seg_len : (n_segs,) int32
        First frame (within the document) and length of each segment.
    seg_wid : (n_segs,) int32
        Word of each segment as a part-local word id:
        ``words[part_word_offset[p] + seg_wid]``.
    words : (n_words,) uint64
        Distinct words, per part ascending (restricted to the part's bits,
        shifted); one non-empty posting list each.
    part_word_offset : (n_parts + 1,) int64
    list_offset : (n_words + 1,) int64
        Posting list of word i = entries ``list_offset[i]:list_offset[i+1]``
        of the ``list_*`` arrays, in (doc, seg) order.
    list_doc, list_seg : (n_segs,) int32
        The postings (doc, seg) (seg 0-based within document and part).
    list_start, list_end : (n_segs,) int32
        First and last frame of the posting's segment.

    Build with :func:`build_index` or :meth:`from_columns`; never mutate.
    """

    parts: tuple
    doc_lengths: np.ndarray
    part_seg_offset: np.ndarray
    doc_seg_offset: np.ndarray
    seg_start: np.ndarray
    seg_len: np.ndarray
    seg_wid: np.ndarray
    words: np.ndarray
    part_word_offset: np.ndarray
    list_offset: np.ndarray
    list_doc: np.ndarray
    list_seg: np.ndarray
    list_start: np.ndarray
    list_end: np.ndarray

    @property
    def n_docs(self) -> int:
        return len(self.doc_lengths)

    @property
    def n_frames(self) -> int:
        return int(self.doc_lengths.sum())

    @property
    def nbytes(self) -> int:
        """Memory held by the index arrays."""
        return sum(getattr(self, f).nbytes for f in self.__dataclass_fields__ if f != "parts")

    def part_id(self, part: str) -> int:
        """Position of ``part`` in :attr:`parts`; ParameterError when absent."""
        try:
            return self.parts.index(part)
        except ValueError:
            raise ParameterError(
                f"the index has no part {part!r} (it has {', '.join(self.parts)}); "
                f"rebuild it with build_index(..., feature_sets=...) including {part!r}") from None

    def segments(self, part: str, doc: int):
        """Segments of one document: ``(start, length, word)`` int64/int64/uint64 (§1.3)."""
        p = self.part_id(part)
        a, b = self.doc_seg_offset[p, doc], self.doc_seg_offset[p, doc + 1]
        return (self.seg_start[a:b].astype(np.int64), self.seg_len[a:b].astype(np.int64),
                self.words[self.part_word_offset[p] + self.seg_wid[a:b]])

    def posting_list(self, part: str, word: int):
        """Posting list of ``word`` in ``part``: ``(doc, seg)`` int64 arrays in (doc, seg) order."""
        p = self.part_id(part)
        lo, hi = self.part_word_offset[p], self.part_word_offset[p + 1]
        i = lo + np.searchsorted(self.words[lo:hi], np.uint64(word))
        if i == hi or self.words[i] != np.uint64(word):
            return np.empty(0, np.int64), np.empty(0, np.int64)
        a, b = self.list_offset[i], self.list_offset[i + 1]
        return self.list_doc[a:b].astype(np.int64), self.list_seg[a:b].astype(np.int64)

    def kernel_arrays(self) -> tuple:
        """The arrays the search kernels take, in their argument order."""
        return (self.words, self.list_offset, self.list_doc, self.list_seg, self.list_start,
                self.list_end, self.seg_start, self.seg_len, self.seg_wid, self.part_word_offset,
                self.doc_seg_offset)

    # ---- columns <-> index -------------------------------------------------

    def to_columns(self) -> dict:
        """The segment table as the columns of the DuckDB ``postings`` table.

        ``postings(motion_id, feature_set, seg, word, start_frame, n_frames)``.

        Returns
        -------
        dict of (n_segs,) arrays, rows ordered by (feature_set, doc, seg)
            ``doc`` int64 (0-based document position; map it to
            ``motion_id``), ``feature_set`` int8 (code = position in
            :data:`INDEX_PARTS`), ``seg`` int64 (0-based within document and
            part), ``word`` uint64, ``start_frame`` int64 (0-based),
            ``n_frames`` int64.  A posting list is
            ``SELECT doc, seg ... WHERE feature_set = ? AND word = ? ORDER BY doc, seg``.
        """
        n = len(self.seg_start)
        codes = np.empty(n, np.int8)
        doc = np.empty(n, np.int64)
        seg = np.empty(n, np.int64)
        word = np.empty(n, np.uint64)
        for p, name in enumerate(self.parts):
            a, b = self.part_seg_offset[p], self.part_seg_offset[p + 1]
            codes[a:b] = INDEX_PARTS.index(name)
            counts = np.diff(self.doc_seg_offset[p])
            doc[a:b] = np.repeat(np.arange(self.n_docs), counts)
            seg[a:b] = np.arange(a, b) - np.repeat(self.doc_seg_offset[p, :-1], counts)
            word[a:b] = self.words[self.part_word_offset[p] + self.seg_wid[a:b]]
        return {"doc": doc, "feature_set": codes, "seg": seg, "word": word,
                "start_frame": self.seg_start.astype(np.int64),
                "n_frames": self.seg_len.astype(np.int64)}

    @classmethod
    def from_columns(cls, doc, feature_set, seg, word, start_frame, n_frames, *, doc_lengths):
        """Rebuild the searchable index from postings-table columns (any row order).

        Parameters
        ----------
        doc, seg, start_frame, n_frames : (n,) int
            0-based document position, segment id within (part, document),
            first frame and run length.
        feature_set : (n,) int or str
            Part code (position in :data:`INDEX_PARTS`) or part name; codes
            are much faster (no per-row strings).
        word : (n,) uint64
        doc_lengths : (n_docs,) int
            Frames per document, in document-position order (documents without
            frames have no rows but count).

        Raises
        ------
        ParameterError
            Columns of different lengths, unknown part, or segments that do not
            tile each document exactly (gaps, overlaps, wrong seg numbering).
        """
        n = len(doc)
        fs = np.asarray(feature_set)
        if fs.dtype.kind in "UOS":  # names: map the few distinct ones, not every row
            names, inverse = np.unique(fs.astype(str), return_inverse=True)
            unknown = [x for x in names.tolist() if x not in INDEX_PARTS]
            if unknown:
                raise ParameterError(f"feature_set holds unknown part {unknown[0]!r}; "
                                     f"allowed: {', '.join(INDEX_PARTS)}")
            fs = np.array([INDEX_PARTS.index(x) for x in names.tolist()], np.int64)[inverse]
        # integer columns keep their dtype (no copies of millions of rows)
        doc, fs, seg, start, length = (_as_int(c, name) for c, name in (
            (doc, "doc"), (fs, "feature_set"), (seg, "seg"), (start_frame, "start_frame"),
            (n_frames, "n_frames")))
        word = _as_u64(word, "word")
        lengths = _doc_lengths(doc_lengths)
        for name, col in (("feature_set", fs), ("seg", seg), ("word", word),
                          ("start_frame", start), ("n_frames", length)):
            if len(col) != n:
                raise ParameterError(f"column {name} has {len(col)} rows, doc has {n}")
        if n and (fs.min() < 0 or fs.max() >= len(INDEX_PARTS)):
            raise ParameterError(f"feature_set codes must be in 0..{len(INDEX_PARTS) - 1}")
        if n and (doc.min() < 0 or doc.max() >= len(lengths)):
            raise ParameterError(f"doc ids must be in 0..{len(lengths) - 1} (len(doc_lengths)); "
                                 f"got {doc.min()}..{doc.max()}")
        present = np.flatnonzero(np.bincount(fs, minlength=len(INDEX_PARTS)))
        if len(present) == 0:
            raise ParameterError("no postings rows: cannot tell which parts the index has")
        parts = tuple(INDEX_PARTS[c] for c in present)
        # row position in (part, doc, seg) order without sorting: groups (part,
        # doc) are counted, a row goes to its group's offset + seg
        n_docs = len(lengths)
        part_pos = np.full(len(INDEX_PARTS), -1, np.int64)
        part_pos[present] = np.arange(len(present))
        group_offset = np.zeros(len(parts) * n_docs + 1, np.int64)
        _group_count_kernel(part_pos, fs, doc, n_docs, group_offset)
        np.cumsum(group_offset, out=group_offset)
        ok = n == 0 or (start.min() >= 0 and length.min() > 0 and
                        max(start.max(), length.max()) <= _I32_MAX)
        seg_start = np.empty(n, np.int32)
        seg_len = np.empty(n, np.int32)
        seg_word = np.empty(n, np.uint64)
        if ok:
            ok = _scatter_rows_kernel(part_pos, fs, doc, seg, start, length, word, n_docs,
                                      group_offset, np.zeros(n, np.bool_), seg_start, seg_len,
                                      seg_word)
        doc_seg_offset = np.stack([group_offset[p * n_docs:(p + 1) * n_docs + 1]
                                   for p in range(len(parts))])
        for p in range(len(parts)):
            if ok:  # the runs must tile every document exactly
                ok = _tiling_error_kernel(doc_seg_offset[p], seg_start, seg_len, lengths) < 0
            if not ok:
                raise ParameterError(
                    f"part {parts[p]!r}: segments do not tile the documents given by doc_lengths "
                    "(seg numbering, start_frame or n_frames inconsistent); rebuild the postings "
                    "with build_index")
        part_seg_offset = group_offset[np.arange(len(parts) + 1) * n_docs]
        return cls._assemble(parts, lengths, part_seg_offset, doc_seg_offset, seg_start, seg_len,
                             seg_word)

    @classmethod
    def _assemble(cls, parts, lengths, part_seg_offset, doc_seg_offset, start, length, word):
        """Posting lists and word ids from the segment table (all parts, global order)."""
        if len(lengths) > _I32_MAX:
            raise ParameterError(f"at most {_I32_MAX} documents per index")
        n = len(start)
        seg_start = start.astype(np.int32, copy=False)
        seg_len = length.astype(np.int32, copy=False)
        seg_wid = np.empty(n, np.int32)
        words_all, counts_all, wofs = [], [], [0]
        for p in range(len(parts)):
            a, b = part_seg_offset[p], part_seg_offset[p + 1]
            first_seen = np.empty(b - a, np.int64)
            distinct, counts = _distinct_words_kernel(word, a, b, first_seen)
            order = np.argsort(distinct)  # few distinct words: word ids ascending by word
            rank = np.empty(len(order), np.int32)
            rank[order] = np.arange(len(order), dtype=np.int32)
            seg_wid[a:b] = rank[first_seen]
            words_all.append(distinct[order])
            counts_all.append(counts[order])
            wofs.append(wofs[-1] + len(order))
        words = np.concatenate(words_all)
        list_offset = np.zeros(len(words) + 1, np.int64)
        np.cumsum(np.concatenate(counts_all), out=list_offset[1:])
        list_doc = np.empty(n, np.int32)
        list_seg = np.empty(n, np.int32)
        list_start = np.empty(n, np.int32)
        list_end = np.empty(n, np.int32)
        for p in range(len(parts)):
            cursor = list_offset[wofs[p]:wofs[p + 1]].copy()
            _fill_postings_kernel(seg_wid, doc_seg_offset[p], seg_start, seg_len, cursor,
                                  list_doc, list_seg, list_start, list_end)
        return cls(parts=tuple(parts), doc_lengths=lengths,
                   part_seg_offset=np.asarray(part_seg_offset, np.int64),
                   doc_seg_offset=np.ascontiguousarray(doc_seg_offset, np.int64),
                   seg_start=seg_start, seg_len=seg_len, seg_wid=seg_wid, words=words,
                   part_word_offset=np.asarray(wofs, np.int64), list_offset=list_offset,
                   list_doc=list_doc, list_seg=list_seg, list_start=list_start,
                   list_end=list_end)


def _flatten_docs(words_per_doc, doc_lengths):
    if doc_lengths is not None:
        words = _as_u64(words_per_doc, "words")
        if words.ndim != 1:
            raise ParameterError("with doc_lengths, words must be one flat (n_frames,) array")
        return words, _doc_lengths(doc_lengths, len(words))
    if isinstance(words_per_doc, np.ndarray):
        raise ParameterError("pass a sequence of per-document word arrays, "
                             "or one flat array together with doc_lengths=")
    docs = [_as_u64(w, f"words_per_doc[{i}]").ravel() for i, w in enumerate(words_per_doc)]
    lengths = _doc_lengths(np.array([len(w) for w in docs], dtype=np.int64))
    words = np.concatenate(docs) if docs else np.empty(0, np.uint64)
    return words, lengths


def build_index(words_per_doc, *, doc_lengths=None, feature_sets=SET_PARTS) -> Index:
    """Build the inverted file index of many documents (KEYFRAMES.md §1).

    Parameters
    ----------
    words_per_doc : sequence of (n_d,) uint64, or (n_frames,) uint64 with ``doc_lengths``
        Packed 30 Hz feature words per document (document ids = positions).
    doc_lengths : (n_docs,) int, optional
        Frames per document when ``words_per_doc`` is one flat array.
    feature_sets : sequence of str, default ('upper', 'lower', 'mix')
        Parts to build: the toolbox's per-set indexes and/or ``'full'`` (one
        index over the whole 40-bit word).

    Returns
    -------
    Index

    Notes
    -----
    The toolbox downsamples 120 Hz features by 4 inside ``index_build``; the
    input here already is the 30 Hz word sequence (every 4th frame).

    References
    ----------
    KEYFRAMES.md §1; toolbox ``index_build.m``, ``runs_find_constant.m``.
    """
    parts = _part_names(feature_sets)
    words, lengths = _flatten_docs(words_per_doc, doc_lengths)
    runs = [segment_runs(words, lengths, feature_set=name) for name in parts]
    part_seg_offset = np.zeros(len(parts) + 1, np.int64)
    np.cumsum([len(r[0]) for r in runs], out=part_seg_offset[1:])
    doc_seg_offset = np.stack([r[3] + part_seg_offset[p] for p, r in enumerate(runs)])
    start, length, word = (np.concatenate([r[i] for r in runs]) for i in range(3))
    return Index._assemble(parts, lengths, part_seg_offset, doc_seg_offset, start, length, word)


# --------------------------------------------------------------------------
# one fuzzy keyframe against one part


def _fuzzy(index: Index, part: str, mask, value, want_union, strategy=0):
    p = index.part_id(part)
    nbits = PART_BITS[part][1]
    m, v = int(mask), int(value)
    if m < 0 or v < 0 or m >> nbits or v & ~m:
        raise ParameterError(
            f"mask={m:#x}/value={v:#x} must be {part!r}-local words (bits 0..{nbits - 1}) "
            "with value bits only where mask is set")
    return _fuzzy_kernel(*index.kernel_arrays(), p, np.uint64(m), np.uint64(v), 0, index.n_docs,
                         want_union, strategy)


def fuzzy_postings(index: Index, part: str, mask, value) -> Postings:
    """Words of ``part`` matching a fuzzy keyframe and the union of their lists (§3).

    Parameters
    ----------
    index : Index
    part : str
        Part to query; ``mask``/``value`` are words local to it (feature 1 of
        the set = bit 0).
    mask, value : int
        A word w matches iff ``w & mask == value`` (mask bit 0 = wildcard).

    Returns
    -------
    Postings
    """
    idx, _, _, _, u_doc, u_seg = _fuzzy(index, part, mask, value, True)
    return Postings(index.words[idx], np.diff(index.list_offset)[idx], u_doc, u_seg)


def fuzzy_intervals(index: Index, part: str, mask, value) -> Segments:
    """Frame intervals of a fuzzy keyframe (§3, re-segmentation of the union list).

    Per document a sorted list of disjoint, non-adjacent intervals: the
    maximal runs of frames whose ``part`` word matches ``(mask, value)``.

    Returns
    -------
    Segments
        ``(doc, start, end)``, sorted by (doc, start).
    """
    _, doc, start, end, _, _ = _fuzzy(index, part, mask, value, False)
    return Segments(doc, start, end)


__all__ = ["INDEX_PARTS", "PART_BITS", "SET_PARTS", "Index", "Postings", "Segments",
           "build_index", "fuzzy_intervals", "fuzzy_postings", "segment_runs"]
