"""Byte-level helpers shared by the text readers (AMC, BVH).

The hot loop of reading a motion file is turning ASCII decimals into floats.
:func:`_parse_number` does that inside numba kernels and is exact: it uses
Clinger's fast path (an integer mantissa below 2**53 times or divided by an
exactly representable power of ten is one correctly rounded IEEE operation),
so its result equals Python's ``float(token)``. Tokens outside the fast path
(more than 16 significant digits, or a decimal exponent beyond ±22, e.g.
``2.72109e-026``) are reported back and converted by ``float()`` in Python —
a few per file at most.
"""
from __future__ import annotations

import math

import numpy as np

from mocapdb._numba import inline_jit, jit
from mocapdb.errors import ParseError

#: exactly representable powers of ten (10**22 is the largest, 5**22 < 2**53)
_P10 = np.array([10.0 ** k for k in range(23)])

#: number status codes returned by :func:`_parse_number`
NUM_OK, NUM_SLOW, NUM_BAD = 0, 1, 2

_TWO53 = 2 ** 53
_ZERO = np.uint8(48)
#: digits that always fit the int64 mantissa (10**17 < 2**63)
_MAX_DIGITS = 17
_NINE = np.uint8(9)


#: byte classes: 0 = token byte, 1 = blank (space, tab, CR, VT, FF), 2 = LF.
#: CR is a blank so CRLF and LF files read alike.
_CLASS = np.zeros(256, dtype=np.uint8)
_CLASS[[32, 9, 13, 11, 12]] = 1
_CLASS[10] = 2


@jit
def _is_space(c):  # pragma: no cover - numba
    """Blank within a line (not LF)."""
    return _CLASS[c] == 1


@inline_jit
def _scan_number(buf, i, end):  # pragma: no cover - numba
    """Parse the decimal number starting at ``buf[i]``, up to the next delimiter.

    A delimiter is a blank, LF or ``end``. Returns ``(value, status, j)``
    with ``j`` the delimiter's index; status 0 = exact value, 1 = valid
    number outside the fast path (the caller converts ``buf[i:j]`` with
    ``float``), 2 = not a number. Accepts ``[+-]digits[.digits][(e|E)[+-]digits]``
    with digits on at least one side of the point — what Python's ``float``
    accepts, minus inf/nan and underscores. One pass over the bytes: this
    is the innermost loop of every reader.
    """
    neg = False
    c = int(buf[i])  # int(): exact arithmetic also when run without numba
    if c == 45:
        neg = True
        i += 1
    elif c == 43:
        i += 1
    m = 0
    exp10 = 0
    bad = False
    # the digit loops do one unsigned compare per byte (a byte below '0' wraps
    # around above 9) and count digits instead of checking m: more than 17
    # digits may overflow m and take Python's float (the slow path) anyway
    first = i
    while i < end:
        d = buf[i] - _ZERO
        if d > _NINE:
            break
        m = m * 10 + int(d)
        i += 1
    nd = i - first
    c = int(buf[i]) if i < end else 0
    if c == 46:
        i += 1
        first = i
        while i < end:
            d = buf[i] - _ZERO
            if d > _NINE:
                break
            m = m * 10 + int(d)
            i += 1
        exp10 -= i - first
        nd += i - first
        c = int(buf[i]) if i < end else 0
    anyd = nd > 0
    big = nd > _MAX_DIGITS
    if not anyd:
        bad = True
    if i < end and (c == 101 or c == 69) and not bad:
        i += 1
        eneg = False
        if i < end and (buf[i] == 45 or buf[i] == 43):
            eneg = buf[i] == 45
            i += 1
        ex = 0
        anye = False
        while i < end:
            c = int(buf[i])
            if c < 48 or c > 57:
                break
            anye = True
            if ex < 100000:
                ex = ex * 10 + (c - 48)
            i += 1
        if not anye:
            bad = True
        exp10 += -ex if eneg else ex
    if i < end and _CLASS[buf[i]] == 0:
        bad = True
        while i < end and _CLASS[buf[i]] == 0:
            i += 1
    if bad:
        return 0.0, NUM_BAD, i
    if big or m > _TWO53:
        return 0.0, NUM_SLOW, i
    if m == 0:
        return (-0.0 if neg else 0.0), NUM_OK, i
    if 0 <= exp10 <= 22:
        v = m * _P10[exp10]
    elif -22 <= exp10 < 0:
        v = m / _P10[-exp10]
    else:
        return 0.0, NUM_SLOW, i
    return (-v if neg else v), NUM_OK, i


