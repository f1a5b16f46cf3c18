"""Numba kernels of the keyframe search (KEYFRAMES.md §3-5), used by :mod:`mocapdb.keyframes`.

* intervals: every keyframe's frame intervals (:func:`_keyframe_intervals_kernel`,
  for :func:`~mocapdb.keyframes.keyframe_intervals` and the GA's cache) or one
  query's intervals behind a document filter (:func:`_query_intervals_kernel`:
  documents where not every keyframe matches are skipped, keyframes from the
  fewest postings up; each keyframe by heap merge, bitset or forward scan);
* the chain search of C_KeyframeSearch.c (:func:`_chain_scan_kernel` and its
  drivers).

Kernels do no validation; the wrappers in :mod:`mocapdb.keyframes` do.
Frames and documents are 0-based, interval ends inclusive.
"""
from __future__ import annotations

import numpy as np

from mocapdb._numba import jit
from mocapdb.keyframes.index_kernels import (_bitset_cost, _forward_intervals_kernel, _fuzzy_kernel, _heap_cost,
                                             _match_lists_kernel, _union_kernel)


@jit
def _rewind(cur, ptr0, K):  # pragma: no cover
    """Put the per-keyframe list pointers back to the start of the current document
    (its search is repeated with bigger output buffers)."""
    for k in range(1, K):
        cur[k] = ptr0[k]


@jit
def _intersect_kernel(a_doc, a_s, a_e, na, b_doc, b_s, b_e, nb,
                      o_doc, o_s, o_e):  # pragma: no cover
    """Intersection of two sorted interval lists (frames matching both); returns the count."""
    i = 0
    j = 0
    n = 0
    while i < na and j < nb:
        if a_doc[i] < b_doc[j]:
            i += 1
        elif b_doc[j] < a_doc[i]:
            j += 1
        else:
            s = max(a_s[i], b_s[j])
            e = min(a_e[i], b_e[j])
            if s <= e:
                o_doc[n] = a_doc[i]
                o_s[n] = s
                o_e[n] = e
                n += 1
            if a_e[i] < b_e[j]:
                i += 1
            else:
                j += 1
    return n


@jit
def _keyframe_intervals_kernel(words, list_offset, list_doc, list_seg, list_start, list_end,
                               seg_start, seg_len, seg_wid, part_word_offset, doc_seg_offset,
                               sub_part, sub_mask, sub_value, kf_sub_offset,
                               d0, d1):  # pragma: no cover
    """Per-keyframe interval lists B[k] for many keyframes, documents d0 <= d < d1 (§3).

    The first 11 arguments are :meth:`Index.kernel_arrays`.  A keyframe is
    the conjunction of one or more single-part sub-keyframes (its constraints
    on each feature set); its intervals are the intersection of theirs.
    Returns flat ``(doc, start, end)`` and ``kf_offset`` (n_kf+1,).  Output
    sizes are data dependent, hence the allocation here.
    """
    n_kf = len(kf_sub_offset) - 1
    kf_offset = np.zeros(n_kf + 1, np.int64)
    cap = 256
    out_doc = np.empty(cap, np.int64)
    out_s = np.empty(cap, np.int64)
    out_e = np.empty(cap, np.int64)
    n_out = np.int64(0)
    for k in range(n_kf):
        nc = -1
        c_doc = out_doc[:0]
        c_s = out_s[:0]
        c_e = out_e[:0]
        for j in range(kf_sub_offset[k], kf_sub_offset[k + 1]):
            if nc == 0:
                break
            _, b_doc, b_s, b_e, _, _ = _fuzzy_kernel(words, list_offset, list_doc, list_seg,
                                                     list_start, list_end, seg_start, seg_len,
                                                     seg_wid, part_word_offset, doc_seg_offset,
                                                     sub_part[j], sub_mask[j], sub_value[j],
                                                     d0, d1, np.bool_(False), np.int64(0))
            nb = len(b_doc)
            if nc < 0:
                c_doc, c_s, c_e, nc = b_doc, b_s, b_e, nb
                continue
            t_doc = np.empty(nc + nb, np.int64)
            t_s = np.empty(nc + nb, np.int64)
            t_e = np.empty(nc + nb, np.int64)
            nc = _intersect_kernel(c_doc, c_s, c_e, nc, b_doc, b_s, b_e, nb, t_doc, t_s, t_e)
            c_doc, c_s, c_e = t_doc, t_s, t_e
        if nc < 0:
            nc = np.int64(0)
        out_doc, out_s, out_e = _append3(out_doc, out_s, out_e, n_out, c_doc, c_s, c_e, nc)
        n_out += nc
        kf_offset[k + 1] = n_out
    return out_doc[:n_out], out_s[:n_out], out_e[:n_out], kf_offset


