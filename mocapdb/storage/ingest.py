"""Ingest recordings into a mocap database: read → features → store, one transaction per file.

A file that fails to read leaves the database exactly as it was; a file whose
bytes (and skeleton bytes) are already stored is skipped, so re-ingesting a
folder is a no-op.
"""
from __future__ import annotations

import hashlib
import json
import logging
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa

from mocapdb.errors import MocapdbError, ParameterError
from mocapdb.features import FEATURE_RATE, feature_frame_count, motion_features
from mocapdb.readers import SUPPORTED_EXTENSIONS, find_skeleton, load_mapping, read_motion
from mocapdb.storage.motions import incomplete_motions
from mocapdb.storage.postings import index_motions, unindex_motions
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction

log = logging.getLogger("mocapdb")

#: file extensions ingest reads as motions
MOTION_SUFFIXES = SUPPORTED_EXTENSIONS
#: files a motion folder holds beside its motions, and why they are not ingested
_COMPANIONS = {".asf": "an ASF skeleton (read with its AMC takes)"}


@dataclass
class IngestReport:
    """What an :func:`ingest` call did, file by file."""

    ingested: list = field(default_factory=list)     # (path, motion_id, n_frames)
    skipped: list = field(default_factory=list)      # (path, reason): already stored
    repaired: list = field(default_factory=list)     # (path, reason): stored with incomplete features, replaced
    failed: list = field(default_factory=list)       # (path, reason)
    unsupported: list = field(default_factory=list)  # (path, reason): files of a folder that are not motions
    source_frames: int = 0

    def summary(self) -> str:
        out = (f"{len(self.ingested)} ingested{f' ({len(self.repaired)} repaired)' if self.repaired else ''}, "
               f"{len(self.skipped)} skipped, {len(self.failed)} failed")
        if self.unsupported:
            out += f", {len(self.unsupported)} not motion files"
        return out


def _folder_files(folder: Path) -> list[Path]:
    # hidden files and folders (.DS_Store, .git) are nobody's motions
    return sorted(q for q in folder.rglob("*") if q.is_file()
                  and not any(part.startswith(".") for part in q.relative_to(folder).parts))


def motion_files(paths, *, unsupported=None) -> list[Path]:
    """Expand files and folders (recursively) into motion files, in sorted order.

    Parameters
    ----------
    paths : iterable of str or Path
    unsupported : list, optional, keyword-only
        Receives ``(path, reason)`` for every file of a folder that is not a
        motion file (a file named explicitly is always returned: reading it
        says what is wrong).

    Raises
    ------
    ParameterError
        If a path does not exist.
    """
    out = []
    for p in map(Path, paths):
        if p.is_dir():
            for q in _folder_files(p):
                ext = q.suffix.lower()
                if ext in MOTION_SUFFIXES:
                    out.append(q)
                elif unsupported is not None:
                    why = _COMPANIONS.get(ext) or (f"unsupported file type {q.suffix!r}" if q.suffix
                                                   else "no file extension")
                    unsupported.append((str(q), why + " (motions: " + ", ".join(MOTION_SUFFIXES) + ")"))
        elif p.is_file():
            out.append(p)
        else:
            raise ParameterError(f"paths: {str(p)!r} does not exist")
    return out


def _sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@dataclass
class _Prepared:
    path: Path
    sha256: str
    skeleton_path: Path | None
    skeleton_sha256: str | None
    motion: object = None
    words: np.ndarray | None = None
    error: str | None = None
    reader_options: str | None = None  # JSON of the reader options besides the skeleton
    replaces: int | None = None  # a stored motion of the same bytes whose features are incomplete


def _fingerprint(path: Path, asf) -> _Prepared:
    skel = None
    if path.suffix.lower() == ".amc":
        skel = Path(asf) if asf is not None else find_skeleton(path)
    try:
        return _Prepared(path, _sha256(path), skel, _sha256(skel) if skel is not None else None)
    except OSError as exc:
        raise MocapdbError(f"{path}: cannot read it ({exc.strerror or exc})") from None


def prepare_file(path, *, asf=None, maps=None):
    """Fingerprint one file as ingest does, before reading it.

    Parameters
    ----------
    path : str or Path
    asf : str or Path, optional, keyword-only
        Skeleton of an AMC file (default: found by the dataset conventions).
    maps : dict, optional, keyword-only
        :func:`reader_maps` output.

    Returns
    -------
    record
        ``path``, ``sha256``, ``skeleton_path`` and ``skeleton_sha256`` (the
        ``motions`` key) and ``reader_options``; the input of :func:`compute_motion`.

    Raises
    ------
    MocapdbError
        If an AMC file's skeleton cannot be found, or the file cannot be read.
    """
    prep = _fingerprint(Path(path), asf)
    prep.reader_options = _reader_options(prep.path, maps or {})
    return prep


