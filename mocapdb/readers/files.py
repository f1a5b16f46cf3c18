"""Read any supported motion file into a :class:`~mocapdb.bodies.motion.Motion`.

:func:`read_motion` dispatches on the extension (``.amc`` with its ASF
skeleton, ``.bvh``, ``.c3d``, AMASS ``.npz``; each also compressed or inside a
zip archive, :mod:`~mocapdb.readers.sources`); :func:`find_skeleton` implements the
dataset conventions for locating the ASF of an AMC file.

References
----------
DESIGN.md §1, §6; READERS.md §5, §7, §9.
"""
from __future__ import annotations

import os
import re
import time
from pathlib import Path

import numpy as np

from mocapdb.errors import MocapdbError, ParameterError, ParseError
from mocapdb.readers.amass import read_amass
from mocapdb.readers.amc import read_amc
from mocapdb.bodies.acclaim import Skeleton
from mocapdb.readers.asf import read_asf
from mocapdb.bodies.asf_humanoid import asf_humanoid_joints
from mocapdb.readers.bvh import read_bvh
from mocapdb.readers.bvh_head import MAX_HEADER_LINE, check_bvh_start
from mocapdb.readers.c3d import read_c3d
from mocapdb.bodies.humanoid import MappingError
from mocapdb.bodies.kinematics import asf_forward_kinematics, joint_node_indices, node_positions
from mocapdb.bodies.motion import Motion, check_finite_motion
from mocapdb.readers.textscan import has_line_longer
from mocapdb.readers.options import ReaderOptions
from mocapdb.readers.sources import (COMPRESSED, FileCache, as_path, is_file, list_dir, max_decompressed, motion_stem,
                                     motion_suffix, open_stream, special_kind, split_archive)

__all__ = ["read_motion", "read_asf_amc", "find_skeleton", "skeleton_candidates", "skeleton_note",
           "load_skeleton", "SUPPORTED_EXTENSIONS"]

SUPPORTED_EXTENSIONS = (".amc", ".bvh", ".c3d", ".npz")

_CMU_TAKE = re.compile(r"^(\d+)_\d+$")
_HDM_TAKE = re.compile(r"^HDM_([A-Za-z]+)_")


#: bytes of a text recording read to decide whether it can be one, before it is hashed or read whole
START_BYTES = 1 << 16


def check_start(path) -> None:
    """Refuse a text recording (BVH, AMC, ASF) that cannot be one from its first bytes.

    A file whose first line never ends (500 MiB of NUL bytes as a 0.5 MB ``.bvh.gz``) took minutes and
    gigabytes to refuse; its first :data:`START_BYTES` say enough: a BVH must start with ``HIERARCHY``,
    and no line of a BVH header, an AMC or an ASF is longer than :data:`MAX_HEADER_LINE` bytes.
    ``ingest`` asks this before hashing a file, :func:`read_motion` before reading it.

    Raises
    ------
    ParseError
        Naming the file and what its start shows.
    OSError
        The file cannot be read (or decompresses past the cap).
    """
    ext = motion_suffix(path)
    if ext not in (".bvh", ".amc", ".asf"):
        return
    key = _start_key(path)
    if key is not None and key in _STARTS_PASSED:
        return
    with open_stream(path) as fh:   # an OSError (unreadable, over the cap) is the caller's to word
        head = fh.read(START_BYTES)
    if ext == ".bvh":
        check_bvh_start(head, path)
    elif has_line_longer(head, MAX_HEADER_LINE):
        raise ParseError(path, None, f"a line longer than {MAX_HEADER_LINE:,} bytes within its first "
                         f"{START_BYTES:,} (an {ext[1:].upper()} file's lines are short: not an {ext[1:].upper()} "
                         "file?)")
    if key is not None:
        if len(_STARTS_PASSED) >= 4096:
            _STARTS_PASSED.clear()
        _STARTS_PASSED.add(key)


#: files whose start passed :func:`check_start`, by path, size, mtime and the decompression cap: ingest
#: checks a take before hashing it and again before reading it, in the same process when on threads
_STARTS_PASSED = set()


def _start_key(path):
    """The key of a plain (or compressed) file for :data:`_STARTS_PASSED`, or None: a zip member, a file
    that cannot be looked at, or one changed in the last two seconds (a change within the file system's
    clock tick would leave its mtime as it was)."""
    if split_archive(path)[1] is not None:
        return None
    try:
        st = os.stat(path)
    except OSError:
        return None
    if time.time_ns() - st.st_mtime_ns < _RACY_NS:
        return None
    return str(path), st.st_size, st.st_mtime_ns, max_decompressed()