#: how one sub-keyframe's intervals are computed (all give the same intervals;
#: tests force each): by the cost model, heap merge or bitset over the
#: posting lists, or a forward scan of the surviving documents' segments
_AUTO, _HEAP, _BITSET, _FORWARD = 0, 1, 2, 3


@jit
def _sub_intervals_kernel(list_doc, list_seg, list_start, list_end, seg_start, seg_len, seg_wid,
                          offsets, word_lo, n_words, idx, lst_lo, lst_hi, total, d0, d1, alive,
                          docs, n_alive, filtered, strategy):  # pragma: no cover
    """Intervals of one single-part sub-keyframe in the documents ``docs[:n_alive]``.

    ``idx``/``lst_lo``/``lst_hi``/``total``: its matching words and their
    lists (:func:`~mocapdb.keyframes.index_kernels._match_lists_kernel`) in a part with
    ``n_words`` words from ``word_lo`` and document row ``offsets``.
    Without ``filtered``, ``docs`` holds every document d0 <= d < d1; with
    it, ``alive`` flags exactly ``docs[:n_alive]`` and the other documents'
    postings are skipped.  The method is chosen by cost (ns, measured on
    100 h): the posting lists cost per posting (heap: and per heap level;
    bitset: plus a sweep of the part's segments), the forward scan per
    segment of the surviving documents -- cheaper once the document filter
    has removed most documents.  Returns (doc, start, end) sorted by (doc, start).
    """
    if total == 0 or n_alive == 0:
        empty = np.empty(0, np.int64)
        return empty, empty, empty
    if strategy == _AUTO:
        heap = _heap_cost(total, len(idx))
        bitset = _bitset_cost(total, offsets[d1] - offsets[d0], d1 - d0)
        strategy = _HEAP if heap <= bitset else _BITSET
        if filtered:  # forward scan ~ 3 ns per segment of the surviving documents
            seen = 0
            for i in range(n_alive):
                seen += offsets[docs[i] + 1] - offsets[docs[i]]
            if 3 * seen + 4 * n_alive < min(heap, bitset):
                strategy = _FORWARD
    if strategy == _FORWARD:
        match = np.zeros(n_words, np.uint8)
        for i in idx:
            match[i - word_lo] = 1
        o_doc = np.empty(total, np.int64)
        o_s = np.empty(total, np.int64)
        o_e = np.empty(total, np.int64)
        n_iv = _forward_intervals_kernel(seg_start, seg_len, seg_wid, offsets, match, docs,
                                         n_alive, o_doc, o_s, o_e)
        return o_doc[:n_iv], o_s[:n_iv], o_e[:n_iv]
    o_doc, o_s, o_e, _, _ = _union_kernel(list_doc, list_seg, list_start, list_end, seg_start,
                                          seg_len, offsets, lst_lo, lst_hi, total, d0, d1,
                                          alive if filtered else alive[:0], np.bool_(False), strategy)
    return o_doc, o_s, o_e


@jit
def _doc_filter_kernel(list_doc, lst_lo, lst_hi, level, step):  # pragma: no cover
    """Promote documents with ``level[d] == step`` that occur in the lists to ``step + 1``.

    Applied to the sub-keyframes one after another, ``level[d] == n`` marks
    the documents where all n matched.  Reads only the postings' documents.
    Returns the number of documents promoted.
    """
    n = 0
    nxt = step + 1
    for i in range(len(lst_lo)):
        for j in range(lst_lo[i], lst_hi[i]):
            d = list_doc[j]
            if level[d] == step:
                level[d] = nxt
                n += 1
    return n


