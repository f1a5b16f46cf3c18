"""Reading motions back from the database: ids, metadata and packed feature words."""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, replace

import numpy as np
import pyarrow as pa

from mocapdb.errors import ParameterError, SchemaError, shorten
from mocapdb.readers import READER_OPTIONS, read_motion
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction


def _sql(name):
    return statement("motions.sql", name)


def motion_ids(con, motions) -> list[int]:
    """Resolve motion ids or names to ids (a name may name several motions).

    Raises
    ------
    SchemaError
        For an id or name the database does not have.
    """
    out = []
    for m in motions:
        if isinstance(m, (int, np.integer)) or (isinstance(m, str) and m.isdigit()):
            rows = con.execute(_sql("by_id"), {"id": int(m)}).fetchall()
        else:
            rows = con.execute(_sql("by_name"), {"name": str(m)}).fetchall()
        if not rows:
            raise SchemaError(f"no motion {m!r} in the database (see: SELECT motion_id, name FROM motions)")
        out.extend(r[0] for r in rows)
    return out


@dataclass(frozen=True, eq=False)
class Documents:
    """Motions as concatenated documents, in motion-id order.

    Attributes
    ----------
    motion_ids : (n,) int64
    names : list of str
    fps : (n,) float64
        Rate of the words (30 Hz).
    lengths : (n,) int64
        Words per motion.
    words : (N,) uint64
        Packed feature words of all motions, concatenated.
    source_fps : (n,) float64
    n_source_frames : (n,) int64
    """

    motion_ids: np.ndarray
    names: list
    fps: np.ndarray
    lengths: np.ndarray
    words: np.ndarray
    source_fps: np.ndarray
    n_source_frames: np.ndarray

    def words_of(self, name) -> np.ndarray:
        """The words of the motion named ``name`` (the first of that name)."""
        k = self.names.index(name)
        start = int(self.lengths[:k].sum())
        return self.words[start:start + int(self.lengths[k])]


def motion_documents(con, ids=None) -> Documents:
    """The motions ``ids`` (default: all) with their words, in motion-id order.

    Raises
    ------
    SchemaError
        For an unknown id, or when features and motions disagree.
    """
    params = {"ids": None if ids is None else [int(i) for i in ids]}
    meta = con.execute(_sql("meta"), params).fetchnumpy()
    found = np.asarray(meta["motion_id"], dtype=np.int64)
    if ids is not None and len(found) != len(set(params["ids"])):
        missing = sorted(set(params["ids"]) - set(found.tolist()))
        raise SchemaError(f"no motion with id {missing} (see: SELECT motion_id, name FROM motions)")
    bits = con.execute(_sql("words"), params).fetchnumpy()["bits"]
    lengths = np.asarray(meta["n_frames"], dtype=np.int64)
    if int(lengths.sum()) != len(bits):
        raise SchemaError("features and motions.n_frames disagree; the database is inconsistent")
    return Documents(found, [str(n) for n in meta["name"]], np.asarray(meta["fps"], np.float64), lengths,
                     np.asarray(bits, dtype=np.uint64), np.asarray(meta["source_fps"], np.float64),
                     np.asarray(meta["n_source_frames"], np.int64))


def documents_by_name(con, names) -> Documents:
    """The motions named ``names``: a motion name (the file stem) that names one
    motion, or a file name (``HDM_dg_06-03_03_120.c3d``) where the stem names
    several (the same take as AMC and C3D). ``Documents.names`` are the names
    as given.

    Raises
    ------
    SchemaError
        A name matches no motion, or several (name the file instead).
    """
    count = dict(con.execute(_sql("name_counts")).fetchall())
    wanted = sorted(set(names))
    ids, missing, dup = {}, [], []
    for n in wanted:
        if count.get(n, 0) == 1:
            ids[n] = con.execute(_sql("by_name"), {"name": n}).fetchall()[0][0]
            continue
        by_file = [r[0] for r in con.execute(_sql("by_file_name"), {"name": n}).fetchall()]
        if len(by_file) == 1:
            ids[n] = by_file[0]
        elif count.get(n, 0) > 1 or len(by_file) > 1:
            dup.append(n)
        else:
            missing.append(n)
    if missing:
        raise SchemaError(f"documents {missing} are not in the database; ingest them first "
                          "(document = motion name, the file stem, or the file name)")
    if dup:
        raise SchemaError(f"documents {dup} name several motions (e.g. the same take as .amc and .c3d); "
                          "name the file instead (86_09.amc), or delete duplicates")
    docs = motion_documents(con, sorted(set(ids.values())))
    given = {mid: n for n, mid in ids.items()}
    return replace(docs, names=[given[int(m)] for m in docs.motion_ids])


