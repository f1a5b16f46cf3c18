"""The distance function Δ: subsequence DTW of quantized motion templates on packed words.

TEMPLATES.md §9 and §12, paper Sect. 4 eq. (2):

* :func:`cost_table` — the wildcard-aware local cost c^Q of one template as a
  ``(K, 42)`` table indexed by popcount((value XOR word) AND mask);
* :func:`mt_distance` — Δ of one or many templates over one or many documents
  (one parallel numba kernel over (template, document chunk) pairs);
* :func:`mt_distance_slices` — the same kernel on arbitrary (template, slice)
  tasks, e.g. the segments of a keyframe preselection (§10.1);
* :func:`subsequence_dtw` — the same dynamic programme on a dense cost matrix.

Two selection rules share the kernel (``rule=``):

``"toolbox"`` (default)
    The predecessor with the smallest accumulated cost is chosen first,
    comparing predecessor values only, then ``D = D[pred] + w·C``
    (``C_DTWpartial_compute_D_variablePathSteps.cpp``); reproduces the
    authors' Δ bit for bit.
``"textbook"``
    Minimise ``D[pred] + w·C`` over the steps (ties: first step), as
    ``librosa.sequence.dtw(C=C, subseq=True, step_sizes_sigma=…,
    weights_mul=…)`` does with ``C`` of shape (K, n_frames); reproduces it bit
    for bit.

Steps are ``(Δi, Δj, weight)`` triples, Δi in template columns, Δj in document
frames. Row 0 is a free start (D[0, j] = C[0, j]); "no path" is +inf (the
toolbox's NaN). Start frames are carried through the DP (equal to the
toolbox's backtracking): the frame at which the selected path enters template
column 0.
"""
import math

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic

from mocapdb._numba import jit, pjit, prange
from mocapdb.errors import ParameterError
from mocapdb.features import N_BITS, N_FEATURES, unpack_words
from mocapdb.features import as_words as _as_words
from mocapdb.templates.template import QuantizedTemplate, _expand_counts

__all__ = ["ANNOTATION_STEPS", "DEFAULT_CHUNK", "RETRIEVAL_STEPS", "RULES", "cost_table", "mt_distance",
           "mt_distance_slices", "subsequence_dtw", "weighted_cost_tables"]

#: (Δi template, Δj document, weight) used for annotation (motionClass_to_Delta.m)
ANNOTATION_STEPS = ((1, 1, 1.0), (1, 2, 1.0), (2, 1, 2.0))
#: default of the toolbox's retrieval functions when no steps are passed
RETRIEVAL_STEPS = ((1, 1, 1.0), (0, 1, 1.0), (1, 0, 1.0))
RULES = ("toolbox", "textbook")
_N_COST = N_BITS + 1  # popcount of a masked difference over the feature bits (40 + derived): 0..41
_N_BYTES = 5  # bytes of a 40-bit word: the feature-weighted cost is a sum of one table entry per byte
_CACHE_BITS = 12  # 4096 slots of the weighted costs of recent words, per worker thread
_NO_WORD = np.uint64(1 << 63)  # a tag no 40-bit word has

#: default number of output frames per parallel work item
DEFAULT_CHUNK = 8192


# ---------------------------------------------------------------------------
# kernels


@intrinsic
def _popcount_intrinsic(typingctx, x):
    """Population count of a uint64 (LLVM ctpop → one popcnt instruction)."""
    if x != types.uint64:
        return None
    sig = types.uint64(types.uint64)

    def codegen(context, builder, signature, args):
        return builder.ctpop(args[0])
    return sig, codegen


def _popcount_python(x):  # pragma: no cover - only under NUMBA_DISABLE_JIT
    return int(x).bit_count()


# an intrinsic cannot run as plain Python (the NUMBA_DISABLE_JIT coverage job)
_popcount = _popcount_python if numba.config.DISABLE_JIT else _popcount_intrinsic


@jit
def _pred_base(jj, slot, di, dj, R1, L, pad):  # pragma: no cover
    """Ring index of the predecessor of row 0 along step (di, dj) at DP frame jj (in ring slot
    ``slot`` = jj % R1; dj < R1, so no second modulo is needed).

    Frames before the DP's first frame map to the all-+inf slot R1; row
    ``-di`` lands in the slot's +inf padding.
    """
    if jj - dj < 0:
        return R1 * L + pad - di
    p = slot - dj
    if p < 0:
        p += R1
    return p * L + pad - di


