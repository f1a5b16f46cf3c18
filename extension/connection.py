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

So the functions are registered **once per instance** and held here for as long
as the process lives (a few closures; the models and the index they cache
are dropped when the instance's last connection closes). A registration is
recognised by a token UDF, ``mocap_instance()``. The macros (``annotate``,
``mt_distance``, …) are temporary, that is per connection: every
:class:`Connection` and every cursor of one installs them.

**The native extension.** Where it is installed (:func:`mocapdb.extension.native.extension_path`)
and not turned off (``MOCAPDB_NATIVE=0``), the first connection of an instance LOADs it through a
hidden connection of its own, the *keeper*: ``annotate``, ``mt_distance``, ``keyframe_search``,
``keyframe_search_words`` and ``similar_to`` are then the native functions (the macros of
``sql/native_macros.sql`` keep the named arguments and ``similar_to``'s rows), and no Python UDF is
registered. The extension's own connection
holds the instance; when the last user connection of it closes or is garbage-collected, the keeper
calls ``mocapdb_release()`` and closes, so the file is really closed. An instance whose extension
was released while something else kept it open (a plain ``duckdb.connect`` of the same file) gets
the Python UDFs on its next ``mocapdb.connect``. Where the extension is missing (no C compiler at
install), every function is a Python UDF.
"""
from __future__ import annotations

import os
import threading
import uuid
import weakref

import duckdb
from duckdb import sqltypes as T

from mocapdb.errors import SchemaError
from mocapdb.extension.native import NativeExtensionMissing, extension_path
from mocapdb.extension.udfs import make_udfs, register, register_macros, register_python_functions
from mocapdb.storage.cache import ConnectionCache, share_cache
from mocapdb.storage.model_store import SHIPPED_MODELS, model_names
from mocapdb.storage.schema import connect_raw, open_database
from mocapdb.storage.sqltext import statement

__all__ = ["Connection", "connect", "NATIVE_ENV"]

#: set to 0 to keep mocapdb.connect from loading the native extension (the Python UDFs answer)
NATIVE_ENV = "MOCAPDB_NATIVE"


def native_extension():
    """The path of the native extension mocapdb.connect loads, or None (missing, or ``MOCAPDB_NATIVE=0``)."""
    if os.environ.get(NATIVE_ENV, "1").strip() == "0":
        return None
    try:
        return extension_path()
    except NativeExtensionMissing:
        return None


def _is_open(con) -> bool:
    """Whether a raw connection is still open (DuckDB closes a connection's cursors with it)."""
    try:
        con.cursor().close()
    except duckdb.Error:
        return False
    return True


class _Registration:
    """The functions of one database instance, the cache they answer from, and its live connections."""

    def __init__(self):
        self.token = uuid.uuid4().hex
        self.connections = weakref.WeakSet()  # raw duckdb connections, cursors included
        self.cache = ConnectionCache(self)
        self.udfs = ()
        self.native = False  # the macros call the native functions
        self.keeper = None   # the hidden connection that loaded the extension; it releases it

    def cursor(self):
        """A cursor of any open connection of the instance (the cache reads through it)."""
        for con in list(self.connections):
            try:
                return con.cursor()
            except duckdb.Error:  # closed
                continue
        raise SchemaError("every connection to this database is closed; open it again with mocapdb.connect")

    def register(self, con, keeper=None, native=None):
        """Register the functions on a fresh instance: LOAD the native extension through ``keeper``
        (a connection of the instance no user holds) when ``native`` is its path, the Python UDFs of
        what it lacks on ``con``."""
        if native is not None and keeper is not None:
            try:
                keeper.execute(statement("connection.sql", "load", literals={"extension": native}))
            except duckdb.Error as exc:
                raise SchemaError(f"loading the native extension {native} failed: {str(exc).splitlines()[0]} "
                                  f"(set {NATIVE_ENV}=0 to use the Python functions instead)") from None
            self.keeper, self.native = keeper, True
        token = self.token
        self.udfs = (*register(con, cache=self.cache, native=self.native), lambda: token)
        con.create_function("mocap_instance", self.udfs[-1], [], T.VARCHAR)

    def fall_back(self, con):
        """The instance's extension was released (it outlived its mocapdb connections): the Python
        UDFs answer from now on."""
        udfs = make_udfs(self.cache)
        register_python_functions(con, udfs)
        self.udfs = (*udfs, self.udfs[-1])
        self.native = False

    def add(self, con):
        self.connections.add(con)
        weakref.finalize(con, self.released)

    def released(self, con=None):
        with _LOCK:
            if con is not None:
                self.connections.discard(con)
            # iterating yields the live ones only (len() would count one being collected now)
            if not [other for other in self.connections if _is_open(other)]:  # a cursor closes with its connection
                self.cache.clear()
                self._release_native()

    def _release_native(self):
        """The keeper lets the extension go and closes: nothing of mocapdb holds the instance."""
        keeper, self.keeper = self.keeper, None
        if keeper is None:
            return
        try:
            keeper.execute(statement("connection.sql", "release")).fetchall()
        except duckdb.Error:
            pass  # the instance is going already (interpreter exit)
        finally:
            keeper.close()


#: token → registration; kept for the life of the process (DuckDB may call a UDF while any
#: connection of its instance is open, including one opened by plain duckdb.connect)
_REGISTRATIONS: dict = {}
#: re-entrant: a finalizer (a connection garbage-collected) may run inside _attach on this thread
_LOCK = threading.RLock()


def _registration_of(con):
    """The registration whose functions ``con``'s instance has, or None for a fresh instance."""
    try:
        token = con.execute(statement("connection.sql", "instance")).fetchall()[0][0]
    except duckdb.CatalogException:
        return None
    reg = _REGISTRATIONS.get(token)
    if reg is None:
        raise SchemaError("this database is open in this process with SQL functions registered outside "
                          "mocapdb.connect; open it with mocapdb.connect only")
    return reg


def _stores_shipped_models(con) -> bool:
    """Whether the database holds every shipped model. The native functions read models from the
    database only; a file made before a model shipped, opened read-only (so the model cannot be
    installed into it), answers with the Python UDFs, which read the package's copy."""
    try:
        return set(SHIPPED_MODELS) <= set(model_names(con))
    except duckdb.Error:  # no models table at all
        return False


def _attach(con, reopen=None):
    """Give a raw connection the SQL functions: the instance's registration (made on first use)
    and the macros. ``reopen()`` opens another connection to the instance (the keeper of the
    native extension; None for a cursor, whose instance has its registration). Returns the
    registration."""
    with _LOCK:
        reg = _registration_of(con)
        if reg is None:
            reg = _Registration()
            native = native_extension() if reopen is not None and _stores_shipped_models(con) else None
            keeper = reopen() if native is not None else None
            try:
                reg.register(con, keeper, native)
            except BaseException:
                if reg.keeper is not None:
                    reg._release_native()  # loaded: let it go, or the file stays open
                elif keeper is not None:
                    keeper.close()
                raise
            _REGISTRATIONS[reg.token] = reg
        else:
            if reg.native and reg.keeper is None:
                reg.fall_back(con)
            register_macros(con, native=reg.native)
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
    path = str(path)
    if path == ":memory:":
        # a throw-away database with a name of its own, which the keeper can open too
        path = f":memory:mocapdb_{uuid.uuid4().hex}"
    con = open_database(path, read_only=read_only, memory_limit=memory_limit, wait=wait)
    try:
        return Connection(con, _attach(con, lambda: connect_raw(path, read_only=read_only)))
    except BaseException:
        con.close()
        raise
