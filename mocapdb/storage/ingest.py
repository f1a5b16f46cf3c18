"""Ingest recordings into a mocap database: read → features → store, one transaction per file.

A file that fails to read leaves the database exactly as it was; a file whose
bytes (and skeleton bytes) are already stored is skipped, so re-ingesting a
folder is a no-op.
"""
from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import threading
import uuid
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import pyarrow as pa

from mocapdb.errors import MocapdbError, ParameterError
from mocapdb.features import FEATURE_RATE, feature_frame_count
from mocapdb.readers import ReaderOptions, motion_files
from mocapdb.readers.sources import motion_stem, stream_size
from mocapdb.storage.ingest_log import IngestLog, write_report
from mocapdb.storage.ingest_read import _compute_slim, _read_new, forget_stored, remember_stored, stored_prefixes
from mocapdb.storage.ingest_pool import (WorkerDied, chunk_for, executor, head_start, ordered, use_processes,
                                         window_for)
from mocapdb.storage.motions import incomplete_motions
from mocapdb.storage.postings import index_motions, unindex_motions
from mocapdb.storage.sqltext import statement
from mocapdb.storage.transaction import registered, transaction

log = logging.getLogger("mocapdb")

@dataclass
class IngestReport:
    """What an :func:`ingest` call did, file by file.

    ``notes`` holds what the readers decided for a stored file — a joint
    placed without markers, a marker rebuilt, lost tracking interpolated, a
    stretch cut, a rate or skeleton found by a fallback — as ``(path, note)``;
    the same notes are stored with the motion (``motions.reader_options``,
    key ``notes``). ``unreadable`` lists folder entries that could not be
    looked at (a folder without permission, a damaged zip archive).
    """

    ingested: list = field(default_factory=list)     # (path, motion_id, n_frames)
    replaced: list = field(default_factory=list)     # (path, former motion_id): read again with replace
    skipped: list = field(default_factory=list)      # (path, reason): already stored, or hidden (not read)
    repaired: list = field(default_factory=list)     # (path, reason): stored with incomplete features, replaced
    failed: list = field(default_factory=list)       # (path, reason)
    unsupported: list = field(default_factory=list)  # (path, reason): files of a folder that are not motions
    notes: list = field(default_factory=list)        # (path, note): what the reader decided for a stored file
    unreadable: list = field(default_factory=list)   # (path, reason): folder entries that could not be read
    source_frames: int = 0
    run_id: int | None = None   # the run's rows in ingest_log (mocapdb.storage.ingest_log)

    def summary(self) -> str:
        out = (f"{len(self.ingested)} ingested"
               + (f" ({len(self.replaced)} replacing stored motions)" if self.replaced else "")
               + (f" ({len(self.repaired)} repaired)" if self.repaired else "")
               + f", {len(self.skipped)} skipped, {len(self.failed)} failed")
        if self.unsupported:
            out += f", {len(self.unsupported)} not motion files"
        if self.unreadable:
            out += f", {len(self.unreadable)} unreadable"
        noted = len({p for p, _ in self.notes})
        if noted:
            out += f"; {noted} read with notes"
        return out


def _sql(name):
    return statement("motions.sql", name)


def _stored_keys(con) -> dict:
    """(sha256, skeleton_sha256) -> motion_id of everything already stored."""
    return {(a, b): mid for mid, a, b in con.execute(_sql("stored_keys")).fetchall()}


