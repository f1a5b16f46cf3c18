"""Motion template learning by iterative warping and averaging (paper Sect. 3).

Implements TEMPLATES.md §2–§8 (toolbox strategy 5) so that the learned template
is bit-identical to the authors' toolbox:

* :func:`weighted_dtw` — weighted full DTW (§3) and the warping of a sequence
  onto the reference's time axis (§4);
* :func:`average_step` — one averaging step with a fixed reference (§5);
* :func:`expand_weighted`, :func:`contract_weighted`, :func:`balance_weighted`
  — time balancing (§6);
* :func:`learn_template` — the iterative learner with reference cycling (§7);

The template classes and δ-quantization (§8) are in :mod:`mocapdb.templates.template`.

Sequences are frames-first: a (weighted) sequence is an ``(L, 40)`` float64
matrix plus an ``(L,)`` weight vector. Exactness (§3, §12): every sum the
toolbox forms is accumulated sequentially in float64, each L1 term is divided
by 40 before it is added, and rounding is Matlab's (halves away from zero).

Speed: one learning iteration needs the DTW of every ordered pair of
sequences; the cost matrix and accumulated cost of (B, A) are exactly the
transposes of those of (A, B), so each unordered pair's DP runs once and
records the tie-broken choices of both orientations (``_pair_dtw_kernel``).
"""

import numpy as np

from mocapdb._numba import jit, pjit, prange
from mocapdb.errors import ParameterError
from mocapdb.features import MIRROR_FEATURES, N_FEATURES, mirror_words
from mocapdb.templates.template import MotionTemplate, _as_sequence, _as_weights, _expand_counts

__all__ = [
    "learn_template", "weighted_dtw", "average_step", "expand_weighted", "contract_weighted",
    "balance_weighted",
]

#: contraction threshold of contractWeightedVectorSequence.m (§6.2)
CONTRACT_THRESHOLD = 0.75

# ---------------------------------------------------------------------------
# kernels


@jit
def _pair_dtw_kernel(X, Xt, w, r0, n, c0, m, D2, acc, E):  # pragma: no cover
    """Weighted full DTW of A = X[r0:r0+n] (rows) against B = X[c0:c0+m] (§3).

    Xt = X.T (so that a cost row vectorises over j); w the weights of X.
    Scratch D2 (2, >=m), acc (>=m,). E (n*m,) uint8 receives, per cell, the
    predecessor choice (1 diagonal, 2 (a, b-1), 3 (a-1, b)) for both
    orientations: bits 0-1 with A as the reference (ties: diagonal, then the
    step advancing B only, then A only — the toolbox's order), bits 2-3 with
    B as the reference (the same order seen from B). One DP serves both
    references: C and hence D of (B, A) are exactly the transposes of those
    of (A, B) (|a-b| = |b-a|, weights added commutatively; min is exact).
    Returns the alignment cost D[n-1, m-1].
    """
    p = X.shape[1]
    for i in range(n):
        # C[i, :] in the toolbox's order: start at 0, add |A - B| / p feature by
        # feature (each term divided), then scale by the mean weight
        for j in range(m):
            acc[j] = 0.0
        for f in range(p):
            vf = X[r0 + i, f]
            xt = Xt[f, c0:c0 + m]
            for j in range(m):
                acc[j] += abs(vf - xt[j]) / p
        wi = w[r0 + i]
        for j in range(m):
            acc[j] = acc[j] * ((wi + w[c0 + j]) / 2.0)
        cur = i & 1
        prv = cur ^ 1
        if i == 0:
            D2[0, 0] = acc[0]
            for j in range(1, m):
                D2[0, j] = D2[0, j - 1] + acc[j]
            continue
        D2[cur, 0] = D2[prv, 0] + acc[0]
        row = i * m
        for j in range(1, m):
            d = D2[prv, j - 1]
            h = D2[cur, j - 1]
            v = D2[prv, j]
            # strict "<": A as reference prefers diagonal, h, v; B as reference d, v, h
            best = d
            ch1 = 1
            if h < best:
                best = h
                ch1 = 2
            if v < best:
                best = v
                ch1 = 3
            b2 = d
            ch2 = 1
            if v < b2:
                b2 = v
                ch2 = 3
            if h < b2:
                ch2 = 2
            D2[cur, j] = best + acc[j]
            E[row + j] = ch1 | (ch2 << 2)
    return D2[(n - 1) & 1, m - 1]