@jit
def _query_intervals_kernel(words, list_offset, list_doc, list_seg, list_start, list_end,
                            seg_start, seg_len, seg_wid, part_word_offset, doc_seg_offset,
                            sub_part, sub_mask, sub_value, kf_sub_offset, kfs, d0, d1,
                            strategy):  # pragma: no cover
    """Intervals of the keyframes ``kfs`` of one query, only where the query can hit.

    A document is searched only if every keyframe matches in it (§5).  So
    first a document filter: the sub-keyframes' posting lists, from the
    fewest postings up (their lengths are known before any union), mark the
    documents where all of them occur, reading only the postings' document
    ids; an empty step ends the query.  Then each keyframe's intervals are
    computed in those documents only, by the cheapest method
    (:func:`_sub_intervals_kernel`).  In every surviving document they
    equal :func:`_keyframe_intervals_kernel`'s; elsewhere there are none.
    Returns flat ``(doc, start, end)`` and ``kf_offset`` (len(kfs)+1,), in
    the order of ``kfs``.
    """
    n_kf = len(kfs)
    n_docs = len(doc_seg_offset[0]) - 1
    n_steps = np.int64(0)
    room = 0
    for i in range(n_kf):
        for j in range(kf_sub_offset[kfs[i]], kf_sub_offset[kfs[i] + 1]):
            n_steps += 1
            room += part_word_offset[sub_part[j] + 1] - part_word_offset[sub_part[j]]
    # match every sub-keyframe once: words and list ranges, flat
    step_sub = np.empty(n_steps, np.int64)
    step_total = np.empty(n_steps, np.int64)
    step_off = np.zeros(n_steps + 1, np.int64)
    m_idx = np.empty(room, np.int64)
    m_lo = np.empty(room, np.int64)
    m_hi = np.empty(room, np.int64)
    t = np.int64(0)
    for i in range(n_kf):
        for j in range(kf_sub_offset[kfs[i]], kf_sub_offset[kfs[i] + 1]):
            o = step_off[t]
            nw, total = _match_lists_kernel(words, list_offset, list_doc, part_word_offset,
                                            n_docs, sub_part[j], sub_mask[j], sub_value[j], d0,
                                            d1, m_idx[o:], m_lo[o:], m_hi[o:])
            step_sub[t] = j
            step_total[t] = total
            step_off[t + 1] = o + nw
            t += 1
    kf_offset = np.zeros(n_kf + 1, np.int64)
    alive = np.zeros(n_docs, np.uint8)
    filtered = n_steps > 1
    if filtered:
        order = np.arange(n_steps)  # steps by total, stable (a few per query)
        _insertion_sort_by(order, np.int64(0), n_steps, step_total)
        empty = np.empty(0, np.int64)
        if step_total[order[0]] == 0:
            return empty, empty, empty, kf_offset
        level = np.zeros(n_docs, np.uint16)
        n_filter = min(n_steps, 65535)  # more steps would only tighten the filter
        for t in range(n_filter):
            a = step_off[order[t]]
            b = step_off[order[t] + 1]
            if _doc_filter_kernel(list_doc, m_lo[a:b], m_hi[a:b], level, t) == 0:
                return empty, empty, empty, kf_offset
        docs = np.empty(d1 - d0, np.int64)
        n_alive = np.int64(0)
        for d in range(d0, d1):
            if level[d] == n_filter:
                alive[d] = 1
                docs[n_alive] = d
                n_alive += 1
    else:
        docs = np.arange(d0, d1)
        n_alive = d1 - d0
    # growing flat outputs, not lists of arrays: a typed list costs seconds of cold compile
    out_doc = np.empty(64, np.int64)
    out_s = np.empty(64, np.int64)
    out_e = np.empty(64, np.int64)
    n_out = np.int64(0)
    t = np.int64(0)
    for i in range(n_kf):
        c_doc = np.empty(0, np.int64)
        c_s = c_doc
        c_e = c_doc
        for j in range(kf_sub_offset[kfs[i]], kf_sub_offset[kfs[i] + 1]):
            p = sub_part[j]
            a = step_off[t]
            b = step_off[t + 1]
            b_doc, b_s, b_e = _sub_intervals_kernel(
                list_doc, list_seg, list_start, list_end, seg_start, seg_len, seg_wid,
                doc_seg_offset[p], part_word_offset[p],
                part_word_offset[p + 1] - part_word_offset[p], m_idx[a:b], m_lo[a:b],
                m_hi[a:b], step_total[t], d0, d1, alive, docs, n_alive, filtered, strategy)
            if j == kf_sub_offset[kfs[i]]:
                c_doc, c_s, c_e = b_doc, b_s, b_e
            else:  # a keyframe over several parts: frames matching all of them
                nb = len(c_doc) + len(b_doc)
                t_doc = np.empty(nb, np.int64)
                t_s = np.empty(nb, np.int64)
                t_e = np.empty(nb, np.int64)
                nc = _intersect_kernel(c_doc, c_s, c_e, len(c_doc), b_doc, b_s, b_e, len(b_doc),
                                       t_doc, t_s, t_e)
                c_doc, c_s, c_e = t_doc[:nc], t_s[:nc], t_e[:nc]
            t += 1
        nc = len(c_doc)
        out_doc, out_s, out_e = _append3(out_doc, out_s, out_e, n_out, c_doc, c_s, c_e, nc)
        n_out += nc
        kf_offset[i + 1] = n_out
    return out_doc[:n_out], out_s[:n_out], out_e[:n_out], kf_offset


