"""Slow, obviously-correct references for the template / DTW / annotation kernels.

Straight transcriptions of TEMPLATES.md (and of the toolbox behaviour it
describes): full dense matrices, plain Python loops, no packing, no rolling
buffers, no chunking. Only for tests.
"""
import numpy as np


# ---------------------------------------------------------------------------
# learning (TEMPLATES.md §3–§6)

def naive_weighted_dtw(V, W, wV, wW):
    """§3–§4 literally: full C, D, E, backtracking, warping; returns (Ww, ww, cost)."""
    n, p = V.shape
    m = W.shape[0]
    C = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            s = 0.0
            for f in range(p):
                s += abs(V[i, f] - W[j, f]) / p
            C[i, j] = s * ((wV[i] + wW[j]) / 2)
    D = np.zeros((n, m))
    E = np.zeros((n, m), dtype=int)
    D[0, 0] = C[0, 0]
    for i in range(1, n):
        D[i, 0] = D[i - 1, 0] + C[i, 0]
    for j in range(1, m):
        D[0, j] = D[0, j - 1] + C[0, j]
    for i in range(1, n):
        for j in range(1, m):
            cands = [D[i - 1, j - 1], D[i, j - 1], D[i - 1, j]]
            k = 0
            for t in (1, 2):
                if cands[t] < cands[k]:
                    k = t
            E[i, j] = k
            D[i, j] = cands[k] + C[i, j]
    path = [(n - 1, m - 1)]
    i, j = n - 1, m - 1
    while i > 0 and j > 0:
        di, dj = [(1, 1), (0, 1), (1, 0)][E[i, j]]
        i, j = i - di, j - dj
        path.append((i, j))
    while i > 0:
        i -= 1
        path.append((i, j))
    while j > 0:
        j -= 1
        path.append((i, j))
    path = path[::-1]
    Ww = np.zeros((n, p))
    ww = np.zeros(n)
    for b in range(n):
        js = [j for (i, j) in path if i == b]
        num = np.zeros(p)
        den = 0.0
        for j in js:
            for f in range(p):
                num[f] += wW[j] * W[j, f]
            den += wW[j]
        Ww[b] = num / den
        ww[b] = den
    for j in range(m):
        bs = [i for (i, jj) in path if jj == j]
        r = len(bs)
        for b in bs:
            ww[b] = ww[b] / r
    return Ww, ww, D[n - 1, m - 1]


def naive_average_step(seqs, weights):
    """§5 literally: warp every other sequence onto seqs[0], weighted mean."""
    n, p = seqs[0].shape
    U = len(seqs)
    warped = [(seqs[0], weights[0], 0.0)]
    for k in range(1, U):
        warped.append(naive_weighted_dtw(seqs[0], seqs[k], weights[0], weights[k]))
    T = np.zeros((n, p))
    sw = np.zeros(n)
    for Ww, ww, _ in warped:
        for b in range(n):
            for f in range(p):
                T[b, f] = T[b, f] + ww[b] * Ww[b, f]
            sw[b] = sw[b] + ww[b]
    for b in range(n):
        T[b] = T[b] / sw[b]
    return T, sw / U, np.array([c for _, _, c in warped])


def naive_contract(X, w, threshold=0.75):
    """contractWeightedVectorSequence.m transcribed (list-based)."""
    outX, outw = [], []
    n = len(w)
    i = 0
    while i < n:
        s = w[i]
        if s >= threshold:
            outX.append(X[i].copy())
            outw.append(s)
            i += 1
            continue
        r = i
        border = False
        while s < threshold:
            r += 1
            if r < n:
                s = s + w[r]
            else:
                border = True
                r -= 1
                break
        if border and i > 0:
            i -= 1
            outX.pop()
            outw.pop()
            s = s + w[i]
        num = np.zeros(X.shape[1])
        for c in range(i, r + 1):
            num = num + w[c] * X[c]
        outX.append(num / s)
        outw.append(s)
        i = r + 1
    return np.array(outX), np.array(outw)


