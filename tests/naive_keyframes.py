"""Slow, obviously correct references for mocapdb.keyframes.index and mocapdb.keyframes.

Plain Python over frames: runs of constant word, posting lists as dicts, the
toolbox's enumeration of all 2^w wildcard words, and a brute-force keyframe
chain search that never looks at the toolbox's pointer logic.

What the toolbox returns (KEYFRAMES.md §5), restated without pointers: a
*path* is a choice of one maximal run of matching frames I_k per keyframe.
Its admissible chains are the frame tuples t_k in I_k with
d_min[g] <= t_{g+1} - t_g <= d_max[g].  Every path with at least one chain
gives the hit [min t_1, max t_K] over its chains (the reconstruction starts
from the leftmost frame of X_K and greedily takes the leftmost compatible
frame per level, which is the leftmost t_1 of all the path's chains).
Segments = hits extended by the margins (clipped to the document) and merged
when they overlap (start <= previous end; adjacent segments stay apart).
The brute force enumerates the paths and computes the reachable frames of
each with explicit frame sets.
"""
from __future__ import annotations

import itertools

import numpy as np

INF = float("inf")


def words_from_bits(bits) -> np.ndarray:
    """(n, 40) 0/1 -> packed uint64 words, bit k-1 = feature k, one frame at a time."""
    out = np.zeros(len(bits), np.uint64)
    for t, row in enumerate(np.asarray(bits)):
        w = 0
        for k, b in enumerate(row):
            if b:
                w |= 1 << k
        out[t] = w
    return out


def naive_segments(words, first_bit, n_bits):
    """Maximal runs of the restricted word: list of (word, start, length)."""
    segs = []
    for t, w in enumerate(words):
        x = (int(w) >> first_bit) & ((1 << n_bits) - 1)
        if segs and segs[-1][0] == x:
            segs[-1][2] += 1
        else:
            segs.append([x, t, 1])
    return [tuple(s) for s in segs]


def naive_postings(segments_per_doc):
    """word -> list of (doc, seg) in the order the toolbox appends them."""
    lists = {}
    for d, segs in enumerate(segments_per_doc):
        for s, (w, _, _) in enumerate(segs):
            lists.setdefault(w, []).append((d, s))
    return lists


def naive_fuzzy_words(mask, value, n_bits):
    """All 2^w words of a keyframe (indicesFixedBits.m): fixed bits set, wildcards enumerated."""
    free = [b for b in range(n_bits) if not (mask >> b) & 1]
    out = []
    for combo in itertools.product((0, 1), repeat=len(free)):
        w = value
        for b, x in zip(free, combo):
            w |= x << b
        out.append(w)
    return sorted(out)


def naive_union(lists, words):
    """Union of posting lists, sorted, unique (C_union_presorted_2xn.cpp)."""
    return sorted({p for w in words for p in lists.get(w, [])})


def naive_match(words, mask, value):
    """Per frame: does the word match the keyframe?"""
    return np.array([(int(w) & mask) == value for w in words], dtype=bool)


def naive_runs(flags):
    """Maximal runs of True as a list of (start, end), inclusive."""
    runs = []
    for t, f in enumerate(flags):
        if f:
            if runs and runs[-1][1] == t - 1:
                runs[-1][1] = t
            else:
                runs.append([t, t])
    return [tuple(r) for r in runs]


def _reach(prev, run, lo, hi, n):
    """Frames t in run with some t' in prev and lo <= t - t' <= hi."""
    out = set()
    for t in range(run[0], run[1] + 1):
        for tp in prev:
            if lo <= t - tp <= hi:
                out.add(t)
                break
    return out


def naive_hits_doc(runs, d_min, d_max, n):
    """All path hits of one document as a list of (start, end)."""
    K = len(runs)
    hits = []

    def dfs(k, reach_sets, path):
        if k == K:
            # backward pass: frames that lie on a complete chain
            back = reach_sets[-1]
            for g in range(K - 2, -1, -1):
                back = {t for t in reach_sets[g]
                        if any(d_min[g] <= u - t <= d_max[g] for u in back)}
            hits.append((min(back), max(reach_sets[-1])))
            return
        for run in runs[k]:
            if k == 0:
                r = set(range(run[0], run[1] + 1))
            else:
                r = _reach(reach_sets[-1], run, d_min[k - 1], d_max[k - 1], n)
            if r:
                dfs(k + 1, reach_sets + [r], path + [run])

    dfs(0, [], [])
    return hits


