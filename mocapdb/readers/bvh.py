"""Biovision hierarchy (BVH) reader: any humanoid skeleton, any dialect (READERS.md §2).

:func:`read_bvh` parses the ``HIERARCHY`` (joints with ``OFFSET``, ``CHANNELS``
in any number and order, ``End Site``\\ s; one-line blocks, names with spaces
or namespaces, CR, LF or CRLF line ends) and the ``MOTION`` lines (the numba
scanner of :mod:`mocapdb.readers.textscan`), runs forward kinematics and
places the 24 canonical joints:

* files written with ASF bone names (:func:`mocapdb.writers.bvh_write.write_bvh`)
  take the exact ASF points (FEATURES.md §2.2);
* any other humanoid goes through :func:`mocapdb.bodies.humanoid.map_humanoid`
  (names with prefixes stripped, else topology; :mod:`~mocapdb.readers.bvh_mapping`)
  and must then be a human (:func:`~mocapdb.bodies.humanoid.humanoid_problem`:
  plausible proportions, upright in its rest pose or in some frames);
* a user ``joint_map`` overrides either.

The motion lines are parsed 4 MiB at a time (:func:`parse_bvh_stream`), so a
file is never held whole; lost tracking (``NaN``, ``inf`` or absurd values)
is mended or cut (:mod:`~mocapdb.readers.bvh_tracking`), and
``Motion.meta["notes"]`` says so.

BVH semantics (the common reading of the format, as bvhio, MotionBuilder and
Blender):

* a joint's rotation is the product of its rotation channels **in the order
  listed** (``Zrotation Yrotation Xrotation`` = ``Rz·Ry·Rx``), in degrees;
  global rotation = parent global · local;
* a joint's origin = parent origin + parent global · t, where t is the
  ``OFFSET``; position channels of a non-root joint **replace** the OFFSET's
  coordinates, those of the root are added to it;
* an End Site = joint origin + joint global · its OFFSET;
* Y is up. The frame time is snapped to a common rate (``.0083`` → 120 Hz,
  :func:`mocapdb.bodies.motion.snap_rate`).

A rest pose that converters put in frame 1 (cmuconvert) is dropped: its jump
to frame 2 is far above the motion's largest frame-to-frame change.
Feature #40 reads the pelvis's rotation only when its axes follow the ASF
convention (x from the right to the left hip at rest); otherwise
``root_rotation`` is None and #40 uses the hip axis.

References
----------
FEATURES.md §2.2, §2.3b; READERS.md §1, §2, §4; DESIGN.md §6.
"""
from __future__ import annotations

import io
import math
import re
import threading
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from mocapdb._numba import jit
from mocapdb.errors import ParameterError, ParseError
from mocapdb.readers.bvh_head import FRAME_TIME, FRAMES, READ_BLOCK, find_motion, read_head
from mocapdb.readers.bvh_kinematics import _bvh_joints_kernel, bvh_node_positions
from mocapdb.readers.bvh_mapping import auto_map, bvh_joint_map, plan
from mocapdb.readers.bvh_tracking import lost_samples, mend, pose_frame
from mocapdb.bodies.humanoid import Z_UP_TO_Y_UP, SkeletonTree, hip_axis_is_x, humanoid_problem, mapping_template
from mocapdb.bodies.joints import JOINT_INDEX, JOINT_NAMES
from mocapdb.bodies.motion import Motion, check_finite_motion, snap_rate
from mocapdb.readers.sources import (as_path, max_decompressed, motion_stem, open_stream, special_kind,
                                     stream_size)
from mocapdb.readers.textscan import line_of, parse_rows_into, rows_bound
from mocapdb.bodies.units import bvh_unit, leg_length

__all__ = ["BvhJoint", "BvhHierarchy", "BvhData", "read_bvh", "parse_bvh", "parse_bvh_stream", "bvh_node_positions",
           "bvh_to_motion", "bvh_joint_map", "joint_map_template", "fps_from_frame_time", "MAX_DEPTH"]

#: bytes of a BVH file read and parsed at a time, header and motion lines (tests make it small)
_READ_BLOCK = READ_BLOCK

#: BVH channel names (case-insensitive in files) -> (kind, axis): kind 0 =
#: position, 1 = rotation; axis 0 = x, 1 = y, 2 = z
CHANNELS = {"xposition": (0, 0), "yposition": (0, 1), "zposition": (0, 2),
            "xrotation": (1, 0), "yrotation": (1, 1), "zrotation": (1, 2)}
