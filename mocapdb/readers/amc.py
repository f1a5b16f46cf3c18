"""Acclaim motion (AMC) reader.

:func:`read_amc` returns the raw DOF values of every frame as one
``(n_frames, n_columns)`` float64 array plus the column of each bone
(:class:`AmcMotion`); :mod:`mocapdb.bodies.kinematics` turns them into joint
positions. Bone lines may come in any order (values are keyed by bone name,
case-insensitively as in the toolbox); DOFs a file never lists stay 0.

Parsing the text is the bottleneck of ingest, so the body is scanned by one
numba kernel over the file's bytes (:func:`_parse_amc_kernel`); it stops at
the first malformed token and reports its byte offset, and the Python side
turns that into a :class:`~mocapdb.errors.ParseError` with file, line, frame
and bone.

Header keywords: ``:FULLY-SPECIFIED`` (accepted), ``:DEGREES``/``:RADIANS``
(unit of the angles; without either, the ASF ``:units angle`` applies, as in
the toolbox), ``:SAMPLES-PER-SECOND n`` (default 120 Hz). Every frame must
list the same bones as frame 1, frame numbers must count up by one.

References
----------
FEATURES.md §1, §2.2, §9; toolbox ``tools/parser/ASFAMCparser/readAMC.m``,
``readFrames.m``.
"""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from mocapdb._numba import address, jit, load_u64
from mocapdb.readers.textscan import (_CLASS, _few_tokens, _is_space, _line_tokens, _note_slow, _scan_at,
                                      _scan_number, _short_numbers, _token_end, fix_slow_numbers, line_of,
                                      number_error, token_at, truncation_hint)
from mocapdb.bodies.acclaim import DEFAULT_FPS, AmcMotion, Skeleton, column_layout
from mocapdb.readers.sources import as_path, read_bytes
from mocapdb.errors import ParseError

__all__ = ["read_amc", "parse_amc"]

log = logging.getLogger("mocapdb")

# error codes reported by the kernel in status[0]
_E_NONE, _E_NUMBER, _E_COUNT, _E_UNKNOWN_BONE, _E_DUPLICATE, _E_FRAME_SEQ, \
    _E_FRAME_LINE, _E_INCOMPLETE, _E_OVERFLOW, _E_NO_FRAME = range(10)


# ----------------------------------------------------------------------------
# kernels

#: the low k bytes of a word set, k = 0 … 8
_BYTE_MASK = np.array([(1 << (8 * k)) - 1 for k in range(9)], dtype=np.uint64)


@jit
def _close_frame(seen, ref, nb, frame):  # pragma: no cover
    """Whether a finished frame lists the same bones as frame 1 (frame 0 sets the reference)."""
    ok = True
    for b in range(nb):
        if frame == 0:
            ref[b] = seen[b]
        elif seen[b] != ref[b]:
            ok = False
    return ok


@jit
def _flush_values(base, size, out, frame, pend, npend, fb_index, fb_start, fb_end, nfb, status):  # pragma: no cover
    """Convert the ``npend`` values of frame ``frame`` whose token starts, columns and bones are
    ``pend[0:3, :npend]`` (text order) into ``out``: side by side (:func:`_short_numbers`), the other
    spellings by the exact scanner (:func:`_scan_at`). A token that is no number sets ``status`` as the token-after-token
    loop did (the first in the text: an error found after it, later in the text, is replaced); returns
    the count of tokens left to ``float()``."""
    lo = pend[3].view(np.uint64)
    hi = pend[4].view(np.uint64)
    vals = pend[5].view(np.float64)
    flag = pend[6]
    for k in range(npend):
        a = base + pend[0, k]
        lo[k] = load_u64(a)
        hi[k] = load_u64(a + 8)
    _short_numbers(lo, hi, npend, vals, flag)
    ncols = out.shape[1]
    for k in range(npend):
        v = vals[k]
        if flag[k] != 0:
            s = pend[0, k]
            v, st, j = _scan_at(base, s, size)
            if st == 2:  # NUM_BAD
                status[:6] = 0
                status[0] = 1  # _E_NUMBER
                status[1] = s
                status[2] = frame
                status[3] = pend[2, k]
                return nfb
            if st == 1:  # NUM_SLOW
                nfb = _note_slow(fb_index, fb_start, fb_end, nfb, frame * ncols + pend[1, k], s, j)
        out[frame, pend[1, k]] = v
    return nfb


