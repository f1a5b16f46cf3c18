"""Map any humanoid skeleton tree onto the 24 canonical joints (READERS.md §2).

Input is a tree of points — joint origins and End Sites — with their
positions in the rest pose; output is a :class:`JointMap`: each canonical
joint as a weighted sum of tree points (a point, or a point between two),
plus the joint whose global rotation is the body's root rotation.

How a skeleton is read, whatever its naming:

0. **Names first.** Joints named for a knee and an ankle (``LowerLeg_L`` and
   ``Foot_L``, ``LeftLeg`` and ``LeftFoot``) on each side give the feet, a
   joint named Head the head top, joints named for an elbow and a wrist the
   arms — trusted over the geometry of one pose (a frame with a foot in the
   air, a rest pose lying on its side).
1. **Topology.** The feet are the leaves in the lowest quarter of the body;
   the pelvis is their common ancestor; the head top is the highest leaf;
   the spine is the path from the pelvis to it. The two legs are the
   pelvis's branches that hold the feet, the two arms the longest branches
   off the spine above the pelvis. Each limb is the path from where it
   branches off to its farthest leaf (toe tip, longest finger tip).
2. **Names** place the joints of a limb where they exist: after stripping
   namespaces and rig prefixes (``mixamorig:``, ``Bip01``, ``joint_``, …)
   and splitting CamelCase, a knee is a ``Leg``/``LowLeg``/``Knee``/``Calf``/
   ``Shin``, an ankle a ``Foot``/``Ankle``, an elbow a ``ForeArm``/
   ``LowArm``/``Elbow``, a wrist a ``Hand``/``Wrist``, the hip or shoulder
   the point before the knee or elbow; twist and roll joints are skipped.
   Without usable names, thigh and shin (upper arm and forearm) are the two
   consecutive bones of a limb that are longest together minus the bone that
   follows them (foot, hand).
3. **Sides** come from the names (``Left``/``L``/``Right``/``R``) or else
   from the rest pose: left is up × forward, forward being the direction
   from ankle to toe (BVH: Y up).
4. **Spine points.** belly and chest lie at 1/3 and 2/3 of the spine's
   length from the pelvis to the neck (as the three equal ASF spine bones
   do), so they are distinct points whatever the number of spine joints;
   the neck is the first joint of the head's branch where the arms branch
   off (or, when that joint is the head itself, the midpoint of the two
   clavicle joints); clavicles are the neck point, as in ASF data.

A user map (``joint_map``: canonical joint → a joint name, ``"Name/end"``
for its End Site, or a list of names whose mean it is) overrides any of it.

Legs, arms and a head do not make a human: :func:`humanoid_problem` checks the
mapped body's proportions and that it stands upright in its rest pose or in
some of its frames (a dog's "arms" reach the floor, its trunk is longer than
its legs; READERS.md §2.1).
"""
from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass

import numpy as np

from mocapdb._numba import jit
from mocapdb.bodies.joints import JOINT_INDEX, JOINT_NAMES
from mocapdb.bodies.units import _column_medians_kernel, _pair_lengths_kernel

__all__ = ["SkeletonTree", "JointMap", "MappingError", "map_humanoid", "normalized_name", "name_side",
           "mapping_template", "hip_axis_is_x", "Z_UP_TO_Y_UP", "humanoid_problem", "upright_frames",
           "HUMAN_PROPORTIONS", "MIN_UPRIGHT", "LIMB_WORDS"]

#: rotation of -90° about x: +Z (up in many capture tools) becomes +Y, +Y becomes -Z
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])

#: rig prefixes stripped from joint names (after any ``namespace:``)
_PREFIXES = {"mixamorig", "bip01", "bip001", "bip02", "bip", "character1", "character", "joint", "jnt",
             "j", "b", "def", "mch", "org", "bn", "bone", "sk", "ccbase", "cc", "base", "rig", "skel",
             "mocap", "valvebiped", "bip1", "hik", "model", "armature"}
_LEFT = {"left", "l", "lt", "lft"}
_RIGHT = {"right", "r", "rt", "rgt"}
#: name words of a limb's middle joint (knee, elbow) and end joint (ankle, wrist)
_KNEE = {"leg", "lowleg", "lowerleg", "knee", "calf", "shin", "tibia", "loleg", "leglower", "crus"}
_ANKLE = {"foot", "ankle"}
_ELBOW = {"forearm", "lowarm", "lowerarm", "elbow", "radius", "ulna", "loarm", "armlower"}
_WRIST = {"hand", "wrist"}
_THIGH = {"upleg", "upperleg", "thigh", "femur", "hip", "legupper", "uleg"}
_UPPERARM = {"arm", "uparm", "upperarm", "humerus", "armupper", "shoulder"}
_TWIST = ("roll", "twist", "share", "helper", "aux", "corrective")
_HEAD = {"head"}
#: name words of each limb point (after side and rig prefix are taken off)
LIMB_WORDS = {"thigh": _THIGH, "knee": _KNEE, "ankle": _ANKLE, "upper arm": _UPPERARM, "elbow": _ELBOW,
              "wrist": _WRIST}
