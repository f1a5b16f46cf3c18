"""What a connection keeps in memory: parsed models and the keyframe index.

A model is parsed once per connection and kept while its fingerprint stays
the same; the stored keyframe index (``mocap_index.postings``) is loaded once
and kept while ``mocap_index.state.version`` stays the same (ingest, delete
and import bump it in their transaction), together with the keyframe search
results of each model on it. The SQL functions pass the fingerprint and the
version in, so a UDF never queries its connection unless something changed;
then the cache re-reads through a cursor of the connection, which also works
inside a UDF.
"""
from __future__ import annotations

import threading
import weakref

import numpy as np

from mocapdb.annotation import keyframe_preselection, preselection_slices
from mocapdb.errors import SchemaError
from mocapdb.storage.models import (SHIPPED_MODELS, model_fingerprint, model_from_tables, read_model_tables,
                                    shipped_model_tables, unknown_model)
from mocapdb.storage.postings import index_version, load_index, motion_positions
from mocapdb.storage.sqltext import INDEX_SCHEMA

#: "ask the database" (the caller did not pass a fingerprint or version)
UNKNOWN = object()

NO_INDEX = (f"this database has no keyframe index ({INDEX_SCHEMA}.postings); build it with "
            "`mocapdb create-index` (mocapdb.api.create_index), or annotate without keyframes "
            "(--no-keyframes, keyframes := false)")


class ConnectionCache:
    """Models and the keyframe index of one connection (see the module docstring)."""

    def __init__(self, con):
        self._con = weakref.ref(con)
        self._lock = threading.Lock()
        self._models = {}      # name -> (fingerprint, Model)
        self._index = None     # (version, Index, motion ids)
        self._found = {}       # (model name, fingerprint, version) -> keyframe_preselection output

    def _cursor(self):
        con = self._con()
        if con is None:
            raise SchemaError("the connection of this cache is closed")
        return con.cursor()

    def model(self, name, fingerprint=UNKNOWN):
        """The model ``name``; ``fingerprint`` as stored (None: not in the database).

        Returns
        -------
        key : tuple
            (name, fingerprint) — identifies the parsed model.
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
                if fingerprint is None and name in SHIPPED_MODELS:
                    # a read-only database without the shipped models: read them from the package
                    fingerprint = "shipped"
                hit = self._models.get(name)
                if hit is not None and hit[0] == fingerprint:
                    return (name, fingerprint), hit[1]
                if fingerprint == "shipped":
                    model = model_from_tables(shipped_model_tables(name))
                else:
                    cur = cur or self._cursor()
                    if fingerprint is None:
                        raise unknown_model(cur, name)
                    model = model_from_tables(read_model_tables(cur, name))
                self._models[name] = (fingerprint, model)
                return (name, fingerprint), model
            finally:
                if cur is not None:
                    cur.close()

    def clear(self) -> None:
        """Forget the parsed models and the loaded index (the connections are gone)."""
        with self._lock:
            self._models, self._index, self._found = {}, None, {}

    def index(self, version=UNKNOWN):
        """The stored keyframe index: ``(version, Index, motion_ids)``.

        Raises
        ------
        SchemaError
            If the database has no keyframe index.
        """
        with self._lock:
            cur = None
            try:
                if version is UNKNOWN:
                    cur = self._cursor()
                    version = index_version(cur)
                if version is None:
                    raise SchemaError(NO_INDEX)
                if self._index is None or self._index[0] != version:
                    cur = cur or self._cursor()
                    index, ids = load_index(cur)
                    self._index = (version, index, ids)
                    self._found = {}
                return self._index
            finally:
                if cur is not None:
                    cur.close()

    def preselection(self, key, model, motion_ids, lengths, *, version=UNKNOWN):
        """The keyframe preselection of ``model`` for motions, from the stored index.

        The search over the whole index runs once per model and index version;
        this call only picks the motions' segments.

        Parameters
        ----------
        key : tuple
            The model's key from :meth:`model`.
        model : mocapdb.annotation.Model
        motion_ids : (n,) int
            The motions to annotate, in concatenation order.
        lengths : (n,) int
            Their word counts.

        Returns
        -------
        list
            The ``preselection`` input of :func:`mocapdb.annotation.annotate`.
        """
        version, index, ids = self.index(version)
        with self._lock:
            found = self._found.get((key, version))
            if found is None:
                found = self._found[(key, version)] = keyframe_preselection(index, model)
        motion_ids = np.asarray(motion_ids, dtype=np.int64)
        docs = motion_positions(ids, motion_ids) if len(ids) else np.zeros(len(motion_ids), np.int64)
        inside = (docs < len(ids)) & (ids[np.minimum(docs, len(ids) - 1)] == motion_ids) if len(ids) else \
            np.zeros(len(motion_ids), bool)
        if not inside.all():
            missing = motion_ids[~inside].tolist()
            raise SchemaError(f"motions {missing} are not in the keyframe index; rebuild it with "
                              "`mocapdb create-index`")
        return preselection_slices(found, docs, lengths)


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
    (:mod:`mocapdb.extension.connection`), so a model or the index is parsed once."""
    with _CACHES_LOCK:
        _CACHES[con] = cache


__all__ = ["ConnectionCache", "connection_cache", "share_cache", "UNKNOWN", "NO_INDEX"]