_CHANNEL_NAMES = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
_KEYWORDS = {"JOINT", "END", "}", "{", "OFFSET", "CHANNELS", "MOTION", "ROOT"}

#: deepest hierarchy read (a human has ~10 levels; fingers and rigs add some)
MAX_DEPTH = 256


@dataclass(frozen=True)
class BvhJoint:
    """One BVH joint.

    Attributes
    ----------
    name : str
    parent : int
        Index of the parent joint, -1 for the root.
    offset : ndarray, shape (3,)
    channels : tuple of str
        Channel names as normalised (``"Xposition"``, ..., ``"Zrotation"``).
    channel_start : int
        Column of the first channel in the motion array.
    end_site : ndarray, shape (3,), or None
        OFFSET of the joint's End Site.
    line : int
    """

    name: str
    parent: int
    offset: np.ndarray
    channels: tuple
    channel_start: int
    end_site: np.ndarray | None = None
    line: int = 0


@dataclass(frozen=True)
class BvhHierarchy:
    """The joints of a BVH file in file order (parents before children)."""

    joints: tuple
    n_channels: int

    def index(self, name: str) -> int:
        """Index of joint ``name`` (case-insensitive); KeyError if absent."""
        key = name.lower()
        for k, j in enumerate(self.joints):
            if j.name.lower() == key:
                return k
        raise KeyError(name)

    def children(self, k: int) -> list:
        return [i for i, j in enumerate(self.joints) if j.parent == k]

    def arrays(self):
        """The hierarchy as the FK kernel's arrays (built once per hierarchy):
        parent, offset, channel start and count per joint, channel kind and axis,
        End Site flag and offset."""
        cached = self.__dict__.get("_arrays")
        if cached is not None:
            return cached
        joints = self.joints
        nj = len(joints)
        kinds = np.zeros(self.n_channels, dtype=np.int64)
        axes = np.zeros(self.n_channels, dtype=np.int64)
        for j in joints:
            for c, name in enumerate(j.channels):
                kinds[j.channel_start + c], axes[j.channel_start + c] = CHANNELS[name.lower()]
        out = (np.array([j.parent for j in joints], dtype=np.int64),
               np.array([j.offset for j in joints], dtype=np.float64).reshape(nj, 3),
               np.array([j.channel_start for j in joints], dtype=np.int64),
               np.array([len(j.channels) for j in joints], dtype=np.int64),
               kinds, axes,
               np.array([j.end_site is not None for j in joints]),
               np.array([j.end_site if j.end_site is not None else np.zeros(3) for j in joints],
                        dtype=np.float64).reshape(nj, 3))
        object.__setattr__(self, "_arrays", out)  # a frozen dataclass: a private memo
        return out

    def tree(self) -> SkeletonTree:
        """Joint origins then End Sites, rest-pose positions (OFFSETs accumulated); once per hierarchy
        (asked per take, shared by an archive's takes), arrays read-only."""
        cached = self.__dict__.get("_tree")
        if cached is not None:
            return cached
        nj = len(self.joints)
        names = [j.name for j in self.joints]
        parent = [j.parent for j in self.joints]
        rest = np.zeros((nj, 3))
        for k, j in enumerate(self.joints):
            rest[k] = j.offset + (rest[j.parent] if j.parent >= 0 else 0.0)
        ends = [(k, j) for k, j in enumerate(self.joints) if j.end_site is not None]
        end_rest = np.array([rest[k] + j.end_site for k, j in ends]).reshape(-1, 3)
        names += [f"{j.name}/end" for _, j in ends]
        parent += [k for k, _ in ends]
        tree = SkeletonTree(tuple(names), np.array(parent, dtype=np.int64), np.concatenate([rest, end_rest]),
                            np.array([True] * nj + [False] * len(ends)))
        for a in (tree.parent, tree.rest, tree.is_joint):
            a.setflags(write=False)
        object.__setattr__(self, "_tree", tree)  # a frozen dataclass: a private memo
        return tree


@dataclass(frozen=True)
class BvhData:
    """A parsed BVH file: hierarchy and raw channel values."""

    hierarchy: BvhHierarchy
    values: np.ndarray  # (n_frames, n_channels) float64
    frame_time: float
    path: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def fps(self) -> float:
        return fps_from_frame_time(self.frame_time)