@jit
def _warp_kernel(Xt, w, n, c0, m, E, e0, transposed, jlo, jhi, blo, bhi, Ww,
                 ww):  # pragma: no cover
    """Backtrack a pair's DP and warp W = X[c0:c0+m] onto the reference axis (§3, §4).

    The reference has n frames. The pair's choices are E[e0:e0 + n*m]: laid
    out (n, m) with the reference as rows (transposed=False, bits 0-1), or
    (m, n) with W as rows (transposed=True, bits 2-3). Fills jlo/jhi (>=n,)
    (W range of every reference frame) and blo/bhi (>=m,) (reference range
    of every W frame), then Ww (>=n, 40) and ww (>=n,).
    """
    p = Xt.shape[0]
    for b in range(n):
        jlo[b] = m
        jhi[b] = -1
    for j in range(m):
        blo[j] = n
        bhi[j] = -1
    # pair coordinates (a rows, b cols); reference frame i, W frame j
    if transposed:
        na, nb, shift = m, n, 2
    else:
        na, nb, shift = n, m, 0
    a = na - 1
    bb = nb - 1
    while True:
        if transposed:
            i = bb
            j = a
        else:
            i = a
            j = bb
        if j < jlo[i]:
            jlo[i] = j
        if j > jhi[i]:
            jhi[i] = j
        if i < blo[j]:
            blo[j] = i
        if i > bhi[j]:
            bhi[j] = i
        if a > 0 and bb > 0:
            ch = (E[e0 + a * nb + bb] >> shift) & 3
            if ch == 1:
                a -= 1
                bb -= 1
            elif ch == 2:
                bb -= 1
            else:
                a -= 1
        elif a > 0:
            a -= 1
        elif bb > 0:
            bb -= 1
        else:
            break
    # warped columns: weighted mean of the matched W frames (sequential sums)
    for b in range(n):
        s = 0.0
        for f in range(p):
            Ww[b, f] = 0.0
        for j in range(jlo[b], jhi[b] + 1):
            wj = w[c0 + j]
            s += wj
            for f in range(p):
                Ww[b, f] += wj * Xt[f, c0 + j]
        for f in range(p):
            Ww[b, f] = Ww[b, f] / s
        ww[b] = s
    # second pass: a W frame stretched over r reference frames spreads its
    # weight over them (cumulative division, W frames in increasing order)
    for j in range(m):
        r = bhi[j] - blo[j] + 1
        if r > 1:
            for b in range(blo[j], bhi[j] + 1):
                ww[b] = ww[b] / r


@pjit
def _pairs_kernel(X, Xt, w, off, pa, pb, eoff, E, pcost):  # pragma: no cover
    """The DP of every unordered pair (pa[q] < pb[q]) once, in parallel."""
    for q in prange(pa.shape[0]):
        r0 = off[pa[q]]
        n = off[pa[q] + 1] - r0
        c0 = off[pb[q]]
        m = off[pb[q] + 1] - c0
        pcost[q] = _pair_dtw_kernel(X, Xt, w, r0, n, c0, m, np.empty((2, m)), np.empty(m),
                                    E[eoff[q]:eoff[q] + n * m])