# glued single-letter sides of ASF/CMU names: LHipJoint → l hip joint, lfemur → l femur
_GLUED = re.compile(r"^([lr])(hipjoint|femur|tibia|foot|toes|toe|clavicle|humerus|radius|wrist|hand|"
                    r"fingers|fingerbase|thumb|shoulder|elbow|knee|ankle|hip|collar|uparm|lowarm|"
                    r"upleg|lowleg|arm|leg|forearm)(\d*)$")


@functools.lru_cache(maxsize=1 << 16)
def _tokens(name: str) -> tuple:
    """Lower-case words of a joint name: namespace dropped, CamelCase and digits split."""
    base = re.split(r"[:|]", name)[-1]
    base = re.sub(r"([a-z0-9])([A-Z])", r"\1 \2", base)
    base = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1 \2", base)
    words = [w for w in re.split(r"[^A-Za-z0-9]+", base) if w]
    out = []
    for w in words:
        w = w.lower()
        m = _GLUED.match(w)
        if m:
            out.extend(x for x in m.groups() if x)
        else:
            out.extend(re.findall(r"[a-z]+|\d+", w))
    while len(out) > 1 and out[0] in _PREFIXES:
        out.pop(0)
    return tuple(out)


def name_side(name: str) -> str | None:
    """``"l"``, ``"r"`` or None: the side a joint name states."""
    toks = _tokens(name)
    left = any(t in _LEFT for t in toks)
    right = any(t in _RIGHT for t in toks)
    if left != right:
        return "l" if left else "r"
    return None


def normalized_name(name: str) -> str:
    """The name's words without side and rig prefix, joined: ``mixamorig:LeftForeArm`` → ``forearm``."""
    return "".join(t for t in _tokens(name) if t not in _LEFT and t not in _RIGHT and not t.isdigit())


@dataclass(frozen=True)
class SkeletonTree:
    """Points of a skeleton: joint origins, then End Sites.

    Attributes
    ----------
    names : tuple of str
        One per point; an End Site is ``"<joint>/end"``.
    parent : ndarray, shape (n_points,), int64
        Parent point (-1 for the root). An End Site's parent is its joint.
    rest : ndarray, shape (n_points, 3)
        Rest-pose positions (offsets accumulated), Y up.
    is_joint : ndarray, shape (n_points,), bool
        False for End Sites.
    """

    names: tuple
    parent: np.ndarray
    rest: np.ndarray
    is_joint: np.ndarray

    @property
    def n(self) -> int:
        return len(self.names)


@dataclass(frozen=True)
class JointMap:
    """The 24 canonical joints as weighted sums of tree points.

    Attributes
    ----------
    weights : ndarray, shape (24, n_points)
        ``joints[f] = weights @ points[f]``; every row sums to 1.
    rotation_point : int
        The pelvis joint: its global rotation is the root rotation.
    how : dict
        Canonical joint → how it was placed (for messages and templates).
    up : ndarray, shape (3, 3), or None
        A rotation to apply to the positions when the skeleton is Z-up (a
        proper rotation taking +Z to +Y: never a mirror); None when Y is up.
    """

    weights: np.ndarray
    rotation_point: int
    how: dict
    up: np.ndarray | None = None


class MappingError(Exception):
    """No humanoid mapping: ``missing`` lists canonical joints it could not place."""

    def __init__(self, message, missing, partial):
        super().__init__(message)
        self.missing = list(missing)
        self.partial = dict(partial)


# ----------------------------------------------------------------------------
# tree helpers

def _children(tree: SkeletonTree) -> list:
    kids = [[] for _ in range(tree.n)]
    for i, p in enumerate(tree.parent):
        if p >= 0:
            kids[p].append(i)
    return kids


def _path_to_root(tree: SkeletonTree, i: int) -> list:
    out = []
    while i >= 0:
        out.append(i)
        i = int(tree.parent[i])
    return out[::-1]


def _farthest_leaf(tree, kids, start):
    """The leaf below ``start`` with the longest rest path from it, and the path."""
    best, best_len, best_path = start, -1.0, [start]
    stack = [(start, 0.0, [start])]
    while stack:
        i, length, path = stack.pop()
        if not kids[i]:
            if length > best_len + 1e-12:
                best, best_len, best_path = i, length, path
            continue
        for k in kids[i]:
            seg = float(np.linalg.norm(tree.rest[k] - tree.rest[i]))
            stack.append((k, length + seg, path + [k]))
    return best, best_len, best_path