def fps_from_frame_time(frame_time: float) -> float:
    """``1 / frame_time`` snapped to a common rate within 0.5 % (READERS.md §1)."""
    return snap_rate(1.0 / frame_time)


# ----------------------------------------------------------------------------
# parsing

_TOKEN = re.compile(rb"[{}]|[^\s{}]+")
def parse_bvh(data: bytes, *, path="<bvh>") -> BvhData:
    """Parse the bytes of a BVH file into hierarchy and channel values; see :func:`parse_bvh_stream`.

    Raises
    ------
    ParseError
        Malformed hierarchy or motion (file, line and what was expected).
    """
    return parse_bvh_stream(io.BytesIO(data), path=path, size=len(data))


class _MotionLines:
    """A BVH stream after its header (read whole): the hierarchy, ``n_frames``, ``frame_time``; iterating
    gives the channel values of a 4 MiB block of motion lines at a time ((rows, n_channels) float64), never
    the whole text. More or fewer lines than ``Frames:`` announces is a ParseError."""

    def __init__(self, fh, path, size):
        self.fh, self.path = fh, str(path)
        path = self.path
        # a short take is read by its size (≥ 64 KiB): reading a whole block allocated 4 MiB per take
        first = _READ_BLOCK if size is None else min(_READ_BLOCK, max(size + 1, 1 << 16))
        head, self.eof = read_head(fh, path, first)
        if head.startswith(b"\xef\xbb\xbf"):
            head = head[3:]
            size = None if size is None else size - 3
        if b"\n" not in head and b"\r" in head:
            head = (head + (b"" if self.eof else fh.read())).replace(b"\r", b"\n")   # classic-Mac line ends
            self.eof = True
        m = find_motion(head)
        if m is None:
            if not head.lstrip().upper().startswith(b"HIERARCHY"):
                raise ParseError(path, 1, "expected 'HIERARCHY' (not a BVH file?)")
            raise ParseError(path, line_of(head, len(head)), "no 'MOTION' section (truncated file?)")
        self.hierarchy = _cached_hierarchy(head, m[0], path)
        self.n_frames, self.frame_time, self.frames_line, start = _parse_motion_header(head, m[1], path)
        # the motion lines are ``rest`` from byte ``start`` (not sliced off: a short take's text is not copied)
        self.rest, self.start = head, start
        self.line_base = head.count(b"\n", 0, start)
        #: bytes of motion lines still to come when the stream's size is known, else None
        self.size_left = None if size is None else size - start

    def max_rows(self, n_bytes) -> int:
        """The most motion lines ``n_bytes`` of text can hold, at most the announced count."""
        return rows_bound(n_bytes, self.n_frames, self.hierarchy.n_channels)

    @property
    def motion_bytes(self) -> int:
        """Bytes of motion lines read with the header."""
        return len(self.rest) - self.start

    def __iter__(self):
        n_cols = self.hierarchy.n_channels
        rest, at, eof, row = self.rest, self.start, self.eof, 0
        if not eof:   # a stream read on: its blocks are motion lines alone
            rest, at = rest[at:], 0
        self.rest = None
        while True:
            if not eof:
                more = self.fh.read(_READ_BLOCK)
                eof = not more
                rest += more
            if eof:
                block, rest = rest, b""
            else:
                cut = rest.rfind(b"\n") + 1
                block, rest = rest[:cut], rest[cut:]
            values = np.empty((min(self.n_frames - row, self.max_rows(len(block) - at)), n_cols))
            # from byte ``at`` of the whole text the lines are counted from its start
            got = parse_rows_into(block, at, values, self.path, n_rows=self.n_frames, what="channel values",
                                  first_frame=row + 1, allow_nonfinite=True, line_base=0 if at else self.line_base)
            at = 0
            if not eof:   # the lines before the next block, for its messages (a pass over the text: not after the last)
                self.line_base += block.count(b"\n")
            row += got
            if got:
                yield values[:got]
            if eof:
                break
        if row != self.n_frames:
            raise ParseError(self.path, self.frames_line, f"'Frames: {self.n_frames}' but only "
                             f"{row} motion lines follow (truncated file?)")