def skeleton_candidates(amc_path) -> list:
    """Where :func:`find_skeleton` looks, in order of preference.

    1. the same stem: ``walk.amc`` -> ``walk.asf``;
    2. a CMU take's subject skeleton in the same folder: ``02_01.amc`` -> ``02.asf``;
    3. an HDM05 actor skeleton ``HDM_<actor>.asf`` in the same folder, then in
       the parent folder (``hdm05_cut/<class>/HDM_bd_...amc`` ->
       ``hdm05_cut/HDM_bd.asf``);
    4. the folder's only ASF, when it holds exactly one (other writers' takes
       follow no name pattern).

    The folder may lie inside a zip archive (:mod:`~mocapdb.readers.sources`);
    a candidate may be compressed (``walk.asf.gz``).
    """
    out = _named_candidates(amc_path)
    own = _folder_asf(Path(amc_path).parent)
    if own is not None and own not in out:
        out.append(own)
    return out


def _named_candidates(amc_path) -> list:
    """Rules 1–3 of :func:`skeleton_candidates`: the name patterns."""
    return [folder / name for folder, name in _named_places(amc_path)]


def _named_places(amc_path) -> list:
    """:func:`_named_candidates` as ``(folder, name)`` pairs (no path built per candidate)."""
    p = as_path(amc_path)
    d = p.parent
    stem = motion_stem(p)
    out = [(d, f"{stem}.asf")]
    m = _CMU_TAKE.match(stem)
    if m:
        out.append((d, f"{m.group(1)}.asf"))
    m = _HDM_TAKE.match(stem)
    if m:
        out.append((d, f"HDM_{m.group(1)}.asf"))
        out.append((d.parent, f"HDM_{m.group(1)}.asf"))
    return out


def _folder_asf(folder):
    """The folder's only ASF (plain or compressed), or None (listed once per folder and version: an
    archive's folder of thousands of takes is not listed again for each take)."""
    try:
        st = os.stat(split_archive(folder)[0])   # the folder, or the zip archive it lies in
    except OSError:
        st = None
    key = None if st is None else (str(folder), st.st_size, st.st_mtime_ns)
    if key is None or key not in _FOLDER_ASF:
        own = [q for q in list_dir(folder) if motion_suffix(q) == ".asf" and is_file(q)]
        own = own[0] if len(own) == 1 else None
        if key is None:
            return own
        if len(_FOLDER_ASF) >= 256:
            _FOLDER_ASF.clear()
        _FOLDER_ASF[key] = own
    return _FOLDER_ASF[key]


#: folder -> its only ASF or None, keyed with the folder's (or its zip archive's) size and mtime, which
#: change when entries come or go
_FOLDER_ASF = {}


class _Names:
    """The entry names of a folder, to rule out candidates without a ``stat`` each (an archive's AMC takes
    asked ~10 each: a sixth of a short take's reading)."""

    def __init__(self, names):
        self.names = frozenset(names)
        self.folded = frozenset(n.lower() for n in self.names)

    def may_hold(self, name: str) -> bool:
        """False only when no entry can be ``name``: on a case-insensitive file system a differently cased
        entry answers too, so those (and any non-ASCII name, which such a system may also normalise) are
        still probed."""
        return name in self.names or not name.isascii() or name.lower() in self.folded


#: folder -> ((size, mtime), its _Names); like _FOLDER_ASF
_FOLDER_NAMES = {}
#: a folder (or file) changed this recently is not cached: a change within the file system's clock tick
#: after the look would leave its mtime as it was (git's "racy" files)
_RACY_NS = 2_000_000_000


def _entry_names(folder) -> _Names | None:
    """The names in a plain folder (listed once while it does not change), or None: unreadable, inside a
    zip archive, or changed in the last two seconds (then every candidate is probed)."""
    try:
        st = os.stat(folder)
    except OSError:   # also a folder inside a zip archive: its members are probed
        return None
    key, version = str(folder), (st.st_size, st.st_mtime_ns)
    hit = _FOLDER_NAMES.get(key)
    if hit is not None and hit[0] == version:
        return hit[1]
    if time.time_ns() - st.st_mtime_ns < _RACY_NS:
        return None
    try:
        names = _Names(os.listdir(folder))
    except OSError:
        return None
    if len(_FOLDER_NAMES) >= 256:
        _FOLDER_NAMES.clear()
    _FOLDER_NAMES[key] = (version, names)
    return names


