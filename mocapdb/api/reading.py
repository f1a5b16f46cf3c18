"""A database file read by many short requests of one process (``mocapdb serve``): opened read-only for each,
never held between them, and each request interruptible.

DuckDB lets one process write a database file, and no other process open it
meanwhile, not even read-only. A reader that kept the file open would
therefore lock every ``ingest``, ``annotate`` or ``delete`` out for as long as
it runs. So :class:`SharedReader` opens the file read-only when a request
comes (waiting up to ``wait`` seconds for a writer, the one lock-wait of
:func:`mocapdb.storage.schema.open_database`) and closes it when the answer is
ready; between requests the file is free.

What is worth keeping between requests is kept in memory, not in a
connection: one :class:`~mocapdb.storage.cache.ConnectionCache` (parsed
models, the keyframe index batches that query by example reads) is shared by
the connection of every request. Its entries are keyed by the model's
fingerprint and the index version, which every write changes, so what it
keeps is never stale; a new file at the path (another inode) starts a fresh
cache. (The connections are DuckDB's own, without the SQL functions of
:func:`mocapdb.api.connect`: those are registered per database instance, and
an instance per request would register them anew each time.)

A request may be cancelled from another thread (:meth:`Request.cancel`, say
when it runs out of time): its connection and every cursor of it are
interrupted (DuckDB's ``interrupt()``), and no query starts on them after.
"""
from __future__ import annotations

import contextlib
import os
import threading
from pathlib import Path

import duckdb

from mocapdb.errors import MocapdbError, SchemaError
from mocapdb.storage.cache import ConnectionCache, share_cache
from mocapdb.storage.schema import DatabaseLockedError, check_database_file, open_database

__all__ = ["SharedReader", "Request", "RequestCancelled", "DatabaseLockedError"]


class RequestCancelled(MocapdbError):
    """The request was cancelled (out of time, or its client left) and its work interrupted."""


class Request:
    """One request's connections (its own and each cursor of it): cancelled and interrupted together."""

    def __init__(self):
        self.reason = None
        self._cons = []
        self._lock = threading.Lock()

    def track(self, con):
        with self._lock:
            self._cons.append(con)
            cancelled = self.reason is not None
        if cancelled:
            con.interrupt()

    def cancel(self, reason):
        """Stop the request's DuckDB work (from any thread); ``reason`` is what :class:`RequestCancelled` says."""
        with self._lock:
            if self.reason is None:
                self.reason = reason
            cons = list(self._cons)
        for con in cons:
            with contextlib.suppress(duckdb.Error):  # closed already
                con.interrupt()

    def check(self):
        """Raise :class:`RequestCancelled` once the request is cancelled."""
        if self.reason is not None:
            raise RequestCancelled(self.reason)


class _Interruptible:
    """A request's DuckDB connection (or cursor): every method forwarded, its cursors tracked, and no
    query started once the request is cancelled (an ``interrupt()`` reaches only a running query)."""

    def __init__(self, con, request):
        self._con = con
        self._request = request
        request.track(con)

    def __getattr__(self, name):
        return getattr(self._con, name)

    def execute(self, *args, **kwargs):
        self._request.check()
        return self._con.execute(*args, **kwargs)

    def sql(self, *args, **kwargs):
        self._request.check()
        return self._con.sql(*args, **kwargs)

    def cursor(self):
        self._request.check()
        return _Interruptible(self._con.cursor(), self._request)

    def check(self):
        """Raise :class:`RequestCancelled` once the request is cancelled (between two steps of work)."""
        self._request.check()


class _RequestConnection:
    """What the shared cache reads through: the connection of the request the calling thread answers."""

    def __init__(self):
        self.local = threading.local()

    def cursor(self):
        con = getattr(self.local, "con", None)
        if con is None:
            raise SchemaError("no request is reading the archive in this thread")
        return con.cursor()

    def check(self):
        con = getattr(self.local, "con", None)
        if con is not None:
            con.check()


class SharedReader:
    """A database file read by short requests, each with a read-only connection of its own (module docstring).

    Parameters
    ----------
    path : str or Path
        The database file; it must exist.
    wait : float, keyword-only
        Seconds a request waits for a writer's lock before
        :class:`~mocapdb.storage.schema.DatabaseLockedError`.
    memory_limit : str, optional, keyword-only
        DuckDB's memory limit of each request's connection.

    Raises
    ------
    SchemaError
        No file at ``path``, or one that is not a DuckDB database.
    """

    def __init__(self, path, *, wait=1.0, memory_limit=None):
        self.path = Path(path)
        if not self.path.is_file():
            raise SchemaError(f"{self.path}: no such database file (a mistyped --db? `mocapdb ingest` creates one)")
        check_database_file(self.path)   # a CSV or Parquet named as --db: refused before any request opens it
        self.wait = float(wait)
        self.memory_limit = memory_limit
        self._reader = _RequestConnection()
        self._lock = threading.Lock()
        self._cache = None
        self._identity = None

    def _shared_cache(self):
        st = os.stat(self.path)
        with self._lock:
            if self._cache is None or self._identity != (st.st_dev, st.st_ino):
                self._cache = ConnectionCache(self._reader)
                self._identity = (st.st_dev, st.st_ino)
            return self._cache

    @contextlib.contextmanager
    def reading(self, request=None):
        """A read-only connection for the ``with`` block, closed after it (interrupted with ``request``).

        Raises
        ------
        DatabaseLockedError
            Another process has held the file for longer than ``wait``.
        RequestCancelled
            ``request`` is cancelled.
        """
        request = request or Request()
        request.check()
        raw = open_database(self.path, read_only=True, memory_limit=self.memory_limit, wait=self.wait)
        con = _Interruptible(raw, request)
        try:
            share_cache(con, self._shared_cache())
            self._reader.local.con = con
            yield con
        finally:
            self._reader.local.con = None
            raw.close()