def compute_motion(prep):
    """Read a prepared file and compute its 30 Hz feature words, as ingest does.

    Sets ``prep.motion`` (:class:`mocapdb.readers.Motion`) and ``prep.words``
    ((n_frames,) uint64), or ``prep.error`` (the reader's message) when the
    file cannot be read; returns ``prep``.
    """
    # any failure stays with its file: a reader raises only MocapdbError, but a
    # bug must not stop the other files of an archive (READERS.md §4)
    try:
        options = json.loads(prep.reader_options) if prep.reader_options else {}
        prep.motion = read_motion(prep.path, asf=prep.skeleton_path, **options)
        prep.words = motion_features(prep.motion)
    except MocapdbError as exc:
        prep.error = str(exc)
    except Exception as exc:  # noqa: BLE001 - reported per file, never raised
        log.warning("internal error reading %s", prep.path, exc_info=True)
        prep.error = f"{prep.path}: internal error while reading ({type(exc).__name__}: {exc}); please report it"
    if prep.error is not None:
        prep.motion = prep.words = None
    return prep


def _sql(name):
    return statement("motions.sql", name)


def _stored_keys(con) -> dict:
    """(sha256, skeleton_sha256) -> motion_id of everything already stored."""
    return {(a, b): mid for mid, a, b in con.execute(_sql("stored_keys")).fetchall()}


def motions_table(preps) -> pa.Table:
    """The ``motions`` rows of computed files (:func:`compute_motion`), without
    ``motion_id`` and ``ingested_at``.

    Raises
    ------
    MocapdbError
        If a file's feature frames do not match its source frames.
    """
    for p in preps:
        n30 = int(p.words.shape[0])
        if n30 != feature_frame_count(p.motion.n_frames, p.motion.fps):
            raise MocapdbError(f"{p.path}: {n30} feature frames for {p.motion.n_frames} source frames")
    return pa.table({
        "name": pa.array([p.motion.name or p.path.stem for p in preps], pa.string()),
        "source_path": pa.array([str(p.path.resolve()) for p in preps], pa.string()),
        "format": pa.array([p.motion.source_format for p in preps], pa.string()),
        "sha256": pa.array([p.sha256 for p in preps], pa.string()),
        "skeleton_sha256": pa.array([p.skeleton_sha256 for p in preps], pa.string()),
        "source_fps": pa.array([float(p.motion.fps) for p in preps], pa.float64()),
        "fps": pa.array([FEATURE_RATE] * len(preps), pa.float64()),
        "n_source_frames": pa.array([p.motion.n_frames for p in preps], pa.int32()),
        "n_frames": pa.array([int(p.words.shape[0]) for p in preps], pa.int32()),
        "skeleton": pa.array([p.motion.skeleton for p in preps], pa.string()),
        "skeleton_path": pa.array([str(p.skeleton_path.resolve()) if p.skeleton_path else None for p in preps],
                                  pa.string()),
        "reader_options": pa.array([p.reader_options for p in preps], pa.string()),
    })



def store_motions(con, preps) -> list[int]:
    """Insert computed motions — their ``motions`` rows, ``features`` rows and,
    when the keyframe index exists, postings — in one transaction (which first
    deletes the stored motions they replace, ``prep.replaces``).

    Returns the new motion ids in the order of ``preps``.
    """
    meta = motions_table(preps)
    meta = meta.add_column(0, "ord", pa.array(np.arange(len(preps), dtype=np.int32)))
    with transaction(con):
        remove_motions(con, [p.replaces for p in preps if p.replaces is not None])
        return insert_motions(con, meta, [p.words for p in preps])


def insert_motions(con, meta: pa.Table, words: list) -> list[int]:
    """Insert ``motions`` rows (``meta``, with ``ord``) with their words as features and postings,
    inside the caller's transaction; returns the new ids in the order of ``meta``."""
    with registered(con, mocap_new_motions=meta):
        rows = con.execute(_sql("insert_motions")).fetchall()
    by_key = {(a, b): mid for mid, a, b in rows}
    ids = [by_key[k] for k in zip(meta.column("sha256").to_pylist(), meta.column("skeleton_sha256").to_pylist())]
    insert_features(con, ids, words)
    return ids


