"""The connection ``mocapdb.connect`` returns: a DuckDB connection whose cursors have the SQL functions too.

Two facts of DuckDB's Python client shape this module:

* Connections to one file in one process share a database **instance**, and
  a Python UDF is registered with the instance, not with the connection
  that created it: a second registration of the same name is a
  ``CatalogException`` (a notebook cell run twice), and every connection of
  the instance, cursors included, sees the UDF.
* DuckDB lets go of the Python function when the connection that
  registered it closes, while the instance (kept open by other connections)
  still calls it.

So the UDFs are registered **once per instance** and held here for as long
as the process lives (a few closures; the models and the index they cache
are dropped when the instance's last connection closes). A registration is
recognised by a token UDF, ``mocap_instance()``. The macros (``annotate``,
``mt_distance``, …) are temporary, that is per connection: every
:class:`Connection` and every cursor of one installs them.
"""
from __future__ import annotations

import threading
import uuid
import weakref

import duckdb
from duckdb import sqltypes as T

from mocapdb.errors import SchemaError
from mocapdb.extension.udfs import register, register_macros
from mocapdb.storage.cache import ConnectionCache, share_cache
from mocapdb.storage.schema import open_database
from mocapdb.storage.sqltext import statement

__all__ = ["Connection", "connect"]


class _Registration:
    """The UDFs of one database instance, the cache they answer from, and its live connections."""

    def __init__(self):
        self.token = uuid.uuid4().hex
        self.connections = weakref.WeakSet()  # raw duckdb connections, cursors included
        self.cache = ConnectionCache(self)
        self.udfs = ()

    def cursor(self):
        """A cursor of any open connection of the instance (the cache reads through it)."""
        for con in list(self.connections):
            try:
                return con.cursor()
            except duckdb.Error:  # closed
                continue
        raise SchemaError("every connection to this database is closed; open it again with mocapdb.connect")

    def add(self, con):
        self.connections.add(con)
        weakref.finalize(con, self.released)

    def released(self, con=None):
        if con is not None:
            self.connections.discard(con)
        if not self.connections:
            self.cache.clear()


#: token → registration; kept for the life of the process (DuckDB may call a UDF while any
#: connection of its instance is open, including one opened by plain duckdb.connect)
_REGISTRATIONS: dict = {}
_LOCK = threading.Lock()


def _registration_of(con):
    """The registration whose UDFs ``con``'s instance has, or None for a fresh instance."""
    try:
        token = con.execute(statement("connection.sql", "instance")).fetchone()[0]
    except duckdb.CatalogException:
        return None
    reg = _REGISTRATIONS.get(token)
    if reg is None:
        raise SchemaError("this database is open in this process with SQL functions registered outside "
                          "mocapdb.connect; open it with mocapdb.connect only")
    return reg


def _attach(con):
    """Give a raw connection the SQL functions: the instance's registration (made on first use)
    and the macros. Returns the registration."""
    with _LOCK:
        reg = _registration_of(con)
        if reg is None:
            reg = _Registration()
            token = reg.token
            reg.udfs = (*register(con, cache=reg.cache), lambda: token)
            con.create_function("mocap_instance", reg.udfs[-1], [], T.VARCHAR)
            _REGISTRATIONS[token] = reg
        else:
            register_macros(con)
        reg.add(con)
        return reg


class Connection:
    """A DuckDB connection with the mocapdb SQL functions (what :func:`mocapdb.connect` returns).

    Every method and attribute of ``duckdb.DuckDBPyConnection`` works on it
    (they are forwarded); :meth:`cursor` returns a :class:`Connection` with
    the functions too. :attr:`duckdb` is the DuckDB connection itself, for
    a library that insists on that type.
    """

    def __init__(self, con, registration):
        self._con = con
        self._registration = registration
        share_cache(self, registration.cache)

    @property
    def duckdb(self) -> duckdb.DuckDBPyConnection:
        """The underlying ``duckdb.DuckDBPyConnection``."""
        return self._con

    def __getattr__(self, name):
        return getattr(self._con, name)

    def cursor(self) -> "Connection":
        """A new connection to the same database (DuckDB's cursor), with the SQL functions."""
        cur = self._con.cursor()
        try:
            return Connection(cur, _attach(cur))
        except BaseException:
            cur.close()
            raise

    def close(self) -> None:
        """Close the connection (and, as DuckDB does, its cursors)."""
        self._con.close()
        self._registration.released(self._con)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        return f"<mocapdb.Connection of {self._con!r}>"


def connect(path=":memory:", *, read_only: bool = False, memory_limit=None, wait: float = 0.0) -> Connection:
    """Open a database (:func:`mocapdb.storage.schema.open_database`) with the SQL functions.

    Any number of connections to one file may be open in one process (a
    notebook cell run again); each, and each of their cursors, has the
    functions. See :func:`mocapdb.api.connect`.
    """
    con = open_database(path, read_only=read_only, memory_limit=memory_limit, wait=wait)
    try:
        return Connection(con, _attach(con))
    except BaseException:
        con.close()
        raise
