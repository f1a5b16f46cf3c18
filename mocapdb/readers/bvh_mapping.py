"""Where the 24 canonical joints are in a BVH skeleton: the joint map of a parsed hierarchy.

* files written with ASF bone names (:func:`mocapdb.writers.bvh_write.write_bvh`)
  take the exact ASF points;
* any other humanoid goes through :func:`mocapdb.bodies.humanoid.map_humanoid`
  (names first, else topology; a rest pose on its side is judged by a frame
  of the motion; a Z-up rig is turned to Y up);
* a user ``joint_map`` overrides either.

A plan that the hierarchy alone decides is cached per parsed hierarchy (the
files of one skeleton share it); one that needed a frame of the motion is
not: a file reads the same whatever was read before it.
"""
from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np

from mocapdb.errors import ParseError
from mocapdb.bodies.humanoid import Z_UP_TO_Y_UP, JointMap, MappingError, SkeletonTree, map_humanoid
from mocapdb.bodies.joints import JOINT_INDEX, JOINT_NAMES
from mocapdb.bodies.kinematics import ASF_JOINT_BONES

__all__ = ["bvh_joint_map", "plan", "auto_map"]


def _asf_map(hier: BvhHierarchy, tree: SkeletonTree) -> JointMap | None:
    """The exact ASF points when the file uses ASF bone names (our writer)."""
    names = {nm.lower(): k for k, nm in enumerate(tree.names)}
    need = set(ASF_JOINT_BONES.values()) | {"root"}
    if not need <= names.keys():
        return None
    weights = np.zeros((len(JOINT_NAMES), tree.n))
    how = {}
    for j in JOINT_NAMES:
        bone = ASF_JOINT_BONES[j]
        if j == "root":
            point = names["root"]
        else:
            k = names[bone]
            # a bone's tip: its End Site, or the origin of its first child joint
            point = names.get(f"{bone}/end")
            if point is None:
                kids = hier.children(k)
                if not kids:
                    return None
                point = kids[0]
        weights[JOINT_INDEX[j], point] = 1.0
        how[j] = (tree.names[point], "ASF bone names")
    return JointMap(weights, names["root"], how)


def _user_map(tree: SkeletonTree, joint_map: dict, auto: JointMap | None, path) -> JointMap:
    names = {nm.lower(): k for k, nm in enumerate(tree.names)}
    weights = np.zeros((len(JOINT_NAMES), tree.n)) if auto is None else auto.weights.copy()
    how = {} if auto is None else dict(auto.how)
    for j, value in joint_map.items():
        items = [value] if isinstance(value, str) else value
        row = np.zeros(tree.n)
        for item in items:
            k = names.get(item.lower())
            if k is None:
                raise ParseError(path, None, f"joint_map: {j} = {item!r}: no such joint in this file "
                                 f"(its joints: {', '.join(n for n, jt in zip(tree.names, tree.is_joint) if jt)}"
                                 "; an End Site is 'Joint/end')")
            row[k] += 1.0 / len(items)
        weights[JOINT_INDEX[j]] = row
        how[j] = (value, "joint_map")
    missing = [j for j in JOINT_NAMES if not weights[JOINT_INDEX[j]].any()]
    if missing:
        raise ParseError(path, None, f"joint_map places {len(JOINT_NAMES) - len(missing)} of 24 joints and "
                         f"the automatic mapping failed; add {', '.join(missing)}")
    root = joint_map.get("root")
    if isinstance(root, str):
        rot_point = names[root.lower()]
    else:
        rot_point = auto.rotation_point if auto is not None else 0
    if not tree.is_joint[rot_point]:
        rot_point = int(tree.parent[rot_point])
    return JointMap(weights, rot_point, how)


_MAP_CACHE: dict = {}
_MAP_LOCK = threading.Lock()


def bvh_joint_map(hier: BvhHierarchy, *, joint_map: dict | None = None, path="<bvh>", pose=None) -> JointMap:
    """Where the 24 canonical joints are in a BVH skeleton.

    ``pose`` (a callable giving the points of one motion frame) is used when
    the rest pose is not an upright body.

    Raises
    ------
    ParseError
        Not a humanoid the mapper can read, and no complete ``joint_map``:
        the message names the file's joints and the canonical joints it
        could not place, and how to get a mapping template.
    """
    return plan(hier, joint_map, path, pose)[0]