def parse_bvh_stream(fh, *, path="<bvh>", size=None) -> BvhData:
    """Parse a BVH file from a binary stream, block by block (:class:`_MotionLines`), into hierarchy and
    channel values (sized by the stream's ``size`` when known, else grown): memory holds the values,
    not the text as well.

    Raises
    ------
    ParseError
        Malformed hierarchy or motion (file, line and what was expected).
    """
    lines = _MotionLines(fh, path, size)
    n_cols = lines.hierarchy.n_channels
    values = np.empty((lines.max_rows(lines.size_left if lines.size_left is not None else lines.motion_bytes), n_cols))
    row = 0
    for block in lines:
        if row + len(block) > values.shape[0]:
            # a stream of unknown size: grow geometrically, never past the announced count
            grown = np.empty((min(lines.n_frames, max(row + len(block), 2 * values.shape[0])), n_cols))
            grown[:row] = values[:row]
            values = grown
        values[row:row + len(block)] = block
        row += len(block)
    return BvhData(lines.hierarchy, values[:row], lines.frame_time, lines.path)


class _LazyLine:
    """A line number counted only when a message prints it (counting costs a pass)."""

    def __init__(self, data, pos):
        self.data, self.pos = data, pos

    def __int__(self):
        return line_of(self.data, self.pos)

    def __str__(self):
        return str(int(self))

    __format__ = lambda self, spec: format(int(self), spec)  # noqa: E731


def _parse_motion_header(data, pos, path):
    head = data[pos:pos + 4096]
    fm = FRAMES.search(head)
    if fm is None:
        raise ParseError(path, line_of(data, pos), "expected 'Frames:' after MOTION")
    frames_at = pos + fm.start()
    frames_line = _LazyLine(data, frames_at)
    tok = fm.group(1).decode("latin-1")
    if not tok.isdigit():
        raise ParseError(path, frames_line, f"Frames: expected a frame count, found {tok!r}")
    n_frames = int(tok)
    if n_frames == 0:
        raise ParseError(path, frames_line, "no frames ('Frames: 0')")
    tm = FRAME_TIME.search(head, fm.end())
    if tm is None:
        raise ParseError(path, int(frames_line) + 1, "expected 'Frame Time:' after 'Frames:'")
    line = _LazyLine(data, pos + tm.start())
    tok = tm.group(1).decode("latin-1")
    try:
        frame_time = float(tok)
    except ValueError:
        raise ParseError(path, line, f"Frame Time: expected a number, found {tok!r}") from None
    # 10 kHz is the fastest rate READERS.md §4 accepts
    if not (math.isfinite(frame_time) and frame_time >= 1e-4):
        raise ParseError(path, line, f"Frame Time: expected a time of at least 0.0001 s (at most "
                         f"10 kHz), found {tok!r}")
    if frame_time > 3600.0:
        raise ParseError(path, line, f"Frame Time: {tok} s per frame is not a motion recording")
    return n_frames, frame_time, frames_line, pos + tm.end()


# an archive's files share a handful of skeletons: parse each header once
_HIER_CACHE: dict = {}
_HIER_LOCK = threading.Lock()


def _cached_hierarchy(data, end, path) -> BvhHierarchy:
    head = bytes(data[:end])
    with _HIER_LOCK:
        hit = _HIER_CACHE.get(head)
    if hit is None:
        hit = _parse_hierarchy(data, end, path)
        with _HIER_LOCK:
            if len(_HIER_CACHE) > 64:
                _HIER_CACHE.clear()
            _HIER_CACHE[head] = hit
    return hit


class _Tokens:
    """Tokens of the hierarchy with byte offsets; line numbers only for messages."""

    def __init__(self, data, end, path):
        self.data = data
        self.path = path
        self.items = [(m.group().decode("latin-1"), m.start()) for m in _TOKEN.finditer(data, 0, end)]
        self.k = 0

    def error(self, pos, msg):
        return ParseError(self.path, line_of(self.data, pos), msg)

    def next(self, what):
        if self.k >= len(self.items):
            raise self.error(len(self.data), f"unexpected end of the hierarchy, expected {what}")
        tok = self.items[self.k]
        self.k += 1
        return tok

    def peek(self):
        return self.items[self.k][0] if self.k < len(self.items) else None

    def expect(self, word):
        tok, pos = self.next(repr(word))
        if tok.upper() != word.upper():
            raise self.error(pos, f"expected {word!r}, found {tok!r}")
        return pos

    def numbers(self, what):
        pos = self.expect("OFFSET")
        out = []
        for _ in range(3):
            tok = self.peek()
            if tok is None or tok.upper() in _KEYWORDS:
                raise self.error(pos, f"{what}: expected 3 numbers, found {len(out)}"
                                 + (f" (then {tok!r})" if tok else ""))
            tok, p = self.next("a number")
            try:
                v = float(tok)
            except ValueError:
                raise self.error(p, f"{what}: expected a number, found {tok!r}") from None
            if not math.isfinite(v) or abs(v) > 1e12:
                raise self.error(p, f"{what}: expected a finite length, found {tok!r}")
            out.append(v)
        return np.array(out)