@jit
def _parse_amc_kernel(buf, start, names, name_start, name_len, col_start, ndof, out,
                      fb_index, fb_start, fb_end, seen, ref, status):  # pragma: no cover
    """Scan AMC frames from byte ``start`` into ``out`` (uninitialised: each frame's row is zeroed as the
    frame starts).

    ``names`` holds the lower-case bone names back to back (``name_start``,
    ``name_len``; entry 0 = root). On the first error the scan stops and
    ``status`` = [code, byte offset, frame index, bone index, expected,
    found, n_slow_tokens, n_frames]. Tokens outside the exact fast path are
    listed in ``fb_*`` (flat index into ``out``, byte range) for Python.
    """
    size = buf.shape[0]
    base = address(buf)
    nb = name_start.shape[0]
    ncols = out.shape[1]
    nrows = out.shape[0]
    # predicted next bone: after bone b comes nxt[b]; nxt[nb] = first bone of a frame
    nxt = np.full(nb + 1, -1, dtype=np.int64)
    last = nb
    frame = -1
    prev_num = 0
    nfb = 0
    last_line = start
    # the values of the current frame's usual bone lines, converted together when the frame ends: rows
    # token start, column, bone, then scratch for _flush_values (words, values, flags)
    pend = np.zeros((7, ncols + 9), dtype=np.int64)
    pend_at = address(pend[0])
    # each bone's name (lower case) as two words, its bytes past the name 0 (names of up to 16 bytes)
    name_lo = np.zeros(nb, dtype=np.uint64)
    name_hi = np.zeros(nb, dtype=np.uint64)
    for b in range(nb):
        for k in range(min(name_len[b], 16)):
            byte = np.uint64(names[name_start[b] + k]) << np.uint64(8 * (k % 8))
            if k < 8:
                name_lo[b] |= byte
            else:
                name_hi[b] |= byte
    npend = 0
    i = start
    while True:
        # ---- start of a line
        while i < size and _is_space(buf[i]):
            i += 1
        if i >= size:
            break
        c = buf[i]
        if c == 10:
            i += 1
            continue
        if c == 35:  # '#' comment line
            while i < size and buf[i] != 10:
                i += 1
            continue
        line_start = i
        if 48 <= c <= 57:
            # ---- frame number line
            if npend > 0:
                nfb = _flush_values(base, size, out, frame, pend, npend, fb_index, fb_start, fb_end, nfb, status)
                npend = 0
                if status[0] != 0:
                    break
            num = 0
            while i < size and 48 <= buf[i] <= 57:
                if num < 1000000000000:
                    num = num * 10 + (int(buf[i]) - 48)
                i += 1
            j = i
            while j < size and _is_space(buf[j]):
                j += 1
            if (j < size and buf[j] != 10) or (j == i and i < size and buf[i] != 10):
                status[0] = 6  # _E_FRAME_LINE
                status[1] = line_start
                status[2] = frame + 1
                break
            if frame >= 0:
                if num != prev_num + 1:
                    status[0] = 5  # _E_FRAME_SEQ
                    status[1] = line_start
                    status[2] = frame + 1
                    status[4] = prev_num + 1
                    status[5] = num
                    break
                # close the previous frame: same bones as frame 1
                if not _close_frame(seen, ref, nb, frame):
                    status[0] = 7  # _E_INCOMPLETE
                    status[1] = last_line
                    status[2] = frame
                    break
            frame += 1
            if frame >= nrows:
                status[0] = 8  # _E_OVERFLOW
                status[1] = line_start
                status[2] = frame
                break
            prev_num = num
            # the frame's row zeroed as it starts (DOFs a file never lists stay 0): ``out`` comes uninitialised,
            # as np.zeros of the frame-count bound (about twice the frames) cleared ~2x the rows used
            for k in range(ncols):
                out[frame, k] = 0.0
            for b in range(nb):
                seen[b] = 0
            last = nb
            last_line = line_start
            i = j
            continue
        # ---- bone line: name
        if frame < 0:
            status[0] = 9  # _E_NO_FRAME
            status[1] = line_start
            break
        s = i
        # the usual line, name and values at once by byte masks (the value starts into the frame's list)
        e, n, eol, few = _few_tokens(base, s, size, pend_at + 8 * npend)
        if not few:
            e = _token_end(base, s, size)
        i = e
        bone = -1
        cand = nxt[last]
        ln = e - s
        if cand >= 0 and name_len[cand] == ln and ln <= 16 and s + 16 <= size:
            # the predicted bone spelt as the ASF spells it (lower case): two words compared
            lo = load_u64(base + s) & _BYTE_MASK[min(ln, 8)]
            hi = load_u64(base + s + 8) & _BYTE_MASK[max(ln - 8, 0)]
            if lo == name_lo[cand] and hi == name_hi[cand]:
                bone = cand
        for attempt in range(0 if bone >= 0 else nb + 1):
            b = cand if attempt == 0 else attempt - 1
            if b < 0 or (attempt > 0 and b == cand):
                continue
            ln = name_len[b]
            if ln != e - s:
                continue
            o = name_start[b]
            ok = True
            for k in range(ln):
                ch = int(buf[s + k])
                if 65 <= ch <= 90:
                    ch += 32
                if ch != names[o + k]:
                    ok = False
                    break
            if ok:
                bone = b
                break
        if bone < 0:
            status[0] = 3  # _E_UNKNOWN_BONE
            status[1] = s
            status[2] = frame
            break
        if seen[bone] != 0:
            status[0] = 4  # _E_DUPLICATE
            status[1] = s
            status[2] = frame
            status[3] = bone
            break
        seen[bone] = 1
        if frame == 0:
            nxt[last] = bone
        last = bone
        last_line = line_start
        # ---- values
        nd = ndof[bone]
        col = col_start[bone]
        # the usual line: its nd values converted with the frame's others
        ok = few
        if not few:
            n, eol, ok = _line_tokens(base, i, size, pend_at + 8 * npend, nd + 1)
        if ok and n == nd and eol + 16 <= size:
            for k in range(8):      # 8 slots whatever nd (the arrays have room): no branch on nd
                pend[1, npend + k] = col + k
                pend[2, npend + k] = bone
            for k in range(8, nd):
                pend[1, npend + k] = col + k
                pend[2, npend + k] = bone
            npend += nd
            i = eol + 1 if few else eol   # past the LF (_line_tokens may stop at the text's end)
            continue
        count = 0
        failed = False
        while True:
            while i < size and _is_space(buf[i]):
                i += 1
            if i >= size or buf[i] == 10:
                break
            s = i
            if count >= nd:
                while i < size and _CLASS[buf[i]] == 0:
                    i += 1
            else:
                v, st, i = _scan_number(base, i, size)
                if st == 2:  # NUM_BAD
                    status[0] = 1  # _E_NUMBER
                    status[1] = s
                    status[2] = frame
                    status[3] = bone
                    failed = True
                    break
                if st == 1:  # NUM_SLOW
                    nfb = _note_slow(fb_index, fb_start, fb_end, nfb, frame * ncols + col + count, s, i)
                out[frame, col + count] = v
            count += 1
        if failed:
            break
        if count != nd:
            status[0] = 2  # _E_COUNT
            status[1] = line_start
            status[2] = frame
            status[3] = bone
            status[4] = nd
            status[5] = count
            break
    if npend > 0:   # the last frame's values, or those before an error (an earlier bad one wins)
        nfb = _flush_values(base, size, out, frame, pend, npend, fb_index, fb_start, fb_end, nfb, status)
    if status[0] == 0 and frame >= 0:
        # close the last frame
        if not _close_frame(seen, ref, nb, frame):
            status[0] = 7  # _E_INCOMPLETE
            status[1] = last_line
            status[2] = frame
    status[6] = nfb
    status[7] = frame + 1


