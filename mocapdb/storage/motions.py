"""Reading motions back from the database: ids, metadata and packed feature words."""
from __future__ import annotations

import os
from dataclasses import dataclass, replace

import duckdb
import numpy as np
import pyarrow as pa

from mocapdb.errors import ParameterError, SchemaError, shorten
from mocapdb.readers import ReaderOptions, read_motion
from mocapdb.readers.sources import is_file, sha256
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
            # an id beyond the schema's 32-bit ids names no motion (DuckDB would refuse the parameter)
            rows = con.execute(_sql("by_id"), {"id": int(m)}).fetchall() if 0 <= int(m) < 2**31 else []
        else:
            rows = con.execute(_sql("by_name"), {"name": str(m)}).fetchall()
        if not rows:
            raise SchemaError(f"no motion {m!r} in the database (see: SELECT motion_id, name FROM motions)")
        out.extend(r[0] for r in rows)
    return out


def _first_line(exc, limit=200) -> str:
    text = (str(exc).splitlines() or [type(exc).__name__])[0]
    return text if len(text) <= limit else text[:limit] + "…"


def select_motions(con, *, where=None, label=None, model) -> list[int]:
    """The ids of the motions a filter selects, ascending: every motion, those with a stored segment of
    ``label`` (of ``model``), those a SQL condition over ``motions``' columns holds for, or both.

    Raises
    ------
    ParameterError
        ``where`` not one condition (a statement of its own, two, or invalid SQL), or a label without
        stored segments (the labels that have some are named).
    """
    condition = "TRUE" if where is None else str(where).strip()
    text = _sql("selected").replace("{where}", condition)
    try:   # DuckDB's own parser: one SELECT, or the condition closed the query and began another
        stmts = duckdb.extract_statements(text)
    except duckdb.Error as exc:
        raise ParameterError(f"where: not a SQL condition over motions ({_first_line(exc)})"
                             ) from None
    if not condition or len(stmts) != 1 or stmts[0].type != duckdb.StatementType.SELECT:
        raise ParameterError(f"where: give one SQL condition over motions' columns, e.g. \"format = 'bvh'\"; "
                             f"got {shorten(condition)}")
    if label is not None:
        stored = [r[0] for r in con.execute(_sql("stored_labels"), {"model": model}).fetchall()]
        if label not in stored:
            raise ParameterError(f"label {label!r}: no stored segment of it (model {model}); labels stored: "
                                 + (", ".join(stored) or "none (annotate first)"))
    try:
        return [r[0] for r in con.execute(text, {"label": label, "model": model}).fetchall()]
    except duckdb.Error as exc:
        raise ParameterError(f"where {shorten(condition)}: {_first_line(exc)}") from None


def one_motion(con, motion) -> int:
    """The id of one motion given by id or name; a name must name one motion (view, similar, similar_to).

    Raises
    ------
    SchemaError
        No such motion.
    ParameterError
        A name that names several motions (the same take as AMC and C3D).
    """
    ids = motion_ids(con, [motion])
    if len(ids) > 1:
        raise ParameterError(f"{motion!r} names {len(ids)} motions (ids {', '.join(map(str, ids))}); give the id")
    return ids[0]


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

    def take(self, positions) -> "Documents":
        """The documents at ``positions`` (ascending), with their words."""
        k = np.asarray(positions, dtype=np.int64)
        starts = np.concatenate(([0], np.cumsum(self.lengths)))
        words = np.concatenate([self.words[starts[i]:starts[i + 1]] for i in k] or [np.zeros(0, np.uint64)])
        return Documents(self.motion_ids[k], [self.names[i] for i in k], self.fps[k], self.lengths[k], words,
                         self.source_fps[k], self.n_source_frames[k])

    def native_rates(self) -> dict:
        """Document name → its source frame rate (label files in seconds land on native frames)."""
        return dict(zip(self.names, self.source_fps.tolist()))

    def native_lengths(self) -> dict:
        """Document name → its number of source frames (a label beyond it is an error)."""
        return dict(zip(self.names, self.n_source_frames.tolist()))

    def words_of(self, name) -> np.ndarray:
        """The words of the motion named ``name`` (the first of that name)."""
        k = self.names.index(name)
        start = int(self.lengths[:k].sum())
        return self.words[start:start + int(self.lengths[k])]


