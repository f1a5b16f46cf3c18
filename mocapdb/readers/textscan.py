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

from mocapdb._numba import (address, inline_jit, jit, load_u64, load_u8, mask64_eq, mask64_le, store_i64,
                            trailing_zeros)
from mocapdb.errors import ParseError

#: exactly representable powers of ten (10**22 is the largest, 5**22 < 2**53)
_P10 = np.array([10.0 ** k for k in range(23)])

#: number status codes returned by :func:`_parse_number`
NUM_OK, NUM_SLOW, NUM_BAD = 0, 1, 2

_TWO53U = np.uint64(2 ** 53)
#: digits that always fit the mantissa (10**17 < 2**63)
_MAX_DIGITS = 17


#: byte classes: 0 = token byte, 1 = blank (space, tab, CR, VT, FF), 2 = LF.
#: CR is a blank so CRLF and LF files read alike.
_CLASS = np.zeros(256, dtype=np.uint8)
_CLASS[[32, 9, 13, 11, 12]] = 1
_CLASS[10] = 2


@jit
def _is_space(c):  # pragma: no cover - numba
    """Blank within a line (not LF)."""
    return _CLASS[c] == 1


#: the word arithmetic of the scanner, all uint64 (numba types a mixed int64/uint64 sum as float64)
_U = np.uint64
_ZEROS8 = _U(0x3030303030303030)    # '0' in every byte
_LOW7 = _U(0x7F7F7F7F7F7F7F7F)
_ADD76 = _U(0x7676767676767676)     # a byte below 0x80 plus 0x76 reaches 0x80 when it is 10 or more
_HIGH8 = _U(0x8080808080808080)
_PAIR_MASK = _U(0x000000FF000000FF)
_MUL1 = _U(100 + (1000000 << 32))
_MUL2 = _U(1 + (10000 << 32))
_U0, _U3, _U4, _U8, _U16, _U32, _U10, _U255 = (_U(k) for k in (0, 3, 4, 8, 16, 32, 10, 255))
#: 10**k as uint64, k = 0 … 19 (the mantissa of more than 17 digits takes the slow path, so its
#: wrapped value is never used)
_P10U = np.array([10 ** k for k in range(20)], dtype=np.uint64)


# The scanner reads the text by address (:func:`mocapdb._numba.address`, ``load_u64``, ``load_u8``):
# numba counts the references to an array handed to a function, and inlined per token that was an
# atomic add and a call to release it per number, most of the scanner's time.

@jit
def _word_tail(base, i, end):  # pragma: no cover - numba
    """The bytes ``i … end-1`` (fewer than 8) at ``base`` as a little-endian uint64, the bytes past
    ``end`` 0 (not a digit)."""
    w = _U0
    for k in range(min(end - i, 8)):
        w |= _U(load_u8(base + i + k)) << _U(8 * k)
    return w


@inline_jit
def _word_at(base, i, end):  # pragma: no cover - numba
    """The 8 bytes from ``i`` as a little-endian uint64, read in place (the bytes at or past ``end``
    0): one load but in the last 8 bytes of the text."""
    return load_u64(base + i) if i + 8 <= end else _word_tail(base, i, end)


@inline_jit
def _leading_digits(w):  # pragma: no cover - numba
    """``(count, value)`` of the run of ASCII digits that the word ``w`` starts with (0 … 8 of them):
    every byte classified at once (no carry crosses a byte), the run's length by the trailing zero
    bits of the non-digit flags, its value by three multiplications (the "eight digits" method of
    fast_float and simdjson, the bytes past the run shifted out first)."""
    a = w ^ _ZEROS8                                  # digits become bytes 0 … 9
    nondigit = (((a & _LOW7) + _ADD76) | a) & _HIGH8
    n = np.int64(trailing_zeros(nondigit) >> _U3)    # 8 when every byte is a digit
    sh = _U(32 - 4 * n)                              # two shifts: a shift by 64 is undefined
    t = (a << sh) << sh                              # the run in the high bytes, zeros (leading) below
    t = t * _U10 + (t >> _U8)                        # pairs of digits
    t = ((t & _PAIR_MASK) * _MUL1 + ((t >> _U16) & _PAIR_MASK) * _MUL2) >> _U32
    return n, t