def insert_features(con, ids, words: list) -> None:
    """Insert the ``features`` rows (frames 1 … n) and postings of motions, inside the caller's transaction."""
    counts = np.array([len(w) for w in words], dtype=np.int64)
    feats = pa.table({
        "motion_id": pa.array(np.repeat(np.array(ids, dtype=np.int32), counts)),
        "frame": pa.array(np.concatenate([np.arange(1, c + 1, dtype=np.int32) for c in counts] or
                                         [np.zeros(0, np.int32)])),
        "bits": pa.array(np.concatenate(words or [np.zeros(0, np.uint64)]).astype(np.uint64, copy=False)),
    })
    with registered(con, mocap_new_features=feats):
        con.execute(_sql("insert_features"))
    index_motions(con, dict(zip(ids, words)))


def store_words(con, words_by_name: dict, *, fps: float = FEATURE_RATE, source: str = "words") -> list[int]:
    """Store motions given only as 30 Hz feature words (computed elsewhere, or synthetic).

    Each becomes a ``motions`` row (format ``words``, no source file to re-read:
    ``source_path`` is ``"<source>:<name>"``), its ``features`` rows and its
    postings, in one transaction.

    Returns
    -------
    list of int
        The new motion ids, in the order of ``words_by_name``.
    """
    names = list(words_by_name)
    words = [np.ascontiguousarray(words_by_name[n], dtype=np.uint64) for n in names]
    n30 = np.array([len(w) for w in words], dtype=np.int64)
    meta = pa.table({
        "ord": pa.array(np.arange(len(names), dtype=np.int32)),
        "name": pa.array(names, pa.string()),
        "source_path": pa.array([f"{source}:{n}" for n in names], pa.string()),
        "format": pa.array(["words"] * len(names), pa.string()),
        "sha256": pa.array([hashlib.sha256(w.tobytes()).hexdigest() for w in words], pa.string()),
        "skeleton_sha256": pa.array([None] * len(names), pa.string()),
        "source_fps": pa.array([float(fps)] * len(names), pa.float64()),
        "fps": pa.array([FEATURE_RATE] * len(names), pa.float64()),
        "n_source_frames": pa.array(((n30 - 1) * fps / FEATURE_RATE + 1).astype(np.int32), pa.int32()),
        "n_frames": pa.array(n30.astype(np.int32), pa.int32()),
        "skeleton": pa.array([None] * len(names), pa.string()),
        "skeleton_path": pa.array([None] * len(names), pa.string()),
        "reader_options": pa.array([None] * len(names), pa.string()),
    })
    with transaction(con):
        return insert_motions(con, meta, words)


#: computed files are stored in batches, one transaction per batch, once a batch
#: holds this many files or source frames (a commit costs milliseconds, a file
#: of the HDM05 cut ~2 ms of compute)
BATCH_FILES = 64
BATCH_FRAMES = 1_000_000