@jit
def _parse_number(buf, s, e):  # pragma: no cover - numba
    """Parse the whole of ``buf[s:e]``; returns ``(value, status)`` as :func:`_scan_number`."""
    v, st, j = _scan_number(buf, s, e)
    if j != e:
        return 0.0, NUM_BAD
    return v, st


@jit
def _parse_numbers_kernel(buf, starts, ends, out, status):  # pragma: no cover - numba
    """Parse many tokens (tests and small headers): ``out[k] = buf[starts[k]:ends[k]]``."""
    for k in range(starts.shape[0]):
        v, st = _parse_number(buf, starts[k], ends[k])
        out[k] = v
        status[k] = st


def parse_numbers(tokens) -> tuple:
    """Parse byte tokens with the kernel's number parser (for tests).

    Returns ``(values float64 (n,), status int64 (n,))``; status as in
    :func:`_parse_number`.
    """
    starts = np.zeros(len(tokens), dtype=np.int64)
    ends = np.zeros(len(tokens), dtype=np.int64)
    pos = 0
    for k, t in enumerate(tokens):
        starts[k] = pos
        pos += len(t)
        ends[k] = pos
    buf = np.frombuffer(b"".join(tokens) or b"\0", dtype=np.uint8)
    out = np.zeros(len(tokens))
    status = np.zeros(len(tokens), dtype=np.int64)
    _parse_numbers_kernel(buf, starts, ends, out, status)
    return out, status


@jit
def _nonfinite_token(buf, s, e):  # pragma: no cover - numba
    """True when ``buf[s:e]`` spells a non-finite number: ``nan``, ``inf``, ``infinity`` (any case,
    signed, ``nan(ind)``), or a Windows C runtime form (``1.#QNAN``, ``-1.#IND``, ``1.#INF``)."""
    k = s
    if k < e and (buf[k] == 43 or buf[k] == 45):
        k += 1
    if e - k >= 3:
        a, b, c = buf[k] | 32, buf[k + 1] | 32, buf[k + 2] | 32
        if (a == 110 and b == 97 and c == 110) or (a == 105 and b == 110 and c == 102):
            return True
    j = k
    while j < e and (48 <= buf[j] <= 57 or buf[j] == 46):
        j += 1
    return j > k and j < e and buf[j] == 35


@jit
def _parse_rows_kernel(buf, start, out, fb_index, fb_start, fb_end, status, allow_nonfinite):  # pragma: no cover
    """Read lines of exactly ``out.shape[1]`` numbers from byte ``start`` into ``out``.

    Blank lines are skipped. Stops at the first error with ``status`` =
    [code, byte offset, row, expected, found, n_slow, n_rows, n_nonfinite]: code 1 = not a
    number (offset of the token), 2 = wrong count (offset of the line),
    3 = more rows than ``out`` has (offset of the first extra line).
    Slow-path tokens are listed in ``fb_*`` as in the AMC kernel. With
    ``allow_nonfinite``, a token spelling NaN or infinity reads as NaN (lost
    tracking, for the caller to mend) instead of stopping.
    """
    size = buf.shape[0]
    ncols = out.shape[1]
    nrows = out.shape[0]
    fb_cap = fb_index.shape[0]
    nfb = 0
    row = 0
    i = start
    while True:
        # blanks and line ends (direct compares: faster than the class table here)
        while i < size and (buf[i] == 32 or buf[i] == 10 or buf[i] == 13 or buf[i] == 9 or buf[i] == 11
                            or buf[i] == 12):
            i += 1
        if i >= size:
            break
        line_start = i
        if row >= nrows:
            status[0] = 3
            status[1] = line_start
            status[2] = row
            break
        count = 0
        failed = False
        while True:
            while i < size and (buf[i] == 32 or buf[i] == 13 or buf[i] == 9 or buf[i] == 11 or buf[i] == 12):
                i += 1
            if i >= size or buf[i] == 10:
                break
            s = i
            if count >= ncols:
                while i < size and _CLASS[buf[i]] == 0:
                    i += 1
            else:
                v, st, i = _scan_number(buf, i, size)
                if st == 2 and allow_nonfinite and _nonfinite_token(buf, s, i):
                    v, st = math.nan, 0
                    status[7] += 1
                if st == 2:
                    status[0] = 1
                    status[1] = s
                    status[2] = row
                    failed = True
                    break
                if st == 1:
                    if nfb < fb_cap:
                        fb_index[nfb] = row * ncols + count
                        fb_start[nfb] = s
                        fb_end[nfb] = i
                    nfb += 1
                out[row, count] = v
            count += 1
        if failed:
            break
        if count != ncols:
            status[0] = 2
            status[1] = line_start
            status[2] = row
            status[3] = ncols
            status[4] = count
            break
        row += 1
    status[5] = nfb
    status[6] = row


