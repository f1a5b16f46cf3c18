"""What a connection keeps in memory: parsed models and recently used pieces of the keyframe index.

A model is parsed once per connection and kept while its fingerprint stays
the same. The keyframe index is never held whole: an archive of any size is
searched a batch of motions at a time, each batch's postings read from
``mocap_index.postings`` (:func:`mocapdb.storage.postings.load_index`), so
memory follows the batch (:data:`mocapdb.storage.motions.BATCH_FRAMES`), not
the archive. The batches loaded stay while they fit in
:data:`INDEX_CACHE_BYTES` (the first ones of a pass, when the archive is larger) and ``mocap_index.state.version`` stays the same
(ingest, delete and import bump it in their transaction): on an archive of a
few hours the whole index is one batch, loaded once per connection. The SQL
functions pass the fingerprint and the version in, so a UDF queries its
connection only for what changed or is not kept; it reads through a cursor of
the connection, which also works inside a UDF.
"""
from __future__ import annotations

import contextlib
import threading
import weakref
from collections import OrderedDict

import numpy as np

from mocapdb.annotation import index_parts, keyframe_preselection, model_index_parts, preselection_slices
from mocapdb.errors import SchemaError
from mocapdb.keyframes import keyframe_search
from mocapdb.storage.model_store import load_model, model_fingerprint, model_version
from mocapdb.storage.motions import BATCH_FRAMES, frame_batches
from mocapdb.storage.postings import index_version, load_index
from mocapdb.storage.sqltext import INDEX_SCHEMA, statement

#: "ask the database" (the caller did not pass a fingerprint or version)
UNKNOWN = object()

NO_INDEX = (f"this database has no keyframe index ({INDEX_SCHEMA}.postings); build it with "
            "`mocapdb create-index` (mocapdb.api.create_index), or annotate without keyframes "
            "(--no-keyframes, keyframes := false)")

#: index batches kept per connection (Index arrays): a batch of BATCH_FRAMES frames is about 30 MB
#: with every part (annotation), 13 MB with the ``full`` runs alone (query by example), so the
#: runs of a 100 h archive stay in memory and a query by example reads no postings
INDEX_CACHE_BYTES = 192 * 2**20