def find_skeleton(amc_path) -> Path | None:
    """The ASF skeleton of an AMC file by the dataset conventions, or None.

    See :func:`skeleton_candidates` for the rules; ``.ASF`` in upper case and
    compressed skeletons (``.asf.gz``, ``.bz2``, ``.xz``) are accepted too.
    The folder is listed (rule 4) only when no name pattern matches.
    """
    places = _named_places(amc_path)
    for folder, name in places:
        names = _entry_names(folder)
        # the spellings are ruled out by name against the folder's listing before a path is built
        for spelling in (name, name[:-4] + ".ASF", *(name + z for z in COMPRESSED)):
            if names is not None and not names.may_hold(spelling):
                continue
            cand = folder / spelling
            if is_file(cand):
                return cand
    own = _folder_asf(as_path(amc_path).parent)
    return own if own is not None and own not in [folder / name for folder, name in places] else None


def skeleton_note(amc_path, asf_path) -> str | None:
    """The ingest note when ``asf_path`` is the AMC's folder's only ASF, found by no name pattern."""
    own = _folder_asf(as_path(amc_path).parent)
    if own is None or as_path(asf_path) != own or any(motion_stem(own) == motion_stem(c)
                                                   and own.parent == c.parent
                                                   for c in _named_candidates(amc_path)):
        return None
    return f"skeleton {own.name}: the folder's only ASF (no name pattern matched {Path(amc_path).name})"


# Skeletons are re-read for every take of an actor during ingest; cache them by
# file identity (path, size, mtime; an archive member's CRC). Skeleton objects are immutable.
_ASF_CACHE = FileCache(64)


def load_skeleton(asf) -> Skeleton:
    """A :class:`Skeleton` from a path (cached by file identity) or a Skeleton."""
    if isinstance(asf, Skeleton):
        return asf
    return _ASF_CACHE.get(as_path(asf), read_asf)


def read_asf_amc(amc_path, asf) -> Motion:
    """Read an AMC file with an explicit skeleton (path or :class:`Skeleton`).

    A skeleton with the CMU bone names gives the toolbox's joints (bone tips by
    name); any other is read through the humanoid mapper
    (:mod:`~mocapdb.bodies.asf_humanoid`) and must be a human.
    """
    amc_path = as_path(amc_path)
    asf_path = asf.path if isinstance(asf, Skeleton) else str(asf)
    try:
        skel = load_skeleton(asf)
    except OSError as exc:
        # the skeleton is the file that could not be read: name it
        raise ParseError(asf_path, None, f"cannot read the skeleton of {amc_path} "
                         f"({exc.strerror or exc})") from None
    amc = read_amc(amc_path, skel)
    notes = [f"ASF {note}" for note in skel.notes]
    if amc.meta.get("fps_source") == "the ASF's :documentation":
        notes.append(f"rate {amc.fps:g} Hz from the ASF's :documentation (the AMC has no :SAMPLES-PER-SECOND)")
    try:
        nodes = joint_node_indices(skel)
    except ParameterError:
        nodes = None
    if nodes is not None:
        joints, rot = asf_forward_kinematics(skel, amc)
        how = "CMU bone names"
    else:
        try:
            positions, rot = node_positions(skel, amc)
            joints, rot, _, problem = asf_humanoid_joints(skel, positions, rot)
        except MappingError as exc:
            raise ParseError(asf_path, None, f"the skeleton of {amc_path.name} lacks the CMU bone names "
                             f"and is not a humanoid mocapdb can map: {exc}") from None
        if problem:
            what, why = problem
            raise ParseError(amc_path, None, f"not a human {what} ({Path(asf_path).name}): {why}")
        notes.append(f"skeleton {Path(asf_path).name} read by its shape and bone names (not the CMU names)")
        how = "humanoid mapper"
    # an absurd root translation or ASF unit overflows to inf in FK
    check_finite_motion(joints, amc_path)
    return Motion(joints=joints, root_rotation=rot, fps=amc.fps, name=motion_stem(amc_path),
                  skeleton=motion_stem(asf_path) or skel.name, source_format="amc",
                  meta={"asf": asf_path, "asf_name": skel.name, "mapping": how, "notes": notes,
                        "frames": (1, len(joints))})