def _is_twist(tree, i) -> bool:
    return any(t in _TWIST for t in _tokens(tree.names[i]))


def _distinct(tree, path, tol):
    """Path points without twist joints and without repeats of the previous position."""
    out = []
    for i in path:
        if tree.is_joint[i] and _is_twist(tree, i) and i != path[-1]:
            continue
        if out and np.linalg.norm(tree.rest[i] - tree.rest[out[-1]]) <= tol:
            # a repeated position: keep the deeper point only for an End Site leaf of a
            # zero-length bone (the joint itself is the better-named one)
            continue
        out.append(i)
    return out


def _named(tree, chain, words):
    return [i for i in chain if tree.is_joint[i] and normalized_name(tree.names[i]) in words]


# ----------------------------------------------------------------------------
# limbs

def _limb_points(tree, chain, tol, mid_words, end_words, top_words):
    """(top, middle, end, tip) points of a limb chain (attach point first, leaf last).

    Names first (middle joint: knee/elbow words; end: ankle/wrist words; top:
    the named thigh/upper arm or the point before the middle one); else the
    two longest consecutive bones.
    """
    pts = _distinct(tree, chain, tol)
    tip = pts[-1]
    mids = _named(tree, pts, mid_words)
    if mids:
        mid = mids[0]
        k = pts.index(mid)
        tops = _named(tree, pts[:k], top_words)
        top = tops[-1] if tops else (pts[k - 1] if k >= 1 else None)
        ends = _named(tree, pts[k + 1:], end_words)
        end = ends[0] if ends else (pts[k + 1] if k + 1 < len(pts) else None)
        if top is not None and end is not None:
            return top, mid, end, tip, "names"
    if len(pts) < 4:
        return None
    seg = [float(np.linalg.norm(tree.rest[pts[i + 1]] - tree.rest[pts[i]])) for i in range(len(pts) - 1)] + [0.0]
    # the two long bones (thigh and shin, upper arm and forearm) followed by a short
    # one (foot, hand): the longest pair minus what follows it. The plain longest
    # pair would take clavicle and upper arm on skeletons with a long clavicle and
    # a short forearm (HDM05: 21, 27, 17 cm)
    best = max(range(len(seg) - 2), key=lambda i: seg[i] + seg[i + 1] - seg[i + 2])
    if best + 2 >= len(pts):
        return None
    return pts[best], pts[best + 1], pts[best + 2], tip, "bone lengths"


# ----------------------------------------------------------------------------
# names

def _words(tree) -> tuple:
    """Per point: (side, name without side and rig prefix), or None for End Sites; once per tree."""
    return tuple((name_side(n), normalized_name(n)) if j else None for n, j in zip(tree.names, tree.is_joint))


def _named_side(words_of, words, side):
    """Joints whose name, without side and rig prefix, is one of ``words`` and whose side is ``side``."""
    return [i for i, w in enumerate(words_of) if w is not None and w[0] == side and w[1] in words]


def _below(tree, top, i) -> bool:
    """True when point ``i`` lies in the subtree of ``top`` (``top`` included)."""
    while i >= 0:
        if i == top:
            return True
        i = int(tree.parent[i])
    return False


def _named_pair(tree, words_of, mid_words, end_words, side):
    """The shallowest (middle, end) joints of a limb named for ``side`` (knee and ankle, elbow and
    wrist), the end below the middle; or None."""
    ends_all = _named_side(words_of, end_words, side)
    for mid in sorted(_named_side(words_of, mid_words, side), key=lambda i: len(_path_to_root(tree, i))):
        ends = [e for e in ends_all if e != mid and _below(tree, mid, e)]
        if ends:
            return mid, min(ends, key=lambda i: len(_path_to_root(tree, i)))
    return None


def _named_body(tree, kids) -> dict:
    """What the joint names say: ``feet`` (the farthest leaf below each named ankle), ``head``
    (the farthest leaf below the shallowest joint named Head) and ``arms`` (the named elbow of each
    side); None where the names do not say it for both sides."""
    words_of = _words(tree)
    legs = [_named_pair(tree, words_of, _KNEE, _ANKLE, s) for s in "lr"]
    arms = [_named_pair(tree, words_of, _ELBOW, _WRIST, s) for s in "lr"]
    feet = None
    if all(legs) and not (_below(tree, legs[0][0], legs[1][0]) or _below(tree, legs[1][0], legs[0][0])):
        feet = [_farthest_leaf(tree, kids, ankle)[0] for _, ankle in legs]
    heads = [i for i, w in enumerate(words_of) if w is not None and w[1] in _HEAD]
    head = None
    if heads:
        top = min(heads, key=lambda i: len(_path_to_root(tree, i)))
        head = _farthest_leaf(tree, kids, top)[0]
    return {"feet": feet, "head": head,
            "arms": [a[0] for a in arms] if all(arms) and arms[0][0] != arms[1][0] else None}