# ----------------------------------------------------------------------------
# public API

def read_amc(path, skeleton: Skeleton) -> AmcMotion:
    """Read an AMC motion file for ``skeleton``.

    Parameters
    ----------
    path : str or Path
    skeleton : Skeleton
        From :func:`mocapdb.readers.asf.read_asf`; gives each bone's DOFs.

    Returns
    -------
    AmcMotion

    Raises
    ------
    ParseError
        Names the file, line, frame and bone, and what was expected vs found:
        a bone not in the ASF, a wrong number of values, a non-numeric or
        NaN/inf value, a frame that lacks bones of frame 1 (truncated file),
        out-of-sequence frame numbers, no frames.

    References
    ----------
    FEATURES.md §1, §2.2, §9.
    """
    path = as_path(path)
    return parse_amc(read_bytes(path), skeleton, path=path)


def parse_amc(data: bytes, skeleton: Skeleton, *, path="<amc>") -> AmcMotion:
    """Parse the bytes of an AMC file. See :func:`read_amc`."""
    path = str(path)
    start, fps, unit = _parse_header(data, path)
    fps_source = ":SAMPLES-PER-SECOND"
    if fps is None:
        # no :SAMPLES-PER-SECOND: the rate the ASF's documentation notes, else
        # the toolbox's default
        fps_source = "the ASF's :documentation" if skeleton.documented_fps else "the default"
        fps = skeleton.documented_fps or DEFAULT_FPS
    if unit is None:
        unit = skeleton.angle_unit
    elif unit != skeleton.angle_unit:
        log.warning("%s: AMC angles in %s but the ASF says %s; using the AMC's unit",
                    path, unit, skeleton.angle_unit)
    names, ndof, col_start, columns, dof_names, name_buf, name_start, name_len, ncols, owner = _kernel_layout(skeleton)
    buf = np.frombuffer(data, dtype=np.uint8) if data else np.zeros(1, np.uint8)

    if start >= len(data):
        raise ParseError(path, line_of(data, len(data)),
                         "no frames (expected a frame number line followed by bone lines)")
    # Upper bound on the frame count without a scan: every frame lists the
    # bones of frame 1 (the kernel enforces it) with their values, so it has
    # at least as many bytes as the shortest spelling of frame 1; +1 for a
    # truncated last frame. np.empty is lazy: untouched slack costs nothing.
    n_rows = (len(data) - start) // _min_frame_bytes_kernel(buf, start, name_buf, name_start, name_len, ndof) + 1
    cap = 1024
    while True:
        out = np.empty((n_rows, ncols), dtype=np.float64)   # the kernel zeroes the rows it reads
        fb_index = np.empty(cap, dtype=np.int64)   # only the first status[6] entries are read
        fb_start = np.empty(cap, dtype=np.int64)
        fb_end = np.empty(cap, dtype=np.int64)
        seen = np.zeros(len(names), dtype=np.int8)
        ref = np.zeros(len(names), dtype=np.int8)
        status = np.zeros(8, dtype=np.int64)
        _parse_amc_kernel(buf, start, name_buf, name_start, name_len, col_start, ndof, out,
                          fb_index, fb_start, fb_end, seen, ref, status)
        if status[0] == _E_OVERFLOW and n_rows <= len(data) // 2:
            n_rows = len(data) // 2 + 1  # cannot happen (see above); be safe anyway
            continue
        if status[0] != _E_NONE or status[6] <= cap:
            break
        cap = int(status[6])
    first = _first_frame_number(data, start)
    if status[0] != _E_NONE:
        raise _kernel_error(data, path, status, names, seen, ref, dof_names, first, skeleton)
    nfb = int(status[6])
    def describe(flat):
        return first + flat // ncols, f"bone {names[owner[flat % ncols]]!r}: "

    fix_slow_numbers(data, out.reshape(-1), fb_index[:nfb], fb_start[:nfb], fb_end[:nfb], path,
                     describe=describe)
    out = out[:int(status[7])]
    return AmcMotion(values=out, columns=columns, dof_names=dof_names, fps=fps,
                     angle_unit=unit, first_frame=first, path=path, meta={"fps_source": fps_source})