#: feature frames an archive-wide pass (annotation, keyframe search, import) holds at a time: its
#: memory then does not grow with the archive. 1 M frames are 8 MB of words, ~30 MB of keyframe
#: index and ~16 MB per class-row array of the annotation chain's batches
BATCH_FRAMES = 1_000_000


def motion_rows(con, ids=None) -> dict:
    """Metadata of the motions ``ids`` (default: all) in motion-id order; unknown ids are left out.

    Returns
    -------
    dict of str to ndarray
        ``motion_id``, ``name``, ``fps``, ``n_frames``, ``source_fps``, ``n_source_frames``.
    """
    return con.execute(_sql("meta"), {"ids": None if ids is None else [int(i) for i in ids]}).fetchnumpy()


def frame_batches(lengths, max_frames=BATCH_FRAMES) -> list:
    """Consecutive motions in batches of at most ``max_frames`` frames (a longer motion alone).

    Parameters
    ----------
    lengths : (n,) int
        Frames of each motion, in order.
    max_frames : int or None
        None: one batch (also of no motions).

    Returns
    -------
    list of (first, stop)
        Positions into ``lengths``; every motion in exactly one batch, in order.
    """
    n = len(lengths)
    if max_frames is None:
        return [(0, n)]
    ends = np.cumsum(np.asarray(lengths, dtype=np.int64))
    out, first = [], 0
    while first < n:
        base = int(ends[first - 1]) if first else 0
        stop = max(first + 1, int(np.searchsorted(ends, base + max_frames, side="right")))
        out.append((first, stop))
        first = stop
    return out


def read_words(con, motion_ids, n_frames):
    """The words of motions, each checked to be exactly its frames 1 … ``n_frames``.

    Parameters
    ----------
    motion_ids : (n,) int, ascending
    n_frames : (n,) int
        ``motions.n_frames`` of each.

    Returns
    -------
    words : (N,) uint64
        The words of the complete motions, concatenated in order.
    complete : (n,) bool
        Whether a motion's feature rows are its frames 1 … n_frames, once each.
    rows : (n,) int64
        Feature rows found per motion.
    """
    ids = np.asarray(motion_ids, dtype=np.int64)
    n = np.asarray(n_frames, dtype=np.int64)
    if not len(ids):
        return np.zeros(0, np.uint64), np.zeros(0, bool), np.zeros(0, np.int64)
    got = con.execute(_sql("words_of"), {"ids": ids.tolist(), "lo": int(ids[0]), "hi": int(ids[-1])}).fetchnumpy()
    bits, complete, rows = check_frames(ids, n, got["motion_id"], got["frame"], got["bits"])
    return (bits if complete.all() else bits[np.repeat(complete, rows)]), complete, rows


def check_frames(motion_ids, n_frames, row_motion, row_frame, row_bits):
    """Feature rows sorted by (motion, frame) and checked: is each motion exactly its frames 1 … n?

    Parameters
    ----------
    motion_ids : (n,) int, ascending
    n_frames : (n,) int
    row_motion, row_frame, row_bits : (m,) arrays
        Feature rows of these motions in any order (rows of other motions are not allowed).

    Returns
    -------
    bits : (m,) uint64
        The rows' words sorted by (motion, frame).
    complete : (n,) bool
        The motion's rows are its frames 1 … n_frames, once each.
    rows : (n,) int64
        Rows per motion.
    """
    ids = np.asarray(motion_ids, dtype=np.int64)
    mid = np.asarray(row_motion, dtype=np.int64)
    frame = np.asarray(row_frame, dtype=np.int64)
    bits = np.asarray(row_bits, dtype=np.uint64)
    key = (mid << 32) | frame
    if len(key) > 1 and (np.diff(key) < 0).any():  # DuckDB usually returns the stored order, which is this one
        order = np.argsort(key, kind="stable")
        mid, frame, bits = mid[order], frame[order], bits[order]
    pos = np.searchsorted(ids, mid)
    rows = np.bincount(pos, minlength=len(ids)).astype(np.int64)
    # frames 1, 2, … in order within each motion: no gap, no duplicate
    expected = np.arange(len(mid)) - np.repeat(np.cumsum(rows) - rows, rows) + 1
    complete = (rows == np.asarray(n_frames, dtype=np.int64)) & \
        (np.bincount(pos[frame != expected], minlength=len(ids)) == 0)
    return bits, complete, rows