def _named_arms(tree, elbows, spine, on_spine):
    """``[(attach on the spine, first joint of the arm)]`` for named elbows, or None."""
    if elbows is None:
        return None
    out = []
    for elbow in elbows:
        path = _path_to_root(tree, elbow)
        off = [k for k, i in enumerate(path) if i in on_spine]
        if not off or off[-1] + 1 >= len(path):
            return None
        attach, first = path[off[-1]], path[off[-1] + 1]
        if attach not in spine:
            return None
        out.append((attach, first))
    if out[0][1] == out[1][1]:
        return None
    return out


# ----------------------------------------------------------------------------
# the mapper

def map_humanoid(tree: SkeletonTree, pose=None) -> JointMap:
    """Place the 24 canonical joints on a skeleton tree; see the module docstring.

    Parameters
    ----------
    tree : SkeletonTree
    pose : ndarray, shape (n_points, 3), optional
        Positions to judge up, down, left and right by (default: the rest
        pose). Rigs whose rest pose lies on its side (root axes along the
        spine) are read from a frame of the motion instead.

    Raises
    ------
    MappingError
        The tree is not a humanoid (no two legs, two arms and a head), with
        the canonical joints it could not place.
    """
    n = tree.n
    rest = tree.rest  # lengths: the same in any pose
    pose = rest if pose is None else np.asarray(pose, dtype=np.float64)
    kids = _children(tree)
    leaves = [i for i in range(n) if not kids[i]]
    height = float(pose[:, 1].max() - pose[:, 1].min()) if n else 0.0
    size = float(np.ptp(pose, axis=0).max()) if n else 0.0
    tol = 1e-6 * max(size, 1e-12)
    partial: dict = {}
    if n < 5 or size <= 0.0:
        raise MappingError(f"{n} points in a rest pose of size {size:g}: too few for a body",
                           JOINT_NAMES, partial)
    named = _named_body(tree, kids)
    if named["feet"] is not None:
        # names that say thigh, knee and ankle are trusted over one pose's geometry (a frame
        # with both feet off the ground, a rest pose lying on its side)
        feet = named["feet"]
    else:
        if height <= 0.0:
            raise MappingError("a flat rest pose and no joint names of legs", JOINT_NAMES, partial)
        floor = float(pose[:, 1].min())
        feet = [i for i in leaves if pose[i, 1] <= floor + 0.25 * height]
        if len(feet) < 2:
            raise MappingError("fewer than two leaves near the floor: no two legs", JOINT_NAMES, partial)
    head_leaf = named["head"] if named["head"] is not None else max(leaves, key=lambda i: pose[i, 1])
    paths = {i: _path_to_root(tree, i) for i in feet}
    # pelvis: the deepest common ancestor of the feet
    common = paths[feet[0]]
    for i in feet[1:]:
        p = paths[i]
        k = 0
        while k < min(len(common), len(p)) and common[k] == p[k]:
            k += 1
        common = common[:k]
    if not common:
        raise MappingError("the feet have no common ancestor", JOINT_NAMES, partial)
    pelvis = common[-1]
    depth = len(common)
    up = pose[head_leaf] - pose[pelvis]
    if named["feet"] is None and (up[1] < 0.5 * np.linalg.norm(up) or any(pose[i, 1] >= pose[pelvis, 1]
                                                                         for i in feet)):
        raise MappingError("the pose is not an upright body (head above the pelvis, feet below)", JOINT_NAMES,
                           partial)
    branches = {}
    for i in feet:
        if len(paths[i]) <= depth:
            raise MappingError("a foot is the pelvis itself", JOINT_NAMES, partial)
        branches.setdefault(paths[i][depth], []).append(i)
    if len(branches) < 2:
        raise MappingError("the feet hang off one branch: no two legs", JOINT_NAMES, partial)
    legs = sorted(branches, key=lambda b: -_farthest_leaf(tree, kids, b)[1])[:2]
    spine = _path_to_root(tree, head_leaf)
    if pelvis not in spine:
        raise MappingError("the head is not above the pelvis in the tree", JOINT_NAMES, partial)
    spine = spine[spine.index(pelvis):]
    on_spine = set(spine)
    # arms: named elbows and wrists, else the longest branches off the spine above the pelvis (not the legs)
    arms = _named_arms(tree, named["arms"], spine, on_spine)
    if arms is None:
        arm_cands = []
        for s in spine:
            for k in kids[s]:
                if k in on_spine or k in legs:
                    continue
                leaf, length, _ = _farthest_leaf(tree, kids, k)
                arm_cands.append((length + float(np.linalg.norm(rest[k] - rest[s])), s, k))
        arm_cands.sort(key=lambda t: -t[0])
        if len(arm_cands) < 2 or arm_cands[1][0] < 0.15 * size:
            raise MappingError("fewer than two arms branch off the spine",
                               [j for j in JOINT_NAMES if j[0] in "lr"
                                and j[1:] in ("clavicle", "shoulder", "elbow", "wrist", "fingers")], partial)
        arms = [(s, k) for _, s, k in arm_cands[:2]]

    def chain(attach, first):
        _, _, path = _farthest_leaf(tree, kids, first)
        return [attach] + path

    limb = {}
    for kind, items, words in (("leg", [(pelvis, b) for b in legs], (_KNEE, _ANKLE, _THIGH)),
                               ("arm", arms, (_ELBOW, _WRIST, _UPPERARM))):
        for attach, first in items:
            c = chain(attach, first)
            got = _limb_points(tree, c, tol, *words)
            if got is None:
                parts = "thigh, shin and foot" if kind == "leg" else "upper arm, forearm and hand"
                points = ("hip", "knee", "ankle", "toes") if kind == "leg" else ("shoulder", "elbow", "wrist",
                                                                                 "fingers")
                raise MappingError(f"cannot find the joints of an {kind} in {' → '.join(tree.names[i] for i in c)} "
                                   f"(an {kind} has {parts})", [f"{s}{p}" for s in "lr" for p in points], partial)
            limb[(kind, first)] = (c, got)

    # sides: names, else rest pose (left = up × forward)
    def side_of(c):
        votes = [name_side(tree.names[i]) for i in c if tree.is_joint[i]]
        left, right = votes.count("l"), votes.count("r")
        return "l" if left > right else "r" if right > left else None

    leg_keys = [("leg", b) for b in legs]
    arm_keys = [("arm", k) for _, k in arms]
    forward = np.zeros(3)
    for key in leg_keys:
        _, (top, mid, end, tip, _) = limb[key]
        forward += pose[tip] - pose[end]
    forward[1] = 0.0
    if np.linalg.norm(forward) < 1e-9 * size:
        forward = np.array([0.0, 0.0, 1.0])  # BVH convention: the character faces +Z
    left_dir = np.cross([0.0, 1.0, 0.0], forward / np.linalg.norm(forward))
    sides = {}
    for pair in (leg_keys, arm_keys):
        named = [side_of(limb[k][0]) for k in pair]
        if sorted(x for x in named if x) == ["l", "r"]:
            sides.update(zip(pair, named))
            continue
        lat = [float(np.dot(pose[limb[k][1][2]] - pose[pelvis], left_dir)) for k in pair]
        if abs(lat[0] - lat[1]) < 1e-6 * size:
            raise MappingError("cannot tell left from right (names carry no side and the limbs overlap "
                               "in the rest pose)", [], partial)
        first_left = lat[0] > lat[1]
        sides[pair[0]] = "l" if first_left else "r"
        sides[pair[1]] = "r" if first_left else "l"

    weights = np.zeros((len(JOINT_NAMES), n))
    how = {}

    def put(joint, point, why):
        weights[JOINT_INDEX[joint]] = 0.0
        weights[JOINT_INDEX[joint], point] = 1.0
        how[joint] = (tree.names[point], why)

    for keys, joints in ((leg_keys, ("hip", "knee", "ankle", "toes")),
                         (arm_keys, ("shoulder", "elbow", "wrist", "fingers"))):
        for key in keys:
            s = sides[key]
            top, mid, end, tip, why = limb[key][1]
            for joint, point in zip(joints, (top, mid, end)):
                put(f"{s}{joint}", point, why)
            put(f"{s}{joints[3]}", tip, "leaf")
    arm_attach = {sides[("arm", first)]: (attach, first) for attach, first in arms}

    put("root", pelvis, "pelvis: common ancestor of the feet")
    # head top: the highest leaf; head: the joint named Head on the spine path, else
    # the last distinct joint before the head top
    sp = _distinct(tree, spine, tol)
    put("headtop", sp[-1], "highest leaf")
    heads = [i for i in sp[:-1] if tree.is_joint[i] and normalized_name(tree.names[i]) in _HEAD]
    if heads:
        put("head", heads[-1], "names")
    elif len(sp) >= 2:
        put("head", sp[-2], "last joint below the head top")
    # neck: the first joint of the head's branch at the point the arms branch off
    # (where the ASF clavicles start), unless that joint is the head itself
    fork = max(spine.index(a) for a, _ in arms)
    head_node = int(np.argmax(weights[JOINT_INDEX["head"]]))
    branch = spine[fork + 1] if fork + 1 < len(spine) else None
    if branch is not None and tree.is_joint[branch] and branch != head_node and branch != sp[-1]:
        put("neck", branch, "first joint of the head's branch")
    else:
        a, b = arm_attach["l"][1], arm_attach["r"][1]
        weights[JOINT_INDEX["neck"]] = 0.0
        weights[JOINT_INDEX["neck"], a] += 0.5
        weights[JOINT_INDEX["neck"], b] += 0.5
        how["neck"] = ([tree.names[a], tree.names[b]], "between the clavicle joints")
    for s in "lr":
        weights[JOINT_INDEX[f"{s}clavicle"]] = weights[JOINT_INDEX["neck"]]
        how[f"{s}clavicle"] = how["neck"]
    # belly and chest at 1/3 and 2/3 of the spine from the pelvis to the neck
    neck_node = int(np.argmax(weights[JOINT_INDEX["neck"]]))
    neck_pos = weights[JOINT_INDEX["neck"]] @ rest
    upto = spine[:spine.index(neck_node) + 1] if neck_node in on_spine else spine[:fork + 1]
    pts = _distinct(tree, upto, tol)
    poly = [rest[i] for i in pts]
    nodes = list(pts)
    if np.linalg.norm(poly[-1] - neck_pos) > tol:
        poly.append(neck_pos)
        nodes.append(None)
    seg = [float(np.linalg.norm(poly[i + 1] - poly[i])) for i in range(len(poly) - 1)]
    total = sum(seg)
    if total <= tol:
        raise MappingError("the spine has no length (neck at the pelvis)", ["belly", "chest"], how)
    for joint, frac in (("belly", 1 / 3), ("chest", 2 / 3)):
        target = frac * total
        acc = 0.0
        for i, L in enumerate(seg):
            if acc + L >= target or i == len(seg) - 1:
                u = min(max((target - acc) / L, 0.0), 1.0) if L > 0 else 0.0
                row = np.zeros(n)
                row[nodes[i]] += 1.0 - u
                if nodes[i + 1] is None:
                    row += u * weights[JOINT_INDEX["neck"]]
                else:
                    row[nodes[i + 1]] += u
                weights[JOINT_INDEX[joint]] = row
                how[joint] = (None, f"at {frac * 3:.0f}/3 of the spine from the pelvis to the neck")
                break
            acc += L
    return JointMap(weights, int(pelvis), how)


