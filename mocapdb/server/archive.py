"""The database as ``mocapdb serve`` reads it: opened read-only for each request, never held between requests.

DuckDB lets one process write a database file, and no other process open it
meanwhile, not even read-only. A server that kept the file open would
therefore lock every ``ingest``, ``annotate`` or ``delete`` out for as long
as it runs. So :class:`Archive` opens the file read-only when a request
comes and closes it when the answer is ready (a page of the archive holds it
for tens of milliseconds); between requests the file is free. While a writer
holds it, a request waits up to :data:`BUSY_WAIT` seconds for it, then
answers "busy" (:class:`~mocapdb.storage.schema.DatabaseLockedError`, HTTP
503: the pages say so and ask again); the first request after the writer
finished sees what it wrote. A writer that starts while a request is being
answered waits for it (``mocapdb.api.connect``'s ``lock_wait``).

What is worth keeping between requests is kept in the server's memory, not
in a connection: one :class:`~mocapdb.storage.cache.ConnectionCache` (parsed
models, the keyframe index batches that query by example reads) is shared by
the connection of every request. Its entries are keyed by the model's
fingerprint and the index version, which every write changes, so what it
keeps is never stale; a new file at the path (another inode) starts a fresh
cache.
"""
from __future__ import annotations

import contextlib
import os
import threading
import time
from pathlib import Path

from mocapdb.errors import SchemaError
from mocapdb.storage.cache import ConnectionCache, share_cache
from mocapdb.storage.model_store import DEFAULT_MODEL
from mocapdb.storage.schema import DatabaseLockedError, open_database

__all__ = ["Archive", "BUSY_WAIT", "DatabaseLockedError"]

#: seconds a request waits for another process's lock on the file before it answers "busy"
BUSY_WAIT = 1.0
#: seconds between two tries to open a locked file
_POLL = 0.05


class _RequestConnection:
    """What the shared cache reads through: the connection of the request the calling thread answers."""

    def __init__(self):
        self.local = threading.local()

    def cursor(self):
        con = getattr(self.local, "con", None)
        if con is None:
            raise SchemaError("no request is reading the archive in this thread")
        return con.cursor()


class Archive:
    """A database file served read-only, opened per request (see the module docstring).

    Parameters
    ----------
    path : str or Path
        The database file; it must exist.
    model : str, keyword-only
        The model whose stored annotations the pages show.
    busy_wait : float, keyword-only
        Seconds a request waits for a writer's lock (:data:`BUSY_WAIT`).
    memory_limit : str, optional, keyword-only
        DuckDB's memory limit of each request's connection.
    """

    def __init__(self, path, *, model=DEFAULT_MODEL, busy_wait=BUSY_WAIT, memory_limit=None):
        self.path = Path(path)
        if not self.path.is_file():
            raise SchemaError(f"{self.path}: no such database file (a mistyped --db?)")
        self.model = model
        self.busy_wait = float(busy_wait)
        self.memory_limit = memory_limit
        self._reader = _RequestConnection()
        self._lock = threading.Lock()
        self._cache = None
        self._identity = None

    def _open(self):
        deadline = time.monotonic() + self.busy_wait
        while True:
            try:
                return open_database(self.path, read_only=True, memory_limit=self.memory_limit)
            except DatabaseLockedError:
                if time.monotonic() >= deadline:
                    raise
                time.sleep(_POLL)

    def _shared_cache(self):
        st = os.stat(self.path)
        with self._lock:
            if self._cache is None or self._identity != (st.st_dev, st.st_ino):
                self._cache = ConnectionCache(self._reader)
                self._identity = (st.st_dev, st.st_ino)
            return self._cache

    @contextlib.contextmanager
    def reading(self):
        """A read-only connection for the ``with`` block, closed after it.

        Raises
        ------
        DatabaseLockedError
            Another process has held the file for longer than ``busy_wait``.
        """
        con = self._open()
        try:
            share_cache(con, self._shared_cache())
            self._reader.local.con = con
            yield con
        finally:
            self._reader.local.con = None
            con.close()