def parse_rows(data: bytes, start: int, n_rows: int, n_cols: int, path, *,
               what="values", first_frame=1, allow_nonfinite=False):
    """Parse ``n_rows`` lines of ``n_cols`` numbers starting at byte ``start``.

    Returns a float64 ``(rows_read, n_cols)`` array (``rows_read <= n_rows``;
    the caller decides whether fewer rows is an error). With
    ``allow_nonfinite``, NaN and infinity (spelled out, or a number that
    overflows) read as NaN.

    Raises
    ------
    ParseError
        A non-numeric or non-finite value, a line with the wrong number of
        values, or more lines than ``n_rows`` (file, line and frame named).
    """
    # a header's row count is never trusted for allocation: a row of n_cols
    # values takes at least 2·n_cols bytes (one more row detects extra lines).
    # np.empty does not touch the rows it will not fill.
    out = np.empty((rows_bound(len(data) - start, n_rows, n_cols), n_cols))
    rows = parse_rows_into(data, start, out, path, n_rows=n_rows, what=what, first_frame=first_frame,
                           allow_nonfinite=allow_nonfinite)
    return out[:rows]


def rows_bound(n_bytes: int, n_rows: int, n_cols: int) -> int:
    """Rows to allocate for ``n_bytes`` of lines of ``n_cols`` numbers: the most they can hold
    (each value takes two bytes or more), at most ``n_rows`` (a line beyond it is an error)."""
    return min(n_rows, max(n_bytes, 0) // max(2 * n_cols, 1) + 2)


def parse_rows_into(data: bytes, start: int, out: np.ndarray, path, *, n_rows: int, what="values",
                    first_frame=1, allow_nonfinite=False, line_base=0) -> int:
    """Parse lines of ``out.shape[1]`` numbers from byte ``start`` into ``out`` (row 0 first).

    ``data`` may be one block of a longer text (whole lines): ``line_base``
    is the number of lines before it, ``first_frame`` the frame number of its
    first row, ``n_rows`` the rows the whole text may hold. Returns the rows
    parsed; raises as :func:`parse_rows` (a row beyond ``out`` is one more
    than ``n_rows``: the caller sizes ``out`` so).
    """
    if start >= len(data):
        return 0
    buf = np.frombuffer(data, dtype=np.uint8)
    n_cols = out.shape[1]
    cap = max(256, out.shape[0] * n_cols // 256)  # slow-path tokens are rare; rerun if not
    while True:
        fb_index = np.zeros(cap, dtype=np.int64)
        fb_start = np.zeros(cap, dtype=np.int64)
        fb_end = np.zeros(cap, dtype=np.int64)
        status = np.zeros(8, dtype=np.int64)
        _parse_rows_kernel(buf, start, out, fb_index, fb_start, fb_end, status, allow_nonfinite)
        if status[0] != 0 or status[5] <= cap:
            break
        cap = int(status[5])
    code, pos, row = int(status[0]), int(status[1]), int(status[2])
    frame = row + first_frame
    if code == 1:
        raise number_error(data, pos, path, frame=frame, hint=truncation_hint(data, pos), line_base=line_base)
    if code == 2:
        raise ParseError(path, line_base + line_of(data, pos), f"expected {int(status[3])} {what}, "
                         f"found {int(status[4])}" + truncation_hint(data, pos), frame=frame)
    if code == 3:
        raise ParseError(path, line_base + line_of(data, pos), f"more motion lines than the {n_rows} "
                         "announced", frame=frame)
    nfb = int(status[5])
    fix_slow_numbers(data, out.reshape(-1), fb_index[:nfb], fb_start[:nfb], fb_end[:nfb], path,
                     describe=lambda flat: (flat // max(n_cols, 1) + first_frame, ""),
                     allow_nonfinite=allow_nonfinite, line_base=line_base)
    return int(status[6])


def line_of(data: bytes, pos: int) -> int:
    """1-based line number of byte offset ``pos`` (lines end with LF)."""
    return data.count(b"\n", 0, max(0, min(pos, len(data)))) + 1


def token_at(data: bytes, pos: int) -> str:
    """The whitespace-delimited token starting at ``pos``, decoded for messages."""
    end = pos
    while end < len(data) and data[end] not in b" \t\r\n\v\f":
        end += 1
    return data[pos:end].decode("latin-1")


def number_error(data: bytes, pos: int, path, *, frame=None, where="", hint="", line_base=0) -> ParseError:
    """ParseError for a token at ``pos`` that is not a finite number (``line_base`` lines precede ``data``)."""
    tok = token_at(data, pos)
    low = tok.lower().lstrip("+-")
    if low in ("nan", "inf", "infinity") or (low and _is_nonfinite(tok)):
        what = f"expected a finite number, found {tok!r} (NaN/inf values are not allowed)"
    else:
        what = f"expected a number, found {tok!r}"
    return ParseError(path, line_base + line_of(data, pos), f"{where}{what}{hint}", frame=frame)


def _is_nonfinite(tok: str) -> bool:
    try:
        return not np.isfinite(float(tok))
    except ValueError:
        return False


def fix_slow_numbers(data: bytes, flat_out, index, starts, ends, path, describe=None, allow_nonfinite=False,
                     line_base=0):
    """Convert the tokens the kernel left for Python (``float``) into ``flat_out``.

    ``describe(flat_index) -> (frame, prefix)`` names the place for messages.
    Raises ParseError for values that overflow to inf (e.g. ``1e999``), unless
    ``allow_nonfinite`` (then they read as NaN).
    """
    if len(index) == 0:
        return
    vals = np.array([float(data[s:e]) for s, e in zip(starts.tolist(), ends.tolist())])
    bad = np.flatnonzero(~np.isfinite(vals))
    if bad.size and allow_nonfinite:
        vals[bad] = np.nan
    elif bad.size:
        k = int(bad[0])
        frame, where = describe(int(index[k])) if describe is not None else (None, "")
        raise number_error(data, int(starts[k]), path, frame=frame, where=where, line_base=line_base)
    flat_out[index] = vals


def truncation_hint(data: bytes, pos: int) -> str:
    """A hint when ``pos`` lies on the last line and that line has no line end."""
    if data.endswith(b"\n") or data.find(b"\n", pos) >= 0:
        return ""
    return " (the last line is incomplete: the file may be truncated)"


@jit
def _line_ends_kernel(a):  # pragma: no cover - numba
    """``(first line end, last line end, longest gap between two line ends)`` of the bytes ``a`` (LF or
    CR; -1, -1, 0 when there is none): one pass, no temporaries (a take's header is checked per file)."""
    first = -1
    prev = -1
    gap = 0
    for i in range(a.shape[0]):
        c = a[i]
        if c == 10 or c == 13:
            if first < 0:
                first = i
            elif i - prev > gap:
                gap = i - prev
            prev = i
    return first, prev, gap


def longest_line(chunk, carry: int = 0) -> tuple:
    """``(longest line, length of the unfinished last line)`` of the bytes ``chunk`` (LF or CR ends), its
    first line continuing one of ``carry`` bytes: linear in the chunk, whatever its lines (a "line" of
    megabytes of NUL bytes is found in one pass, not by a scanner waiting for its end)."""
    a = np.frombuffer(chunk, np.uint8)
    first, last_end, gap = _line_ends_kernel(a)
    if first < 0:
        return carry + a.size, carry + a.size
    last = int(a.size - last_end - 1)
    inner = int(gap) - 1 if last_end > first else 0
    return max(carry + int(first), inner, last), last