def hip_axis_is_x(hip_axis) -> bool:
    """True when a hip axis (lhip − rhip), expressed in the pelvis's own frame,
    runs along +x (within 20°): the ASF root convention feature #40 relies on."""
    a = np.asarray(hip_axis, dtype=np.float64)
    norm = float(np.linalg.norm(a))
    return bool(norm > 0 and a[0] / norm > np.cos(np.radians(20.0)))


def mapping_template(tree: SkeletonTree, partial: dict | None = None, *, source: str = "") -> str:
    """A ready-to-edit TOML joint map: every canonical joint, filled where placed.

    ``partial`` maps canonical joints to ``(name or [names], why)``; the file's
    own joints are listed in a comment.
    """
    partial = partial or {}
    lines = [f"# mocapdb joint map{' for ' + source if source else ''}",
             "# canonical joint = \"the file's joint\" (its origin), \"Joint/end\" (its End Site),",
             "# or [\"A\", \"B\"] (the point between them). Use with: mocapdb ingest --joint-map FILE",
             "# the file's joints: " + ", ".join(nm for nm, j in zip(tree.names, tree.is_joint) if j)]
    for j in JOINT_NAMES:
        name, why = partial.get(j, (None, None))
        if isinstance(name, list):
            lines.append(f"{j} = [" + ", ".join(f'"{x}"' for x in name) + "]")
        elif name is not None:
            lines.append(f'{j} = "{name}"')
        elif why is not None:
            lines.append(f'# {j}: {why} (automatic; name a joint to override)')
        else:
            lines.append(f'# {j} = ""   # could not place: fill in')
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------
# is it a human?