def source_motion(con, motion_id):
    """Re-read a stored motion's source file with the options it was ingested with.

    The joints are not stored (24 × 3 floats per frame would be ~36× the
    8-byte feature word); the viewer and the figures re-read the source, whose
    path is stored absolute.

    Returns
    -------
    mocapdb.readers.Motion

    Raises
    ------
    SchemaError
        No such motion.
    SchemaError
        The source file (or skeleton) is gone: moved (:func:`relocate_sources`)
        or deleted.
    ParseError
        The source file changed since ingest.
    """
    rows = con.execute(_sql("source"), {"id": int(motion_id)}).fetchall()
    if not rows:
        raise SchemaError(f"no motion with id {motion_id} (see: SELECT motion_id, name FROM motions)")
    path, skeleton, options = rows[0]
    for f in (path, skeleton):
        if f and os.path.isabs(f) and not os.path.exists(f):
            raise SchemaError(f"motion {motion_id}: {f} is gone; if the files moved, repoint the database: "
                              "mocapdb relocate OLD_FOLDER NEW_FOLDER")
    # only the reader's own options: notes and source frames stored beside them only inform
    kwargs = {k: v for k, v in (json.loads(options) if options else {}).items() if k in READER_OPTIONS}
    if skeleton:
        kwargs["asf"] = skeleton
    return read_motion(path, **kwargs)


def motions_to_delete(con, motions, *, all_named=False):
    """The motions ``delete`` removes: ids, and names that name one motion (or every one with ``all_named``).

    Parameters
    ----------
    motions : iterable of int or str
        Motion ids (ints or digit strings) or names.
    all_named : bool, keyword-only
        A name that names several motions (the same take as AMC and C3D)
        means all of them; otherwise that is an error listing them.

    Returns
    -------
    rows : list of tuple
        ``(motion_id, name, format, source_path)`` of each motion, once.
    absent : list
        The ids and names the database does not have (nothing to delete:
        a delete run twice is no error).

    Raises
    ------
    ParameterError
        A name names several motions and ``all_named`` is False (nothing is deleted).
    """
    found, absent, ambiguous = {}, [], []
    for m in motions:
        if isinstance(m, (int, np.integer)) or (isinstance(m, str) and m.isdigit()):
            rows = con.execute(_sql("for_delete"), {"ids": [int(m)]}).fetchall()
        else:
            rows = con.execute(_sql("named"), {"name": str(m)}).fetchall()
            if len(rows) > 1 and not all_named:
                ambiguous.append((m, rows))
        if not rows:
            absent.append(m)
        found.update((r[0], r) for r in rows)
    if ambiguous:
        name, rows = ambiguous[0]
        listed = "; ".join(f"{r[0]} ({r[2]}, {r[3]})" for r in rows[:10])
        raise ParameterError(f"{shorten(name)} names {len(rows)} motions: {listed}. Give the motion ids, or "
                             "all_named=True (--all-named) to delete every motion of that name")
    return [found[k] for k in sorted(found)], absent


def _sha256(path) -> str:
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def _moved(path, old, new):
    """``path`` with the folder ``old`` replaced by ``new`` (whole path components), or None."""
    if path is None:
        return None
    if path == old:
        return new
    if path.startswith(old.rstrip(os.sep) + os.sep):
        return os.path.join(new, path[len(old.rstrip(os.sep)) + 1:])
    return None


def relocate_sources(con, old_prefix, new_prefix):
    """Repoint the stored source paths (and skeleton paths) under ``old_prefix`` to ``new_prefix``.

    A motion is repointed only when its file (and skeleton) exists at the new
    place with the bytes that were ingested (sha256): a wrong prefix changes
    nothing.

    Parameters
    ----------
    old_prefix, new_prefix : str or Path
        Folders (made absolute; whole path components match).

    Returns
    -------
    moved : list of (motion_id, old path, new path)
    refused : list of (motion_id, new path, reason)
        Motions under ``old_prefix`` whose new file is missing or differs.
    """
    old, new = os.path.abspath(old_prefix), os.path.abspath(new_prefix)
    if old == new:
        raise ParameterError(f"old and new prefix are the same folder: {old}")
    moved, refused, rows = [], [], []
    for mid, _name, src, sha, skel, skel_sha in con.execute(_sql("sources_for_relocate")).fetchall():
        new_src, new_skel = _moved(src, old, new), _moved(skel, old, new)
        if new_src is None and new_skel is None:
            continue
        target = (new_src or src, new_skel or skel)
        problem = None
        for path, digest in ((target[0], sha), (target[1], skel_sha)):
            if path is None or digest is None:
                continue
            if not os.path.isfile(path):
                problem = f"{path} does not exist"
            elif _sha256(path) != digest:
                problem = f"{path} has other bytes than the file ingested"
            if problem:
                break
        if problem:
            refused.append((mid, target[0], problem))
            continue
        moved.append((mid, src, target[0]))
        rows.append((mid, *target))
    if rows:
        table = pa.table({"motion_id": pa.array([r[0] for r in rows], pa.int32()),
                          "source_path": pa.array([r[1] for r in rows], pa.string()),
                          "skeleton_path": pa.array([r[2] for r in rows], pa.string())})
        with transaction(con):
            with registered(con, mocap_relocated=table):
                con.execute(_sql("relocate"))
    return moved, refused


__all__ = ["Documents", "motion_ids", "motion_documents", "documents_by_name", "source_motion", "motions_to_delete",
           "relocate_sources"]
