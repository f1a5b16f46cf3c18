"""Slow, obviously correct references for mocapdb.evaluation.metrics (paper Eq. (5)–(8)).

Rows are (document, label, start, end), 0-based inclusive frames.
"""


def naive_frame_sets(rows):
    """The set {(document, frame, label)} of paper Eq. (5)/(6)."""
    return {(str(d), f, str(p)) for d, p, s, e in rows for f in range(int(s), int(e) + 1)}


def _ratio(a, b):
    return a / b if b else 0.0


def _f(p, r):
    return 2 * p * r / (p + r) if p + r else 0.0


def naive_frame_measures(truth, auto):
    m, a = naive_frame_sets(truth), naive_frame_sets(auto)
    both = m & a
    p, r = _ratio(len(both), len(a)), _ratio(len(both), len(m))
    return p, r, _f(p, r), (len(m), len(a), len(both))


def _overlaps(x, ys):
    d, p, s, e = x
    return any(str(d) == str(d2) and str(p) == str(p2) and s <= e2 and s2 <= e
               for d2, p2, s2, e2 in ys)


def naive_segment_measures(truth, auto):
    found = sum(_overlaps(t, auto) for t in truth)
    correct = sum(_overlaps(a, truth) for a in auto)
    p, r = _ratio(correct, len(auto)), _ratio(found, len(truth))
    return p, r, _f(p, r), (len(truth), len(auto), found, correct)
