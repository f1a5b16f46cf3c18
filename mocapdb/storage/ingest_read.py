"""The per-file half of ingest, what its worker processes run: a file's fingerprint, then its motion and words.

A module of its own, importing only the readers and features: an ingest worker process
(:mod:`mocapdb.storage.ingest_pool`) unpickles these functions, and importing the database side
(DuckDB, Arrow, the index) as well cost each worker ~0.2 CPU-s of its start (issue 35).
"""
from __future__ import annotations

import contextlib
import json
import logging
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mocapdb.errors import MocapdbError
from mocapdb.features import motion_features
from mocapdb.readers import ReaderOptions, find_skeleton, skeleton_note
from mocapdb.readers.files import check_start, read_options
from mocapdb.readers.sources import FileCache, as_path, holding, motion_suffix, read_held, sha256, special_kind

log = logging.getLogger("mocapdb")


@dataclass
class _Prepared:
    path: Path
    sha256: str
    skeleton_path: Path | None
    skeleton_sha256: str | None
    motion: object = None
    words: np.ndarray | None = None
    error: str | None = None
    options: ReaderOptions = field(default_factory=ReaderOptions)   # how it is read (the skeleton: skeleton_path)
    reader_options: str | None = None  # JSON stored in motions.reader_options: its options, the reader's notes
    replaces: int | None = None  # the stored motion of the same bytes this one replaces (replace=True,
    #                              or its stored features are incomplete)
    notes: list = field(default_factory=list)   # what the reader decided (stored under reader_options "notes")
    log_reason: str | None = None   # the ingest_log reason of a stored file: the motion it replaces
    deferred: bool = False   # fingerprinted only, not read (its bytes may be stored already: _read_new)


#: skeletons' SHA-256 by file identity (path, size, mtime; a member's CRC), like the skeletons themselves
_SKELETON_SHA256 = FileCache(64)


def _skeleton_sha256(skel) -> str:
    """The skeleton's SHA-256, from :data:`_SKELETON_SHA256` when its file has not changed."""
    try:
        return _SKELETON_SHA256.get(skel, sha256)
    except (KeyError, zipfile.BadZipFile):   # a member that is not there, a damaged archive: as sha256 words it
        return sha256(skel)


def _fingerprint(path: Path, asf) -> _Prepared:
    """The file's and its skeleton's hashes: the key that makes re-ingest a no-op."""
    kind = special_kind(path)
    if kind is not None:   # opening a FIFO would block, a device never end
        raise MocapdbError(f"{path}: {kind}, not a motion file")
    skel = None
    if motion_suffix(path) == ".amc":
        skel = as_path(asf) if asf is not None else find_skeleton(path)
    try:
        check_start(path)   # what its first bytes refuse is not hashed whole first (a gigabyte of NUL bytes)
        digest = sha256(path)
    except OSError as exc:
        raise MocapdbError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    try:
        # an actor's skeleton is hashed once per ingest (per worker), not once per take
        skel_digest = _skeleton_sha256(skel) if skel is not None else None
    except OSError as exc:
        # the skeleton is what cannot be read: say so under its name
        raise MocapdbError(f"{skel}: cannot read this skeleton of {path} ({exc.strerror or exc})") from None
    return _Prepared(path, digest, skel, skel_digest)


def prepare_file(path, options=None):
    """Fingerprint one file as ingest does, before reading it.

    Parameters
    ----------
    path : str or Path
    options : ReaderOptions, optional
        How files are read (:class:`mocapdb.readers.ReaderOptions`; its
        ``asf``, else the AMC's skeleton by the dataset conventions). Its
        decompression cap applies to the hashing: a compression bomb stops
        here.

    Returns
    -------
    record
        ``path``, ``sha256``, ``skeleton_path`` and ``skeleton_sha256`` (the
        ``motions`` key), ``options`` and ``reader_options`` (what the
        motion stores); the input of :func:`compute_motion`.

    Raises
    ------
    MocapdbError
        If an AMC file's skeleton cannot be found, or the file cannot be read.
    """
    options = options or ReaderOptions()
    with options.capped():
        prep = _fingerprint(as_path(path), options.asf)
    prep.options = options
    prep.reader_options = options.stored(prep.path)
    return prep


def compute_motion(prep):
    """Read a prepared file and compute its 30 Hz feature words, as ingest does.

    Sets ``prep.motion`` (:class:`mocapdb.bodies.Motion`) and ``prep.words``
    ((n_frames,) uint64), or ``prep.error`` (the reader's message) when the
    file cannot be read; returns ``prep``.
    """
    return _compute(prep, checked=False)


def _compute(prep, checked: bool):
    """:func:`compute_motion`; ``checked``: the file's bytes are held and were fingerprinted so (its kind
    and start checked: :func:`~mocapdb.readers.files.read_options`)."""
    # any failure stays with its file: a reader raises only MocapdbError, but a
    # bug must not stop the other files of an archive (READERS.md §4)
    try:
        prep.motion = read_options(prep.path, _with_skeleton(prep.options, prep.skeleton_path), checked=checked)
        prep.words = motion_features(prep.motion)
        prep.notes = _notes(prep)
        if prep.notes or prep.motion.meta.get("frames", (1, None))[0] != 1:
            # kept with the motion; the re-read path (storage.motions.source_motion) gives only the
            # reader's own options back to the reader (ReaderOptions.from_stored)
            options = prep.options.for_file(prep.path)
            options["notes"] = prep.notes
            first, last = prep.motion.meta.get("frames", (1, prep.motion.n_frames))
            options["source_frames"] = [int(first), int(last)]
            prep.reader_options = json.dumps(options, sort_keys=True)
    except MocapdbError as exc:
        prep.error = str(exc)
    except Exception as exc:  # noqa: BLE001 - reported per file, never raised
        log.warning("internal error reading %s", prep.path, exc_info=True)
        prep.error = f"{prep.path}: internal error while reading ({type(exc).__name__}: {exc}); please report it"
    if prep.error is not None:
        prep.motion = prep.words = None
    return prep