def _parse_hierarchy(data, end, path) -> BvhHierarchy:
    t = _Tokens(data, end, path)
    t.expect("HIERARCHY")
    tok, pos = t.next("'ROOT'")
    if tok.upper() != "ROOT":
        raise t.error(pos, f"expected 'ROOT', found {tok!r}")
    joints: list = []
    n_channels = 0
    # an explicit stack instead of recursion: depth is bounded, not Python's limit
    stack = []  # (joint index, its fields under construction)

    def open_joint(start_pos, parent):
        name_toks = []
        while True:
            tok, p = t.next("'{'")
            if tok == "{":
                break
            if tok in ("}", "JOINT", "ROOT", "OFFSET", "CHANNELS", "MOTION"):  # a name may be "root"
                raise t.error(p, f"expected a joint name and '{{', found {tok!r}")
            name_toks.append(tok)
        if not name_toks:
            raise t.error(start_pos, "joint without a name")
        if len(stack) >= MAX_DEPTH:
            raise t.error(start_pos, f"hierarchy deeper than {MAX_DEPTH} joints")
        name = " ".join(name_toks)
        joints.append(None)
        stack.append([len(joints) - 1, name, parent, None, (), None, start_pos, None])

    open_joint(pos, -1)
    while stack:
        cur = stack[-1]
        me, name = cur[0], cur[1]
        tok, p = t.next("'}'")
        key = tok.upper()
        if key == "OFFSET":
            t.k -= 1
            cur[3] = t.numbers(f"joint {name!r}: OFFSET")
        elif key == "CHANNELS":
            cnt_tok, cp = t.next("a channel count")
            if not cnt_tok.isdigit() or int(cnt_tok) > 64:
                raise t.error(cp, f"joint {name!r}: CHANNELS: expected a count (0–64), found {cnt_tok!r}")
            cnt = int(cnt_tok)
            names = []
            for _ in range(cnt):
                nxt = t.peek()
                if nxt is None or nxt.upper() in _KEYWORDS:
                    raise t.error(cp, f"joint {name!r}: CHANNELS {cnt} but {len(names)} channel names follow")
                ch, chp = t.next("a channel name")
                k = ch.lower()
                if k not in CHANNELS:
                    raise t.error(chp, f"joint {name!r}: unknown channel {ch!r} (expected "
                                  + ", ".join(_CHANNEL_NAMES) + ")")
                names.append(_CHANNEL_NAMES[CHANNELS[k][0] * 3 + CHANNELS[k][1]])
            cur[4] = tuple(names)
            cur[7] = n_channels
            n_channels += cnt
        elif key == "JOINT":
            if cur[3] is None:
                raise t.error(p, f"joint {name!r}: expected OFFSET before its child joints")
            open_joint(p, me)
        elif key == "END":
            site, sp = t.next("'Site'")
            if site.upper() != "SITE":
                raise t.error(sp, f"expected 'End Site', found 'End {site}'")
            t.expect("{")
            cur[5] = t.numbers(f"joint {name!r}: End Site OFFSET")
            t.expect("}")
        elif key == "}":
            if cur[3] is None:
                raise t.error(p, f"joint {name!r}: no OFFSET")
            stack.pop()
            joints[me] = (name, cur[2], cur[3], cur[4], cur[7] if cur[7] is not None else n_channels,
                          cur[5], cur[6])
        else:
            raise t.error(p, f"joint {name!r}: expected OFFSET, CHANNELS, JOINT, End Site or '}}', "
                          f"found {tok!r}")
    nxt = t.peek()
    if nxt is not None:
        tok, p = t.next("")
        if tok.upper() == "ROOT":
            raise t.error(p, "a second ROOT: only one skeleton per file is supported")
        raise t.error(p, f"expected 'MOTION', found {tok!r}")
    # line numbers of all joints in one pass (one count from the file's start per joint made
    # 100,000 siblings quadratic)
    newlines = np.flatnonzero(np.frombuffer(data, dtype=np.uint8, count=end) == 10)
    lines = np.searchsorted(newlines, [j[6] for j in joints]) + 1
    return BvhHierarchy(tuple(BvhJoint(name=j[0], parent=j[1], offset=j[2], channels=j[3], channel_start=j[4],
                                       end_site=j[5], line=int(line)) for j, line in zip(joints, lines)),
                        n_channels)