@jit
def _insertion_sort_by(idx, a, b, key):  # pragma: no cover
    """Stable sort of ``idx[a:b]`` by ``key[idx]`` (groups are short and nearly sorted)."""
    for i in range(a + 1, b):
        x = idx[i]
        j = i - 1
        while j >= a and key[idx[j]] > key[x]:
            idx[j + 1] = idx[j]
            j -= 1
        idx[j + 1] = x


@jit
def _grow1(a, n, cap):  # pragma: no cover
    # element loops, not slice assignment: slice assignment compiles numba's
    # shape-mismatch error formatting (seconds of cold compile) for no gain here
    b = np.empty(cap, a.dtype)
    for i in range(n):
        b[i] = a[i]
    return b


@jit
def _append3(out_doc, out_s, out_e, n_out, c_doc, c_s, c_e, nc):  # pragma: no cover
    """Append ``nc`` intervals to three growing outputs of ``n_out`` used entries (doubling when
    full); returns the (possibly reallocated) outputs."""
    if n_out + nc > len(out_doc):
        cap = max(2 * len(out_doc), n_out + nc)
        out_doc = _grow1(out_doc, n_out, cap)
        out_s = _grow1(out_s, n_out, cap)
        out_e = _grow1(out_e, n_out, cap)
    for i in range(nc):
        out_doc[n_out + i] = c_doc[i]
        out_s[n_out + i] = c_s[i]
        out_e[n_out + i] = c_e[i]
    return out_doc, out_s, out_e


@jit
def _grow_rows(a, n, need):  # pragma: no cover
    if need <= a.shape[0]:
        return a
    b = np.empty((max(need, 2 * a.shape[0]), 3), np.int64)
    for i in range(n):
        for j in range(3):
            b[i, j] = a[i, j]
    return b