def read_motion(path, options=None, *, asf=None, joint_map=None, marker_map=None, marker_rules=None,
                body_model=None) -> Motion:
    """Read a motion file (by extension) into the 24 canonical joints.

    Parameters
    ----------
    path : str or Path
        ``.amc`` (Acclaim motion; needs a skeleton), ``.bvh``, ``.c3d`` or an
        AMASS ``.npz``.
    options : ReaderOptions, optional
        How to read it (:class:`~mocapdb.readers.options.ReaderOptions`: what
        ingest, ray-annotate and the viewer pass); or the keywords below,
        which build one (not both).
    asf : str, Path or Skeleton, optional, keyword-only
        Skeleton of an AMC file; default: :func:`find_skeleton`. Ignored for BVH.
    joint_map : dict, str or Path, optional, keyword-only
        BVH only: canonical joint → the file's joint(s), overriding the
        automatic mapping (:func:`~mocapdb.readers.mapping.load_mapping`).
    marker_map : dict, str or Path, optional, keyword-only
        C3D only: canonical joint → the markers whose mean it is
        (:func:`~mocapdb.readers.c3d.read_c3d`).
    marker_rules : {"toolbox", "anatomical"}, optional, keyword-only
        C3D only: how the HDM05/CMU marker set is read (default ``"toolbox"``,
        the reference; :func:`~mocapdb.readers.c3d.read_c3d`).
    body_model : str or Path, optional, keyword-only
        AMASS ``.npz`` only: an SMPL-family body model file, or a folder of
        them, giving the take's own rest joints
        (:func:`~mocapdb.readers.amass.read_amass`; default: the generic rest
        skeleton).

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
    ParameterError
        Bad options, or ``options`` with keywords.

    References
    ----------
    DESIGN.md §1, §6; FEATURES.md §2.
    """
    keywords = {"asf": asf, "joint_map": joint_map, "marker_map": marker_map, "marker_rules": marker_rules,
                "body_model": body_model}
    if options is None:
        options = ReaderOptions(**keywords)
    elif any(v is not None for v in keywords.values()):
        raise ParameterError("read_motion: give options or the keywords asf, joint_map, marker_map, marker_rules, "
                             "body_model, not both")
    return read_options(as_path(path), options)


def read_options(path: Path, options, *, checked: bool = False) -> Motion:
    """:func:`read_motion` of a ``Path`` with its :class:`~mocapdb.readers.options.ReaderOptions`;
    ``checked``: the caller holds the file's bytes (:func:`~mocapdb.readers.sources.holding`) and has
    checked them as this would — not a FIFO or device, :func:`check_start` passed (ingest's fingerprint of
    a held take: the two checks cost a short take ~10 µs each, issue 35)."""
    if not checked:
        kind = special_kind(path)
        if kind is not None:   # reading a FIFO would block, a device never end
            raise ParseError(path, None, f"{kind}, not a motion file")
    try:
        # hostile values overflow in FK; the result is checked for finiteness
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"), options.capped():
            if not checked:
                check_start(path)
            return _read(path, options)
    except MocapdbError:
        raise
    except OSError as exc:
        raise ParseError(path, None, f"cannot read the file ({exc.strerror or exc})") from None
    except (MemoryError, RecursionError, ValueError, ArithmeticError, IndexError, KeyError, TypeError) as exc:
        # READERS.md §4: nothing but a MocapdbError leaves a reader. Known
        # malformations raise ParseErrors with a position; this is the net for
        # the ones nobody foresaw
        raise ParseError(path, None, f"unreadable ({type(exc).__name__}: {exc})") from None


def _read(path, options) -> Motion:
    ext = motion_suffix(path)
    asf = options.asf
    if ext == ".amc":
        if asf is None:
            asf = find_skeleton(path)
            if asf is None:
                looked = ", ".join(str(c) for c in skeleton_candidates(path))
                raise ParseError(path, None, f"no ASF skeleton found (looked for {looked}); give the "
                                 "skeleton: --asf FILE (command line) or asf=FILE (Python). A CMU take "
                                 "without its subject's ASF reads with any CMU subject's ASF (the bones "
                                 "are the same; their lengths approximate).")
            note = skeleton_note(path, asf)
            if note:
                motion = read_asf_amc(path, asf)
                motion.meta["notes"].insert(0, note)
                return motion
        return read_asf_amc(path, asf)
    if ext == ".bvh":
        return read_bvh(path, joint_map=options.mapping("joint_map"))
    if ext == ".c3d":
        return read_c3d(path, marker_map=options.mapping("marker_map"), marker_rules=options.marker_rules)
    if ext == ".npz":
        return read_amass(path, body_model=options.body_model)
    raise ParseError(path, None, f"unsupported file type {ext or path.suffix!r} (expected "
                     + " or ".join(SUPPORTED_EXTENSIONS) + ", optionally compressed: "
                     + ", ".join(COMPRESSED) + ")")