# ----------------------------------------------------------------------------
# joint maps

def joint_map_template(path) -> str:
    """A ready-to-edit TOML joint map for a BVH file, filled with what the automatic mapping places.

    Raises
    ------
    ParseError
        The file's hierarchy is malformed, or it is no regular file (a FIFO).
    """
    path = Path(path)
    kind = special_kind(path)
    if kind is not None:   # reading a FIFO would wait for a writer forever, a device never end
        raise ParseError(path, None, f"{kind}, not a BVH file")
    try:
        with open_stream(path) as fh:   # the header only: the motion lines are not needed
            data, _ = read_head(fh, str(path))
    except OSError as exc:
        raise ParseError(path, None, f"cannot read the file ({exc.strerror or exc})") from None
    m = find_motion(data)
    hier = _parse_hierarchy(data, m[0] if m else len(data), str(path))
    tree = hier.tree()
    auto, problem, _ = auto_map(hier, tree)
    return mapping_template(tree, auto.how if auto is not None else problem.partial, source=str(path))


# ----------------------------------------------------------------------------
# reading

@jit
def _steps_kernel(joints, out):  # pragma: no cover - compiled
    """out[0] = the largest joint move from frame 0 to 1, out[1] = the largest
    later frame-to-frame move, out[2] = the height range after frame 0."""
    n, nj = joints.shape[0], joints.shape[1]
    lo, hi = np.inf, -np.inf
    out[0] = 0.0
    out[1] = 0.0
    for f in range(n - 1):
        m = 0.0
        for j in range(nj):
            d = 0.0
            for c in range(3):
                x = joints[f + 1, j, c] - joints[f, j, c]
                d += x * x
            if d > m:
                m = d
            y = joints[f + 1, j, 1]
            lo = min(lo, y)
            hi = max(hi, y)
        if f == 0:
            out[0] = math.sqrt(m)
        elif m > out[1] * out[1]:
            out[1] = math.sqrt(m)
    out[2] = hi - lo


def _z_up(joints: np.ndarray) -> bool:
    """True when the take stands along +Z: the spine (root → neck) of frame 1
    and of the median frame points up the z axis, not the y axis. (A person
    lying down for a whole Y-up take has no vertical spine at all.)"""
    first = joints[0, JOINT_INDEX["neck"]] - joints[0, JOINT_INDEX["root"]]
    first = first / max(float(np.linalg.norm(first)), 1e-12)
    if not (first[2] > 0.8 and abs(first[1]) < 0.3):
        return False  # the usual case, decided by one frame
    spine = joints[:, JOINT_INDEX["neck"]] - joints[:, JOINT_INDEX["root"]]
    spine = spine / np.maximum(np.linalg.norm(spine, axis=1, keepdims=True), 1e-12)
    return bool(np.median(spine, axis=0)[2] > 0.8)


def _rest_frame(joints: np.ndarray) -> bool:
    """True when frame 0 is a converter's rest pose: its jump to frame 1 is far
    above every later frame-to-frame change (READERS.md §2)."""
    if joints.shape[0] < 4:
        return False
    out = np.empty(3)
    _steps_kernel(joints, out)
    first, later, size = out[0], out[1], out[2] or 1.0
    return bool(first > 4.0 * later and first > 0.05 * size)