# ---------------------------------------------------------------------------
# matching (TEMPLATES.md §9)

def naive_cost_matrix(template, weights, doc, doc_weights=None):
    """c^Q from the 0 / 1 / 0.5 template matrix (K, 40) and a bool document (m, 40).

    C[i, j] = (mismatches / K) · ((wV[i] + wW[j]) / (2 · max(1, nonfuzzy(i)))),
    in the toolbox's order of operations; not from popcounts.
    """
    K = template.shape[0]
    m = doc.shape[0]
    if doc_weights is None:
        doc_weights = np.ones(m)
    C = np.zeros((K, m))
    for i in range(K):
        fixed = template[i] != 0.5
        nonfuzzy = max(1, int(fixed.sum()))
        for j in range(m):
            mism = int((fixed & (template[i] != doc[j].astype(float))).sum())
            C[i, j] = (mism / K) * ((weights[i] + doc_weights[j]) / (2 * nonfuzzy))
    return C


def naive_subsequence_dtw(C, steps, rule):
    """Full-matrix subsequence DTW with explicit backtracking.

    steps: (di, dj, weight) triples. rule "toolbox": choose the predecessor by
    its value (first on ties, inf = invalid), D = pred + w·C; backtrack while
    i > 0 and j > 0, then walk down to row 0 (start = column reached).
    rule "textbook": librosa's recurrence (row 0 also relaxed along di = 0
    steps) and backtracking (while i > 0). Returns (delta, starts, D).
    """
    K, m = C.shape
    INF = np.inf
    D = np.full((K, m), INF)
    E = np.full((K, m), -1, dtype=int)

    def get(i, j):
        return D[i, j] if i >= 0 and j >= 0 else INF

    for j in range(m):
        D[0, j] = C[0, j]
        if rule == "textbook":
            for s, (di, dj, w) in enumerate(steps):
                if di == 0:
                    v = get(0, j - dj) + w * C[0, j]
                    if v < D[0, j]:
                        D[0, j] = v
                        E[0, j] = s
        for i in range(1, K):
            if rule == "toolbox":
                best, bs = INF, -1
                for s, (di, dj, w) in enumerate(steps):
                    v = get(i - di, j - dj)
                    if v < best:
                        best, bs = v, s
                if bs >= 0:
                    D[i, j] = best + steps[bs][2] * C[i, j]
                    E[i, j] = bs
            else:
                for s, (di, dj, w) in enumerate(steps):
                    v = get(i - di, j - dj) + w * C[i, j]
                    if v < D[i, j]:
                        D[i, j] = v
                        E[i, j] = s
    starts = np.full(m, -1)
    for e in range(m):
        if not D[K - 1, e] < INF:
            continue
        i, j = K - 1, e
        if rule == "toolbox":
            while i > 0 and j > 0:
                di, dj, _ = steps[E[i, j]]
                i, j = i - di, j - dj
        else:
            while i > 0:
                di, dj, _ = steps[E[i, j]]
                i, j = i - di, j - dj
        starts[e] = j
    return D[K - 1].copy(), starts, D


# ---------------------------------------------------------------------------
# annotation (TEMPLATES.md §9.1, §10.3)

def naive_hits(delta, starts, tau, match_num_max=None):
    """The toolbox's hit loop: repeated first-minimum with exclusion of [s, e]."""
    dh = np.array(delta, dtype=float)
    cd = np.full(dh.size, np.inf)
    hits = []
    while dh.size:
        e = int(np.argmin(dh))  # first index of the minimum
        cost = dh[e]
        if not cost <= tau:
            break
        if match_num_max is not None and len(hits) == match_num_max:
            raise RuntimeError("The maximum number of hits did not suffice.")
        s = int(starts[e])
        for f in range(s, e + 1):
            if cd[f] == np.inf:
                cd[f] = cost
        hits.append((s, e, cost))
        dh[s:e + 1] = np.inf
    if match_num_max is not None and len(hits) == match_num_max:
        raise RuntimeError("The maximum number of hits did not suffice.")
    return hits, cd