@jit
def _long_run(base, i, end, m):  # pragma: no cover - numba
    """The rest of a run of digits whose first 8 (value ``m``) end before byte ``i``: ``(digits after
    them, value of the whole run, next byte or 0 at end)``; the value wraps past 19 digits (more
    than 17 take the slow path: it is not used then)."""
    total = 0
    while True:
        w = _word_at(base, i + total, end)
        n, v = _leading_digits(w)
        m = m * _P10U[n] + v
        total += n
        if n < 8:
            return total, m, np.int64((w >> _U(8 * n)) & _U255)


@inline_jit
def _digit_run(base, i, end):  # pragma: no cover - numba
    """``(count, value, next byte)`` of the run of digits at byte ``i`` (next byte 0 at ``end``)."""
    w = _word_at(base, i, end)
    n, m = _leading_digits(w)
    if n < 8:
        return n, m, np.int64((w >> _U(8 * n)) & _U255)
    k, m, c = _long_run(base, i + 8, end, m)   # 8 digits or more: rare
    return n + k, m, c


@inline_jit
def _scan_number(base, i, end):  # pragma: no cover - numba
    """Parse the decimal number starting at byte ``i`` of the text at address ``base``
    (:func:`mocapdb._numba.address`), up to the next delimiter.

    A delimiter is a blank, LF or ``end``. Returns ``(value, status, j)``
    with ``j`` the delimiter's index; status 0 = exact value, 1 = valid
    number outside the fast path (the caller converts ``buf[i:j]`` with
    ``float``), 2 = not a number. Accepts ``[+-]digits[.digits][(e|E)[+-]digits]``
    with digits on at least one side of the point — what Python's ``float``
    accepts, minus inf/nan and underscores. This is the innermost loop of
    every reader: the digits are read eight bytes at a time (:func:`_leading_digits`),
    so no branch depends on a digit; the sign is taken without one.
    """
    c = np.int64(load_u8(base + i)) if i < end else 0
    neg = c == 45
    i += np.int64(c == 45) | np.int64(c == 43)
    nd, m, c = _digit_run(base, i, end)
    i += nd
    exp10 = 0
    if c == 46:
        i += 1
        nf, f, c = _digit_run(base, i, end)
        i += nf
        m = m * _P10U[min(nf, 19)] + f
        exp10 = -nf
        nd += nf
    bad = nd == 0
    if (c == 101 or c == 69) and not bad:   # an exponent: rare in motion files, a byte at a time
        i += 1
        c = np.int64(load_u8(base + i)) if i < end else 0
        eneg = c == 45
        if c == 45 or c == 43:
            i += 1
        ex = 0
        anye = False
        while i < end:
            c = np.int64(load_u8(base + i))
            if c < 48 or c > 57:
                break
            anye = True
            if ex < 100000:
                ex = ex * 10 + (c - 48)
            i += 1
        if not anye:
            bad = True
        exp10 += -ex if eneg else ex
        c = np.int64(load_u8(base + i)) if i < end else 0
    if i < end and _CLASS[c] == 0:
        bad = True
        while i < end and _CLASS[load_u8(base + i)] == 0:
            i += 1
    if bad:
        return 0.0, NUM_BAD, i
    if nd > _MAX_DIGITS or m > _TWO53U:
        return 0.0, NUM_SLOW, i
    if 0 <= exp10 <= 22:
        v = float(np.int64(m)) * _P10[exp10]   # m ≤ 2**53: the signed conversion is one instruction
    elif -22 <= exp10 < 0:
        v = float(np.int64(m)) / _P10[-exp10]
    elif m == 0:
        v = 0.0
    else:
        return 0.0, NUM_SLOW, i
    return (-v if neg else v), NUM_OK, i


_SPACE8 = _U(0x2020202020202020)
_AT_MOST_0D = _U(0x7F7F7F7F7F7F7F7F - 0x0D0D0D0D0D0D0D0D)   # per byte 0x7F - 0x0D
_AT_MOST_08 = _U(0x7F7F7F7F7F7F7F7F - 0x0808080808080808)