@jit
def _average_kernel(X, Xt, w, off, r, pidx, eoff, E, pcost, T, wT, costs):  # pragma: no cover
    """One averaging step (§5) with sequence r as reference, the others in order.

    X (N, 40) concatenated sequences, Xt = X.T, w (N,), off (M+1,); the pair
    DPs of :func:`_pairs_kernel` (pidx (M, M) pair index of r < k, eoff, E,
    pcost). Writes the averaged template T (n_r, 40), its weights wT (n_r,),
    and costs (M,) (costs[0] = 0 for the reference itself, then one per other
    sequence in order).
    """
    M = off.shape[0] - 1
    p = X.shape[1]
    a = off[r]
    n = off[r + 1] - a
    mmax = 0
    for k in range(M):
        mmax = max(mmax, off[k + 1] - off[k])
    jlo = np.empty(n, dtype=np.int64)
    jhi = np.empty(n, dtype=np.int64)
    blo = np.empty(mmax, dtype=np.int64)
    bhi = np.empty(mmax, dtype=np.int64)
    Ww = np.empty((n, p))
    ww = np.empty(n)
    sumw = np.empty(n)
    # k = 1 (the reference itself): UtemplateHelp = 0 + w .* U1
    for b in range(n):
        sumw[b] = w[a + b]
        for f in range(p):
            T[b, f] = w[a + b] * X[a + b, f]
    costs[0] = 0.0
    row = 1
    for k in range(M):
        if k == r:
            continue
        q = pidx[k, r] if k < r else pidx[r, k]
        _warp_kernel(Xt, w, n, off[k], off[k + 1] - off[k], E, eoff[q], k < r,
                     jlo, jhi, blo, bhi, Ww, ww)
        costs[row] = pcost[q]
        row += 1
        for b in range(n):
            wb = ww[b]
            sumw[b] += wb
            for f in range(p):
                T[b, f] += wb * Ww[b, f]
    for b in range(n):
        for f in range(p):
            T[b, f] = T[b, f] / sumw[b]
        wT[b] = sumw[b] / M


@pjit
def _iteration_kernel(X, Xt, w, off, pidx, eoff, E, pcost, T, wT, costs):  # pragma: no cover
    """All M averaging steps of one learning iteration (§7), in parallel over r.

    T (N, 40), wT (N,) share the layout ``off`` of X; costs (M, M) gets column
    r = the costs of reference r (the toolbox's Vcost(:, r) before normalising).
    """
    M = off.shape[0] - 1
    for r in prange(M):
        a = off[r]
        b = off[r + 1]
        _average_kernel(X, Xt, w, off, r, pidx, eoff, E, pcost, T[a:b], wT[a:b], costs[:, r])


@jit
def _contract_kernel(V, w, V_out, w_out, threshold):  # pragma: no cover
    """contractWeightedVectorSequence.m (§6.2); returns the number of output columns.

    V (n, 40), w (n,); V_out (n, 40), w_out (n,) preallocated.
    """
    n = V.shape[0]
    p = V.shape[1]
    cin = 0
    cout = -1
    while cin < n:
        cout += 1
        s = w[cin]
        if s >= threshold:
            for f in range(p):
                V_out[cout, f] = V[cin, f]
            w_out[cout] = s
            cin += 1
            continue
        cright = cin
        border = False
        while s < threshold:
            cright += 1
            if cright < n:
                s = s + w[cright]
            else:
                border = True
                cright -= 1
                break
        if border and cin > 0:
            # right-border rule: take one more column from the left and replace
            # the previously emitted output column (earlier members are lost)
            cin -= 1
            cout -= 1
            s = s + w[cin]
        # (border at the very first column: the toolbox would fail; we emit one
        # column for the whole sequence, TEMPLATES.md §6 "proposed")
        for f in range(p):
            acc = 0.0
            for c in range(cin, cright + 1):
                acc += w[c] * V[c, f]
            V_out[cout, f] = acc / s
        w_out[cout] = s
        cin = cright + 1
    return cout + 1


@jit
def _seq_sum(x):  # pragma: no cover
    """Sequential left-to-right float64 sum (the toolbox's accumulation order)."""
    s = 0.0
    for v in x.ravel():
        s += v
    return s


