"""Read any supported motion file into a :class:`~mocapdb.readers.motion.Motion`.

:func:`read_motion` dispatches on the extension (``.amc`` with its ASF
skeleton, ``.bvh``); :func:`find_skeleton` implements the dataset
conventions for locating the ASF of an AMC file.

References
----------
DESIGN.md §1, §6; data/README.md (file conventions).
"""
from __future__ import annotations

import os
import re
import threading
from pathlib import Path

import numpy as np

from mocapdb.readers.amc import read_amc
from mocapdb.readers.asf import Skeleton, read_asf
from mocapdb.readers.bvh import read_bvh
from mocapdb.readers.c3d import read_c3d
from mocapdb.errors import MocapdbError, ParseError
from mocapdb.readers.kinematics import asf_forward_kinematics
from mocapdb.readers.mapping import load_mapping
from mocapdb.readers.motion import Motion, check_finite_motion

__all__ = ["read_motion", "read_asf_amc", "find_skeleton", "skeleton_candidates",
           "load_skeleton", "SUPPORTED_EXTENSIONS"]

SUPPORTED_EXTENSIONS = (".amc", ".bvh", ".c3d")

_CMU_TAKE = re.compile(r"^(\d+)_\d+$")
_HDM_TAKE = re.compile(r"^HDM_([A-Za-z]+)_")


def skeleton_candidates(amc_path) -> list:
    """Where :func:`find_skeleton` looks, in order of preference.

    1. the same stem: ``walk.amc`` -> ``walk.asf``;
    2. a CMU take's subject skeleton in the same folder: ``02_01.amc`` -> ``02.asf``;
    3. an HDM05 actor skeleton ``HDM_<actor>.asf`` in the same folder, then in
       the parent folder (``hdm05_cut/<class>/HDM_bd_...amc`` ->
       ``hdm05_cut/HDM_bd.asf``);
    4. the folder's only ASF, when it holds exactly one (other writers' takes
       follow no name pattern).
    """
    p = Path(amc_path)
    d = p.parent
    stem = p.stem
    out = [d / f"{stem}.asf"]
    m = _CMU_TAKE.match(stem)
    if m:
        out.append(d / f"{m.group(1)}.asf")
    m = _HDM_TAKE.match(stem)
    if m:
        out.append(d / f"HDM_{m.group(1)}.asf")
        out.append(d.parent / f"HDM_{m.group(1)}.asf")
    try:
        own = [q for q in d.iterdir() if q.suffix.lower() == ".asf" and q.is_file()]
    except OSError:
        own = []
    if len(own) == 1 and own[0] not in out:
        out.append(own[0])
    return out


def find_skeleton(amc_path) -> Path | None:
    """The ASF skeleton of an AMC file by the dataset conventions, or None.

    See :func:`skeleton_candidates` for the rules; ``.ASF`` in upper case is
    accepted too.
    """
    for c in skeleton_candidates(amc_path):
        for cand in (c, c.with_suffix(".ASF")):
            if cand.is_file():
                return cand
    return None


# Skeletons are re-read for every take of an actor during ingest; cache them by
# file identity (path, size, mtime). Skeleton objects are immutable.
_ASF_CACHE: dict = {}
_ASF_LOCK = threading.Lock()


def load_skeleton(asf) -> Skeleton:
    """A :class:`Skeleton` from a path (cached by file identity) or a Skeleton."""
    if isinstance(asf, Skeleton):
        return asf
    p = Path(asf)
    st = os.stat(p)
    key = (str(p.resolve()), st.st_size, st.st_mtime_ns)
    with _ASF_LOCK:
        hit = _ASF_CACHE.get(key)
    if hit is None:
        hit = read_asf(p)
        with _ASF_LOCK:
            if len(_ASF_CACHE) > 64:
                _ASF_CACHE.clear()
            _ASF_CACHE[key] = hit
    return hit


