"""C3D files → raw marker trajectories, read with ezc3d behind a layout guard.

:func:`read_c3d_points` returns every 3D point of a C3D file as an array in
the file's own axes and unit, with its label, the rate, ``POINT:UNITS``,
``POINT:SCALE`` and a gap mask; turning markers into joints is
:mod:`~mocapdb.readers.c3d`'s job.

Reading is ezc3d's (a maintained C++ reader with binary wheels: Intel, DEC
and MIPS files, float and integer data, analog data skipped, ``LABELS2``…
beyond 255 points, residuals). ezc3d trusts the file's counts: a single
flipped byte in the parameter section (a dimension count of 251, a frame
count past the end of the file) makes it allocate without bound or crash the
process. So :func:`check_layout` first walks the header and the parameter
section the way ezc3d will, within the file's bytes, and refuses a file whose
records run past the section or whose declared frames do not fit in the
bytes that follow the data start. Only then does ezc3d read it, and any
exception it raises becomes a :class:`~mocapdb.errors.ParseError`.

References
----------
READERS.md §3, §4; FEATURES.md §2.4.2; the C3D file format (c3d.org, "The
C3D File Format User Guide", Motion Lab Systems, 2008).
"""
from __future__ import annotations

import contextlib
import math
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocapdb.errors import ParseError
from mocapdb.bodies.motion import check_rate, snap_rate
from mocapdb.readers.sources import bytes_file, open_stream, plain_file, read_bytes, stream_size

__all__ = ["C3dPoints", "read_c3d_points", "check_layout", "printable", "BLOCK_POINTS"]

_BLOCK = 512
#: processor type byte of the parameter section → struct byte order
_PROCESSORS = {84: "<", 85: "<", 86: ">"}   # Intel, DEC, SGI/MIPS
#: parameter type byte → bytes per element (-1 char, 1 byte, 2 int16, 4 float)
_TYPE_SIZE = {-1: 1, 1: 1, 2: 2, 4: 4}


@dataclass(frozen=True)
class C3dPoints:
    """The 3D points of one C3D file, as stored.

    Attributes
    ----------
    xyz : ndarray, shape (n_frames, n_points, 3), float64
        Coordinates in the file's axes and unit (``units``); NaN where the
        point is missing (negative residual, or ezc3d's NaN).
    valid : ndarray, shape (n_frames, n_points), bool
        False where a point is missing: NaN, a negative residual, or exactly
        (0, 0, 0) (the usual Vicon gap; FEATURES.md §2.4.7).
    labels : tuple of str
        ``POINT:LABELS`` followed by ``LABELS2``, ``LABELS3``… (one per point;
        ``"?<i>"`` where the file has fewer labels than points), as stored.
    rate : float
        ``POINT:RATE`` in Hz (the header's rate when the parameter is absent),
        snapped to a common rate within 0.5 % (:func:`~mocapdb.bodies.motion.snap_rate`).
    units : str
        ``POINT:UNITS`` lower-cased (``"mm"`` when absent, the C3D default).
    scale : float
        ``POINT:SCALE`` (negative: float data).
    screen : tuple of str
        ``POINT:X_SCREEN`` and ``POINT:Y_SCREEN`` (``""`` where absent).
    first_frame : int
        Number of the first frame in the capture (header), for messages.
    """

    xyz: np.ndarray
    valid: np.ndarray
    labels: tuple
    rate: float
    units: str
    scale: float
    screen: tuple = ("", "")
    first_frame: int = 1
    meta: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.xyz.shape[0])


_UNPRINTABLE = re.compile(r"[^\x20-\x7e\u00a0-\u00ff]")


def printable(text: str, limit: int = 40) -> str:
    """``text`` for a one-line message: control characters as ``?``, at most ``limit`` characters."""
    text = _UNPRINTABLE.sub("?", str(text))
    return text if len(text) <= limit else text[:limit - 1] + "…"


def _float(raw: bytes, proc: int) -> float:
    """A 4-byte C3D float in the processor's format (DEC: words swapped, exponent + 2)."""
    if proc == 85:
        b = bytes((raw[2], raw[3], raw[0], (raw[1] - 1) & 0xFF if raw[1] else 0))
        return struct.unpack("<f", b)[0]
    return struct.unpack(_PROCESSORS[proc] + "f", raw)[0]