class ConnectionCache:
    """Models and index batches of one connection (see the module docstring).

    Attributes
    ----------
    batch_frames : int
        Frames of a batch of motions in this connection's archive-wide passes
        (SQL functions, ``mocapdb.api.annotate``); default
        :data:`~mocapdb.storage.motions.BATCH_FRAMES`.
    """

    def __init__(self, con):
        self.batch_frames = BATCH_FRAMES
        self._con = weakref.ref(con)
        self._lock = threading.Lock()
        self._models = {}                # name -> (fingerprint, Model)
        self._indexes = OrderedDict()    # (version, parts, motion ids) -> Index, in the order loaded

    def _cursor(self):
        con = self._con()
        if con is None:
            raise SchemaError("the connection of this cache is closed")
        return con.cursor()

    def check(self):
        """Raise when the work reading through this cache was cancelled (the connection's ``check()``:
        ``mocapdb serve``'s requests, :class:`mocapdb.api.reading.Request`); a no-op on other connections.
        Long passes call it between batches, where a DuckDB interrupt cannot reach (numba kernels)."""
        check = getattr(self._con(), "check", None)
        if check is not None:
            check()

    @contextlib.contextmanager
    def cursor(self):
        """A cursor of the connection for the ``with`` block (works inside a UDF, where the
        connection itself is busy with the query calling it)."""
        cur = self._cursor()
        try:
            yield cur
        finally:
            cur.close()

    def model(self, name, fingerprint=UNKNOWN):
        """The model ``name``, parsed once while its version stays the same.

        Parameters
        ----------
        name : str
        fingerprint : str or None
            As stored (None: not in the database); default: ask the database.
            :func:`~mocapdb.storage.model_store.load_model` reads it (or the package's
            copy of a shipped model the database lacks).

        Returns
        -------
        key : tuple
            (name, version) — identifies the parsed model (version: see
            :func:`~mocapdb.storage.model_store.model_version`).
        model : mocapdb.annotation.Model
        """
        if name is None:
            raise SchemaError("model is NULL; give a model name (default: 'default')")
        with self._lock:
            cur = None
            try:
                if fingerprint is UNKNOWN:
                    cur = self._cursor()
                    fingerprint = model_fingerprint(cur, name)
                version = model_version(name, fingerprint)
                hit = self._models.get(name)
                if hit is not None and hit[0] == version:
                    return (name, version), hit[1]
                cur = cur or self._cursor()
                model = load_model(cur, name, version=version)
                self._models[name] = (version, model)
                return (name, version), model
            finally:
                if cur is not None:
                    cur.close()

    def clear(self) -> None:
        """Forget the parsed models and the index batches kept (the connections are gone)."""
        with self._lock:
            self._models, self._indexes = {}, OrderedDict()

    def version(self, version=UNKNOWN):
        """The keyframe index version (``version`` if given).

        Raises
        ------
        SchemaError
            If the database has no keyframe index.
        """
        if version is UNKNOWN:
            cur = self._cursor()
            try:
                version = index_version(cur)
            finally:
                cur.close()
        if version is None:
            raise SchemaError(NO_INDEX)
        return version

    def batch_index(self, motion_ids, lengths, parts, *, version=UNKNOWN):
        """The stored keyframe index of some motions.

        Parameters
        ----------
        motion_ids : (n,) int, ascending
        lengths : (n,) int
            Their frame counts.
        parts : tuple of str
            The index parts to load.

        Returns
        -------
        mocapdb.keyframes.Index
            Document ``d`` is ``motion_ids[d]``.
        """
        version = self.version(version)
        ids = np.asarray(motion_ids, dtype=np.int64)
        key = (version, tuple(parts), ids.tobytes())
        with self._lock:
            hit = self._indexes.get(key)
            if hit is not None:
                return hit
            cur = self._cursor()
            try:
                index, _ = load_index(cur, parts=parts, motions=(ids, lengths))
            finally:
                cur.close()
            if any(k[0] != version for k in self._indexes):  # the index changed: what is kept is stale
                self._indexes.clear()
            # Archive-wide passes read the batches in the same order every time. Evicting the least
            # recently used batch would then miss on every batch of an archive larger than the cache;
            # evicting the one loaded last keeps the first batches for the next pass (the classic
            # policy for cyclic scans), so the part of the archive that fits is read once.
            kept = sum(x.nbytes for x in self._indexes.values())
            while self._indexes and kept + index.nbytes > INDEX_CACHE_BYTES:
                kept -= self._indexes.popitem(last=True)[1].nbytes
            self._indexes[key] = index
            return index

    def preselection(self, key, model, motion_ids, lengths, *, version=UNKNOWN):
        """The keyframe preselection of ``model`` for some motions, from their stored postings.

        Parameters
        ----------
        key : tuple
            The model's key from :meth:`model` (kept for callers; the search depends on the model only).
        model : mocapdb.annotation.Model
        motion_ids : (n,) int
            The motions to annotate, in concatenation order (each once).
        lengths : (n,) int
            Their word counts.

        Returns
        -------
        list
            The ``preselection`` input of :func:`mocapdb.annotation.annotate`.
        """
        motion_ids = np.asarray(motion_ids, dtype=np.int64)
        lengths = np.asarray(lengths, dtype=np.int64)
        order = np.argsort(motion_ids, kind="stable")
        index = self.batch_index(motion_ids[order], lengths[order], model_index_parts(model) or ("full",),
                                 version=version)
        # documents of the index are the motions in id order; the slices follow the caller's order
        docs = np.empty(len(order), np.int64)
        docs[order] = np.arange(len(order))
        return preselection_slices(keyframe_preselection(index, model), docs, lengths)

    def keyframe_search(self, query, *, extend_left=0, extend_right=0, version=UNKNOWN):
        """Segments of every stored motion that contain a keyframe query's chain, a batch of motions at a time.

        Returns
        -------
        motion_id, start, end : (n,) int64
            0-based inclusive 30 Hz frames, sorted by (motion, start).
        """
        version = self.version(version)
        cur = self._cursor()
        try:
            meta = cur.execute(statement("index.sql", "motion_lengths")).fetchnumpy()
        finally:
            cur.close()
        ids = np.asarray(meta["motion_id"], dtype=np.int64)
        lengths = np.asarray(meta["n_frames"], dtype=np.int64)
        parts = index_parts([query]) or ("full",)
        found = [(np.zeros(0, np.int64),) * 3]
        for a, b in frame_batches(lengths, self.batch_frames):
            index = self.batch_index(ids[a:b], lengths[a:b], parts, version=version)
            segs = keyframe_search(index, query, extend_left=int(extend_left), extend_right=int(extend_right))
            found.append((ids[a:b][segs.doc], segs.start, segs.end))
        return tuple(np.concatenate(x) for x in zip(*found))


_CACHES: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
_CACHES_LOCK = threading.Lock()


def connection_cache(con) -> ConnectionCache:
    """The cache of a connection (created on first use, gone with the connection)."""
    with _CACHES_LOCK:
        cache = _CACHES.get(con)
        if cache is None:
            cache = _CACHES[con] = ConnectionCache(con)
        return cache


def share_cache(con, cache) -> None:
    """Make ``con`` use ``cache``: the connections of one database instance share one
    (:mod:`mocapdb.extension.connection`), so a model or an index batch is read once."""
    with _CACHES_LOCK:
        _CACHES[con] = cache


__all__ = ["ConnectionCache", "connection_cache", "share_cache", "UNKNOWN", "NO_INDEX", "INDEX_CACHE_BYTES"]