#: proportions a human body keeps, as (lowest, highest) ratio to the leg length (hip → knee →
#: ankle); measured 0.58–0.72 (arms), 0.28–0.65 (trunk), 0.18–0.28 (hips), 0.32–0.60 (shoulders)
#: on the HDM05, CMU and other labs' human rigs of the test data, with wide margins: a quadruped's
#: trunk is longer than its legs, a bird's hips are wider
HUMAN_PROPORTIONS = {"arm": (0.35, 1.0), "trunk": (0.2, 1.1), "hip width": (0.05, 0.6),
                     "shoulder width": (0.15, 0.9)}
#: a human stands upright in at least this fraction of a take's frames, or in its rest pose
MIN_UPRIGHT = 0.05
#: frames sampled for the upright test
_SAMPLE = 512


#: the distances the human test measures (legs, arms, trunk, hip and shoulder width); the kernel
#: reads them by position: legs 0-3, arms 4-7, trunk 8, hip width 9, shoulder width 10
_PAIRS = (("lhip", "lknee"), ("lknee", "lankle"), ("rhip", "rknee"), ("rknee", "rankle"),
          ("lshoulder", "lelbow"), ("lelbow", "lwrist"), ("rshoulder", "relbow"), ("relbow", "rwrist"),
          ("root", "neck"), ("lhip", "rhip"), ("lshoulder", "rshoulder"))