@inline_jit
def _token_end(base, i, end):  # pragma: no cover - numba
    """The index of the first byte from ``i`` on that ends a token (a blank or LF, as :data:`_CLASS`
    says: TAB, LF, VT, FF, CR, space), or ``end``: eight bytes a step, no branch per byte."""
    while i < end:
        w = _word_at(base, i, end)
        stop = (_at_most(w ^ _SPACE8, _LOW7)
                | (_at_most(w, _AT_MOST_0D) & ~_at_most(w, _AT_MOST_08)))
        n = np.int64(trailing_zeros(stop) >> _U3)
        if n < 8:
            return min(i + n, end)
        i += 8
    return end


@jit
def _scan_at(base, i, end):  # pragma: no cover - numba
    """:func:`_scan_number` as a call, for the few tokens the side-by-side conversion leaves (one compiled
    copy shared by its callers, instead of one inlined in each: the readers' kernels compile faster)."""
    return _scan_number(base, i, end)


@jit
def _parse_number(buf, s, e):  # pragma: no cover - numba
    """Parse the whole of ``buf[s:e]``; returns ``(value, status)`` as :func:`_scan_number`."""
    v, st, j = _scan_number(address(buf), s, e)
    if j != e:
        return 0.0, NUM_BAD
    return v, st


# ---- the tokens of a line, found before any is parsed
#
# Scanning token after token chains every token's work to the one before (where a number ends
# decides where the next begins): ~50 cycles a token, ~380 MB/s. Finding a line's token starts
# first — bit masks of 64 bytes at a time, then one trailing-zero count per token — leaves the
# numbers independent of each other, so the processor parses several at once.

_AT_MOST_20 = _U(0x5F5F5F5F5F5F5F5F)   # per byte 0x7F - 0x20: :func:`_at_most` finds blanks and controls
_AT_MOST_1F = _U(0x6060606060606060)   # 0x7F - 0x1F: the control bytes
_LF8, _CR8, _TAB8 = _U(0x0A0A0A0A0A0A0A0A), _U(0x0D0D0D0D0D0D0D0D), _U(0x0909090909090909)
_GATHER = _U(0x0102040810204080)       # bit 7 of each byte → the byte's bit of the top byte
_U1, _U7, _U56, _U63 = _U(1), _U(7), _U(56), _U(63)


@inline_jit
def _at_most(x, k):  # pragma: no cover - numba
    """Bit 7 set in each byte of ``x`` that is at most ``0x7F - k`` (per byte of ``k``), no carry
    between bytes; ``k = 0x7F…`` finds the zero bytes."""
    return ~(((x & _LOW7) + k) | x) & _HIGH8


@inline_jit
def _gather(m):  # pragma: no cover - numba
    """The bit 7 of each byte of ``m`` as 8 bits, byte k → bit k."""
    return ((m >> _U7) * _GATHER) >> _U56


@inline_jit
def _chunk_masks(base, p, size):  # pragma: no cover - numba
    """Masks of the 64 bytes from ``buf[p]``, bit k for byte ``p + k``: ``(separator, LF, other control
    byte)``. A separator is any byte up to 0x20 (blank or line end); "other" is a control byte
    that is not TAB, CR or LF (VT, FF or a token byte for :data:`_CLASS`: the caller takes the exact
    path). Bytes from ``size`` on are separators and LFs (the text ends a line).

    Within the text, each mask is one vector compare of the 64 bytes (:func:`mocapdb._numba.mask64_le`);
    the last 63 bytes are read a word at a time, as many as there are, so no load passes ``size``."""
    if p + 64 <= size:
        a = base + p
        lf = mask64_eq(a, 10)
        other = mask64_le(a, 31) & ~(lf | mask64_eq(a, 13) | mask64_eq(a, 9))
        return mask64_le(a, 32), lf, other
    sep = _U0
    lf = _U0
    other = _U0
    for q in range(8):
        w = _word_at(base, p + 8 * q, size)
        ln = _at_most(w ^ _LF8, _LOW7)
        ok = ln | _at_most(w ^ _CR8, _LOW7) | _at_most(w ^ _TAB8, _LOW7)
        sh = _U(8 * q)
        sep |= _gather(_at_most(w, _AT_MOST_20)) << sh
        lf |= _gather(ln) << sh
        other |= _gather(_at_most(w, _AT_MOST_1F) & ~ok) << sh
    if p + 64 > size:
        past = ~((_U1 << _U(max(size - p, 0))) - _U1)
        sep |= past
        lf |= past
        other &= ~past
    return sep, lf, other