#: ``(options, skeleton path)`` → the options with that skeleton: an archive's takes share a few (a
#: ``replace`` checks every field again: ~10 µs a take)
_WITH_SKELETON = {}


def _with_skeleton(options, skeleton_path):
    """``options.replace(asf=skeleton_path)``, kept for the next take of the same pair."""
    key = (options, skeleton_path)
    hit = _WITH_SKELETON.get(key)
    if hit is None:
        if len(_WITH_SKELETON) >= 256:
            _WITH_SKELETON.clear()
        hit = _WITH_SKELETON[key] = options.replace(asf=skeleton_path)
    return hit


def _notes(prep) -> list:
    """The reader's notes for a computed file, with the skeleton found by the folder rule."""
    notes = list(prep.motion.meta.get("notes", ()))
    if prep.skeleton_path is not None and motion_suffix(prep.path) == ".amc":
        note = skeleton_note(prep.path, prep.skeleton_path)
        if note and note not in notes:
            notes.insert(0, note)
    return notes


@contextlib.contextmanager
def read_once(path):
    """Within the block (this thread), hashing ``path`` and reading it share one read of its bytes (a plain
    file up to :data:`~mocapdb.readers.sources.HOLD_MAX`; anything else is streamed as before). Yields
    whether the bytes are held."""
    try:
        data = read_held(path)   # None for a FIFO or device (looked at before it is opened), as for a large file
    except OSError:
        data = None   # the fingerprint reads it again and words what fails
    with holding(path, data):
        yield data is not None


def _read_new(item):
    """What ingest's pool runs per file, ``(path, options, token)``: its fingerprint and — unless its bytes
    may be stored already (:func:`remember_stored` under ``token``) — its motion and words, hashed and read
    from one read of the file (a plain file up to :data:`~mocapdb.readers.sources.HOLD_MAX`); the record
    (``deferred`` when not read), or the one-line reason its fingerprint failed."""
    path, options, token = item
    path = as_path(path)
    with read_once(path) as held:
        try:
            prep = prepare_file(path, options)
        except MocapdbError as exc:
            return str(exc)
        if _maybe_stored(token, prep.sha256) or _seen(token, (prep.sha256, prep.skeleton_sha256)):
            prep.deferred = True
            return prep
        # the bytes the fingerprint checked and hashed are the bytes read: not checked again
        return _compute_slim(prep, checked=held)


#: the stored files' SHA-256 prefixes (sorted uint64) of the ingests running here, by token
_STORED = {}
#: the keys (file and skeleton SHA-256) this process has read in each ingest, by token: a later copy of the
#: same bytes is only fingerprinted (ingest skips it, or reads it after the pass if it was the first in file
#: order after all); at most :data:`_SEEN_MAX` per ingest (then it starts over: a copy is read and dropped)
_SEEN = {}
_SEEN_MAX = 1 << 16


def remember_stored(task):
    """``(token, prefixes)``: the first 64 bits of every stored file's SHA-256 (sorted uint64), which
    :func:`_read_new` of that ingest's files consults (in a worker process, set once per worker)."""
    token, prefixes = task
    _STORED[token] = prefixes


def forget_stored(token):
    """Drop what :func:`remember_stored` kept under ``token`` (the ingest is over)."""
    _STORED.pop(token, None)
    _SEEN.pop(token, None)


def _seen(token, key) -> bool:
    """Whether this process read a file of ``key`` in the ingest ``token`` already (and note that it has)."""
    seen = _SEEN.setdefault(token, set())
    if key in seen:
        return True
    if len(seen) >= _SEEN_MAX:
        seen.clear()
    seen.add(key)
    return False


def stored_prefixes(digests) -> np.ndarray:
    """The sorted unique first 64 bits of SHA-256 hex digests (what :func:`remember_stored` takes)."""
    return np.unique(np.array([int(d[:16], 16) for d in digests if isinstance(d, str) and len(d) >= 16],
                              dtype=np.uint64))


def _maybe_stored(token, digest) -> bool:
    """Whether a file of this digest may be stored already (its 64-bit prefix is): such a file is only
    fingerprinted; the caller decides whether to read it (a prefix shared by other bytes is read then)."""
    prefixes = _STORED.get(token)
    if prefixes is None or not len(prefixes):
        return False
    v = np.uint64(int(digest[:16], 16))
    i = int(np.searchsorted(prefixes, v))
    return i < len(prefixes) and prefixes[i] == v


@dataclass(frozen=True)
class _Computed:
    """What storing a computed file needs of its :class:`~mocapdb.bodies.Motion`: a pool's worker sends
    this back, never the joints."""
    name: str | None
    source_format: str
    fps: float
    n_frames: int
    skeleton: str | None


def _compute_slim(prep, checked: bool = False):
    """:func:`compute_motion` with the motion reduced to :class:`_Computed` (``checked``: see :func:`_compute`)."""
    _compute(prep, checked)
    m = prep.motion
    if m is not None:
        prep.motion = _Computed(m.name, m.source_format, float(m.fps), int(m.n_frames), m.skeleton)
    return prep


__all__ = ["prepare_file", "compute_motion", "read_once", "remember_stored", "forget_stored", "stored_prefixes"]