def _value(raw: bytes, typ: int, proc: int):
    """First element of a parameter's data as a number (None for chars)."""
    if typ == 4 and len(raw) >= 4:
        return _float(raw[:4], proc)
    if typ == 2 and len(raw) >= 2:
        return struct.unpack(_PROCESSORS[proc] + "h", raw[:2])[0]
    if typ == 1 and len(raw) >= 1:
        return struct.unpack("b", raw[:1])[0]
    return None


def _parameters(buf: bytes, start: int, bound: int, proc: int, refuse) -> dict:
    """Walk the parameter records as ezc3d does; return ``{(GROUP, PARAM): (type, first value, count, data offset)}``.

    Every record (name, offset word, type, dimensions, data, description)
    must lie before ``bound``; the walk ends at a zero name length or a zero
    offset, as in ezc3d.
    """
    order = _PROCESSORS[proc]
    groups, params = {}, {}
    pos = start + 4
    for _ in range((bound - pos) // 5 + 1):  # each record takes ≥ 5 bytes: the walk is bounded
        if pos + 2 > bound:
            refuse(f"byte {pos}: the parameter section runs past the end of the file")
        nchars, rid = struct.unpack("bb", buf[pos:pos + 2])
        if nchars == 0:
            break
        name_end = pos + 2 + abs(nchars)
        if name_end + 2 > bound:
            refuse(f"byte {pos}: parameter record runs past the end of the file")
        raw_name = buf[pos + 2:name_end].decode("latin-1").strip().upper()
        name = printable(raw_name)
        (offset,) = struct.unpack(order + "H", buf[name_end:name_end + 2])
        cur = name_end + 2
        if rid == 0:
            refuse(f"byte {pos + 1}: record {name} belongs to group 0 (groups are numbered from 1)")
        if rid < 0:
            if cur + 1 > bound:
                refuse(f"byte {pos}: group {name} runs past the end of the file")
            groups[-rid] = raw_name
            end = cur + 1 + buf[cur]
        else:
            if cur + 2 > bound:
                refuse(f"byte {pos}: parameter {name} runs past the end of the file")
            typ, ndims = struct.unpack("bB", buf[cur:cur + 2])
            if typ not in _TYPE_SIZE:
                refuse(f"byte {cur}: parameter {name} has the unknown data type {typ} "
                       "(expected -1, 1, 2 or 4)")
            dims = buf[cur + 2:cur + 2 + ndims]
            if len(dims) < ndims or ndims > 7:
                refuse(f"byte {cur}: parameter {name} has {ndims} dimensions (at most 7 fit the format)")
            count = math.prod(dims)
            data_at = cur + 2 + ndims
            size = _TYPE_SIZE[typ] * count
            if data_at + size + 1 > bound:
                refuse(f"byte {cur}: parameter {name} declares {count} elements, "
                       "more than the file holds")
            params[(rid, raw_name)] = (typ, _value(buf[data_at:data_at + size], typ, proc), count, data_at)
            end = data_at + size + 1 + buf[data_at + size]
        if end > bound:
            refuse(f"byte {pos}: the description of {name} runs past the end of the file")
        if offset == 0:
            break
        nxt = name_end + offset
        if nxt != end:
            # ezc3d (without ignoreBadFormatting) refuses this too, but only after
            # reading on from the wrong place
            refuse(f"byte {name_end}: the offset of {name} points to byte {nxt}, "
                   f"but its record ends at byte {end}")
        pos = nxt
    else:  # pragma: no cover - the loop bound above is never the exit on a sane walk
        refuse("the parameter section does not end")
    return {(groups.get(gid, f"#{gid}"), name): v for (gid, name), v in params.items()}


def check_layout(buf: bytes, file_size: int, *, path="<c3d>") -> dict:
    """Check a C3D file's header and parameter section before ezc3d reads it.

    The parameter records are walked as ezc3d walks them (name, offset word,
    type, dimensions, data, description), each within the file's bytes, so
    that a corrupt count cannot make the C++ reader allocate without bound
    or read out of range.

    Parameters
    ----------
    buf : bytes
        The file's first bytes: at least the header and the parameter section.
    file_size : int
        Size of the whole file in bytes.
    path : str or Path, keyword-only
        For messages.

    Returns
    -------
    dict
        ``params``: ``{(GROUP, PARAM): (type, first value, element count)}``;
        ``frames``: the frame count the file declares (parameters win over
        the header, as in ezc3d); ``frame_bytes``: bytes per frame of points
        and analog samples; ``data_bytes``: bytes from the data start to the
        end of the file; ``data_start``: the data start block.

        ``point_bytes``: the points' share of ``frame_bytes``; ``proc``: the
        processor type byte; ``header_rate``: the header's point rate;
        ``analog_problem``: why the analog channels cannot be read (ANALOG:SCALE
        or OFFSET shorter than ANALOG:USED, no GEN_SCALE), or None.

    Raises
    ------
    ParseError
        Not a C3D file (no 0x50 key byte, unknown processor type), a record
        running past the section or pointing backwards, a parameter with an
        unknown type or more elements than the file holds, or negative
        counts. The message names the byte offset.
    """
    def refuse(msg):
        raise ParseError(path, None, msg)

    if file_size < _BLOCK or len(buf) < _BLOCK:
        refuse(f"not a C3D file: {file_size} bytes, shorter than the 512-byte header")
    if buf[1] != 0x50:
        refuse(f"not a C3D file: byte 1 is 0x{buf[1]:02x}, expected the key 0x50")
    if buf[0] < 2:
        refuse(f"not a C3D file: byte 0 points to parameter block {buf[0]} (expected ≥ 2)")
    start = _BLOCK * (buf[0] - 1)
    if start + 4 > len(buf):
        refuse(f"byte 0: the parameter section (block {buf[0]}) starts past the end of the file")
    proc = buf[start + 3]
    if proc not in _PROCESSORS:
        refuse(f"byte {start + 3}: unknown processor type {proc} (expected 84 Intel, 85 DEC or 86 MIPS)")
    order = _PROCESSORS[proc]
    n_points, n_analog, first, last = struct.unpack(order + "4H", buf[2:10])
    is_float = _float(buf[12:16], proc) < 0
    (data_start,) = struct.unpack(order + "H", buf[16:18])
    data_at = _BLOCK * (data_start - 1)
    if data_start < 1 or data_at > file_size:
        refuse(f"byte 16: the data start (block {data_start}) lies outside the file "
               f"({file_size} bytes)")
    bound = min(len(buf), data_at) if data_at > start else len(buf)
    params = _parameters(buf, start, bound, proc, refuse)

    def number(group, name, default):
        v = params.get((group, name))
        return default if v is None or v[1] is None or not math.isfinite(v[1]) else v[1]

    # the counts ezc3d will use: parameters win over the header (ezc3d's updateHeader)
    frames = number("POINT", "FRAMES", 0)
    if frames < 0 and params[("POINT", "FRAMES")][0] == 2:
        frames += 65536  # an int16 word read as unsigned, as the standard says
    if frames == 0:
        first0 = first - 1 if first else 0
        last0 = last - 1 if (last and first) else last
        frames = last0 - first0 + 1
    points = number("POINT", "USED", n_points)
    analogs = number("ANALOG", "USED", 0)
    point_rate = number("POINT", "RATE", 0.0)
    analog_rate = number("ANALOG", "RATE", 0.0)
    sub = int(analog_rate / point_rate) if point_rate else (n_analog // analogs if analogs else 0)
    if frames < 0 or points < 0 or analogs < 0 or sub < 0:
        refuse(f"negative counts: {frames} frames, {points} points, {analogs} analog channels")
    analog_problem = None
    if analogs and sub:
        # ezc3d indexes these per channel without a bound check (a missing OFFSET
        # crashes the process): such a file is read without its analog channels
        for name in ("SCALE", "OFFSET"):
            have = sum(v[2] for (g, n), v in params.items()
                       if g == "ANALOG" and (n == name or (n.startswith(name) and n[len(name):].isdigit())))
            if have < analogs:
                analog_problem = analog_problem or f"ANALOG:{name} has {have} values for ANALOG:USED = {analogs} channels"
        if ("ANALOG", "GEN_SCALE") not in params:
            analog_problem = analog_problem or "ANALOG:GEN_SCALE is missing, but the file declares analog channels"
    word = 4 if is_float else 2
    return {"params": params, "frames": int(frames), "frame_bytes": 4 * word * points + word * analogs * sub,
            "point_bytes": 4 * word * points, "data_bytes": file_size - data_at, "data_start": data_start,
            "proc": proc, "analog_problem": analog_problem, "header_rate": _float(buf[20:24], proc),
            "is_float": is_float}


def _read_head(path: Path) -> tuple[bytes, int, bytes | None]:
    """The header and parameter section (the parameter block pointer plus 255 blocks at most), the
    file size and, for a compressed file or a zip member, all its bytes (None for a plain file)."""
    if not plain_file(path):
        data = read_bytes(path)
        return data[:_BLOCK * (max(data[0] if data else 1, 1) + 255)], len(data), data
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(_BLOCK)
        if len(head) == _BLOCK:
            head += fh.read(_BLOCK * (max(head[0], 1) - 1 + 255))
    return head, size, None


def _truncation(layout, n_frames, path):
    """A ParseError when the data end inside a frame; None when they end on a frame boundary."""
    frame_bytes = layout["frame_bytes"]
    partial = layout["data_bytes"] - n_frames * frame_bytes
    if frame_bytes and partial % frame_bytes:
        return ParseError(path, None, f"truncated: the file declares {layout['frames']} frames but its data "
                          f"ends {partial % frame_bytes} bytes into frame {n_frames + 1} "
                          f"({frame_bytes} bytes per frame)")
    return None


def without_analogs(data: bytes, layout: dict, path) -> bytes:
    """The file's bytes with the analog samples taken out of every frame and ``ANALOG:USED`` = 0.

    For a file whose analog metadata is broken (:func:`check_layout`'s
    ``analog_problem``): its points are intact and are read without the
    analog channels the features never use.
    """
    order = _PROCESSORS[layout["proc"]]
    data_at = _BLOCK * (layout["data_start"] - 1)
    frame_bytes, point_bytes = layout["frame_bytes"], layout["point_bytes"]
    n_full = max(len(data) - data_at, 0) // frame_bytes if frame_bytes else 0
    n_full = min(n_full, layout["frames"])
    if n_full < layout["frames"]:
        error = _truncation(layout, n_full, path)
        if error is not None:
            raise error
    head = bytearray(data[:data_at])
    head[4:6] = struct.pack(order + "H", 0)      # header: analog samples per 3D frame
    typ, _, _, at = layout["params"][("ANALOG", "USED")]
    head[at:at + _TYPE_SIZE[typ]] = bytes(_TYPE_SIZE[typ])   # zero in every type (DEC floats too)
    frames = np.frombuffer(data, dtype=np.uint8, count=n_full * frame_bytes, offset=data_at)
    points = frames.reshape(n_full, frame_bytes)[:, :point_bytes]
    return bytes(head) + points.tobytes()


#: where a rate is looked for when POINT:RATE and the header have none
_OTHER_RATES = (("TRIAL", "CAMERA_RATE"), ("TRIAL", "VIDEO_RATE"))


def _point_rate(param_rate: float, layout: dict, path, notes) -> float:
    """The point rate: ``POINT:RATE``, else the header's, else ``TRIAL:CAMERA_RATE`` (noted), snapped."""
    header = layout["header_rate"]
    header = header if math.isfinite(header) else 0.0
    if param_rate > 0:
        rate = param_rate
        if header <= 0:
            notes.append(f"rate {param_rate:g} Hz from POINT:RATE (the header's rate is {header:g})")
    elif header > 0:
        rate = header
    else:
        rate = 0.0
        for key in _OTHER_RATES:
            v = layout["params"].get(key)
            if v is not None and v[1] is not None and math.isfinite(v[1]) and v[1] > 0:
                rate = float(v[1])
                notes.append(f"rate {rate:g} Hz from {key[0]}:{key[1]} (POINT:RATE and the header have none)")
                break
        if rate <= 0:
            raise ParseError(path, None, f"no point rate: POINT:RATE is {param_rate:g}, the header's rate "
                             f"{header:g}, and no TRIAL:CAMERA_RATE")
    return snap_rate(check_rate(rate, path))    # 119.88 is 120


def _strings(value) -> list:
    if value is None:
        return []
    if isinstance(value, str):
        return [value]
    return [str(v) for v in value]


#: points ezc3d reads at a time: a take of more (frames × points) is read a block of frames at a time
#: (ezc3d holds about 200 bytes a point: a 5,000-marker take of 4,000 frames took 4 GB read whole)
BLOCK_POINTS = 1 << 18


def read_c3d_points(path, *, keep=None) -> C3dPoints:
    """The 3D points of a C3D file, with labels, rate, units and gaps.

    A take of more than :data:`BLOCK_POINTS` points (frames × points) is read
    a block of frames at a time: each block goes to ezc3d as a file of its
    own (the header's and ``POINT:FRAMES``'s frame count that block's), and
    only the points ``keep`` names stay.

    Parameters
    ----------
    path : str or Path
    keep : callable, optional, keyword-only
        ``keep(labels)`` → the indices (ascending) of the points to hold, given
        every point's label; default all.

    Returns
    -------
    C3dPoints
        ``labels`` those of the points held; ``meta["file_labels"]`` every
        point's.

    Raises
    ------
    ParseError
        The file cannot be read (damaged compression or archive included),
        fails :func:`check_layout`, ezc3d cannot read it, or it has
        no frames, a rate that is not finite, ≤ 0 or above 10 kHz, or a
        data section that ends inside a frame (truncated).
    FileNotFoundError
    """
    path = Path(path)
    try:
        size = stream_size(path)
        if size is None:   # a compressed file: its size is known once it has been decompressed
            with open_stream(path) as fh:
                size = sum(map(len, iter(lambda: fh.read(1 << 20), b"")))
        with open_stream(path) as fh:
            head = _head(fh)
            layout = check_layout(head, size, path=path)
            if _in_blocks(layout):
                return _read_blocks(fh, head, layout, path, keep)
        head, size, data = _read_head(path)
    except FileNotFoundError:
        raise
    except OSError as exc:   # unreadable, or damaged compressed data / archive
        raise ParseError(path, None, f"cannot read the file ({exc.strerror or exc})") from None
    notes = []
    if layout["analog_problem"]:
        data = without_analogs(data if data is not None else path.read_bytes(), layout, path)
        notes.append(f"analog channels not read: {layout['analog_problem']} (the points do not need them)")
        layout = {**layout, "frame_bytes": layout["point_bytes"], "data_bytes": len(data) - _BLOCK
                  * (layout["data_start"] - 1)}
    with bytes_file(data, path.name) if data is not None else contextlib.nullcontext(path) as name:
        point, xyz, residuals, labels, first_frame = _ezc3d(name, path)
    n_frames = xyz.shape[2] if xyz.ndim == 3 else 0
    if xyz.ndim != 3 or xyz.shape[0] < 3 or xyz.shape[1] == 0:  # no 3D points (e.g. force plates only)
        xyz, residuals, labels = np.zeros((4, 0, n_frames)), np.zeros((1, 0, n_frames)), []
    n_points = xyz.shape[1]
    if n_points and n_frames == 0:
        raise ParseError(path, None, "no frames: the file holds points but zero frames of data")
    _frames_held(layout, n_frames, path, notes)
    labels = labels[:n_points] + [f"?{i + 1}" for i in range(len(labels), n_points)]
    cols = np.arange(n_points) if keep is None else np.asarray(keep(labels), dtype=np.int64)
    res = residuals.reshape(n_points, n_frames).T if residuals.size == n_points * n_frames \
        else np.zeros((n_frames, n_points))
    pts, valid = _points(xyz, res, cols)
    return _c3d_points(point, layout, path, notes, labels, cols, pts, valid, first_frame)


def _head(fh) -> bytes:
    """The header and the parameter section (the parameter block pointer plus 255 blocks at most) of a stream."""
    head = fh.read(_BLOCK)
    if len(head) == _BLOCK:
        head += fh.read(_BLOCK * (max(head[0], 1) - 1 + 255))
    return head


def _ezc3d(name, path):
    """ezc3d's reading of a C3D file: the POINT parameters, points (4, n, frames), residuals, labels and
    the first frame's number; any failure a ParseError."""
    import ezc3d  # imported here: only C3D reading needs the C++ library

    try:
        c3d = ezc3d.c3d(str(name))
        params = c3d["parameters"]
        xyz = np.asarray(c3d["data"]["points"], dtype=np.float64)
        residuals = np.asarray(c3d["data"]["meta_points"]["residuals"], dtype=np.float64)
        labels = [str(s) for s in c3d.c3d_swig.pointNames()]
        first_frame = int(c3d["header"]["points"]["first_frame"]) + 1
    except MemoryError:
        raise ParseError(path, None, "ezc3d ran out of memory reading it (a corrupt count?)") from None
    except Exception as exc:  # ezc3d raises RuntimeError, OSError, IndexError, ... on broken files
        raise ParseError(path, None, f"ezc3d cannot read it: {type(exc).__name__}: "
                         f"{printable(' '.join(str(exc).split()), 200) or 'no detail'}") from None
    return params["POINT"] if "POINT" in params else {}, xyz, residuals, labels, first_frame


def _points(xyz, res, cols):
    """Points ``cols`` of ezc3d's (4, points, frames) array as (frames, cols, 3), NaN where missing, and
    the valid mask: missing is NaN, a negative residual or exactly (0, 0, 0)."""
    pts = np.ascontiguousarray(xyz[:3, cols].transpose(2, 1, 0))          # (frames, points, 3)
    valid = ~(np.isnan(pts).any(axis=2) | (res[:, cols] < 0) | (pts == 0.0).all(axis=2))
    pts[~valid] = np.nan
    return pts, valid


def _frames_held(layout, n_frames, path, notes):
    """A ParseError when the data end inside a frame; a note when they end on a frame boundary early."""
    declared, frame_bytes = layout["frames"], layout["frame_bytes"]
    if n_frames < declared and frame_bytes:
        # ezc3d stops at the end of the file: a file that ends inside a frame was cut
        # short; one that ends on a frame boundary was cropped by a tool that left the
        # counts (ezc3d's own Optotrak sample): read what it holds, and say so
        error = _truncation(layout, n_frames, path)
        if error is not None:
            raise error
        notes.append(f"the file declares {declared} frames but holds {n_frames}; read those")


def _in_blocks(layout) -> bool:
    """Whether a file is read a block of frames at a time: more than :data:`BLOCK_POINTS` points whose
    frame count can be rewritten (the header and an integer or non-DEC float ``POINT:FRAMES``)."""
    word = 4 if layout["is_float"] else 2
    points = layout["point_bytes"] // (4 * word)
    if not points or not layout["frame_bytes"] or layout["frames"] * points <= BLOCK_POINTS:
        return False
    v = layout["params"].get(("POINT", "FRAMES"))
    return v is None or v[0] in (1, 2) or (v[0] == 4 and layout["proc"] != 85)


def _block_head(head: bytes, layout: dict, frames: int) -> bytes:
    """The header and parameter section for a file of ``frames`` frames (the header's last frame and
    ``POINT:FRAMES``), analog channels taken out when their metadata is broken (:func:`without_analogs`)."""
    order = _PROCESSORS[layout["proc"]]
    out = bytearray(head)
    first = struct.unpack(order + "H", out[6:8])[0]
    out[8:10] = struct.pack(order + "H", max(first, 1) + frames - 1)
    v = layout["params"].get(("POINT", "FRAMES"))
    if v is not None:
        typ, _, _, at = v
        out[at:at + _TYPE_SIZE[typ]] = struct.pack(order + {1: "b", 2: "H", 4: "f"}[typ], frames)
    if layout["analog_problem"]:
        out[4:6] = struct.pack(order + "H", 0)      # header: analog samples per 3D frame
        typ, _, _, at = layout["params"][("ANALOG", "USED")]
        out[at:at + _TYPE_SIZE[typ]] = bytes(_TYPE_SIZE[typ])
    return bytes(out)


def _read_blocks(fh, head, layout, path, keep) -> C3dPoints:
    """:func:`read_c3d_points` of a large take: ezc3d reads one block of frames at a time, of which only
    the points ``keep`` names stay."""
    data_at = _BLOCK * (layout["data_start"] - 1)
    frame_bytes, point_bytes = layout["frame_bytes"], layout["point_bytes"]
    word = 4 if layout["is_float"] else 2
    n_points = point_bytes // (4 * word)
    notes = []
    if layout["analog_problem"]:
        notes.append(f"analog channels not read: {layout['analog_problem']} (the points do not need them)")
    n_frames = min(layout["frames"], layout["data_bytes"] // frame_bytes)
    if n_frames == 0:
        raise ParseError(path, None, "no frames: the file holds points but zero frames of data")
    _frames_held(layout, n_frames, path, notes)
    v = layout["params"].get(("POINT", "FRAMES"))
    limit = {1: 127, 2: 32767}.get(v[0] if v is not None else 2, 1 << 30)
    first = struct.unpack(_PROCESSORS[layout["proc"]] + "H", head[6:8])[0]
    step = max(1, min(BLOCK_POINTS // n_points, limit, 65536 - max(first, 1)))
    if len(head) < data_at:   # the parameter section ends before the data start: read up to it
        head += fh.read(data_at - len(head))
    head, pending = head[:data_at], head[data_at:]
    pts = valid = cols = None
    for a in range(0, n_frames, step):
        k = min(step, n_frames - a)
        need = k * frame_bytes
        block = pending[:need]
        if len(block) < need:
            block += fh.read(need - len(block))
        pending = pending[need:]
        if layout["analog_problem"]:
            block = np.frombuffer(block, dtype=np.uint8).reshape(k, frame_bytes)[:, :point_bytes].tobytes()
        with bytes_file(_block_head(head, layout, k) + block, path.name) as name:
            point, xyz, residuals, labels, first_frame = _ezc3d(name, path)
        if xyz.ndim != 3 or xyz.shape[1:] != (n_points, k):
            raise ParseError(path, None, f"ezc3d read {xyz.shape} points for frames {a + 1}–{a + k} of "
                             f"{n_points} points")
        if pts is None:
            labels = labels[:n_points] + [f"?{i + 1}" for i in range(len(labels), n_points)]
            cols = np.arange(n_points) if keep is None else np.asarray(keep(labels), dtype=np.int64)
            pts, valid = np.empty((n_frames, len(cols), 3)), np.empty((n_frames, len(cols)), dtype=bool)
            file_labels, point0, first0 = labels, point, first_frame
        res = residuals.reshape(n_points, k).T if residuals.size == n_points * k else np.zeros((k, n_points))
        pts[a:a + k], valid[a:a + k] = _points(xyz, res, cols)
    return _c3d_points(point0, layout, path, notes, file_labels, cols, pts, valid, first0)


def _c3d_points(point, layout, path, notes, labels, cols, pts, valid, first_frame) -> C3dPoints:
    """The C3dPoints of points ``cols`` of a file: its rate, units, scale and screen axes from its POINT
    parameters (ezc3d's), checked."""
    def param(name):
        return point[name]["value"] if name in point else None

    def number(name, default):
        values = param(name)
        if values is None or not len(values):
            return default
        try:
            return float(np.asarray(values).ravel()[0])
        except (TypeError, ValueError):
            raise ParseError(path, None, f"POINT:{name} is {printable(repr(values), 60)}, not a number") from None

    rate = _point_rate(number("RATE", 0.0), layout, path, notes)
    units = [u.strip().lower() for u in _strings(param("UNITS")) if u.strip()]
    if len(set(units)) > 1:
        raise ParseError(path, None, f"POINT:UNITS mixes {sorted(set(units))}; expected one unit")
    scale = number("SCALE", -1.0)
    screen = tuple((_strings(param(k)) or [""])[0].strip().upper() for k in ("X_SCREEN", "Y_SCREEN"))
    meta = {"declared_frames": layout["frames"], "notes": notes, "file_labels": tuple(labels)}
    return C3dPoints(xyz=pts, valid=valid, labels=tuple(labels[i] for i in cols), rate=rate,
                     units=units[0] if units else "mm", scale=scale, screen=screen,
                     first_frame=first_frame, meta=meta)
