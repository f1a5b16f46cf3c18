"""Biovision hierarchy (BVH) reader and writer.

Reading: :func:`read_bvh` parses the ``HIERARCHY`` (joints with ``OFFSET``,
``CHANNELS`` in any number and order, ``End Site``\\ s) and the ``MOTION``
lines (one numba pass, :func:`mocapdb.readers.textscan.parse_rows`), runs forward
kinematics and picks the 24 canonical joints through the joint-name table of
the skeleton family that fits (:data:`FAMILIES`).

BVH semantics used (the common reading of the format):

* a joint's rotation is the product of its rotation channels **in the order
  listed**: ``Zrotation Yrotation Xrotation`` means ``Rz·Ry·Rx``; angles in
  degrees;
* global rotation = parent global · local; a joint's origin = parent origin +
  parent global · (``OFFSET`` + its position channels); an End Site =
  joint origin + joint global · its ``OFFSET``;
* the root's position channels are added to its ``OFFSET`` (usually 0).

Families (how canonical joints map to BVH nodes; "tip" = the joint's End
Site, or its first child joint's origin when it has no End Site):

* ``"asf"``: BVH written with ASF bone names (our :func:`write_bvh`): every
  canonical joint is the tip of the ASF bone of FEATURES.md §2.2.
* ``"cmu"``: the CMU "cmuconvert" files (FEATURES.md §2.3b): joint origins
  (root = Hips, lhip = LeftUpLeg, ..., neck = lclavicle = rclavicle = Neck,
  lshoulder = LeftArm, lelbow = LeftForeArm), toe/head/finger tips from End
  Sites. lwrist = the origin of LeftFingerBase: in cmuconvert files its
  OFFSET is 0, so that is the spec's LeftHand point; in a BVH written from an
  ASF it carries the ASF wrist bone, so the point is exact there too.
  A first frame of all zeros is cmuconvert's added rest pose and is skipped
  (``skip_rest_frame=None``: only for this family).

Writing: :func:`write_bvh` stores an ASF/AMC motion as BVH (``layout="asf"``
or ``"cmu"``), one joint per ASF bone with its local rotation
``C·M·C⁻¹`` as Euler angles, so that reading it back reproduces the ASF
joint positions and root rotation.

References
----------
FEATURES.md §2.1, §2.3, §2.3b; DESIGN.md §6.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocapdb._numba import jit
from mocapdb.readers.textscan import parse_rows
from mocapdb.readers.amc import AmcMotion
from mocapdb.readers.asf import Skeleton
from mocapdb.errors import ParameterError, ParseError
from mocapdb.readers.joints import JOINT_NAMES
from mocapdb.readers.kinematics import (ASF_JOINT_BONES, _rotate_columns, local_rotations, node_positions,
                         sincos)
from mocapdb.readers.motion import Motion

__all__ = ["BvhJoint", "BvhHierarchy", "BvhData", "FAMILIES", "read_bvh", "parse_bvh",
           "bvh_node_positions", "bvh_to_motion", "write_bvh", "euler_angles",
           "CMU_BONE_NAMES"]

#: BVH channel names (case-insensitive in files) -> (kind, axis): kind 0 =
#: position, 1 = rotation; axis 0 = x, 1 = y, 2 = z
CHANNELS = {"xposition": (0, 0), "yposition": (0, 1), "zposition": (0, 2),
            "xrotation": (1, 0), "yrotation": (1, 1), "zrotation": (1, 2)}
_CHANNEL_NAMES = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")

#: ASF bone -> joint name in the cmuconvert (cgspeed) CMU BVH files
CMU_BONE_NAMES = {
    "root": "Hips",
    "lhipjoint": "LHipJoint", "lfemur": "LeftUpLeg", "ltibia": "LeftLeg", "lfoot": "LeftFoot",
    "ltoes": "LeftToeBase",
    "rhipjoint": "RHipJoint", "rfemur": "RightUpLeg", "rtibia": "RightLeg", "rfoot": "RightFoot",
    "rtoes": "RightToeBase",
    "lowerback": "LowerBack", "upperback": "Spine", "thorax": "Spine1", "lowerneck": "Neck",
    "upperneck": "Neck1", "head": "Head",
    "lclavicle": "LeftShoulder", "lhumerus": "LeftArm", "lradius": "LeftForeArm",
    "lwrist": "LeftHand", "lhand": "LeftFingerBase", "lfingers": "LeftHandIndex1",
    "lthumb": "LThumb",
    "rclavicle": "RightShoulder", "rhumerus": "RightArm", "rradius": "RightForeArm",
    "rwrist": "RightHand", "rhand": "RightFingerBase", "rfingers": "RightHandIndex1",
    "rthumb": "RThumb",
}


def _cmu_family():
    side = {}
    for s, S in (("l", "Left"), ("r", "Right")):
        side.update({
            f"{s}hip": (f"{S}UpLeg", "origin"), f"{s}knee": (f"{S}Leg", "origin"),
            f"{s}ankle": (f"{S}Foot", "origin"), f"{s}toes": (f"{S}ToeBase", "tip"),
            f"{s}clavicle": ("Neck", "origin"), f"{s}shoulder": (f"{S}Arm", "origin"),
            f"{s}elbow": (f"{S}ForeArm", "origin"), f"{s}wrist": (f"{S}FingerBase", "origin"),
            f"{s}fingers": (f"{S}HandIndex1", "tip"),
        })
    side.update({"root": ("Hips", "origin"), "belly": ("Spine", "origin"),
                 "chest": ("Spine1", "origin"), "neck": ("Neck", "origin"),
                 "head": ("Head", "origin"), "headtop": ("Head", "tip")})
    return {"joints": {j: side[j] for j in JOINT_NAMES}, "root": "Hips", "rest_frame": True}


#: skeleton families: canonical joint -> (BVH joint name, "origin" | "tip"),
#: the joint whose global rotation is the root rotation (feature #40), and
#: whether an all-zero first frame is a converter's rest pose
FAMILIES = {
    "asf": {"joints": {j: (ASF_JOINT_BONES[j], "origin" if j == "root" else "tip")
                       for j in JOINT_NAMES},
            "root": "root", "rest_frame": False},
    "cmu": _cmu_family(),
}


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
    """``1 / frame_time``, snapped to the nearest integer rate when within 1e-4.

    BVH files round the frame time (cmuconvert writes ``.0083333``); an fps of
    120.0005 would change the toolbox's millisecond windows
    (``ceil(0.1 · fps)`` = 13 instead of 12 frames).
    """
    fps = 1.0 / frame_time
    r = round(fps)
    return float(r) if r > 0 and abs(fps - r) <= 1e-4 * fps else fps


# ----------------------------------------------------------------------------
# parsing

_TOKEN = re.compile(r"[{}]|[^\s{}]+")


def read_bvh(path, *, family=None, joint_map=None, skip_rest_frame=None) -> Motion:
    """Read a BVH file as a :class:`~mocapdb.readers.motion.Motion` of the 24 canonical joints.

    Parameters
    ----------
    path : str or Path
    family : str or dict, optional, keyword-only
        A key of :data:`FAMILIES` or a family dict of the same form; default:
        the first family whose joint names are all present.
    skip_rest_frame : bool, optional, keyword-only
        Drop an all-zero first frame. Default (None): only for families that
        add one (cmuconvert).

    Returns
    -------
    Motion
        ``source_format="bvh"``, ``skeleton`` = ``"bvh:<family>"``, ``fps`` from
        ``Frame Time`` (:func:`fps_from_frame_time`); ``root_rotation`` is the
        global rotation of the family's root joint.

    Raises
    ------
    ParseError
        Malformed file (file, line, frame and what was expected), or no family
        fits (the message lists each family's missing joints).

    References
    ----------
    FEATURES.md §2.3, §2.3b.
    """
    path = Path(path)
    data = parse_bvh(path.read_bytes(), path=path)
    if joint_map is not None:
        missing = [j for j in JOINT_NAMES if j not in joint_map]
        if missing:
            raise ParameterError(f"joint_map: no entry for {', '.join(missing)}")
        family = {"joints": {j: (joint_map[j], "origin") for j in JOINT_NAMES}, "root": joint_map["root"],
                  "rest_frame": False}
    return bvh_to_motion(data, family=family, skip_rest_frame=skip_rest_frame,
                         name=path.stem)


def parse_bvh(data: bytes, *, path="<bvh>") -> BvhData:
    """Parse the bytes of a BVH file into hierarchy and channel values."""
    path = str(path)
    parser = _HierarchyParser(data, path)
    hierarchy, n_frames, frame_time, start = parser.parse()
    values = parse_rows(data, start, n_frames, hierarchy.n_channels, path,
                        what="channel values")
    if values.shape[0] != n_frames:
        raise ParseError(path, parser.frames_line, f"'Frames: {n_frames}' but only "
                         f"{values.shape[0]} motion lines follow (truncated file?)")
    return BvhData(hierarchy, values, frame_time, path)


class _HierarchyParser:
    """Recursive-descent parser of the HIERARCHY and the MOTION header."""

    def __init__(self, data: bytes, path: str):
        self.data = data
        self.path = path
        self.pos = 3 if data.startswith(b"\xef\xbb\xbf") else 0  # next unread line (skip BOM)
        self.line = 0         # its line number - 1
        self.tokens: list = []  # pending (token, line) of the current line
        self.frames_line = None

    def error(self, line, msg):
        return ParseError(self.path, line, msg)

    def _fill(self):
        while not self.tokens:
            if self.pos >= len(self.data):
                return False
            end = self.data.find(b"\n", self.pos)
            if end < 0:
                end = len(self.data)
            self.line += 1
            text = self.data[self.pos:end].decode("latin-1")
            self.pos = end + 1
            self.tokens = [(t, self.line) for t in _TOKEN.findall(text)]
        return True

    def next(self, what):
        if not self._fill():
            raise self.error(self.line, f"unexpected end of file, expected {what}")
        return self.tokens.pop(0)

    def peek(self):
        if not self._fill():
            return None, self.line
        return self.tokens[0]

    def rest_of_line(self):
        toks = self.tokens
        self.tokens = []
        return toks

    def expect(self, word):
        tok, line = self.next(repr(word))
        if tok.upper() != word.upper():
            raise self.error(line, f"expected {word!r}, found {tok!r}")
        return line

    def offset(self, what):
        """Three numbers on the rest of the OFFSET line."""
        line = self.expect("OFFSET")
        toks = self.rest_of_line()
        if len(toks) != 3:
            raise self.error(line, f"{what}: expected 3 numbers, found {len(toks)} "
                             f"({' '.join(t for t, _ in toks) or 'nothing'})")
        self.tokens = toks
        return np.array([self.number(what)[0] for _ in range(3)])

    def number(self, what):
        tok, line = self.next(what)
        try:
            v = float(tok)
        except ValueError:
            raise self.error(line, f"{what}: expected a number, found {tok!r}") from None
        if not math.isfinite(v):
            raise self.error(line, f"{what}: expected a finite number, found {tok!r}")
        return v, line

    def parse(self):
        self.expect("HIERARCHY")
        tok, line = self.next("'ROOT'")
        if tok.upper() != "ROOT":
            raise self.error(line, f"expected 'ROOT', found {tok!r}")
        joints: list = []
        nch = self.joint(joints, -1, line, 0)
        tok, line = self.next("'MOTION'")
        if tok.upper() == "ROOT":
            raise self.error(line, "a second ROOT: only one skeleton per file is supported")
        if tok.upper() != "MOTION":
            raise self.error(line, f"expected 'MOTION', found {tok!r}")
        tok, line = self.next("'Frames:'")
        if tok.lower() == "frames" and self.peek()[0] == ":":
            self.next("':'")
        elif tok.lower() != "frames:":
            raise self.error(line, f"expected 'Frames:', found {tok!r}")
        self.frames_line = line
        tok, line = self.next("a frame count")
        if not tok.isdigit():
            raise self.error(line, f"Frames: expected a frame count, found {tok!r}")
        n_frames = int(tok)
        t1, line = self.next("'Frame Time:'")
        t2, _ = self.next("'Frame Time:'")
        if (t1.lower(), t2.lower()) != ("frame", "time:"):
            raise self.error(line, f"expected 'Frame Time:', found {t1 + ' ' + t2!r}")
        frame_time, line = self.number("Frame Time")
        if not frame_time > 0:
            raise self.error(line, f"Frame Time: expected a positive time, found {frame_time!r}")
        if self.tokens:
            raise self.error(line, f"unexpected {self.tokens[0][0]!r} after the frame time")
        if n_frames == 0:
            raise self.error(self.frames_line, "no frames ('Frames: 0')")
        hierarchy = BvhHierarchy(tuple(joints), nch)
        return hierarchy, n_frames, frame_time, min(self.pos, len(self.data))

    def joint(self, joints, parent, line, channel_start):
        name_toks = [t for t, _ in self.rest_of_line()]
        if name_toks and name_toks[-1] == "{":
            name_toks.pop()
            self.tokens = [("{", line)]
        if not name_toks:
            raise self.error(line, "joint without a name")
        name = " ".join(name_toks)
        self.expect("{")
        offset = self.offset(f"joint {name!r}: OFFSET")
        me = len(joints)
        joints.append(None)  # placeholder keeps file order (parents first)
        channels = ()
        end_site = None
        nch = channel_start
        while True:
            tok, tline = self.next("'}'")
            key = tok.upper()
            if key == "CHANNELS":
                cnt_tok, cline = self.next("a channel count")
                if not cnt_tok.isdigit():
                    raise self.error(cline, f"CHANNELS: expected a count, found {cnt_tok!r}")
                cnt = int(cnt_tok)
                got = self.rest_of_line()
                names = []
                for t, l in got:
                    k = t.lower()
                    if k not in CHANNELS:
                        raise self.error(l, f"joint {name!r}: unknown channel {t!r} (expected "
                                         + ", ".join(_CHANNEL_NAMES) + ")")
                    names.append(_CHANNEL_NAMES[CHANNELS[k][0] * 3 + CHANNELS[k][1]])
                if len(names) != cnt:
                    raise self.error(cline, f"joint {name!r}: CHANNELS {cnt} but "
                                     f"{len(names)} channel names follow")
                channels = tuple(names)
                nch = channel_start + cnt
            elif key == "JOINT":
                nch = self.joint(joints, me, tline, nch)
            elif key == "END":
                site, sline = self.next("'Site'")
                if site.upper() != "SITE":
                    raise self.error(sline, f"expected 'End Site', found 'End {site}'")
                self.expect("{")
                end_site = self.offset(f"joint {name!r}: End Site OFFSET")
                self.expect("}")
            elif key == "}":
                break
            else:
                raise self.error(tline, f"joint {name!r}: expected CHANNELS, JOINT, End Site "
                                 f"or '}}', found {tok!r}")
        joints[me] = BvhJoint(name=name, parent=parent, offset=offset, channels=channels,
                              channel_start=channel_start, end_site=end_site, line=line)
        return nch


# ----------------------------------------------------------------------------
# kinematics

@jit
def _bvh_fk_kernel(sin, cos, values, parent, offset, ch_start, ch_count, ch_kind, ch_axis,
                   end_site, has_end, origins, ends, rotations, rot_joint):  # pragma: no cover
    """Joint origins (n, nj, 3), End Sites (n, nj, 3) and the global rotation of
    joint ``rot_joint`` (n, 3, 3) for every frame; see the module docstring."""
    n = values.shape[0]
    nj = parent.shape[0]
    h = np.empty((nj, 3, 3))
    t = np.empty(3)
    for f in range(n):
        for j in range(nj):
            p = parent[j]
            for i in range(3):
                for k in range(3):
                    h[j, i, k] = h[p, i, k] if p >= 0 else (1.0 if i == k else 0.0)
                t[i] = offset[j, i]
            s0 = ch_start[j]
            for c in range(ch_count[j]):
                col = s0 + c
                if ch_kind[col] == 0:
                    t[ch_axis[col]] += values[f, col]
                else:
                    _rotate_columns(h, j, ch_axis[col], cos[f, col], sin[f, col])
            for i in range(3):
                if p >= 0:
                    origins[f, j, i] = origins[f, p, i] + (h[p, i, 0] * t[0] + h[p, i, 1] * t[1]
                                                           + h[p, i, 2] * t[2])
                else:
                    origins[f, j, i] = t[i]
            if has_end[j]:
                for i in range(3):
                    ends[f, j, i] = origins[f, j, i] + (h[j, i, 0] * end_site[j, 0]
                                                        + h[j, i, 1] * end_site[j, 1]
                                                        + h[j, i, 2] * end_site[j, 2])
            if j == rot_joint:
                for i in range(3):
                    for k in range(3):
                        rotations[f, i, k] = h[j, i, k]


def bvh_node_positions(data: BvhData, *, rotation_joint: int = 0):
    """Forward kinematics of a parsed BVH file.

    Returns
    -------
    origins : ndarray, shape (n_frames, n_joints, 3)
    end_sites : ndarray, shape (n_frames, n_joints, 3)
        NaN for joints without an End Site.
    rotation : ndarray, shape (n_frames, 3, 3)
        Global rotation of joint ``rotation_joint`` (default: the root).
    """
    hier = data.hierarchy
    joints = hier.joints
    nj = len(joints)
    parent = np.array([j.parent for j in joints], dtype=np.int64)
    offset = np.array([j.offset for j in joints], dtype=np.float64).reshape(nj, 3)
    ch_start = np.array([j.channel_start for j in joints], dtype=np.int64)
    ch_count = np.array([len(j.channels) for j in joints], dtype=np.int64)
    kinds = np.zeros(hier.n_channels, dtype=np.int64)
    axes = np.zeros(hier.n_channels, dtype=np.int64)
    for j in joints:
        for c, name in enumerate(j.channels):
            kinds[j.channel_start + c], axes[j.channel_start + c] = CHANNELS[name.lower()]
    has_end = np.array([j.end_site is not None for j in joints])
    end_site = np.array([j.end_site if j.end_site is not None else np.zeros(3) for j in joints],
                        dtype=np.float64).reshape(nj, 3)
    values = np.ascontiguousarray(data.values, dtype=np.float64)
    sin, cos = sincos(values * (math.pi / 180.0))
    n = values.shape[0]
    origins = np.empty((n, nj, 3))
    ends = np.full((n, nj, 3), np.nan)
    rot = np.empty((n, 3, 3))
    _bvh_fk_kernel(sin, cos, values, parent, offset, ch_start, ch_count, kinds, axes, end_site,
                   has_end, origins, ends, rot, rotation_joint)
    return origins, ends, rot


def _resolve_family(hier: BvhHierarchy, family, path):
    if isinstance(family, dict):
        candidates = [("custom", family)]
    elif family is not None:
        if family not in FAMILIES:
            raise ParameterError(f"family={family!r}: unknown; expected one of "
                                 f"{sorted(FAMILIES)} or a dict like FAMILIES['cmu']")
        candidates = [(family, FAMILIES[family])]
    else:
        candidates = list(FAMILIES.items())
    names = {j.name.lower() for j in hier.joints}
    report = []
    for fname, fam in candidates:
        need = {b for b, _ in fam["joints"].values()} | {fam["root"]}
        missing = sorted(b for b in need if b.lower() not in names)
        if not missing:
            return fname, fam
        report.append(f"family {fname!r} lacks {', '.join(missing)}")
    raise ParseError(path, None, "no known skeleton family fits this BVH: "
                     + "; ".join(report) + " (pass family=... with a joint-name table)")


def _tip(hier: BvhHierarchy, k: int):
    """("end", k) for an End Site, ("origin", child) for the first child joint."""
    if hier.joints[k].end_site is not None:
        return "end", k
    kids = hier.children(k)
    if not kids:
        raise ParameterError(f"BVH joint {hier.joints[k].name!r} has neither an End Site nor "
                             "a child joint: its tip is undefined")
    return "origin", kids[0]


def bvh_to_motion(data: BvhData, *, family=None, skip_rest_frame=None, name="") -> Motion:
    """The canonical joints of a parsed BVH file; see :func:`read_bvh`."""
    hier = data.hierarchy
    fname, fam = _resolve_family(hier, family, data.path)
    values = data.values
    meta = {"bvh_family": fname, "frame_time": data.frame_time}
    skip = fam.get("rest_frame", False) if skip_rest_frame is None else skip_rest_frame
    if skip and values.shape[0] > 1 and not np.any(values[0]):
        values = values[1:]
        meta["rest_frame_skipped"] = True
    sel_kind = []
    for j in JOINT_NAMES:
        bone, where = fam["joints"][j]
        k = hier.index(bone)
        sel_kind.append(("origin", k) if where == "origin" else _tip(hier, k))
    origins, ends, rot = bvh_node_positions(
        BvhData(hier, values, data.frame_time, data.path), rotation_joint=hier.index(fam["root"]))
    joints = np.empty((values.shape[0], len(JOINT_NAMES), 3))
    for c, (kind, k) in enumerate(sel_kind):
        joints[:, c] = origins[:, k] if kind == "origin" else ends[:, k]
    return Motion(joints=joints, root_rotation=rot, fps=data.fps, name=name,
                  skeleton=f"bvh:{fname}", source_format="bvh", meta=meta)


# ----------------------------------------------------------------------------
# writing

_AXIS = {"x": 0, "y": 1, "z": 2}


def euler_angles(rotations, order: str) -> np.ndarray:
    """Euler angles (radians) of rotation matrices: ``R = R_o0(a0)·R_o1(a1)·R_o2(a2)``.

    Parameters
    ----------
    rotations : ndarray, shape (..., 3, 3)
    order : str
        Three distinct axis letters, e.g. ``"zyx"`` (BVH channel order).

    Returns
    -------
    ndarray, shape (..., 3)
        Angles in the order of ``order``; the middle one in [-pi/2, pi/2].
    """
    o = order.lower()
    if sorted(o) != ["x", "y", "z"]:
        raise ParameterError(f"order={order!r}: expected a permutation of 'xyz'")
    i, j, k = (_AXIS[a] for a in o)
    r = np.asarray(rotations, dtype=np.float64)
    # sign of the permutation (i, j, k): +1 for cyclic (xyz, yzx, zxy)
    s = 1.0 if (j - i) % 3 == 1 else -1.0
    b = np.arctan2(s * r[..., i, k], np.hypot(r[..., i, i], r[..., i, j]))
    a = np.arctan2(-s * r[..., j, k], r[..., k, k])
    c = np.arctan2(-s * r[..., i, j], r[..., i, i])
    return np.stack([a, b, c], axis=-1)


def _fmt(x, precision):
    return format(float(x), f".{precision}g")


def write_bvh(path, skeleton: Skeleton, motion: AmcMotion, *, layout: str = "asf",
              rotation_order="ZYX", rest_frame: bool = False, precision: int = 12) -> Path:
    """Write an ASF/AMC motion as a BVH file.

    One BVH joint per ASF bone (its OFFSET is the parent bone's vector, its
    channels the bone's local rotation ``C·M·C⁻¹``), leaf bones end in an End
    Site with their own vector, the root has 6 channels (position = AMC
    translation + ASF position in toolbox units; rotation = ``O·Rz·Ry·Rx``).
    Reading the file back gives the ASF joint positions and, when the ASF
    orientation O is the identity (all files here), the AMC root rotation.

    Parameters
    ----------
    path : str or Path
    skeleton : Skeleton
    motion : AmcMotion
        Read with ``skeleton``.
    layout : {"asf", "cmu"}, keyword-only
        Joint names: ASF bone names, or the cmuconvert names of
        :data:`CMU_BONE_NAMES` (needs the standard CMU bone set).
    rotation_order : str or dict, keyword-only
        Rotation channel order, e.g. ``"ZYX"`` (default, as cmuconvert) or any
        permutation; a dict maps joint names (BVH names) to orders, others ZYX.
    rest_frame : bool, keyword-only
        Prepend an all-zero frame, as cmuconvert does.
    precision : int, keyword-only
        Significant digits. 12 (default) keeps positions within ~1e-11 of a
        bone length and stays on the reader's exact fast path; 17 round-trips
        float64 exactly but reads ~5x slower (mantissas beyond 2**53 go
        through Python's ``float``).

    Returns
    -------
    Path

    Raises
    ------
    ParameterError
        Unknown layout, a bone without a cmuconvert name, a bad rotation order.
    """
    path = Path(path)
    if layout not in ("asf", "cmu"):
        raise ParameterError(f"layout={layout!r}: expected 'asf' or 'cmu'")
    if layout == "cmu":
        missing = [b.name for b in skeleton.bones if b.name.lower() not in CMU_BONE_NAMES]
        if missing:
            raise ParameterError(f"layout='cmu': bones {missing} have no cmuconvert name; "
                                 "use layout='asf'")
        rename = {b.name: CMU_BONE_NAMES[b.name.lower()] for b in skeleton.bones}
        rename["root"] = CMU_BONE_NAMES["root"]
    else:
        rename = {b.name: b.name for b in skeleton.bones}
        rename["root"] = "root"

    def order_of(joint):
        o = rotation_order.get(joint, "ZYX") if isinstance(rotation_order, dict) else rotation_order
        if sorted(o.lower()) != ["x", "y", "z"]:
            raise ParameterError(f"rotation_order={o!r} (joint {joint!r}): expected a "
                                 "permutation of 'XYZ'")
        return o.upper()

    root_rot, local = local_rotations(skeleton, motion)
    positions, _ = node_positions(skeleton, motion)
    bones = skeleton.bones
    children = {"root": [b for b in bones if b.parent == "root"]}
    for b in bones:
        children[b.name] = [c for c in bones if c.parent == b.name]
    fmt = lambda x: _fmt(x, precision)  # noqa: E731
    lines = ["HIERARCHY"]
    columns = []  # per joint: (n, k) arrays in channel order

    def emit(bone, depth, offset):
        ind = "\t" * depth
        name = rename[bone.name if bone is not None else "root"]
        key = "ROOT" if bone is None else "JOINT"
        order = order_of(name)
        rot_names = [f"{a}rotation" for a in order]
        lines.append(f"{ind}{key} {name}")
        lines.append(f"{ind}{{")
        lines.append(f"{ind}\tOFFSET {' '.join(fmt(v) for v in offset)}")
        if bone is None:
            lines.append(f"{ind}\tCHANNELS 6 Xposition Yposition Zposition {' '.join(rot_names)}")
            columns.append(positions[:, 0, :])
            rot = root_rot
        else:
            lines.append(f"{ind}\tCHANNELS 3 {' '.join(rot_names)}")
            rot = local[:, skeleton.bone_index[bone.name]]
        columns.append(np.degrees(euler_angles(rot, order)))
        kids = children[bone.name if bone is not None else "root"]
        own = bone.offset if bone is not None else np.zeros(3)
        for c in kids:
            emit(c, depth + 1, own)
        if bone is not None and not kids:
            lines.append(f"{ind}\tEnd Site")
            lines.append(f"{ind}\t{{")
            lines.append(f"{ind}\t\tOFFSET {' '.join(fmt(v) for v in own)}")
            lines.append(f"{ind}\t}}")
        lines.append(f"{ind}}}")

    emit(None, 0, np.zeros(3))
    table = np.concatenate(columns, axis=1)
    if rest_frame:
        table = np.concatenate([np.zeros((1, table.shape[1])), table])
    lines.append("MOTION")
    lines.append(f"Frames: {table.shape[0]}")
    lines.append(f"Frame Time: {fmt(1.0 / motion.fps)}")
    body = "\n".join(" ".join(fmt(v) for v in row) for row in table)
    path.write_text("\n".join(lines) + "\n" + body + "\n", encoding="latin-1")
    return path