def naive_keyframe_search(docs_words, masks, values, d_min, d_max, *, extend_left=0,
                          extend_right=0, return_hits=False):
    """Brute-force keyframe search: list of (doc, start, end), 0-based inclusive.

    ``d_max`` entries may be ``inf``.  With ``return_hits`` also the set of
    distinct path hits (doc, start, end), sorted.
    """
    segs_out = []
    hits_out = set()
    for d, words in enumerate(docs_words):
        n = len(words)
        runs = [naive_runs(naive_match(words, int(m), int(v))) for m, v in zip(masks, values)]
        if any(not r for r in runs):
            continue
        hits = naive_hits_doc(runs, list(d_min), list(d_max), n)
        hits_out.update((d, s, e) for s, e in hits)
        ext = sorted((max(0, s - extend_left), min(n - 1, e + extend_right)) for s, e in hits)
        merged = []
        for s, e in ext:
            if merged and s <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], e)
            else:
                merged.append([s, e])
        segs_out.extend((d, s, e) for s, e in merged)
    if return_hits:
        return segs_out, sorted(hits_out)
    return segs_out


def naive_reachable_last(docs_words, masks, values, d_min, d_max):
    """Frames of the last keyframe that end some admissible chain: set of (doc, t)."""
    out = set()
    for d, words in enumerate(docs_words):
        match = [naive_match(words, int(m), int(v)) for m, v in zip(masks, values)]
        reach = {t for t in range(len(words)) if match[0][t]}
        for g in range(len(masks) - 1):
            reach = {t for t in range(len(words)) if match[g + 1][t]
                     and any(d_min[g] <= t - u <= d_max[g] for u in reach)}
        out.update((d, t) for t in reach)
    return out


def naive_choose_equally_distributed(quantized, n_keyframes):
    """keyframesChooseLeastGrayValuesEquallyDistributed.m on a (F, L) 0/1/0.5 matrix, 1-based."""
    L = quantized.shape[1]
    ignored = int(L * 0.1)
    mt = quantized[:, ignored:L - ignored]
    gray = [int(sum(1 for x in mt[:, c] if x == 0.5)) for c in range(mt.shape[1])]
    sec = len(gray) // n_keyframes
    pos = []
    cur = 1
    for _ in range(n_keyframes - 1):
        part = gray[cur - 1:cur - 1 + sec]
        pos.append(cur - 1 + part.index(min(part)) + 1 + ignored)
        cur += sec + 1
    part = gray[cur - 1:]
    pos.append(cur - 1 + part.index(min(part)) + 1 + ignored)
    return pos


# --------------------------------------------------------------------------
# reading the toolbox oracle (../shared/oracle/keyframes)


def read_rows(path):
    """CSV file -> list of dicts."""
    import csv
    with open(path) as f:
        return list(csv.DictReader(f))


def int_table(path, columns):
    """Selected columns of a CSV file as an (n, len(columns)) int64 array ('Inf' -> -1)."""
    rows = read_rows(path)
    return np.array([[(-1 if r[c] == "Inf" else int(r[c])) for c in columns] for r in rows],
                    dtype=np.int64).reshape(-1, len(columns))


def load_feat30_words(oracle, stem):
    """Packed 30 Hz words of ``oracle/features/<stem>_feat30.csv`` (header f01..f40)."""
    x = np.loadtxt(oracle / "features" / f"{stem}_feat30.csv", delimiter=",", skiprows=1, ndmin=2)
    return words_from_bits(x.astype(np.int64))


def load_toolbox_query(oracle, name):
    """The oracle's query ``name``: (vectors, set_index, positions, stiffness, templateLength)."""
    rows = read_rows(oracle / "keyframes" / "queries" / f"{name}_keyframes.csv")
    gaps = read_rows(oracle / "keyframes" / "queries" / f"{name}_gaps.csv")
    vectors = [[float(r[f"v{i:02d}"]) for i in range(1, int(r["n_features"]) + 1)] for r in rows]
    return (vectors, [int(r["set_index"]) for r in rows], [int(r["position"]) for r in rows],
            [float(g["stiffness"]) for g in gaps], int(rows[0]["templateLength"]))