def incomplete_reason(motion_id, name, rows, n_frames, *, what="motion",
                      remedy="ingest or import it again to repair it") -> str:
    """Why a motion's features cannot be used (``what``: whose motion), and what to do."""
    return (f"{what} {int(motion_id)} ({name}) has {int(rows)} feature rows for its {int(n_frames)} frames "
            f"(frames 1…{int(n_frames)} expected): {remedy}")


def incomplete_motions(con, ids) -> list:
    """Stored motions among ``ids`` whose features are not their frames 1 … n_frames.

    The check runs in DuckDB with a few numbers per motion (rows, first and
    last frame, sum of frames), so that it costs one scan and no memory that
    grows with the motions; an archive written by an older mocapdb could
    hold such motions (an import of a partial archive).

    Returns
    -------
    list of (motion_id, name, reason)
    """
    if not len(ids):
        return []
    rows = con.execute(_sql("feature_counts"), {"ids": [int(i) for i in ids]}).fetchall()
    return [(mid, name, incomplete_reason(mid, name, n_rows, n)) for mid, name, n, n_rows, ok in rows if not ok]


def iter_documents(con, ids=None, *, max_frames=BATCH_FRAMES, skip_unknown=False):
    """The motions ``ids`` (default: all) in motion-id order, a batch of whole motions at a time.

    Parameters
    ----------
    ids : sequence of int, optional
    max_frames : int or None
        Frames per batch (:data:`BATCH_FRAMES`; None: one batch).
    skip_unknown : bool
        Leave out ids the database does not have (the SQL functions answer NULL
        for them) instead of raising.

    Yields
    ------
    docs : Documents
        The batch's complete motions.
    incomplete : list of (motion_id, name, reason)
        The batch's motions whose features are not their frames 1 … n_frames (left out of ``docs``).

    Raises
    ------
    SchemaError
        For an id the database does not have.
    """
    meta = motion_rows(con, ids)
    found = np.asarray(meta["motion_id"], dtype=np.int64)
    if ids is not None and not skip_unknown and len(found) != len({int(i) for i in ids}):
        missing = sorted({int(i) for i in ids} - set(found.tolist()))
        raise SchemaError(f"no motion with id {missing} (see: SELECT motion_id, name FROM motions)")
    lengths = np.asarray(meta["n_frames"], dtype=np.int64)
    for a, b in frame_batches(lengths, max_frames):
        words, complete, rows = read_words(con, found[a:b], lengths[a:b])
        names = [str(x) for x in meta["name"][a:b]]
        bad = [(int(found[a + k]), names[k], incomplete_reason(found[a + k], names[k], rows[k], lengths[a + k]))
               for k in np.flatnonzero(~complete)]
        keep = np.flatnonzero(complete)
        yield Documents(found[a:b][keep], [names[k] for k in keep],
                        np.asarray(meta["fps"][a:b], np.float64)[keep], lengths[a:b][keep], words,
                        np.asarray(meta["source_fps"][a:b], np.float64)[keep],
                        np.asarray(meta["n_source_frames"][a:b], np.int64)[keep]), bad