def read_bvh(path, *, joint_map=None, skip_rest_frame=None) -> Motion:
    """Read a BVH file as a :class:`~mocapdb.bodies.motion.Motion` of the 24 canonical joints.

    Parameters
    ----------
    path : str or Path
    joint_map : dict, optional, keyword-only
        Canonical joint → the file's joint name (its origin), ``"Name/end"``
        (its End Site) or a list of names (their mean); overrides the
        automatic mapping (:func:`mocapdb.readers.load_mapping` reads files).
    skip_rest_frame : bool, optional, keyword-only
        Drop frame 1 (True) or keep it (False); default: drop it when it is a
        converter's rest pose (:func:`_rest_frame`).

    Returns
    -------
    Motion
        ``source_format="bvh"``; ``skeleton`` = ``"bvh:asf"`` (ASF bone names),
        ``"bvh:humanoid"`` or ``"bvh:joint_map"``; ``fps`` from ``Frame
        Time`` (snapped); ``root_rotation`` = the pelvis's global rotation
        when its axes follow the ASF convention, else None (feature #40 then
        uses the hip axis); ``meta["mapping"]`` says how each joint was placed.

    Raises
    ------
    ParseError
        Malformed file (file, line, frame and what was expected), a skeleton
        that is not a humanoid, non-finite or absurd positions.

    References
    ----------
    FEATURES.md §2.3b; READERS.md §2.
    """
    path = as_path(path)
    if joint_map is not None and not isinstance(joint_map, dict):
        raise ParameterError(f"joint_map must be a dict (see mocapdb.readers.load_mapping), got {joint_map!r}")
    with open_stream(path) as fh:
        motion = _streamed_motion(fh, path, stream_size(path), joint_map, skip_rest_frame)
    if motion is not None:
        return motion
    # lost tracking: mending looks at the whole take's channels (gaps, the longest part kept)
    with open_stream(path) as fh:
        data = parse_bvh_stream(fh, path=path, size=stream_size(path))
    return bvh_to_motion(data, joint_map=joint_map, skip_rest_frame=skip_rest_frame, name=motion_stem(path))


def _streamed_motion(fh, path, size, joint_map, skip_rest_frame) -> Motion | None:
    """:func:`read_bvh` of a take without lost tracking, its channels a block of lines at a time (parsed,
    through FK, dropped): memory holds the joints and the pelvis rotation. None at lost samples."""
    lines = _MotionLines(fh, path, size)
    hier = lines.hierarchy
    joints = rot = plan_ = None
    row = 0
    for block in lines:
        if lost_samples(block, hier) is not None:
            return None
        if plan_ is None:
            plan_ = plan(hier, joint_map, lines.path, lambda: _judged_frame(hier, block, None, 0, lines))
            # the most frames the stream can hold: only the frames written are ever touched
            rows = lines.max_rows(lines.size_left if lines.size_left is not None else max_decompressed())
            joints, rot = np.empty((rows, len(JOINT_NAMES), 3)), np.empty((rows, 3, 3))
        _joints_and_rotation(BvhData(hier, block, lines.frame_time, lines.path), *plan_,
                             out=(joints[row:row + len(block)], rot[row:row + len(block)]))
        row += len(block)
    return _motion(joints[:row], rot[:row], plan_[0], hier, lines.frame_time, lines.path, joint_map,
                   skip_rest_frame, motion_stem(path), 0, row, [])


def _judged_frame(hier, values, bad, pose_at, data):
    """The FK points (origins, End Sites) of frame ``pose_at``, lost samples zeroed (a rig lying on its side)."""
    frame = values[pose_at:pose_at + 1]
    if bad is not None:
        frame = np.where(bad[pose_at:pose_at + 1], 0.0, frame)
    o, e, _ = bvh_node_positions(BvhData(hier, frame, data.frame_time, data.path))
    with_end = [k for k, j in enumerate(hier.joints) if j.end_site is not None]
    return np.concatenate([o[0], e[0, with_end]])


def _placed(how):
    name, why = how
    return name if name is not None else why


#: joint positions per block of the Z-up turn (the block's temporaries, not the take's)
_FK_POINTS = 1 << 18


def _joints_and_rotation(data: BvhData, jm, point, weight, end_of, needed, *, out=None):
    """The 24 canonical joints (n, 24, 3) and pelvis rotation (n, 3, 3) (into the pair ``out`` when given),
    FK and the gather in one kernel call (:func:`_bvh_joints_kernel`): memory never holds every joint's path."""
    n = data.values.shape[0]
    joints, rot = out if out is not None else (np.empty((n, len(JOINT_NAMES), 3)), np.empty((n, 3, 3)))
    parent, offset, ch_start, ch_count, kinds, axes, has_end, end_site = data.hierarchy.arrays()
    _bvh_joints_kernel(np.ascontiguousarray(data.values, dtype=np.float64), parent, offset, ch_start, ch_count,
                       kinds, axes, end_site, has_end, needed, jm.rotation_point, point, end_of, weight, joints, rot)
    return joints, rot