def _kernel_layout(skeleton: Skeleton) -> tuple:
    """The skeleton's column layout (:func:`column_layout`), DOFs per lower-case name, its bone names as
    the kernel reads them (lower case, back to back), the column count and each column's bone: built once
    per skeleton, not per take (a skeleton is immutable; an archive's takes share a few)."""
    cached = skeleton.__dict__.get("_amc_layout")
    if cached is not None:
        return cached
    names, ndof, col_start, columns, dof_names = column_layout(skeleton)
    lower = [n.lower() for n in names]
    enc = [n.encode("latin-1") for n in lower]
    name_len = np.array([len(n) for n in enc], dtype=np.int64)
    name_start = np.zeros(len(enc), dtype=np.int64)
    name_start[1:] = np.cumsum(name_len)[:-1]
    name_buf = np.frombuffer(b"".join(enc), dtype=np.uint8)
    owner = np.repeat(np.arange(len(names)), ndof)  # column -> bone
    out = (names, ndof, col_start, columns, dof_names, name_buf, name_start, name_len, int(ndof.sum()), owner)
    object.__setattr__(skeleton, "_amc_layout", out)  # a frozen dataclass: a private memo
    return out


@jit
def _lower_latin1(c):  # pragma: no cover - compiled
    """``bytes([c]).decode("latin-1").lower()`` as a byte (A–Z, À–Þ but ×)."""
    if 65 <= c <= 90 or (0xC0 <= c <= 0xDE and c != 0xD7):
        return c + 32
    return c