@jit
def _chain_scan_kernel(iv_doc, iv_start, iv_end, kf_lo, kf_hi, d_min, d_max, doc_lengths,
                       ext_l, ext_r, mode, seg_base, segs, n_segs, hits, n_hits, doc_hit,
                       i0, cur):  # pragma: no cover
    """Chain search of one query (C_KeyframeSearch.c, KEYFRAMES.md §5), into fixed buffers.

    Keyframe k's intervals are ``iv_*[kf_lo[k]:kf_hi[k]]`` sorted by (doc,
    start).  The toolbox's recursion runs here as an explicit stack with the
    same per-keyframe pointers (reset per document only; moved back by one
    interval after a scan that found something), so hits come out in the
    toolbox's order.  mode 0: segments; 1: segments and raw hits; 2: only set
    ``doc_hit[d]`` at the first hit of each document.  Segments from
    ``seg_base`` on belong to this query (merging never looks further back).

    Starts at keyframe 1's interval ``i0`` (a document's first) with
    ``cur[k]`` = where to look for that document in keyframe k's list.  When
    ``segs`` or ``hits`` is full it stops and returns ``(False, i0, n_segs,
    n_hits)`` as they were at the start of the current document, whose search
    the caller repeats with larger buffers (a document's search depends on
    that document only); ``(True, ...)`` when done.  Everything on the hot
    path is inlined and no array is re-bound in the loop: numba then counts
    references per iteration (4x slower).
    """
    K = len(kf_lo)
    re = np.empty(K, np.int64)
    ptr = np.empty(K, np.int64)
    xs = np.empty(K, np.int64)
    xe = np.empty(K, np.int64)
    lo = np.empty(K, np.int64)
    hi = np.empty(K, np.int64)
    found = np.zeros(K, np.bool_)
    ptr0 = np.empty(K, np.int64)
    end0 = kf_hi[0]
    while i0 < end0:
        d = iv_doc[i0]
        e0 = i0 + 1
        while e0 < end0 and iv_doc[e0] == d:
            e0 += 1
        ok = True
        for k in range(1, K):  # locate document d in every other keyframe's list
            c = cur[k]
            hk = kf_hi[k]
            while c < hk and iv_doc[c] < d:
                c += 1
            e = c
            while e < hk and iv_doc[e] == d:
                e += 1
            cur[k] = e
            ptr[k] = c
            ptr0[k] = c
            re[k] = e
            if e == c:  # keyframe k has no interval in d: skip the document
                ok = False
                break
        if ok:
            segs0 = n_segs
            hits0 = n_hits
            last = doc_lengths[d] - 1
            done = False
            for p0 in range(i0, e0):
                xs[0] = iv_start[p0]
                xe[0] = iv_end[p0]
                level = 0
                if K > 1:  # enter level 1 with the range allowed by X_1
                    lo[1] = xs[0] + d_min[0]
                    hi[1] = xe[0] + d_max[0]
                    q = ptr[1]
                    while q < re[1] and lo[1] > iv_end[q]:
                        q += 1
                    ptr[1] = q
                    found[1] = False
                    level = 1
                while True:
                    if level == 0:
                        # K = 1 (not defined by the toolbox): every interval is a hit
                        h_s = xs[0]
                        h_e = xe[0]
                    else:
                        k = level
                        p = ptr[k]
                        if p < re[k] and hi[k] >= iv_start[p] and lo[k] <= iv_end[p]:
                            found[k] = True
                            xs[k] = max(iv_start[p], lo[k])
                            xe[k] = min(iv_end[p], hi[k])
                            if k < K - 1:  # recurse into level k+1
                                nk = k + 1
                                lo[nk] = xs[k] + d_min[k]
                                hi[nk] = xe[k] + d_max[k]
                                q = ptr[nk]
                                while q < re[nk] and lo[nk] > iv_end[q]:
                                    q += 1
                                ptr[nk] = q
                                found[nk] = False
                                level = nk
                                continue
                            # last keyframe: reconstruct the hit from the left end of X_K
                            ptr[k] = p + 1
                            h_s = xs[k]
                            for g in range(K - 2, -1, -1):
                                js = max(h_s - d_max[g], xs[g])
                                if js > min(h_s - d_min[g], xe[g]):
                                    raise RuntimeError("keyframe search: illegal interval in the "
                                                       "reconstruction of hits")
                                h_s = js
                            h_e = xe[k]
                        else:
                            # scan of level k done: step back onto the last intersecting
                            # interval (reusable by the next, later range) and return
                            # to level k-1, which moves on to its next interval
                            if found[k]:
                                ptr[k] -= 1
                            level -= 1
                            if level == 0:
                                break
                            ptr[level] += 1
                            continue
                    # a hit [h_s, h_e]
                    if mode == 2:
                        doc_hit[d] = True
                        done = True
                        break
                    if mode == 1:
                        if n_hits == hits.shape[0]:  # full: redo this document
                            _rewind(cur, ptr0, K)
                            return False, i0, segs0, hits0
                        hits[n_hits, 0] = d
                        hits[n_hits, 1] = h_s
                        hits[n_hits, 2] = h_e
                        n_hits += 1
                    s = max(h_s - ext_l, 0)
                    e = min(h_e + ext_r, last)
                    if n_segs > seg_base and segs[n_segs - 1, 0] == d and s <= segs[n_segs - 1, 2]:
                        # overlap: the toolbox overwrites the end; max is the same for
                        # non-decreasing hit ends (§5, proposed) and never shrinks
                        if e > segs[n_segs - 1, 2]:
                            segs[n_segs - 1, 2] = e
                    else:
                        if n_segs == segs.shape[0]:  # full: redo this document
                            _rewind(cur, ptr0, K)
                            return False, i0, segs0, hits0
                        segs[n_segs, 0] = d
                        segs[n_segs, 1] = s
                        segs[n_segs, 2] = e
                        n_segs += 1
                    if level == 0:
                        break
                if done:
                    break
        i0 = e0
    return True, i0, n_segs, n_hits