def plan(hier: BvhHierarchy, joint_map, path, pose):
    """(JointMap, gather arrays, joints FK must compute).

    A plan that the hierarchy alone decides (names, or the rest pose) is
    cached per parsed hierarchy (hierarchies are cached per header, so the
    files of one skeleton share it); one that needed a frame of the motion
    (a rest pose lying on its side) belongs to its file and is not cached:
    a file reads the same whatever was read before it.
    """
    key = (id(hier), None if joint_map is None else repr(sorted(joint_map.items())))
    with _MAP_LOCK:
        hit = _MAP_CACHE.get(key)
    if hit is not None and hit[0] is hier:
        return hit[1]
    jm, from_motion = _map_skeleton(hier, joint_map, path, pose)
    plan = (jm, *_gather(jm, hier))
    if not from_motion:
        with _MAP_LOCK:
            if len(_MAP_CACHE) > 256:
                _MAP_CACHE.clear()
            _MAP_CACHE[key] = (hier, plan)
    return plan


def _gather(jm: JointMap, hier: BvhHierarchy):
    """Per canonical joint its points and weights; the joints FK needs (used points and their ancestors)."""
    nj = len(hier.joints)
    width = max(1, int((jm.weights != 0).sum(axis=1).max()))
    point = np.zeros((len(JOINT_NAMES), width), dtype=np.int64)
    weight = np.zeros((len(JOINT_NAMES), width))
    for j in range(len(JOINT_NAMES)):
        nz = np.flatnonzero(jm.weights[j])
        point[j, :len(nz)] = nz
        weight[j, :len(nz)] = jm.weights[j, nz]
    end_of = np.array([k for k, j in enumerate(hier.joints) if j.end_site is not None] or [0], dtype=np.int64)
    needed = np.zeros(nj, dtype=np.bool_)
    for p in set(point[weight != 0].tolist()) | {jm.rotation_point}:
        k = p if p < nj else int(end_of[p - nj])
        while k >= 0 and not needed[k]:
            needed[k] = True
            k = hier.joints[k].parent
    return point, weight, end_of, needed


def auto_map(hier: BvhHierarchy, tree: SkeletonTree, pose=None):
    """(JointMap or None, the MappingError of the first failure or None, whether a motion frame
    decided it): ASF bone names exactly, else the humanoid mapper — Y up, as BVH has it; a rest
    pose on its side judged by a frame of the motion (``pose``); a Z-up file turned to Y up."""
    exact = _asf_map(hier, tree)
    if exact is not None:
        return exact, None, False

    def poses():
        yield tree.rest, False
        if pose is not None:
            yield pose(), True

    problem = None
    for up in (None, Z_UP_TO_Y_UP):
        for xyz, from_motion in poses():
            try:
                found = map_humanoid(tree, xyz if up is None else xyz @ up.T)
            except MappingError as exc:
                problem = problem or exc
                continue
            return (found if up is None else replace(found, up=up)), None, from_motion
    return None, problem, False


def _map_skeleton(hier, joint_map, path, pose):
    """(JointMap, whether a motion frame decided it)."""
    tree = hier.tree()
    auto, problem, from_motion = auto_map(hier, tree, pose)
    if joint_map:
        return _user_map(tree, joint_map, auto, path), from_motion
    if auto is None:
        own = [n for n, j in zip(tree.names, tree.is_joint) if j]
        missing = problem.missing or [j for j in JOINT_NAMES if j not in problem.partial]
        raise ParseError(path, None, f"not a humanoid skeleton mocapdb can map: {problem}; "
                         f"its {len(own)} joints: {', '.join(own[:40])}{' …' if len(own) > 40 else ''}; "
                         f"could not place: {', '.join(missing)}. Write a joint map (template: "
                         f"mocapdb joint-map-template {path} > map.toml) and ingest with --joint-map map.toml")
    return auto, from_motion