@jit
def _min_frame_bytes_kernel(buf, start, names, name_start, name_len, ndof):  # pragma: no cover - compiled
    """Fewest bytes any frame can take if it lists the bones of frame 1 (the bytes from ``start``: the
    frame number line, then frame 1's lines up to the next line starting with a digit): frame number line
    >= 2 bytes; bone line >= name + (blank + digit) per DOF + LF — the DOFs of the bone named so (case
    aside, as ``str.lower`` of its Latin-1 text; the last of equal names; 0 for an unknown one), from the
    names of :func:`_kernel_layout` (lower case, back to back). A scan of frame 1 only, in a kernel: a
    Python step per line cost ~0.1 ms a take (issue 35)."""
    size = buf.shape[0]
    pos = start
    while pos < size and buf[pos] != 10:
        pos += 1
    pos += 1
    if pos > size:
        return 2
    n = 2
    while pos < size:
        end = pos
        while end < size and buf[end] != 10:
            end += 1
        i = pos
        while i < end and (buf[i] == 32 or 9 <= buf[i] <= 13):
            i += 1
        if i < end and 48 <= buf[i] <= 57:
            break
        if i < end and buf[i] != 35:
            j = i
            while j < end and not (buf[j] == 32 or 9 <= buf[j] <= 13):
                j += 1
            k = 0
            for b in range(name_start.shape[0]):
                if name_len[b] == j - i:
                    same = True
                    for t in range(j - i):
                        if _lower_latin1(buf[i + t]) != names[name_start[b] + t]:
                            same = False
                            break
                    if same:
                        k = ndof[b]
            n += (j - i) + 2 * k + 1
        if end >= size:
            break
        pos = end + 1
    return n


def _first_frame_number(data: bytes, start: int) -> int:
    end = data.find(b"\n", start)
    return int(data[start:end if end >= 0 else len(data)].split()[0])


