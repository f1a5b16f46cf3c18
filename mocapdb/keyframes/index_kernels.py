"""Numba kernels of the inverted file index (:mod:`mocapdb.keyframes.index`).

No validation or allocation here: the callers in index.py and search.py pass
checked, contiguous arrays and their output buffers.
"""
import numpy as np

from mocapdb._numba import jit, trailing_zeros



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
    n = np.int64(0)
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
        _sift_down(hkey, hsrc, n, np.int64(0))
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
    bits = np.int64(10)
    nd = np.int64(0)
    i = lo
    distinct = np.empty(0, np.uint64)
    counts = np.zeros(0, np.int64)
    while True:
        cap = 1 << bits
        keys = np.empty(cap, np.uint64)
        ids = np.full(cap, -1, np.int64)
        grown = np.empty(cap // 2, np.uint64)
        grown_counts = np.zeros(cap // 2, np.int64)
        for t in range(nd):  # loops, not slice assignment (cheaper to compile)
            grown[t] = distinct[t]
            grown_counts[t] = counts[t]
        distinct = grown
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
