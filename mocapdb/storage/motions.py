"""Reading motions back from the database: ids, metadata and packed feature words."""
from __future__ import annotations

import json
from dataclasses import dataclass, replace

import numpy as np

from mocapdb.errors import SchemaError
from mocapdb.readers import READER_OPTIONS, read_motion
from mocapdb.storage.sqltext import statement


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
    ParseError, FileNotFoundError
        The source file moved or changed since ingest.
    """
    rows = con.execute(_sql("source"), {"id": int(motion_id)}).fetchall()
    if not rows:
        raise SchemaError(f"no motion with id {motion_id} (see: SELECT motion_id, name FROM motions)")
    path, skeleton, options = rows[0]
    # only the reader's own options: notes and source frames stored beside them only inform
    kwargs = {k: v for k, v in (json.loads(options) if options else {}).items() if k in READER_OPTIONS}
    if skeleton:
        kwargs["asf"] = skeleton
    return read_motion(path, **kwargs)


__all__ = ["Documents", "motion_ids", "motion_documents", "documents_by_name", "source_motion"]