@inline_jit
def _line_tokens(base, i, size, pos, cap):  # pragma: no cover - numba
    """Token starts of the line from byte ``i`` (the byte before it a separator) to its LF, written
    as int64 at the address ``pos`` (at most ``cap`` of them). Returns ``(count, index of the LF or
    size, ok)``; ok is False when a control byte other than TAB, CR, LF lies in the bytes looked at
    (the caller then reads the line byte by byte, as :data:`_CLASS` says)."""
    n = 0
    p = i
    carry = _U1
    while True:
        sep, lf, other = _chunk_masks(base, p, size)
        if other != _U0:
            return n, p, False
        starts = ~sep & ((sep << _U1) | carry)
        if lf != _U0:
            starts &= (lf & (~lf + _U1)) - _U1   # those before the line's end
        while starts != _U0:
            if n < cap:
                store_i64(pos + 8 * n, p + np.int64(trailing_zeros(starts)))
            n += 1
            starts &= starts - _U1
        if lf != _U0:
            return n, min(p + np.int64(trailing_zeros(lf)), size), True
        carry = sep >> _U63
        p += 64


# ---- a line's numbers converted side by side
#
# Once a line's token starts are known, the numbers need not be read one after the other: the 16 bytes
# at each start are gathered first (two plain loads a token), then one loop without a branch converts
# every token of the common spelling ``[+-]digits[.digits]`` with at most 7 digits on each side of the
# point — the loop LLVM turns into vector code, several tokens per instruction. A token of any other
# spelling (an exponent, 8 digits or more in a run, not a number) is flagged and read by
# :func:`_scan_number`, so values, slow-path tokens and errors stay as they were.

_FILL = _U(0xFFFFFFFFFFFFFFFF)
_U45, _U43, _U46, _U64, _U127 = (_U(k) for k in (45, 43, 46, 64, 127))


@inline_jit
def _bytes_from(lo, hi, q):  # pragma: no cover - numba
    """Bytes ``q … q+7`` (1 ≤ q ≤ 15) of the 16 bytes ``lo``, ``hi`` (little-endian) as a word; the bytes
    past the 16th are 0xFF (not a digit, not a separator). Every shift below 64 either way (a shift
    by 64 or more is undefined in LLVM, and vector code computes both sides of each choice)."""
    b = _U(8 * q)
    if q < 8:
        r = (_U64 - b) & _U63                          # 8 … 56
        return (lo >> (b & _U63)) | (hi << r)
    return (hi >> ((b - _U64) & _U63)) | ((_FILL << ((_U127 - b) & _U63)) << _U1)


@jit
def _short_numbers(lo, hi, n, vals, flag):  # pragma: no cover - numba
    """Convert the tokens whose first 16 bytes are ``lo[k]``, ``hi[k]`` (k < n) into ``vals``, exactly as
    :func:`_scan_number` (Clinger's fast path: a mantissa below 10**14 divided by a power of ten up to
    10**7, one correctly rounded division); ``flag[k]`` is True when the token is not of the short
    spelling and ``vals[k]`` meaningless. No branch depends on a byte."""
    for k in range(n):
        w0 = lo[k]
        w1 = hi[k]
        c0 = w0 & _U255
        neg = c0 == _U45
        sg = np.int64(c0 == _U45) | np.int64(c0 == _U43)
        w = ((w0 >> _U8) | (w1 << _U56)) if sg else w0
        n1, m1 = _leading_digits(w)
        c = (w >> _U(8 * (n1 & 7))) & _U255           # the byte after the run (n1 = 8 is flagged)
        dot = c == _U46
        w2 = _bytes_from(w0, w1, sg + n1 + 1)
        n2, f = _leading_digits(w2)
        c2 = (w2 >> _U(8 * (n2 & 7))) & _U255
        n2 = n2 if dot else 0
        f = f if dot else _U0
        c2 = c2 if dot else c
        # 10**n2 without a table (a table lookup per lane would be a gather)
        p = (_U10 if n2 & 1 else _U1) * (_U(100) if n2 & 2 else _U1) * (_U(10000) if n2 & 4 else _U1)
        v = float(np.int64(m1 * p + f)) / float(np.int64(p))
        vals[k] = -v if neg else v
        flag[k] = (n1 > 7) | (n2 > 7) | (n1 + n2 == 0) | (c2 > _U(32))