@jit
def _chain_query_kernel(iv_doc, iv_start, iv_end, kf_lo, kf_hi, d_min, d_max, doc_lengths,
                        ext_l, ext_r, mode, seg_base, segs, n_segs, hits, n_hits,
                        doc_hit):  # pragma: no cover
    """Chain search of one query (:func:`_chain_scan_kernel`), growing the output buffers.

    Returns the (possibly reallocated) ``segs``, ``n_segs``, ``hits``, ``n_hits``.
    """
    cur = kf_lo.copy()
    i0 = kf_lo[0]
    while True:
        done, i0, n_segs, n_hits = _chain_scan_kernel(
            iv_doc, iv_start, iv_end, kf_lo, kf_hi, d_min, d_max, doc_lengths, ext_l, ext_r,
            mode, seg_base, segs, n_segs, hits, n_hits, doc_hit, i0, cur)
        if done:
            return segs, n_segs, hits, n_hits
        segs = _grow_rows(segs, n_segs, 2 * segs.shape[0] + 64)
        if mode == 1:
            hits = _grow_rows(hits, n_hits, 2 * hits.shape[0] + 64)


@jit
def _chain_batch_kernel(iv_doc, iv_start, iv_end, kf_offset, q_kf, q_kf_offset, d_min, d_max,
                        doc_lengths, ext_l, ext_r, want_hits):  # pragma: no cover
    """Segments (and hits) of many queries, concatenated; per-query offsets."""
    n_q = len(q_kf_offset) - 1
    segs = np.empty((64, 3), np.int64)
    hits = np.empty((64 if want_hits else 0, 3), np.int64)
    seg_q = np.zeros(n_q + 1, np.int64)
    hit_q = np.zeros(n_q + 1, np.int64)
    dummy = np.zeros(0, np.bool_)
    n_segs = np.int64(0)
    n_hits = np.int64(0)
    mode = 1 if want_hits else 0
    for q in range(n_q):
        a = q_kf_offset[q]
        b = q_kf_offset[q + 1]
        kfs = q_kf[a:b]
        g0 = a - q  # gaps of query q start here
        segs, n_segs, hits, n_hits = _chain_query_kernel(
            iv_doc, iv_start, iv_end, kf_offset[kfs], kf_offset[kfs + 1],
            d_min[g0:g0 + b - a - 1], d_max[g0:g0 + b - a - 1], doc_lengths,
            ext_l[q], ext_r[q], mode, n_segs, segs, n_segs, hits, n_hits, dummy)
        seg_q[q + 1] = n_segs
        hit_q[q + 1] = n_hits
    return segs[:n_segs], seg_q, hits[:n_hits], hit_q