@jit
def _dp_task(words, masks, values, tables, btables, C, K, a0, lo, hi, D, S, c, ccache, ctags, R1, pad, di, dj, sw,
             rule, want_starts, delta, starts, o):  # pragma: no cover
    """Subsequence DP of one template over frames a0..hi-1 of a document or slice.

    Local costs of frame j: from the packed word ``words[j]`` against the K
    template columns (masks, values (K,) uint64; tables (K, 42)), or, if
    btables has rows, the sum of the five byte tables (K, 5, 256) of
    feature-weighted costs at the word's bytes, or, if C has rows, the dense
    column ``C[:, j]``. The byte-table costs of a word are kept in the
    direct-mapped cache ``ccache`` (slots × ≥ K) with ``ctags`` (the word in
    each slot), which the caller keeps per thread while the template stays
    the same: a few distinct words recur all over an archive. Writes Δ of frames lo..hi-1 to
    ``delta[o + j]`` and, if want_starts, their start frames (frame indices,
    -1 where Δ is +inf) to ``starts[o + j]``; frames a0..lo-1 only warm the
    DP up (chunking, §12).

    Scratch: D (float64), S (int32) flat ring buffers of R1 + 1 slots of
    pad + K rows (accumulated cost; start frame relative to a0): slots
    0..R1-1 rotate over frames, slot R1 stays +inf / -1 and stands for frames
    before a0; rows 0..pad-1 of a slot are +inf padding for predecessors
    above row 0. c (>= K,) float64 the frame's costs. di, dj, sw are tuples
    of >= 3 steps (the kernels specialise on their length; _check_steps pads
    shorter step sets).

    Selection uses selects over the steps in order with strict "<" (first
    step wins ties); +inf (no path) never wins against a finite value and
    inf + w·c stays inf, so no special case is needed. The whole frame loop
    is one function: a call per frame would cost as much as a column.
    """
    L = pad + K
    nS = len(di)
    dense = C.shape[0] > 0
    weighted = btables.shape[0] > 0
    for k in range((R1 + 1) * L):
        D[k] = np.inf
        S[k] = -1
    w0, w1, w2 = sw[0], sw[1], sw[2]
    for j in range(a0, hi):
        if dense:
            for i in range(K):
                c[i] = C[i, j]
        elif weighted:
            wd = words[j]
            # few distinct words recur: each one's costs are kept in a direct-mapped cache
            slot = (wd * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(64 - _CACHE_BITS)
            c = ccache[slot]
            if ctags[slot] != wd:
                ctags[slot] = wd
                b0 = wd & 255
                b1 = (wd >> 8) & 255
                b2 = (wd >> 16) & 255
                b3 = (wd >> 24) & 255
                b4 = (wd >> 32) & 255
                for i in range(K):
                    c[i] = (btables[i, 0, b0] + btables[i, 1, b1] + btables[i, 2, b2] + btables[i, 3, b3]
                            + btables[i, 4, b4])
        else:
            wd = words[j]
            for i in range(K):
                c[i] = tables[i, _popcount((values[i] ^ wd) & masks[i])]
        jj = j - a0
        slot = jj % R1
        cur = slot * L + pad
        # row 0: free start
        d0 = c[0]
        if rule == 1:
            # librosa also relaxes row 0 along steps with di = 0
            for s in range(nS):
                if di[s] == 0:
                    v = D[_pred_base(jj, slot, np.int64(0), dj[s], R1, L, pad)] + sw[s] * c[0]
                    if v < d0:
                        d0 = v
        D[cur] = d0
        S[cur] = jj
        if nS == 3:
            # Three steps (the annotation and retrieval steps; fewer are
            # padded): column views whose element i is row i's predecessor,
            # so every index is the loop counter — no negative-index
            # wraparound, no data-dependent branch — and LLVM vectorises the
            # Δ loop (its runtime overlap check falls back to the sequential
            # loop for steps with dj = 0, which read the column being
            # written). The starts, if wanted, take a second loop repeating
            # the selection: cheaper than one loop doing both.
            b0 = _pred_base(jj, slot, di[0], dj[0], R1, L, pad)
            b1 = _pred_base(jj, slot, di[1], dj[1], R1, L, pad)
            b2 = _pred_base(jj, slot, di[2], dj[2], R1, L, pad)
            Dc = D[cur:cur + K]
            P0 = D[b0:b0 + K]
            P1 = D[b1:b1 + K]
            P2 = D[b2:b2 + K]
            if rule == 0:
                # toolbox: choose by predecessor value alone, then add weight * C
                for i in range(1, K):
                    v0 = P0[i]
                    v1 = P1[i]
                    v2 = P2[i]
                    m1 = v1 < v0
                    best = v1 if m1 else v0
                    bw = w1 if m1 else w0
                    m2 = v2 < best
                    best = v2 if m2 else best
                    bw = w2 if m2 else bw
                    Dc[i] = best + bw * c[i]
            else:
                # textbook: minimise predecessor + weight * C
                for i in range(1, K):
                    ci = c[i]
                    v0 = P0[i] + w0 * ci
                    v1 = P1[i] + w1 * ci
                    v2 = P2[i] + w2 * ci
                    best = v1 if v1 < v0 else v0
                    Dc[i] = v2 if v2 < best else best
            if want_starts:
                Sc = S[cur:cur + K]
                T0 = S[b0:b0 + K]
                T1 = S[b1:b1 + K]
                T2 = S[b2:b2 + K]
                for i in range(1, K):
                    v0 = P0[i]
                    v1 = P1[i]
                    v2 = P2[i]
                    if rule == 1:  # textbook: compare predecessor + weight * C
                        ci = c[i]
                        v0 = v0 + w0 * ci
                        v1 = v1 + w1 * ci
                        v2 = v2 + w2 * ci
                    m1 = v1 < v0
                    best = v1 if m1 else v0
                    m2 = v2 < best
                    # unconditional loads, then selects: no data-dependent branch
                    s0 = T0[i]
                    s1 = T1[i]
                    s2 = T2[i]
                    st = s1 if m1 else s0
                    st = s2 if m2 else st
                    Sc[i] = st if Dc[i] < np.inf else np.int32(-1)
        else:
            # more steps: one scalar loop over rows and steps
            for i in range(1, K):
                ci = c[i]
                bb = _pred_base(jj, slot, di[0], dj[0], R1, L, pad)
                best = D[bb + i] if rule == 0 else D[bb + i] + sw[0] * ci
                bw = sw[0]
                for s in range(1, nS):
                    b = _pred_base(jj, slot, di[s], dj[s], R1, L, pad)
                    v = D[b + i] if rule == 0 else D[b + i] + sw[s] * ci
                    m = v < best
                    best = v if m else best
                    bw = sw[s] if m else bw
                    bb = b if m else bb
                if rule == 0:
                    best = best + bw * ci
                D[cur + i] = best
                S[cur + i] = S[bb + i] if best < np.inf else -1
        if j >= lo:
            delta[o + j] = D[cur + K - 1]
            if want_starts:
                st = S[cur + K - 1]
                starts[o + j] = st + a0 if st >= 0 else -1


@pjit
def _mt_distance_kernel(words, masks, values, tables, btables, toff, overlap, di, dj, sw, rule, R1, pad,
                        it, iseg, ilo, ihi, iout, delta, starts, want_starts,
                        Dbuf, Sbuf, cbuf, Cbuf, Tbuf, last_t):  # pragma: no cover
    """Δ for many (template, document slice, chunk) work items, in parallel.

    words (N,) uint64; masks, values (ΣK,) uint64 and tables (ΣK, 42) of all
    templates, template t at rows toff[t]:toff[t+1]; btables (ΣK, 5, 256) the
    feature-weighted byte tables of all templates, or no rows (popcount
    costs); overlap (n_t,) warm-up
    frames per template (-1: no chunking). Item q: template it[q], DP over
    the slice of words starting at iseg[q], output frames ilo[q]:ihi[q]
    written to delta[iout[q] + (j - ilo[q])] (and starts, word indices, if
    want_starts). Every item writes only its own output range. Dbuf, Sbuf,
    cbuf: one row of scratch per worker thread (numba.get_thread_id());
    Cbuf, Tbuf: each thread's cache of weighted word costs, valid for the
    template last_t[thread] (emptied when a thread moves to another template).
    """
    no_dense = np.empty((0, 0))
    for q in prange(it.shape[0]):
        tid = numba.get_thread_id()
        t = it[q]
        a = toff[t]
        b = toff[t + 1]
        lo = ilo[q]
        a0 = iseg[q]
        if overlap[t] >= 0:
            a0 = max(a0, lo - overlap[t])
        bt = btables[a:b] if btables.shape[0] > 0 else btables
        if btables.shape[0] > 0 and last_t[tid] != t:
            Tbuf[tid, :] = _NO_WORD
            last_t[tid] = t
        _dp_task(words, masks[a:b], values[a:b], tables[a:b], bt, no_dense, b - a, a0, lo, ihi[q],
                 Dbuf[tid], Sbuf[tid], cbuf[tid], Cbuf[tid], Tbuf[tid], R1, pad, di, dj, sw, rule, want_starts,
                 delta, starts, iout[q] - lo)


@jit
def _dense_dtw_kernel(C, di, dj, sw, rule, R1, pad, delta, starts,
                      want_starts):  # pragma: no cover
    """The DP of :func:`_mt_distance_kernel` on a dense cost matrix C (K, n)."""
    K = C.shape[0]
    _dp_task(np.empty(0, np.uint64), np.empty(0, np.uint64), np.empty(0, np.uint64),
             np.empty((0, _N_COST)), np.empty((0, _N_BYTES, 256)), C, K, np.int64(0), np.int64(0), C.shape[1],
             np.empty((R1 + 1) * (pad + K)), np.empty((R1 + 1) * (pad + K), np.int32),
             np.empty(K), np.empty((1, 1)), np.empty(1, np.uint64), R1, pad, di, dj, sw, rule, want_starts, delta,
             starts, np.int64(0))


def _word_cost_cache(weighted, nthr, Kmax):
    """(Cbuf, Tbuf, last_t) of :func:`_mt_distance_kernel`: per thread 2^_CACHE_BITS slots of
    weighted word costs (only with weighted costs; else placeholders)."""
    if not weighted:
        return np.empty((nthr, 1, 1)), np.empty((nthr, 1), np.uint64), np.full(nthr, -1, np.int64)
    return (np.empty((nthr, 1 << _CACHE_BITS, Kmax)), np.full((nthr, 1 << _CACHE_BITS), _NO_WORD, np.uint64),
            np.full(nthr, -1, np.int64))


def _ring_shape(di, dj):
    """(R1, pad) of the ring buffers: R1 rotating frame slots, pad rows above row 0."""
    return max(max(dj) + 1, 1), max(di)


# ---------------------------------------------------------------------------
# validation helpers


def _check_rule(rule):
    if rule not in RULES:
        raise ParameterError(f"rule must be one of {RULES}, got {rule!r}")
    return RULES.index(rule)


def _check_steps(steps):
    try:
        a = [tuple(s) for s in steps]
    except TypeError:
        raise ParameterError(
            f"steps must be a sequence of (di, dj, weight) triples, got {steps!r}") from None
    if not a or any(len(s) != 3 for s in a):
        raise ParameterError(
            f"steps must be a non-empty sequence of (di, dj, weight) triples, got {steps!r}")
    di = np.array([s[0] for s in a])
    dj = np.array([s[1] for s in a])
    w = np.array([s[2] for s in a], dtype=np.float64)
    if (not np.issubdtype(di.dtype, np.integer) or not np.issubdtype(dj.dtype, np.integer)
            or (di < 0).any() or (dj < 0).any() or ((di == 0) & (dj == 0)).any()):
        raise ParameterError(
            f"steps must have non-negative integer (di, dj), not both 0, got {steps!r}")
    if not np.isfinite(w).all() or (w <= 0).any():
        raise ParameterError(f"step weights must be positive and finite, got {steps!r}")
    # Tuples: the kernels specialise on the number of steps (see _dp_task).
    # One or two steps are padded to three by repeating the last one: a copy
    # ties with its original and ties go to the first step, so it is never
    # chosen and the fast three-step path serves these step sets too.
    n_pad = max(0, 3 - len(a))
    di, dj, w = (np.concatenate([x, np.repeat(x[-1:], n_pad)]) for x in (di, dj, w))
    return (tuple(int(x) for x in di), tuple(int(x) for x in dj), tuple(float(x) for x in w))



def _as_templates(templates):
    single = isinstance(templates, QuantizedTemplate)
    ts = [templates] if single else list(templates)
    for k, t in enumerate(ts):
        if not isinstance(t, QuantizedTemplate):
            raise ParameterError(
                f"templates[{k}] must be a QuantizedTemplate (MotionTemplate.quantize()), "
                f"got {type(t).__name__}")
    return ts, single


def _chunk_overlap(K, di, dj):
    """Warm-up frames so that a chunk reproduces the serial Δ (§12); -1: never chunk.

    A path from template column 0 to K-1 spans at most max(dj/di)·(K-1)
    document frames after its start; with a Δi = 0 step it is unbounded.
    """
    if 0 in di:
        return -1
    ratio = max(float(b) / float(a) for a, b in zip(di, dj))
    return int(math.ceil(ratio * (K - 1)))


# ---------------------------------------------------------------------------
# public API


def cost_table(template, *, doc_weight=1.0):
    """Per-column cost table of a quantized template (TEMPLATES.md §9).

    ``table[i, c] = (c / K) · ((w[i] + doc_weight) / (2 · max(1, popcount(mask[i]))))``,
    the toolbox's c^Q (fraction of disagreeing non-wildcard features, times the
    mean of template and document weight), with the 1/K normalisation of Δ
    folded in, for ``c`` = popcount((value XOR word) AND mask) mismatches.

    Parameters
    ----------
    template : QuantizedTemplate
        K columns (expand it first if the toolbox would, see :func:`mt_distance`).
    doc_weight : float, default 1.0
        Weight of every document frame (the toolbox's callers use 1).

    Returns
    -------
    ndarray, shape (K, 42), float64

    References
    ----------
    TEMPLATES.md §9 (``motionTemplateDTWRetrievalWeightedForClassification.m``); paper eq. (1).
    """
    (template,), _ = _as_templates(template)
    K = len(template)
    nonfuzzy = np.maximum(1, np.bitwise_count(template.mask)).astype(np.float64)
    factor = (template.weights + float(doc_weight)) / (2.0 * nonfuzzy)
    return np.ascontiguousarray((np.arange(_N_COST, dtype=np.float64) / K)[None, :]
                                * factor[:, None])


def _feature_weights(ts, feature_weights):
    """Per template a (K, 40) float64 weight matrix (or None), checked against the templates."""
    if feature_weights is None:
        return [None] * len(ts)
    fw = list(feature_weights)
    if len(fw) != len(ts):
        raise ParameterError(f"feature_weights must have one entry (or None) per template ({len(ts)}), got {len(fw)}")
    out = []
    for k, (t, w) in enumerate(zip(ts, fw)):
        if w is not None:
            w = np.ascontiguousarray(w, dtype=np.float64)
            if w.shape != (len(t), N_FEATURES) or not np.isfinite(w).all() or (w < 0).any():
                raise ParameterError(f"feature_weights[{k}] must be a ({len(t)}, {N_FEATURES}) array of finite "
                                     f"non-negative weights, got shape {w.shape}")
        out.append(w)
    return out


def weighted_cost_tables(template, feature_weights, *, doc_weight=1.0):
    """Byte tables of a feature-weighted local cost (the weighted form of :func:`cost_table`).

    The cost of template column i against a word is the weighted fraction of
    its fixed features that disagree, ``Σ_f w[i, f]·[feature f differs] /
    Σ_f w[i, f]`` over the non-wildcard features, times the column factor
    and 1/K of :func:`cost_table`; with all weights equal it is
    :func:`cost_table`'s cost. It is tabulated per byte of the 40-bit word,
    so a cost is five table look-ups: ``Σ_b table[i, b, (word >> 8b) & 255]``.

    Parameters
    ----------
    template : QuantizedTemplate
        K columns (already expanded if it is to be).
    feature_weights : array_like, shape (K, 40), float
        Non-negative weight of every feature of every column (wildcards
        ignore theirs). A column whose fixed features all weigh 0 costs 0.
    doc_weight : float, default 1.0

    Returns
    -------
    ndarray, shape (K, 5, 256), float64
    """
    (template,), _ = _as_templates(template)
    (w,) = _feature_weights([template], [feature_weights])
    K = len(template)
    val = unpack_words(template.value).astype(np.float64)
    w = np.where(unpack_words(template.mask), w, 0.0)
    total = w.sum(axis=1)
    factor = (template.weights + float(doc_weight)) / 2.0 / K / np.where(total > 0, total, 1.0)
    # feature f of byte value x differs from v: x_f + v - 2·x_f·v, so a byte's table is an affine map of x's bits.
    # The map's sum runs over the bits in order k = 0..7, elementwise: a BLAS matmul sums in the order of its CPU's
    # kernel (OpenBLAS's on AMD Zen differs from its Haswell kernel in the last bit), and the native similar_to
    # (extension/src/similar_plan.c) computes the same doubles in this order
    bits = ((np.arange(256)[:, None] >> np.arange(8)) & 1).astype(np.float64)  # (256, 8)
    out = np.empty((K, _N_BYTES, 256))
    for b in range(_N_BYTES):
        f = slice(8 * b, 8 * b + 8)
        a = w[:, f] * (1.0 - 2.0 * val[:, f])
        acc = np.zeros((K, 256))
        for k in range(8):
            acc = acc + a[:, k, None] * bits[None, :, k]
        out[:, b, :] = ((w[:, f] * val[:, f]).sum(axis=1)[:, None] + acc) * factor[:, None]
    return np.maximum(out, 0.0, out=out)  # a full match sums to 0 up to rounding: never below


def _prepare_templates(ts, expand, di, dj, feature_weights=None):
    fw = _feature_weights(ts, feature_weights)
    if expand:
        reps = [_expand_counts(t.weights)[0] for t in ts]
        fw = [None if w is None else np.repeat(w, r, axis=0) for w, r in zip(fw, reps)]
        ts = [t.expand() for t in ts]
    Ks = np.array([len(t) for t in ts], dtype=np.int64)
    toff = np.zeros(len(ts) + 1, dtype=np.int64)
    toff[1:] = np.cumsum(Ks)
    masks = np.concatenate([t.mask for t in ts])
    values = np.concatenate([t.value for t in ts])
    tables = np.concatenate([cost_table(t) for t in ts])
    if all(w is None for w in fw):
        btables = np.empty((0, _N_BYTES, 256))
    else:  # a template without weights weighs its features equally
        btables = np.concatenate([weighted_cost_tables(t, np.ones((len(t), N_FEATURES)) if w is None else w)
                                  for t, w in zip(ts, fw)])
    overlap = np.array([_chunk_overlap(K, di, dj) for K in Ks], dtype=np.int64)
    return masks, values, tables, btables, toff, overlap


def mt_distance_slices(words, templates, task_template, task_start, task_stop, *,
                       steps=ANNOTATION_STEPS, rule="toolbox", expand=True,
                       return_starts=False, chunk_size=DEFAULT_CHUNK, feature_weights=None):
    """Δ of templates on slices of a word sequence: one DP per (template, slice) task.

    Each task runs the subsequence DTW of template ``task_template[q]`` on
    ``words[task_start[q]:task_stop[q]]`` as if the slice were a document of
    its own (how the toolbox treats whole documents and keyframe segments).

    Parameters
    ----------
    words : array_like, shape (N,), uint64
    templates : sequence of QuantizedTemplate
    task_template : array_like, shape (n_tasks,), int
        Index into ``templates``.
    task_start, task_stop : array_like, shape (n_tasks,), int
        Half-open slice ``[start, stop)`` of ``words`` (0-based).
    steps, rule, expand, return_starts, chunk_size, feature_weights
        As in :func:`mt_distance`.

    Returns
    -------
    delta : ndarray, shape (Σ slice lengths,), float64
        Δ of task q at ``delta[offsets[q]:offsets[q+1]]``; +inf where no path ends.
    offsets : ndarray, shape (n_tasks + 1,), int64
    starts : ndarray, shape (Σ slice lengths,), int64
        Only if ``return_starts``: start frame (index into ``words``) of the
        path ending at each frame, -1 where Δ is +inf.

    Raises
    ------
    ParameterError
        On bad words, templates, slices, steps or rule.
    """
    w = _as_words(words)
    ts, _ = _as_templates(templates)
    di, dj, sw = _check_steps(steps)
    rule_id = _check_rule(rule)
    if (isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer))
            or chunk_size < 1):
        raise ParameterError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    tt = np.asarray(task_template, dtype=np.int64).ravel()
    ta = np.asarray(task_start, dtype=np.int64).ravel()
    tb = np.asarray(task_stop, dtype=np.int64).ravel()
    if not tt.shape == ta.shape == tb.shape:
        raise ParameterError("task_template, task_start and task_stop must have the same length")
    if tt.size and (tt.min() < 0 or tt.max() >= len(ts)):
        raise ParameterError(f"task_template must index templates (0..{len(ts) - 1})")
    if tt.size and ((ta < 0).any() or (tb < ta).any() or (tb > w.shape[0]).any()):
        raise ParameterError(
            f"slices must satisfy 0 <= start <= stop <= len(words) = {w.shape[0]}")
    lengths = tb - ta
    offsets = np.zeros(tt.size + 1, dtype=np.int64)
    offsets[1:] = np.cumsum(lengths)
    # every frame of every task is written by exactly one work item
    delta = np.empty(int(offsets[-1]))
    starts = np.empty(int(offsets[-1]) if return_starts else 0, dtype=np.int64)
    if not ts or offsets[-1] == 0:
        return (delta, offsets, starts) if return_starts else (delta, offsets)
    masks, values, tables, btables, toff, overlap = _prepare_templates(ts, expand, di, dj, feature_weights)
    # work items: chunks of every non-empty task (whole task if not chunkable)
    keep = np.flatnonzero(lengths > 0)
    chunk = np.where(overlap[tt[keep]] >= 0, int(chunk_size), lengths[keep])
    nch = -(-lengths[keep] // chunk)
    q = np.repeat(keep, nch)
    first = np.repeat(np.cumsum(nch) - nch, nch)
    k = np.arange(q.size) - first
    ch = np.repeat(chunk, nch)
    ilo = ta[q] + k * ch
    ihi = np.minimum(ilo + ch, tb[q])
    iout = offsets[q] + (ilo - ta[q])
    # a fixed shuffle spreads templates of different K over the threads' blocks
    perm = np.random.default_rng(0).permutation(q.size)
    q, ilo, ihi, iout = q[perm], ilo[perm], ihi[perm], iout[perm]
    R1, pad = _ring_shape(di, dj)
    Kmax = int(np.diff(toff).max())
    nthr = numba.config.NUMBA_NUM_THREADS
    _mt_distance_kernel(
        w, masks, values, tables, btables, toff, overlap, di, dj, sw, rule_id, R1, pad,
        tt[q], ta[q], ilo, ihi, iout, delta,
        starts if return_starts else np.empty(1, np.int64), bool(return_starts),
        np.empty((nthr, (R1 + 1) * (pad + Kmax))),
        np.empty((nthr, (R1 + 1) * (pad + Kmax)), np.int32),
        np.empty((nthr, Kmax)), *_word_cost_cache(btables.shape[0] > 0, nthr, Kmax))
    return (delta, offsets, starts) if return_starts else (delta, offsets)


def mt_distance(words, templates, *, doc_lengths=None, steps=ANNOTATION_STEPS,
                rule="toolbox", expand=True, return_starts=False, chunk_size=DEFAULT_CHUNK, feature_weights=None):
    """The distance function Δ of quantized motion templates against documents.

    ``Δ(j)`` is the (1/K-normalised) cost of the subsequence-DTW path that
    ends at document frame j (paper eq. (2)); +inf where no path can end
    (e.g. the first ⌊K/2⌋ frames with the annotation steps, or a document
    shorter than the template allows). Documents never share a path.

    Parameters
    ----------
    words : array_like, shape (N,), uint64
        Packed 30 Hz feature words of one document, or of several documents
        concatenated (see ``doc_lengths``).
    templates : QuantizedTemplate or sequence of QuantizedTemplate
    doc_lengths : array_like of int, optional
        Lengths of the concatenated documents (sum = N); default one document.
    steps : sequence of (di, dj, weight), default ANNOTATION_STEPS
        (1,1) w1, (1,2) w1, (2,1) w2; di counts template columns, dj frames.
    rule : {"toolbox", "textbook"}, default "toolbox"
        Predecessor selection (module docstring).
    expand : bool, default True
        Expand the template by its rounded weights first (the toolbox's
        ``expandV = 1``; no-op for balanced templates).
    return_starts : bool, default False
        Also return the start frame of every Δ path.
    chunk_size : int, default 8192
        Output frames per parallel work item; chunks overlap by the longest
        possible path so the result equals the serial one bit for bit.
    feature_weights : sequence of (K, 40) array_like or None, optional
        Per template (same order; None for equal weights) a weight for every
        feature of every column: the local cost becomes the weighted fraction
        of disagreeing fixed features (:func:`weighted_cost_tables`), e.g.
        for retrieval, where rare feature values say more than common ones.
        Default: every fixed feature counts the same (the paper's c^Q).

    Returns
    -------
    delta : ndarray, shape (N,) for one template, (n_templates, N) otherwise, float64
    starts : ndarray of int64, same shape (only if ``return_starts``)
        Index into ``words`` of the path's first frame; -1 where Δ is +inf.

    Raises
    ------
    ParameterError
        On bad words, templates, doc_lengths, steps or rule.

    References
    ----------
    TEMPLATES.md §9, §12; paper Sect. 4, eq. (1)–(2).
    """
    w = _as_words(words)
    ts, single = _as_templates(templates)
    n = w.shape[0]
    if doc_lengths is None:
        lens = np.array([n], dtype=np.int64)
    else:
        lens = np.asarray(doc_lengths, dtype=np.int64).ravel()
        if (lens < 0).any() or lens.sum() != n:
            raise ParameterError(
                f"doc_lengths must be non-negative and sum to len(words) = {n}, "
                f"got sum {int(lens.sum())}")
    bounds = np.concatenate(([0], np.cumsum(lens)))
    nt, nd = len(ts), lens.size
    res = mt_distance_slices(
        w, ts, np.repeat(np.arange(nt), nd), np.tile(bounds[:-1], nt), np.tile(bounds[1:], nt),
        steps=steps, rule=rule, expand=expand, return_starts=return_starts,
        chunk_size=chunk_size, feature_weights=feature_weights)
    delta = res[0].reshape(nt, n)
    if single:
        delta = delta[0]
    if not return_starts:
        return delta
    starts = res[2].reshape(nt, n)
    return delta, (starts[0] if single else starts)


def subsequence_dtw(C, *, steps=ANNOTATION_STEPS, rule="toolbox", return_starts=False):
    """Subsequence DTW on a dense cost matrix (the DP of :func:`mt_distance`).

    Parameters
    ----------
    C : array_like, shape (K, n), float
        Local cost of query column i against sequence frame j (non-negative,
        +inf allowed, no NaN).
    steps : sequence of (di, dj, weight), default ANNOTATION_STEPS
    rule : {"toolbox", "textbook"}, default "toolbox"
    return_starts : bool, default False

    Returns
    -------
    delta : ndarray, shape (n,), float64
        ``D[K-1, :]`` (not normalised: fold 1/K into C).
    starts : ndarray, shape (n,), int64
        Only if ``return_starts``; -1 where ``delta`` is +inf.

    Raises
    ------
    ParameterError
        If C is not 2-D, contains NaN or negative values, or steps/rule are bad.

    Examples
    --------
    ``rule="textbook"`` equals librosa:
    ``librosa.sequence.dtw(C=C, subseq=True, step_sizes_sigma=[[1, 1], [1, 2], [2, 1]],
    weights_mul=[1, 1, 2], backtrack=False)[-1]``.
    """
    C = np.ascontiguousarray(C, dtype=np.float64)
    if C.ndim != 2 or C.shape[0] == 0:
        raise ParameterError(f"C must be a 2-D (K, n) matrix with K >= 1, got shape {C.shape}")
    if np.isnan(C).any() or (C < 0).any():
        raise ParameterError("C must be non-negative without NaN")
    di, dj, sw = _check_steps(steps)
    rule_id = _check_rule(rule)
    delta = np.empty(C.shape[1])
    starts = np.empty(C.shape[1] if return_starts else 1, dtype=np.int64)
    R1, pad = _ring_shape(di, dj)
    _dense_dtw_kernel(C, di, dj, sw, rule_id, R1, pad, delta, starts, bool(return_starts))
    return (delta, starts) if return_starts else delta