def ingest_files(con, paths, *, asf=None, joint_map=None, marker_map=None, progress=None,
                 workers: int = 2) -> IngestReport:
    """Read recordings, compute their features and store them.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
        A connection with the mocapdb schema.
    paths : iterable of str or Path
        Files (``.amc``, ``.bvh``, ``.c3d``) or folders, searched recursively.
    asf : str or Path, optional, keyword-only
        Skeleton for every AMC file. By default each AMC's ASF is found by the
        dataset conventions (:func:`mocapdb.readers.find_skeleton`).
    joint_map, marker_map : dict, str or Path, optional, keyword-only
        Mapping of the canonical joints to a BVH file's joints / a C3D file's
        markers (TOML or JSON file, or dict; :func:`mocapdb.readers.load_mapping`),
        for every file of that type. Stored in ``motions.reader_options``.
    progress : callable, optional, keyword-only
        Called as ``progress(path, n_source_frames)`` once per file.
    workers : int, keyword-only
        Threads that read and compute features (the kernels release the GIL).

    Returns
    -------
    IngestReport
        Ingested, skipped (already stored) and failed files with reasons.

    Notes
    -----
    A file that fails to read is never stored, so it changes nothing. Files
    that computed are stored in batches, one transaction per batch
    (DESIGN.md §6: "one transaction per file or batch"); if storing a batch
    fails, its files are retried one transaction each, so a failure stays
    confined to its file.
    """
    report = IngestReport()
    files = motion_files(paths, unsupported=report.unsupported)
    maps = reader_maps(joint_map=joint_map, marker_map=marker_map)
    stored = _stored_keys(con)
    todo = []
    already = []      # (path, prep, key) of files whose bytes are stored: decided after the loop
    first_of = {}     # key -> the first file of this ingest with those bytes
    duplicates = []   # (path, key): decided once the first file is read
    for path in files:
        try:
            prep = prepare_file(path, asf=asf, maps=maps)
        except MocapdbError as exc:
            report.failed.append((str(path), str(exc)))
            _tick(progress, path, 0)
            continue
        key = (prep.sha256, prep.skeleton_sha256)
        if key in stored:
            already.append((path, prep, key))
        elif key in first_of:
            duplicates.append((path, key))
        else:
            first_of[key] = str(path)
            todo.append(prep)
    # a stored motion whose features are incomplete (an import of a partial archive by an older
    # mocapdb) is stored again from its file, replacing it, in the same transaction
    broken = {mid: reason for mid, _, reason in incomplete_motions(con, [stored[k] for _, _, k in already])}
    for path, prep, key in already:
        mid = stored[key]
        if mid not in broken:
            report.skipped.append((str(path), f"already ingested as motion {mid}"))
            _tick(progress, path, 0)
        elif key in first_of:
            duplicates.append((path, key))
        else:
            first_of[key] = str(path)
            prep.replaces = mid
            report.repaired.append((str(path), broken[mid]))
            todo.append(prep)

    batch = []

    def flush():
        try:
            ids = store_motions(con, batch)
        except Exception:  # noqa: BLE001 - retried file by file below
            ids = []
            for p in batch:  # one transaction each: a failure stays with its file
                try:
                    ids.extend(store_motions(con, [p]))
                except Exception as exc:  # noqa: BLE001 - reported per file
                    report.failed.append((str(p.path), f"{p.path}: not stored ({exc})"))
                    ids.append(None)
        for p, mid in zip(batch, ids):
            if mid is not None:
                report.ingested.append((str(p.path), mid, int(p.words.shape[0])))
                report.source_frames += p.motion.n_frames
            _tick(progress, p.path, p.motion.n_frames)
            p.motion = p.words = None  # free memory early on big archives
        batch.clear()

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        for prep in pool.map(compute_motion, todo):
            if prep.error is not None:
                report.failed.append((str(prep.path), prep.error))
                _tick(progress, prep.path, 0)
                continue
            batch.append(prep)
            if len(batch) >= BATCH_FILES or sum(p.motion.n_frames for p in batch) >= BATCH_FRAMES:
                flush()
        if batch:
            flush()
    # a copy of a stored file is skipped; a copy of a broken one is as broken
    failed = dict(report.failed)
    for path, key in duplicates:
        first = first_of[key]
        if first in failed:
            report.failed.append((str(path), f"{path}: same bytes as {first}, which failed: {failed[first]}"))
        else:
            report.skipped.append((str(path), f"same bytes as {first} of this ingest"))
        _tick(progress, path, 0)
    return report


#: which reader option applies to which file type
_OPTION_SUFFIX = {"joint_map": ".bvh", "marker_map": ".c3d"}


def reader_maps(*, joint_map=None, marker_map=None) -> dict:
    """The reader options of an ingest, loaded and checked once (:func:`mocapdb.readers.load_mapping`)."""
    return {"joint_map": load_mapping(joint_map, what="joint_map"),
            "marker_map": load_mapping(marker_map, what="marker_map")}


def _reader_options(path: Path, maps: dict) -> str | None:
    opts = {k: v for k, v in maps.items() if v is not None and path.suffix.lower() == _OPTION_SUFFIX[k]}
    return json.dumps(opts, sort_keys=True) if opts else None


def _tick(progress, path, n):
    if progress is not None:
        progress(path, n)


def delete_motions(con, motion_ids) -> int:
    """Delete motions with their features, postings and annotations (one transaction).

    Returns
    -------
    int
        The number of motions deleted.
    """
    ids = [int(i) for i in motion_ids]
    if not ids:
        return 0
    with transaction(con):
        return remove_motions(con, ids)


def remove_motions(con, motion_ids) -> int:
    """:func:`delete_motions` inside the caller's transaction; returns the number deleted."""
    ids = {"ids": [int(i) for i in motion_ids]}
    if not ids["ids"]:
        return 0
    con.execute(_sql("delete_features"), ids)
    unindex_motions(con, ids["ids"])
    con.execute(_sql("delete_annotations"), ids)
    return len(con.execute(_sql("delete_motions"), ids).fetchall())


__all__ = ["ingest_files", "IngestReport", "motion_files", "store_motions", "store_words", "delete_motions",
           "remove_motions", "insert_motions", "insert_features",
           "MOTION_SUFFIXES", "prepare_file", "compute_motion", "motions_table", "reader_maps"]