def bvh_to_motion(data: BvhData, *, joint_map=None, skip_rest_frame=None, name="") -> Motion:
    """The canonical joints of a parsed BVH file; see :func:`read_bvh`."""
    if joint_map is not None and not isinstance(joint_map, dict):
        raise ParameterError(f"joint_map must be a dict (see mocapdb.readers.load_mapping), got {joint_map!r}")
    hier = data.hierarchy
    values = data.values
    bad = lost_samples(values, hier)
    pose_at = pose_frame(values, bad)
    jm, point, weight, end_of, needed = plan(hier, joint_map, data.path,
                                             lambda: _judged_frame(hier, values, bad, pose_at, data))
    notes = []
    start, stop = 0, values.shape[0]
    if bad is not None:
        values = values.copy()
        start, stop = mend(values, bad, hier, needed, data.fps, data.path, notes)
        data = replace(data, values=values[start:stop])
    joints, rot = _joints_and_rotation(data, jm, point, weight, end_of, needed)
    return _motion(joints, rot, jm, hier, data.frame_time, data.path, joint_map, skip_rest_frame, name, start,
                   stop, notes)


def _motion(joints, rot, jm, hier, frame_time, path, joint_map, skip_rest_frame, name, start, stop, notes):
    """The Motion of a take's joints and pelvis rotation (frames ``start`` … ``stop`` − 1 of the file):
    turned Y up, the rest frame dropped, checked finite and, when mapped, human."""
    fps = fps_from_frame_time(frame_time)
    up = jm.up if jm.up is not None else (Z_UP_TO_Y_UP if _z_up(joints) else None)
    if up is not None:  # a Z-up file: positions and the pelvis rotation turned to Y up, a block at a time
        step = _FK_POINTS // len(JOINT_NAMES)
        for a in range(0, len(joints), step):
            joints[a:a + step] = joints[a:a + step] @ up.T
            rot[a:a + step] = up @ rot[a:a + step]
    # feature #40 may read the pelvis rotation only where its x axis is the hip axis
    # (ASF convention) in the take itself: R^T (lhip - rhip) along +x
    hips = joints[:, JOINT_INDEX["lhip"]] - joints[:, JOINT_INDEX["rhip"]]
    asf_axes = hip_axis_is_x(np.einsum("fji,fj->i", rot, hips) / max(len(hips), 1))
    kind = ("joint_map" if joint_map else
            "asf" if all(w[1] == "ASF bone names" for w in jm.how.values()) else "humanoid")
    meta = {"bvh_family": kind, "frame_time": frame_time,
            "mapping": {j: _placed(jm.how.get(j, (None, ""))) for j in JOINT_NAMES}}
    skip = start == 0 and (_rest_frame(joints) if skip_rest_frame is None else bool(skip_rest_frame))
    if skip and joints.shape[0] > 1:
        joints, rot = joints[1:], rot[1:]
        meta["rest_frame_skipped"] = True
        start += 1
    check_finite_motion(joints, path)
    leg = leg_length(joints)   # measured once: the unit's, and the human test's when it sees every frame
    if kind == "humanoid":
        # the mapper finds legs, arms and a head; whether they make a human is the body's to say
        rest = jm.weights @ hier.tree().rest
        problem = humanoid_problem(joints, rest @ up.T if up is not None else rest, leg=leg)
        if problem:
            raise ParseError(path, None, "not a human {}: {}".format(*problem))
    meta["frames"] = (start + 1, stop)   # BVH declares no unit: decided once here (notes, every export agree)
    meta["unit"], meta["unit_reason"] = bvh_unit(joints, [j.name for j in hier.joints], leg=leg)
    meta["notes"] = notes + [f"unit {meta['unit_reason']}"]
    return Motion(joints=np.ascontiguousarray(joints), root_rotation=rot if asf_axes else None,
                  fps=fps, name=name, skeleton=f"bvh:{kind}", source_format="bvh", meta=meta)