def weighted_dtw(V, W, *, v_weights=None, w_weights=None):
    """Weighted full DTW of a reference V with a sequence W, with W warped onto V.

    Local cost ``(Σ_f |V[i,f] − W[j,f]| / 40) · (wV[i] + wW[j]) / 2``; steps
    (1,1), (0,1), (1,0) with weight 1; ties: diagonal, then the step advancing
    W only, then the step advancing V only.

    Parameters
    ----------
    V : array_like, shape (n, 40)
        Reference (bool or real in [0, 1]).
    W : array_like, shape (m, 40)
    v_weights, w_weights : array_like, shape (n,) / (m,), optional
        Column weights (default all ones).

    Returns
    -------
    warped : ndarray, shape (n, 40), float64
        W on the time axis of V (§4).
    warped_weights : ndarray, shape (n,), float64
    cost : float
        The alignment cost D[n−1, m−1].

    References
    ----------
    TEMPLATES.md §3–§4 (``new_motionTemplateDTWReal_realInputWeighted.m``).
    """
    V = _as_sequence(V, "V")
    W = _as_sequence(W, "W")
    wV = _as_weights(v_weights, V.shape[0], "v_weights")
    wW = _as_weights(w_weights, W.shape[0], "w_weights")
    n, m = V.shape[0], W.shape[0]
    X = np.concatenate([V, W])
    w = np.concatenate([wV, wW])
    off = np.array([0, n, n + m], dtype=np.int64)
    pidx, eoff, E, pcost = _pair_dtws(X, np.ascontiguousarray(X.T), w, off)
    Ww = np.empty((n, N_FEATURES))
    ww = np.empty(n)
    _warp_kernel(np.ascontiguousarray(X.T), w, n, n, m, E, eoff[0], False,
                 np.empty(n, np.int64), np.empty(n, np.int64), np.empty(m, np.int64),
                 np.empty(m, np.int64), Ww, ww)
    return Ww, ww, float(pcost[0])


def average_step(sequences, weights=None):
    """One averaging step with a fixed reference (§5): sequence 0 is the reference.

    Parameters
    ----------
    sequences : sequence of array_like, each (n_k, 40)
    weights : sequence of array_like (n_k,), optional
        Default all ones.

    Returns
    -------
    template : ndarray, shape (n_0, 40), float64
    template_weights : ndarray, shape (n_0,), float64
    costs : ndarray, shape (len(sequences),), float64
        0 for the reference, then the alignment cost of every other sequence.

    References
    ----------
    TEMPLATES.md §5 (``new_motionTemplateGenerateReal_realInputWeighted.m``).
    """
    X, w, off = _pack_sequences(sequences, weights)
    Xt = np.ascontiguousarray(X.T)
    pidx, eoff, E, pcost = _pair_dtws(X, Xt, w, off)
    n = off[1]
    T = np.empty((n, N_FEATURES))
    wT = np.empty(n)
    costs = np.empty(off.shape[0] - 1)
    _average_kernel(X, Xt, w, off, 0, pidx, eoff, E, pcost, T, wT, costs)
    return T, wT, costs