def read_asf_amc(amc_path, asf) -> Motion:
    """Read an AMC file with an explicit skeleton (path or :class:`Skeleton`)."""
    amc_path = Path(amc_path)
    skel = load_skeleton(asf)
    amc = read_amc(amc_path, skel)
    joints, rot = asf_forward_kinematics(skel, amc)
    # an absurd root translation or ASF unit overflows to inf in FK (READERS.md §4)
    check_finite_motion(joints, amc_path)
    asf_path = skel.path if isinstance(asf, Skeleton) else str(asf)
    return Motion(joints=joints, root_rotation=rot, fps=amc.fps, name=amc_path.stem,
                  skeleton=Path(asf_path).stem or skel.name, source_format="amc",
                  meta={"asf": asf_path, "asf_name": skel.name})


def read_motion(path, *, asf=None, joint_map=None, marker_map=None) -> Motion:
    """Read a motion file (by extension) into the 24 canonical joints.

    Parameters
    ----------
    path : str or Path
        ``.amc`` (Acclaim motion; needs a skeleton), ``.bvh`` or ``.c3d``.
    asf : str, Path or Skeleton, optional, keyword-only
        Skeleton of an AMC file; default: :func:`find_skeleton`. Ignored for BVH.
    joint_map : dict, str or Path, optional, keyword-only
        BVH only: canonical joint → the file's joint(s), overriding the
        automatic mapping (:func:`~mocapdb.readers.mapping.load_mapping`).
    marker_map : dict, str or Path, optional, keyword-only
        C3D only: canonical joint → the markers whose mean it is
        (:func:`~mocapdb.readers.c3d.read_c3d`).

    Returns
    -------
    Motion
        ``name`` = file stem; ``skeleton`` = the ASF file stem (e.g.
        ``"HDM_bd"``, ``"02"``: the ASF ``:name`` is ``"VICON"`` in every CMU
        and HDM05 file, so it would not tell skeletons apart; it is kept in
        ``meta["asf_name"]``) or ``"bvh:<family>"``; ``meta["asf"]`` = the ASF path.

    Raises
    ------
    ParseError
        Malformed file (file, line and what was expected), an unsupported
        extension, or an AMC whose skeleton cannot be found.
    FileNotFoundError

    References
    ----------
    DESIGN.md §1, §6; FEATURES.md §2.
    """
    path = Path(path)
    try:
        # hostile values overflow in FK; the result is checked for finiteness
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return _read(path, asf, joint_map, marker_map)
    except MocapdbError:
        raise
    except OSError as exc:
        raise ParseError(path, None, f"cannot read the file ({exc.strerror or exc})") from None
    except (MemoryError, RecursionError, ValueError, ArithmeticError, IndexError, KeyError, TypeError) as exc:
        # READERS.md §4: nothing but a MocapdbError leaves a reader. Known
        # malformations raise ParseErrors with a position; this is the net for
        # the ones nobody foresaw
        raise ParseError(path, None, f"unreadable ({type(exc).__name__}: {exc})") from None


def _read(path, asf, joint_map, marker_map) -> Motion:
    ext = path.suffix.lower()
    if ext == ".amc":
        if asf is None:
            asf = find_skeleton(path)
            if asf is None:
                looked = ", ".join(str(c) for c in skeleton_candidates(path))
                raise ParseError(path, None, f"no ASF skeleton found (looked for {looked}); give the "
                                 "skeleton: --asf FILE (command line) or asf=FILE (Python). A CMU take "
                                 "without its subject's ASF reads with any CMU subject's ASF (the bones "
                                 "are the same; their lengths approximate).")
        return read_asf_amc(path, asf)
    if ext == ".bvh":
        return read_bvh(path, joint_map=load_mapping(joint_map, what="joint_map"))
    if ext == ".c3d":
        return read_c3d(path, marker_map=load_mapping(marker_map, what="marker_map"))
    raise ParseError(path, None, f"unsupported file type {path.suffix!r} (expected "
                     + " or ".join(SUPPORTED_EXTENSIONS) + ")")