def motion_documents(con, ids=None) -> Documents:
    """The motions ``ids`` (default: all) with their words, in motion-id order, in one piece.

    For archive-wide passes use :func:`iter_documents`, whose memory does not
    grow with the archive.

    Raises
    ------
    SchemaError
        For an unknown id, or a motion whose features are not its frames 1 … n_frames (named).
    """
    [(docs, bad)] = iter_documents(con, ids, max_frames=None)
    if bad:
        raise SchemaError("the database is inconsistent: " + "; ".join(r for _, _, r in bad))
    return docs


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
    ids, missing, dup = _resolve_names(con, names)
    if missing:
        raise SchemaError(f"documents {missing} are not in the database; ingest them first "
                          "(document = motion name, the file stem, or the file name)")
    if dup:
        raise SchemaError(f"documents {dup} name several motions (e.g. the same take as .amc and .c3d); "
                          "name the file instead (86_09.amc), or delete duplicates")
    docs = motion_documents(con, sorted(set(ids.values())))
    given = {mid: n for n, mid in ids.items()}
    return replace(docs, names=[given[int(m)] for m in docs.motion_ids])


def _resolve_names(con, names):
    """``({name: motion id}, missing, ambiguous)``: each name as :func:`documents_by_name` resolves it."""
    count = dict(con.execute(_sql("name_counts")).fetchall())
    ids, missing, dup = {}, [], []
    for n in sorted(set(names)):
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
    return ids, missing, dup


def source_rates(con, names) -> dict:
    """Name → source frame rate (``motions.source_fps``) of the ``names`` that name one motion (as
    :func:`documents_by_name` resolves them); names of no motion, or of several, are left out."""
    ids = _resolve_names(con, names)[0]
    meta = motion_rows(con, sorted(set(ids.values())))
    rate = dict(zip(np.asarray(meta["motion_id"]).tolist(), np.asarray(meta["source_fps"]).tolist()))
    return {n: float(rate[mid]) for n, mid in ids.items() if mid in rate}


def source_motion(con, motion_id):
    """Re-read a stored motion's source file with the options it was ingested with.

    The joints are not stored (24 × 3 floats per frame would be ~36× the
    8-byte feature word); the viewer and the figures re-read the source, whose
    path is stored absolute.

    Returns
    -------
    mocapdb.bodies.Motion

    Raises
    ------
    SchemaError
        No such motion.
    SchemaError
        The source file (or skeleton) is gone: moved (:func:`relocate_sources`)
        or deleted.
    SchemaError
        The source file's bytes (or the skeleton's) no longer hash to the
        sha256 stored at ingest: it changed, or the stored path names another file.
    ParseError
        The source file cannot be read.
    """
    rows = con.execute(_sql("source"), {"id": int(motion_id)}).fetchall()
    if not rows:
        raise SchemaError(f"no motion with id {motion_id} (see: SELECT motion_id, name FROM motions)")
    path, skeleton, options, digest, skeleton_digest = rows[0]
    for f, want in ((path, digest), (skeleton, skeleton_digest)):
        if not f:
            continue
        if os.path.isabs(f) and not is_file(f):  # a file, or a member of a zip archive
            raise SchemaError(f"motion {motion_id}: {f} is gone; if the files moved, repoint the database: "
                              "mocapdb relocate OLD_FOLDER NEW_FOLDER")
        # only the bytes that were ingested are read again: a source path changed in an imported archive
        # (or a file replaced since) could otherwise show any file of this machine with a motion's suffix
        if want is not None and is_file(f) and sha256(f) != want:
            raise SchemaError(f"motion {motion_id}: {f} has other bytes than the file ingested (its sha256 differs); "
                              "if the recordings moved, repoint the database: mocapdb relocate OLD_FOLDER "
                              "NEW_FOLDER; if the file changed, ingest it again")
    # only the reader's own options: notes and source frames stored beside them only inform
    return read_motion(path, ReaderOptions.from_stored(options, asf=skeleton or None))


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
            if not is_file(path):
                problem = f"{path} does not exist"
            elif sha256(path) != digest:  # the digest ingest stored: of the bytes, decompressed
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
           "relocate_sources", "iter_documents", "motion_rows", "frame_batches", "read_words", "check_frames",
           "incomplete_reason", "incomplete_motions", "BATCH_FRAMES", "source_rates", "one_motion"]