def naive_segments(cd_docs, labels):
    """classificationDelta_to_classificationResult.m transcribed.

    cd_docs: list of (n_labels, n_d) arrays. Builds the toolbox's concatenated
    database (2 +inf separator frames after every document, 1-based starts),
    runs the runs / extension / per-document clipping / incremental merging
    exactly as the toolbox, and returns rows (label, doc, start, end, cost)
    with 0-based frames within each document, in the toolbox's output order.
    """
    L = len(labels)
    parts, starts_, lengths = [], [], []
    pos = 1
    for c in cd_docs:
        parts.append(c)
        parts.append(np.full((L, 2), np.inf))
        starts_.append(pos)
        lengths.append(c.shape[1])
        pos += c.shape[1] + 2
    cd = np.concatenate(parts, axis=1)
    nframes = cd.shape[1]
    min_class = np.zeros(nframes + 1, dtype=int)  # 1-based
    for f in range(1, nframes + 1):
        col = cd[:, f - 1]
        k = int(np.argmin(col))
        min_class[f] = 0 if col[k] == np.inf else k + 1
    result = {lab: [] for lab in range(1, L + 1)}  # rows [doc, s_doc, e_doc, s_db, e_db, cost]
    f = 1
    base_doc = 1
    while f <= nframes:
        g = f
        while g + 1 <= nframes and min_class[g + 1] == min_class[f]:
            g += 1
        p = min_class[f]
        if p > 0:
            while True:
                base_doc += 1
                if base_doc > len(starts_) or f < starts_[base_doc - 1]:
                    break
            base_doc -= 1
            s = f
            s_cost = cd[p - 1, s - 1]
            while True:
                s -= 1
                if s < 1 or cd[p - 1, s - 1] > s_cost:
                    break
                s_cost = cd[p - 1, s - 1]
            s += 1
            e = g
            e_cost = cd[p - 1, e - 1]
            while True:
                e += 1
                if e > nframes or cd[p - 1, e - 1] > e_cost:
                    break
                e_cost = cd[p - 1, e - 1]
            e -= 1
            cost = min(s_cost, e_cost)
            hit = set(range(s, e + 1))
            doc = base_doc
            while doc >= 1:
                ds = starts_[doc - 1]
                if not hit & set(range(ds, ds + lengths[doc - 1])):
                    break
                doc -= 1
            doc += 1
            while doc <= len(starts_):
                ds = starts_[doc - 1]
                inter = sorted(hit & set(range(ds, ds + lengths[doc - 1])))
                if not inter:
                    break
                rs, re_ = inter[0], inter[-1]
                prev = [r for r in result[p] if r[0] == doc]
                if prev:
                    data = sorted([r[3:6] for r in prev] + [[rs, re_, cost]],
                                  key=lambda r: r[0])
                    merged = [list(data[0])]
                    for a in data[1:]:
                        if a[0] <= merged[-1][1]:
                            merged[-1][1] = max(merged[-1][1], a[1])
                            merged[-1][2] = min(merged[-1][2], a[2])
                        else:
                            merged.append(list(a))
                    result[p] = [r for r in result[p] if r[0] != doc]
                    for a in merged:
                        result[p].append([doc, a[0] - ds + 1, a[1] - ds + 1, a[0], a[1], a[2]])
                else:
                    result[p].append([doc, rs - ds + 1, re_ - ds + 1, rs, re_, cost])
                doc += 1
        f = g + 1
    rows = []
    for p in range(1, L + 1):
        for r in result[p]:
            rows.append((labels[p - 1], r[0] - 1, r[1] - 1, r[2] - 1, r[5]))
    return rows