def _parse_header(data: bytes, path: str):
    """Header keywords up to the first frame number line.

    Returns ``(byte offset of the first frame line, fps or None, angle unit or None)``.
    """
    fps = None
    unit = None
    pos = 3 if data.startswith(b"\xef\xbb\xbf") else 0  # UTF-8 byte order mark
    size = len(data)
    line = 0
    while pos < size:
        end = data.find(b"\n", pos)
        if end < 0:
            end = size
        line += 1
        s = data[pos:end].strip()
        if s and not s.startswith(b"#"):
            if s.startswith(b":"):
                tok = s[1:].split()
                key = tok[0].upper() if tok else b""
                if key == b"DEGREES":
                    unit = "deg"
                elif key == b"RADIANS":
                    unit = "rad"
                elif key == b"SAMPLES-PER-SECOND":
                    try:
                        fps = float(tok[1])
                    except (IndexError, ValueError):
                        raise ParseError(path, line, ":SAMPLES-PER-SECOND: expected a rate, found "
                                         f"{b' '.join(tok[1:]).decode('latin-1')!r}") from None
                    if not (np.isfinite(fps) and fps > 0):
                        raise ParseError(path, line, f":SAMPLES-PER-SECOND: expected a positive "
                                         f"rate, found {tok[1].decode('latin-1')!r}")
                else:
                    # :FULLY-SPECIFIED and unknown keywords carry no data we need
                    pass
            elif s[:1].isdigit():
                return pos, fps, unit
            else:
                raise ParseError(path, line, "expected a frame number before the first bone line, "
                                 f"found {s[:40].decode('latin-1')!r}")
        pos = end + 1
    return size, fps, unit


def _kernel_error(data, path, status, names, seen, ref, dof_names, first, skeleton):
    code, pos, frame_i, bone = (int(x) for x in status[:4])
    line = line_of(data, pos)
    frame = first + frame_i  # the file's own frame number
    hint = truncation_hint(data, pos)
    if code == _E_NUMBER:
        return number_error(data, pos, path, frame=frame, where=f"bone {names[bone]!r}: ",
                            hint=hint)
    if code == _E_COUNT:
        exp, found = int(status[4]), int(status[5])
        dofs = " ".join(dof_names.get(names[bone], ())) or "none"
        return ParseError(path, line, f"bone {names[bone]!r}: expected {exp} "
                          f"value{'s' if exp != 1 else ''} (DOFs: {dofs}), found {found}" + hint,
                          frame=frame)
    if code == _E_UNKNOWN_BONE:
        asf = Path(skeleton.path).name or skeleton.name
        return ParseError(path, line, f"bone {token_at(data, pos)!r} is not in the skeleton "
                          f"{asf} (its bones: {', '.join(names)})" + hint, frame=frame)
    if code == _E_DUPLICATE:
        return ParseError(path, line, f"bone {names[bone]!r} appears twice in one frame",
                          frame=frame)
    if code == _E_FRAME_SEQ:
        return ParseError(path, line, f"expected frame number {int(status[4])}, "
                          f"found {int(status[5])}", frame=None)
    if code == _E_FRAME_LINE:
        end = data.find(b"\n", pos)
        text = data[pos:end if end >= 0 else len(data)].strip().decode("latin-1")
        return ParseError(path, line, f"expected a frame number alone on its line, found {text!r}")
    if code == _E_INCOMPLETE:
        missing = [names[b] for b in range(len(names)) if ref[b] and not seen[b]]
        extra = [names[b] for b in range(len(names)) if seen[b] and not ref[b]]
        parts = []
        if missing:
            parts.append("missing " + ", ".join(missing))
        if extra:
            parts.append("not in frame 1: " + ", ".join(extra))
        last = frame_i + 1 == int(status[7])
        hint = " (the file may be truncated)" if last and missing else ""
        return ParseError(path, line, "every frame must list the bones of frame 1; "
                          + "; ".join(parts) + hint, frame=frame)
    if code == _E_NO_FRAME:
        return ParseError(path, line, "expected a frame number before the first bone line")
    return ParseError(path, line, f"internal reader error (code {code})", frame=frame)