_PAIR_A = np.array([JOINT_INDEX[a] for a, _ in _PAIRS], dtype=np.int64)
_PAIR_B = np.array([JOINT_INDEX[b] for _, b in _PAIRS], dtype=np.int64)
#: the measures of :data:`HUMAN_PROPORTIONS` in the order the kernel writes their medians
_MEASURES = ("arm", "trunk", "hip width", "shoulder width")
#: the joints the upright test reads (compile-time constants of the kernel)
_J_ROOT, _J_NECK, _J_HEAD = JOINT_INDEX["root"], JOINT_INDEX["neck"], JOINT_INDEX["head"]
_J_LSHOULDER, _J_RSHOULDER = JOINT_INDEX["lshoulder"], JOINT_INDEX["rshoulder"]
_J_LANKLE, _J_RANKLE = JOINT_INDEX["lankle"], JOINT_INDEX["rankle"]
_J_LWRIST, _J_RWRIST = JOINT_INDEX["lwrist"], JOINT_INDEX["rwrist"]
_J_LHIP, _J_RHIP = JOINT_INDEX["lhip"], JOINT_INDEX["rhip"]
#: cos 45°, as NumPy computes it: the trunk's largest angle to the vertical
_COS45 = float(np.cos(np.radians(45.0)))


@jit
def _min_nan(a, b):  # pragma: no cover - compiled
    """``np.minimum(a, b)`` of two floats: NaN when either is NaN."""
    if a != a or b != b:
        return np.nan
    return a if a <= b else b


@jit
def _human_measures_kernel(joints, step, a, b, med, upright):  # pragma: no cover - compiled
    """The human test's numbers over every ``step``-th frame of ``joints`` (issue 35: a dozen NumPy
    calls per take cost more than the arithmetic on a few hundred frames).

    ``med[0]``: the median leg (hip → knee → ankle, both sides, as :func:`~mocapdb.bodies.units.leg_length`),
    ``med[1:5]``: the median of each measure of :data:`_MEASURES`; ``upright[i]``: frame ``i·step``
    stands like a human (:func:`upright_frames`). Returns how many frames stand. Every sum is in the
    order of the NumPy expressions it replaced (``0.5 * (a + b + c + d)``: left to right), the medians
    and distances are the kernels of :mod:`~mocapdb.bodies.units`: the same floats bit for bit.
    """
    n = upright.shape[0]
    ln = np.empty((n, a.shape[0]))
    _pair_lengths_kernel(joints, step, a, b, ln)
    legs = np.empty((2 * n, 1))
    measures = np.empty((n, 4))
    stands = 0
    for i in range(n):
        legs[i, 0] = ln[i, 0] + ln[i, 1]
        legs[n + i, 0] = ln[i, 2] + ln[i, 3]
        measures[i, 0] = 0.5 * (ln[i, 4] + ln[i, 5] + ln[i, 6] + ln[i, 7])
        measures[i, 1] = ln[i, 8]
        measures[i, 2] = ln[i, 9]
        measures[i, 3] = ln[i, 10]
        f = i * step
        leg = 0.5 * (ln[i, 0] + ln[i, 1] + ln[i, 2] + ln[i, 3])
        sx = joints[f, _J_NECK, 0] - joints[f, _J_ROOT, 0]
        sy = joints[f, _J_NECK, 1] - joints[f, _J_ROOT, 1]
        sz = joints[f, _J_NECK, 2] - joints[f, _J_ROOT, 2]
        vertical = sy > _COS45 * math.sqrt(sx * sx + sy * sy + sz * sz)
        head_up = joints[f, _J_HEAD, 1] > 0.5 * (joints[f, _J_LSHOULDER, 1] + joints[f, _J_RSHOULDER, 1])
        feet = _min_nan(joints[f, _J_LANKLE, 1], joints[f, _J_RANKLE, 1])
        hands = _min_nan(joints[f, _J_LWRIST, 1], joints[f, _J_RWRIST, 1])
        hips = _min_nan(joints[f, _J_LHIP, 1], joints[f, _J_RHIP, 1])
        upright[i] = vertical and head_up and hands - feet > 0.25 * leg and feet < hips
        stands += upright[i]
    _column_medians_kernel(legs, med[:1])
    _column_medians_kernel(measures, med[1:])
    return stands