@inline_jit
def _few_tokens(base, i, size, pos):  # pragma: no cover - numba
    """A short line from its first token at byte ``i`` (an AMC bone line: a name, then values) by the byte
    masks of the 64 bytes from ``i``: ``(end of the first token, count of the others, index of the LF,
    ok)``, the starts of the others written at ``pos`` (8 slots written whatever the count: no branch
    depends on it). ok is False — the caller reads the line otherwise — unless the LF lies in those 64
    bytes, the line has at most 8 more tokens, and no control byte but TAB, CR, LF is among them (so the
    first token ends where :func:`_token_end` ends it)."""
    if i + 64 > size:
        return i, 0, i, False
    sep, lf, other = _chunk_masks(base, i, size)
    first_end = i + np.int64(trailing_zeros(sep))
    starts = ~sep & (sep << _U1) & ((lf & (~lf + _U1)) - _U1)    # bit 0 (the first token) left out
    n = 0
    for k in range(8):
        t = np.int64(trailing_zeros(starts))    # 64 past the last start
        store_i64(pos + 8 * k, i + t)
        n += np.int64(t < 64)
        starts &= starts - _U1
    return first_end, n, i + np.int64(trailing_zeros(lf)), lf != _U0 and other == _U0 and starts == _U0


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
def _note_slow(fb_index, fb_start, fb_end, nfb, flat, s, e):  # pragma: no cover - numba
    """List the token ``s … e-1`` (flat index ``flat`` of the output) for ``float()`` (outside the exact
    fast path); returns the new count. Past the lists' size it is only counted: the caller runs again
    with room for them all."""
    if nfb < fb_index.shape[0]:
        fb_index[nfb] = flat
        fb_start[nfb] = s
        fb_end[nfb] = e
    return nfb + 1


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
    pos = np.empty(ncols + 1, dtype=np.int64)   # token starts of a line (one more: a count too large)
    base = address(buf)
    pos_at = address(pos)
    lo = np.empty(ncols, dtype=np.uint64)      # the first 16 bytes of each token of a line
    hi = np.empty(ncols, dtype=np.uint64)
    vals = np.empty(ncols)
    flag = np.empty(ncols, dtype=np.bool_)
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
        # the usual line: its ncols tokens found first, then parsed independently of each other
        n, eol, ok = _line_tokens(base, i, size, pos_at, ncols + 1)
        if ok and n == ncols:
            nfb0 = nfb
            if eol + 16 <= size:   # 16 bytes readable at every token start
                for k in range(ncols):
                    a = base + pos[k]
                    lo[k] = load_u64(a)
                    hi[k] = load_u64(a + 8)
                _short_numbers(lo, hi, ncols, vals, flag)
            else:
                flag[:] = True
            for k in range(ncols):
                v = vals[k]
                if flag[k]:
                    s = pos[k]
                    v, st, j = _scan_at(base, s, size)
                    if st == 2:
                        ok = False
                        break
                    if st == 1:
                        nfb = _note_slow(fb_index, fb_start, fb_end, nfb, row * ncols + k, s, j)
                out[row, k] = v
            if ok:
                row += 1
                i = eol
                continue
            nfb = nfb0
        # any other line (a bad token, NaN, a wrong count, a control byte): token after token, as
        # it always was, for the same values and the same messages
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
                v, st, i = _scan_number(base, i, size)
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
                    nfb = _note_slow(fb_index, fb_start, fb_end, nfb, row * ncols + count, s, i)
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


def has_line_longer(chunk, limit: int) -> bool:
    """Whether a line of the bytes ``chunk`` (LF or CR ends; its first and last lines as far as they go) is
    longer than ``limit`` bytes: ``longest_line(chunk)[0] > limit``, decided by ``bytes.find`` in most
    texts. A line of more than ``limit`` bytes holds a whole aligned window of ``limit // 2 + 1`` bytes, so a
    text with a line end in every such window has none; only a text with a window without one is measured
    line by line (a take's 64 KiB start took ~60 µs through the byte loop, issue 35)."""
    step = limit // 2 + 1
    for a in range(0, len(chunk), step):
        if chunk.find(b"\n", a, a + step) < 0 and chunk.find(b"\r", a, a + step) < 0:
            return longest_line(chunk)[0] > limit
    return False


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