@jit
def _search_kernel(words, list_offset, list_doc, list_seg, list_start, list_end, seg_start,
                   seg_len, seg_wid, part_word_offset, doc_seg_offset,
                   sub_part, sub_mask, sub_value, kf_sub_offset,
                   q_kf, q_kf_offset, d_min, d_max, doc_lengths, ext_l, ext_r, mode,
                   d0, d1, strategy, doc_hit):  # pragma: no cover
    """Intervals + chain search of many queries on documents ``d0 <= d < d1``.

    Each query's intervals come from :func:`_query_intervals_kernel` (only
    the documents where all its keyframes match).  Documents are independent
    (merging never crosses them), so a search can be split into document
    ranges that run on separate threads.  ``mode`` as
    :func:`_chain_query_kernel`; mode 2 fills ``doc_hit`` (n_queries, n_docs).
    Returns segments, per-query segment offsets, hits, per-query hit offsets.
    """
    n_q = len(q_kf_offset) - 1
    segs = np.empty((64, 3), np.int64)
    hits = np.empty((64 if mode == 1 else 0, 3), np.int64)
    seg_q = np.zeros(n_q + 1, np.int64)
    hit_q = np.zeros(n_q + 1, np.int64)
    dummy = np.zeros(0, np.bool_)
    n_segs = np.int64(0)
    n_hits = np.int64(0)
    for q in range(n_q):
        a = q_kf_offset[q]
        b = q_kf_offset[q + 1]
        kfs = np.empty(b - a, np.int64)  # the query's distinct keyframes
        loc = np.empty(b - a, np.int64)  # position -> index into kfs
        nk = 0
        for t in range(a, b):
            u = 0
            while u < nk and kfs[u] != q_kf[t]:
                u += 1
            if u == nk:
                kfs[nk] = q_kf[t]
                nk += 1
            loc[t - a] = u
        iv_doc, iv_start, iv_end, kf_offset = _query_intervals_kernel(
            words, list_offset, list_doc, list_seg, list_start, list_end, seg_start, seg_len,
            seg_wid, part_word_offset, doc_seg_offset, sub_part, sub_mask, sub_value,
            kf_sub_offset, kfs[:nk], d0, d1, strategy)
        g0 = a - q  # gaps of query q start here
        segs, n_segs, hits, n_hits = _chain_query_kernel(
            iv_doc, iv_start, iv_end, kf_offset[loc], kf_offset[loc + 1],
            d_min[g0:g0 + b - a - 1], d_max[g0:g0 + b - a - 1], doc_lengths, ext_l[q], ext_r[q],
            mode, n_segs, segs, n_segs, hits, n_hits, doc_hit[q] if mode == 2 else dummy)
        seg_q[q + 1] = n_segs
        hit_q[q + 1] = n_hits
    return segs[:n_segs], seg_q, hits[:n_hits], hit_q


@jit
def _hit_documents_kernel(iv_doc, iv_start, iv_end, kf_offset, q_kf, q_kf_offset, d_min, d_max,
                          doc_lengths, out):  # pragma: no cover
    """``out[q, d]`` = query q has at least one hit in document d (first hit ends the document).

    Serial on purpose: the GA calls this thousands of times on a small index,
    where a parallel region's wake-up costs more than the work (and stalls for
    milliseconds when another process holds a core); run independent GA runs
    on separate threads instead (the kernel releases the GIL).
    """
    n_q = len(q_kf_offset) - 1
    for q in range(n_q):
        a = q_kf_offset[q]
        b = q_kf_offset[q + 1]
        kfs = q_kf[a:b]
        kf_lo = kf_offset[kfs]
        kf_hi = kf_offset[kfs + 1]
        g0 = a - q
        empty = np.empty((0, 3), np.int64)
        _chain_query_kernel(iv_doc, iv_start, iv_end, kf_lo, kf_hi, d_min[g0:g0 + b - a - 1],
                            d_max[g0:g0 + b - a - 1], doc_lengths, np.int64(0), np.int64(0), np.int64(2), np.int64(0),
                            empty, np.int64(0), empty, np.int64(0), out[q])