def _human_measures(joints, step: int = 1) -> tuple:
    """``(median leg, {measure: median}, per-frame upright, the fraction of frames upright)`` over every
    ``step``-th frame of ``joints`` ((n, 24, 3), Y up): :func:`_human_measures_kernel`."""
    j = np.asarray(joints, dtype=np.float64)
    med = np.empty(5)
    upright = np.empty((len(j) + step - 1) // step, dtype=np.bool_)
    stands = _human_measures_kernel(j, step, _PAIR_A, _PAIR_B, med, upright)
    # count / n: the float np.mean of the booleans gives (an exact sum divided once)
    fraction = stands / len(upright) if len(upright) else float("nan")
    return float(med[0]), dict(zip(_MEASURES, med[1:].tolist())), upright, fraction


def upright_frames(joints: np.ndarray) -> np.ndarray:
    """Per frame: does the body stand like a human — two legs to the floor, two arms off it, the
    head above the shoulders, the trunk within 45° of vertical (Y up)?

    Parameters
    ----------
    joints : ndarray, shape (n_frames, 24, 3)

    Returns
    -------
    ndarray, shape (n_frames,), bool
    """
    return _human_measures(joints)[2]


def _proportions(med, leg) -> dict:
    """Each measure of :data:`HUMAN_PROPORTIONS` per the median leg ``leg``, from the medians ``med``
    (:func:`_human_measures`)."""
    return {what: med[what] / leg for what in HUMAN_PROPORTIONS}


def _proportion_problems(med, leg) -> list:
    """The measures ``(what, ratio, lo, hi)`` of the medians ``med`` outside :data:`HUMAN_PROPORTIONS`."""
    return [(what, ratio, *HUMAN_PROPORTIONS[what]) for what, ratio in _proportions(med, leg).items()
            if not HUMAN_PROPORTIONS[what][0] <= ratio <= HUMAN_PROPORTIONS[what][1]]


def humanoid_problem(joints: np.ndarray, rest: np.ndarray | None = None, *, leg: float | None = None) -> tuple | None:
    """Why a mapped skeleton is not a human, or None when it is one.

    A human has plausible proportions (:data:`HUMAN_PROPORTIONS`, from the
    median bone lengths) and stands upright (:func:`upright_frames`) in its
    rest pose or in at least :data:`MIN_UPRIGHT` of the take's frames.
    Distances across joints (root → neck) change with the pose: where the
    rest pose has a human's proportions and only the take's frames miss
    them, it is the pose that is not a human's (a trunk folded to a tenth of
    the leg), and the reason says so rather than blaming the skeleton that
    other takes share.

    Parameters
    ----------
    joints : ndarray, shape (n_frames, 24, 3)
        The canonical joints of the take, Y up.
    rest : ndarray, shape (24, 3), optional
        The canonical joints in the skeleton's rest pose, Y up.
    leg : float, optional, keyword-only
        ``leg_length(joints)`` when the caller has it (the BVH reader decides the unit on it): used when
        the test sees every frame (a take under 2 × 512 frames), else measured on the frames it samples.

    Returns
    -------
    tuple or None
        ``("skeleton", why)`` or ``("pose", why)``: the message is
        ``not a human {what}: {why}``.
    """
    step = max(1, len(joints) // _SAMPLE)
    median_leg, med, _, stands = _human_measures(joints, step)
    # the one median leg: the unit of a BVH take is decided on it too
    leg = median_leg if leg is None or step > 1 else leg
    if not leg > 0:
        return "skeleton", "the legs have no length"
    problems = _proportion_problems(med, leg)
    upright = None
    if stands < MIN_UPRIGHT and (rest is None or not upright_frames(rest[None])[0]):
        upright = (f"it stands upright (two legs to the floor, arms off it, head above the shoulders) "
                   f"in {stands:.0%} of the frames and not in its rest pose")
    if not problems and upright is None:
        return None
    rest_leg, rest_med, _, _ = _human_measures(rest[None]) if rest is not None else (0.0, None, None, None)
    human_rest = rest_leg > 0 and not _proportion_problems(rest_med, rest_leg)
    if human_rest and not problems:
        # a human's skeleton keeping a human's proportions that never stands: lying, crawling, rolling
        return None
    if human_rest:
        # the skeleton has a human's proportions (other takes share it): the take's frames are what fails
        at_rest = _proportions(rest_med, rest_leg)
        why = [upright] if upright else []
        why += [f"{what} {ratio:.2f} × the leg length over the take's frames, {at_rest[what]:.2f} in its rest pose "
                f"(a human's: {lo}–{hi})" for what, ratio, lo, hi in problems]
        return "pose", "; ".join(why) + " — the skeleton has a human's proportions at rest: it is the take's poses"
    reasons = [upright] if upright else []
    reasons += [f"{what} {ratio:.2f} × the leg length (a human's: {lo}–{hi})" for what, ratio, lo, hi in problems]
    return "skeleton", "; ".join(reasons)