def expand_weighted(X, weights):
    """Expand a weighted sequence (§6.1): column b repeated max(1, round(w[b])) times.

    Each copy gets weight ``w[b] / r[b]``; ``round`` is Matlab's (halves away
    from zero).

    Parameters
    ----------
    X : array_like, shape (L, d)
    weights : array_like, shape (L,)

    Returns
    -------
    X_out : ndarray, shape (L', d); weights_out : ndarray, shape (L',)

    References
    ----------
    TEMPLATES.md §6.1 (``expandWeightedVectorSequence.m``).
    """
    X = np.asarray(X, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    reps, wr = _expand_counts(w)
    return np.repeat(X, reps, axis=0), np.repeat(wr, reps)


def contract_weighted(X, weights, *, threshold=CONTRACT_THRESHOLD):
    """Contract a weighted sequence (§6.2): merge light columns until weight ≥ 0.75.

    Left to right: a column of weight ≥ ``threshold`` is copied; otherwise it
    is merged with the following columns until the accumulated weight reaches
    the threshold (weighted mean of the values, weight = group sum). If the end
    is reached first, the group takes one more column from the left and
    replaces the previously emitted column (right-border rule).

    Parameters
    ----------
    X : array_like, shape (L, d)
    weights : array_like, shape (L,)
    threshold : float, default 0.75

    Returns
    -------
    X_out : ndarray, shape (L', d); weights_out : ndarray, shape (L',)

    Examples
    --------
    >>> import numpy as np
    >>> contract_weighted(np.ones((7, 1)), [1, .5, .125, .125, 1, .25, .4])[1]
    array([1.  , 0.75, 1.65])

    References
    ----------
    TEMPLATES.md §6.2 (``contractWeightedVectorSequence.m``).
    """
    X = np.ascontiguousarray(X, dtype=np.float64)
    w = np.ascontiguousarray(weights, dtype=np.float64)
    if X.ndim != 2 or w.shape != (X.shape[0],):
        raise ParameterError(f"X must be (L, d) and weights (L,), got {X.shape}, {w.shape}")
    Xo = np.empty_like(X)
    wo = np.empty_like(w)
    k = _contract_kernel(X, w, Xo, wo, float(threshold))
    return Xo[:k].copy(), wo[:k].copy()


def balance_weighted(X, weights):
    """Balance a weighted sequence (§6): expand, contract (0.75), expand.

    Returns
    -------
    X_out : ndarray, shape (L', d); weights_out : ndarray, shape (L',)
        Weights in [0.75, 1.5) except in the degenerate border case.

    References
    ----------
    TEMPLATES.md §6 (``balanceWeightedVectorSequence.m``).
    """
    X, w = expand_weighted(X, weights)
    X, w = contract_weighted(X, w)
    return expand_weighted(X, w)


def _pair_dtws(X, Xt, w, off):
    """Run the DP of every unordered pair of sequences once (§3; see _pair_dtw_kernel)."""
    M = off.shape[0] - 1
    pa, pb = np.triu_indices(M, 1)
    lens = np.diff(off)
    sizes = lens[pa] * lens[pb]
    eoff = np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)
    E = np.empty(int(eoff[-1]), dtype=np.uint8)
    pcost = np.empty(pa.size)
    pidx = np.full((M, M), -1, dtype=np.int64)
    pidx[pa, pb] = np.arange(pa.size)
    _pairs_kernel(X, Xt, w, off, pa.astype(np.int64), pb.astype(np.int64), eoff, E, pcost)
    return pidx, eoff, E, pcost


def _averaging_iteration(X, w, off):
    """Every sequence as reference once (§5): templates T, weights wT, costs (M, M)."""
    Xt = np.ascontiguousarray(X.T)
    pidx, eoff, E, pcost = _pair_dtws(X, Xt, w, off)
    M = off.shape[0] - 1
    T = np.empty_like(X)
    wT = np.empty_like(w)
    costs = np.empty((M, M))
    _iteration_kernel(X, Xt, w, off, pidx, eoff, E, pcost, T, wT, costs)
    return T, wT, costs


def _pack_sequences(sequences, weights):
    seqs = [_as_sequence(s, f"clips[{k}]") for k, s in enumerate(sequences)]
    if not seqs:
        raise ParameterError("need at least one clip to learn a template")
    if weights is None:
        ws = [np.ones(s.shape[0]) for s in seqs]
    else:
        if len(weights) != len(seqs):
            raise ParameterError(
                f"weights must have one entry per clip ({len(seqs)}), got {len(weights)}")
        ws = [_as_weights(w, s.shape[0], f"weights[{k}]")
              for k, (s, w) in enumerate(zip(seqs, weights))]
    off = np.zeros(len(seqs) + 1, dtype=np.int64)
    off[1:] = np.cumsum([s.shape[0] for s in seqs])
    return np.concatenate(seqs), np.concatenate(ws), off