def motions_table(preps) -> pa.Table:
    """The ``motions`` rows of computed files (:func:`~mocapdb.storage.ingest_read.compute_motion`), without
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
        "name": pa.array([p.motion.name or motion_stem(p.path) for p in preps], pa.string()),
        # absolute as given, not symlink-resolved: the path the user knows (and can relocate)
        "source_path": pa.array([os.path.abspath(p.path) for p in preps], pa.string()),
        "format": pa.array([p.motion.source_format for p in preps], pa.string()),
        "sha256": pa.array([p.sha256 for p in preps], pa.string()),
        "skeleton_sha256": pa.array([p.skeleton_sha256 for p in preps], pa.string()),
        "source_fps": pa.array([float(p.motion.fps) for p in preps], pa.float64()),
        "fps": pa.array([FEATURE_RATE] * len(preps), pa.float64()),
        "n_source_frames": pa.array([p.motion.n_frames for p in preps], pa.int32()),
        "n_frames": pa.array([int(p.words.shape[0]) for p in preps], pa.int32()),
        "skeleton": pa.array([p.motion.skeleton for p in preps], pa.string()),
        "skeleton_path": pa.array([os.path.abspath(p.skeleton_path) if p.skeleton_path else None for p in preps],
                                  pa.string()),
        "reader_options": pa.array([p.reader_options for p in preps], pa.string()),
    })



def store_motions(con, preps, *, log=None) -> list[int]:
    """Insert computed motions — their ``motions`` rows, ``features`` rows and,
    when the keyframe index exists, postings — in one transaction (which first
    deletes the stored motions they replace, ``prep.replaces``), with their
    ``ingest_log`` rows when ``log`` (:class:`~mocapdb.storage.ingest_log.IngestLog`) is given.

    Returns the new motion ids in the order of ``preps``.
    """
    meta = motions_table(preps)
    meta = meta.add_column(0, "ord", pa.array(np.arange(len(preps), dtype=np.int32)))
    with transaction(con):
        remove_motions(con, [p.replaces for p in preps if p.replaces is not None])
        ids = insert_motions(con, meta, [p.words for p in preps])
        if log is not None:
            log.insert_stored([(p.path, mid, p.log_reason, p.notes) for p, mid in zip(preps, ids)])
        return ids


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
#: holds this many files or source frames (a commit and a batch's inserts cost
#: milliseconds whatever its size, and the parent that stores shares the cores
#: with the workers: fewer, larger batches — 1,024 files spend ~0.2 CPU-s less per 2,470 than 256 did;
#: 4·10⁶ source frames keep a batch's words at 8 MB)
BATCH_FILES = 1024
BATCH_FRAMES = 4_000_000


def ingest_files(con, paths, *, options=None, progress=None, workers: int = 2, replace: bool = False,
                 log_csv=None) -> IngestReport:
    """Read recordings, compute their features and store them.

    Parameters
    ----------
    con : duckdb.DuckDBPyConnection
        A connection with the mocapdb schema.
    paths : iterable of str or Path
        Files (``.amc``, ``.bvh``, ``.c3d``, ``.npz``) or folders, searched
        recursively (:func:`mocapdb.readers.motion_files`).
    options : ReaderOptions, optional, keyword-only
        How every file is read (:class:`mocapdb.readers.ReaderOptions`: the
        AMC skeleton, joint and marker maps, marker rules, the body model of
        AMASS takes, the decompression cap); those of each file's type are
        stored in ``motions.reader_options``.
        Default: every file by its own rules.
    progress : callable, optional, keyword-only
        Called as ``progress(n_files_done, n_files, path)`` once per file (the
        ``progress(n_done, n_total, …)`` of every long command); one call at a
        time, possibly from ingest's writer thread (the one storing batches).
    workers : int, keyword-only
        How many files are hashed, read and turned into features at once:
        worker processes for an archive (:mod:`mocapdb.storage.ingest_pool`),
        threads for a few files.
    replace : bool, keyword-only
        Read files whose bytes are already stored again and replace those
        motions (a new id; their annotations go), e.g. with a corrected
        ``joint_map``. Default: skip them.
    log_csv : str or Path, optional, keyword-only
        Also write the run's ``ingest_log`` rows to this CSV file
        (:func:`mocapdb.storage.ingest_log.write_report`), also when the call fails.

    Returns
    -------
    IngestReport
        Ingested, skipped (already stored) and failed files with reasons;
        ``run_id`` names the call's rows in ``ingest_log``.

    Notes
    -----
    A file that fails to read is never stored, so it changes nothing. Files
    that computed are stored in batches, one transaction per batch
    (DESIGN.md §6: "one transaction per file or batch"); if storing a batch
    fails, its files are retried one transaction each, so a failure stays
    confined to its file. Every file gets its row in ``ingest_log``
    (:mod:`mocapdb.storage.ingest_log`), a stored one in its batch's
    transaction, the others in transactions of their own — also when the
    call fails (a path that does not exist is logged, then raised).
    """
    report = IngestReport()
    log = IngestLog(con, "ingest")
    report.run_id = log.run_id
    try:
        _ingest(con, paths, report, log, options=options or ReaderOptions(), progress=progress, workers=workers,
                replace=replace)
    except BaseException:
        with contextlib.suppress(Exception):   # the call's own error, not the log's, is what to report
            log.add_report(report)
            log.flush()
            if log_csv is not None:
                write_report(con, log.run_id, log_csv)
        raise
    log.add_report(report)
    log.flush()
    if log_csv is not None:
        write_report(con, log.run_id, log_csv)
    return report


def _ingest(con, paths, report, log, *, options, progress, workers, replace):
    paths = list(paths)
    # a worker process starts while the folders are walked (the walk holds one core; head_start)
    with head_start(workers, any(os.path.isdir(p) for p in paths)) as started:
        _ingest_walked(con, _walk(paths, report, log), report, log, started, options=options, progress=progress,
                       workers=workers, replace=replace)


def _walk(paths, report, log) -> list:
    """The motion files of ``paths`` (folders searched), what is not one reported as the walk finds it."""
    files = []
    for p in paths:
        try:
            files += motion_files([p], unsupported=report.unsupported, unreadable=report.unreadable,
                                  refused=report.failed, hidden=report.skipped)
        except ParameterError as exc:   # a path that is not there: logged, and the call fails
            log.add(p, "failed", str(exc))
            raise
    return files


def _ingest_walked(con, files, report, log, started, *, options, progress, workers, replace):
    """Read and store ``files`` (walked), on the pool of ``workers`` (taking the processes ``started``)."""
    # what the walk refused (an earlier copy of a zip member) is keyed by a path a later copy may share:
    # only the files read and failed make a copy of them fail
    walk_refused = len(report.failed)
    tick = _ticker(progress, len(files))
    stored = _stored_keys(con)
    late = []         # files to read after the pass: stored ones read again, and any a stored prefix held back
    already = []      # (path, prep, key) of files whose bytes are stored: decided after the pass
    first_of = {}     # key -> the first file of this ingest with those bytes
    duplicates = []   # (path, key): decided once the first file is read
    processes = use_processes(len(files), sum(_size(f) for f in files), workers)
    batches = _Batches(con, report, log, tick)
    # one pass: each file is hashed, and read unless its bytes may be stored, in the pool, from one read;
    # the decisions below stay in file order (a later copy of a file's bytes is read and dropped)
    token = uuid.uuid4().hex
    setup = (remember_stored, (token, stored_prefixes(k[0] for k in stored)))
    try:
        with executor(workers, processes, setup, started) as pool, batches:
            window, chunk = window_for(workers), chunk_for(processes)
            results = ordered(pool, _read_new, [(f, options, token) for f in files], window=window, chunk=chunk)
            # once every file left is in flight, the batch is stored while the pool reads them: what is stored
            # after the pool's last file (the cores' idle end) is at most the files in flight
            tail = len(files) - window * chunk
            for i, (path, prep) in enumerate(zip(files, results)):
                if i == tail:
                    batches.flush()
                if isinstance(prep, (str, WorkerDied)):   # a compression bomb stops here, while it is hashed
                    report.failed.append((str(path), prep if isinstance(prep, str) else f"{path}: {prep}"))
                    tick(path)
                    continue
                key = (prep.sha256, prep.skeleton_sha256)
                if key in stored:
                    already.append((path, prep, key))
                elif key in first_of:
                    duplicates.append((path, key))
                else:
                    first_of[key] = str(path)
                    if prep.deferred:
                        late.append(prep)
                    else:
                        batches.add(prep)
            batches.wait()   # the connection is the writer's until its last store is done
            _decide_stored(con, report, already, stored, first_of, duplicates, late, replace, tick)
            for sent, prep in zip(late, ordered(pool, _compute_slim, late, window=window, chunk=chunk)):
                if isinstance(prep, WorkerDied):
                    prep, sent.error = sent, f"{sent.path}: {prep}"
                batches.add(prep)
            batches.flush()   # stored before the pool closes (leaving the `with` waits for it)
    finally:
        forget_stored(token)
    # a copy of a stored file is skipped; a copy of a broken one is as broken
    failed = dict(report.failed[walk_refused:])
    for path, key in duplicates:
        first = first_of[key]
        if first in failed:
            report.failed.append((str(path), f"{path}: same bytes as {first}, which failed: {failed[first]}"))
        else:
            report.skipped.append((str(path), f"same bytes as {first} of this ingest"))
        tick(path)


def _decide_stored(con, report, already, stored, first_of, duplicates, todo, replace, tick):
    """Files whose bytes are stored: skipped, or read again (``replace``, or incomplete stored features)."""
    # a stored motion is read again and replaced, in the insert's transaction, with replace=True, or
    # when its features are incomplete (an import of a partial archive by an older mocapdb)
    broken = {mid: reason for mid, _, reason in incomplete_motions(con, [stored[k] for _, _, k in already])}
    for path, prep, key in already:
        mid = stored[key]
        if mid not in broken and not replace:
            report.skipped.append((str(path), f"already ingested as motion {mid} (replace=True, "
                                              "ingest --replace, reads it again)"))
            tick(path)
        elif key in first_of:
            duplicates.append((path, key))
        else:
            first_of[key] = str(path)
            prep.replaces = mid
            if mid in broken:
                report.repaired.append((str(path), broken[mid]))
                prep.log_reason = f"repaired motion {mid}: {broken[mid]}"
            else:
                prep.log_reason = f"replaces motion {mid} (replace=True: read again)"
            todo.append(prep)


class _Batches:
    """Computed files stored a batch (one transaction) at a time, in the order they are added.

    A batch is stored on a writer thread while the caller goes on taking the pool's results: a commit
    (~0.2-0.5 s for 1,024 files) no longer holds up the consumer, whose pace is what hands the workers their
    next tasks, so they do not run out of work during it (RESULTS.md, issue 35: the timeline of an ingest).
    At most one batch is being stored and one filled; the connection is the writer's while a store is
    under way (:meth:`wait` before using it). ``with`` waits for the last store, also on an error."""

    def __init__(self, con, report, log, tick):
        self.con, self.report, self.log, self.tick = con, report, log, tick
        self.batch = []
        self.frames = 0
        self._writer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mocapdb-store")
        self._storing = None   # the future of the batch being stored

    def add(self, prep):
        """One computed file: a failed one is reported, a read one stored with its batch."""
        if prep.error is not None:
            self.report.failed.append((str(prep.path), prep.error))
            self.tick(prep.path)
            return
        self.batch.append(prep)
        self.frames += prep.motion.n_frames
        if len(self.batch) >= BATCH_FILES or self.frames >= BATCH_FRAMES:
            self.flush()

    def flush(self):
        """Hand the batch to the writer (after the previous one is stored: memory stays two batches)."""
        if not self.batch:
            return
        batch, self.batch, self.frames = self.batch, [], 0
        self.wait()
        self._storing = self._writer.submit(self._store, batch)

    def wait(self):
        """Wait until the batches handed over are stored; a store's unexpected error is raised here."""
        storing, self._storing = self._storing, None
        if storing is not None:
            storing.result()

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        try:
            if kind is None:
                self.wait()
            else:   # the caller's own error is what to report; a store under way still ends (and commits)
                with contextlib.suppress(Exception):
                    self.wait()
        finally:
            self._writer.shutdown(wait=True)

    def _store(self, batch):
        """Store a batch: one transaction; if it fails, one per file, so a failure stays with its file."""
        report, log = self.report, self.log
        try:
            ids = store_motions(self.con, batch, log=log)
        except Exception:  # noqa: BLE001 - retried file by file below
            ids = []
            for p in batch:  # one transaction each: a failure stays with its file
                try:
                    ids.extend(store_motions(self.con, [p], log=log))
                except Exception as exc:  # noqa: BLE001 - reported per file
                    report.failed.append((str(p.path), f"{p.path}: not stored ({exc})"))
                    ids.append(None)
        repaired = {r[0] for r in report.repaired}
        for p, mid in zip(batch, ids):
            if mid is not None:
                report.ingested.append((str(p.path), mid, int(p.words.shape[0])))
                if p.replaces is not None and str(p.path) not in repaired:
                    report.replaced.append((str(p.path), p.replaces))
                report.source_frames += p.motion.n_frames
                report.notes.extend((str(p.path), note) for note in p.notes)
            self.tick(p.path)
            p.motion = p.words = None  # free memory early on big archives
        # the rows of the files that failed or were skipped so far, after the batch's commit
        log.add_report(report)
        log.flush()


def _size(path) -> int:
    """The bytes a file holds, as far as known without reading it (0 when not known: a compressed stream)."""
    try:
        return stream_size(path) or 0
    except (OSError, KeyError, ValueError):
        return 0


def _ticker(progress, total):
    """``tick(path)``: one more file of ``total`` done, told to ``progress``."""
    done = 0
    lock = threading.Lock()   # ticked by ingest's thread and by its writer (_Batches): counts stay in order

    def tick(path):
        nonlocal done
        with lock:
            done += 1
            if progress is not None:
                progress(done, total, path)
    return tick


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


__all__ = ["ingest_files", "IngestReport", "store_motions", "store_words", "delete_motions", "remove_motions",
           "insert_motions", "insert_features", "motions_table"]