def learn_template(clips, *, iter_max=10, iter_thresh=0.005, weights=None, flip=None):
    """Learn a motion template by iterative warping and averaging (§7, strategy 5).

    Every iteration uses each current sequence once as the reference, warps
    all others (in their original order) onto it and averages (§5), then
    balances the result (§6); all sequences are replaced simultaneously. The
    loop stops after ``iter_max`` iterations, when the maximal normalised
    alignment cost is ≤ ``iter_thresh``, or when it equals the previous one.

    Parameters
    ----------
    clips : sequence of array_like
        Training clips at 30 Hz, each an ``(n_i, 40)`` bool/0-1 feature matrix
        or ``(n_i,)`` uint64 packed words. The order matters (ties, and the
        result is the template of the first clip's slot).
    iter_max : int, default 10
    iter_thresh : float, default 0.005
    weights : sequence of array_like, optional
        Initial column weights per clip (default all ones).
    flip : sequence of bool, optional
        Mirror these clips left/right first (FEATURES.md §7); default none.

    Returns
    -------
    MotionTemplate
        ``real`` (K, 40), ``weights`` (K,), iteration statistics.

    Raises
    ------
    ParameterError
        On empty input, a clip of the wrong shape, or bad parameters.

    References
    ----------
    TEMPLATES.md §7 (``motionTemplateGenerateDTWIterative.m``); paper Sect. 3;
    Müller & Röder, SCA 2006.
    """
    if isinstance(iter_max, bool) or not isinstance(iter_max, (int, np.integer)) or iter_max < 1:
        raise ParameterError(f"iter_max must be a positive integer, got {iter_max!r}")
    if not isinstance(iter_thresh, (int, float, np.floating)) or not iter_thresh >= 0:
        raise ParameterError(f"iter_thresh must be a non-negative number, got {iter_thresh!r}")
    clips = list(clips)
    if flip is not None:
        flip = list(flip)
        if len(flip) != len(clips):
            raise ParameterError(
                f"flip must have one entry per clip ({len(clips)}), got {len(flip)}")
        clips = [_flip_clip(c) if f else c for c, f in zip(clips, flip)]
    X, w, off = _pack_sequences(clips, weights)
    M = off.shape[0] - 1
    seqs = [X[off[k]:off[k + 1]] for k in range(M)]
    ws = [w[off[k]:off[k + 1]] for k in range(M)]
    err_max, err_mean, err_std = [], [], []
    current = float(iter_thresh) + 1.0
    previous = 0.0
    j = 0
    while j < iter_max and current > iter_thresh and previous != current:
        previous = current
        j += 1
        T, wT, costs = _averaging_iteration(X, w, off)
        for k in range(M):
            seqs[k], ws[k] = balance_weighted(T[off[k]:off[k + 1]], wT[off[k]:off[k + 1]])
            costs[:, k] = costs[:, k] / _seq_sum(ws[k])
        # statistics over all M^2 entries in Matlab's column-major order
        flat = np.ascontiguousarray(costs.T).ravel()
        mean = _seq_sum(flat) / flat.size
        std = (np.sqrt(_seq_sum((flat - mean) ** 2) / (flat.size - 1))
               if flat.size > 1 else 0.0)
        current = float(flat.max())
        err_max.append(current)
        err_mean.append(mean)
        err_std.append(std)
        X = np.concatenate(seqs)
        w = np.concatenate(ws)
        off[1:] = np.cumsum([s.shape[0] for s in seqs])
    return MotionTemplate(seqs[0], ws[0], iterations=j, error_max=np.array(err_max),
                          error_mean=np.array(err_mean), error_std=np.array(err_std), n_clips=M)


def _flip_clip(clip):
    a = np.asarray(clip)
    if a.ndim == 1:
        return mirror_words(a)
    return _as_sequence(a, "clip")[:, list(MIRROR_FEATURES)]
