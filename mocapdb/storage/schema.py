"""Opening a mocap database: a DuckDB file with the mocapdb schema and the shipped models.

The schema lives in ``sql/schema.sql``, ``sql/views.sql`` and ``sql/index.sql``
(plain tables and views, persisted in the file). A read-write open creates
what is missing — a new database gets the tables, the keyframe index and
the shipped models (:data:`mocapdb.storage.model_store.SHIPPED_MODELS`) — so every
SQL function works on a fresh database. A read-only open changes nothing; the
shipped models then come from the package.

The SQL functions themselves are registered by :mod:`mocapdb.extension`
(``mocapdb.connect`` does both). In a DuckDB client without mocapdb, the
tables' comments (``sql/comments.sql``) say how to get them (the native
extension); that file also drops the persisted stand-ins older versions wrote,
which would hide the native functions.
"""
from __future__ import annotations

import os
import re
import time
from pathlib import Path

import duckdb

from mocapdb.errors import SchemaError
from mocapdb.storage.model_store import install_shipped_models
from mocapdb.storage.postings import create_index, create_index_schema
from mocapdb.storage.sqltext import sql_text, statement
from mocapdb.storage.transaction import transaction

#: run in this order on every read-write open; comments.sql (the plain-DuckDB hints) after views.sql,
#: which recreates the views
SCHEMA_FILES = ("schema.sql", "views.sql", "comments.sql")

_LOCK = re.compile(r"Conflicting lock is held in (?P<program>.*?) \(PID (?P<pid>\d+)\)")


class DatabaseLockedError(SchemaError):
    """Another process has the database file open for writing."""


#: DuckDB's memory limit on a mocapdb database (DuckDB's own default is 80 % of RAM): DuckDB keeps
#: table blocks it has read cached up to its limit, so without one a pass over a large archive
#: grows the process to most of the machine's memory. mocapdb's own work runs a batch of motions
#: at a time (mocapdb.storage.motions.BATCH_FRAMES) beside it; beyond the limit DuckDB spills
#: to its temp directory (``<database>.tmp``). Override per connection (``memory_limit=``) or with
#: the environment variable MOCAPDB_MEMORY_LIMIT, or later with ``SET memory_limit``.
DEFAULT_MEMORY_LIMIT = "512MB"
MEMORY_LIMIT_ENV = "MOCAPDB_MEMORY_LIMIT"
#: the storage format of the files mocapdb creates: DuckDB 1.5's, which DuckDB 1.5 and later read, so
#: an archive opens in the clients that load the native extension (the DuckDB CLI, Node and JDBC
#: at 1.5: docs/EXTENSION.md), not only in the Python duckdb that wrote it (2.0 writes a newer format
#: by default, which 1.5 refuses). A file keeps the format it was created with.
STORAGE_VERSION = "v1.5.0"
#: seconds between two tries to open a file another process holds (``open_database(wait=…)``)
LOCK_POLL = 0.05


#: where DuckDB's database files carry their magic bytes (after an 8-byte checksum)
_MAGIC_AT, _MAGIC = 8, b"DUCK"


def check_database_file(path) -> None:
    """Refuse a path that exists but is no DuckDB database file, before DuckDB reads it.

    DuckDB opens a CSV, JSON or Parquet file named as the database as an
    in-memory database with the file as a view: what is then written into it
    is gone when the process exits, silently. A new path, an empty file (a
    fresh one DuckDB fills) and ``:memory:`` pass.

    Raises
    ------
    SchemaError
        A folder, an unreadable file, or a file without DuckDB's magic bytes.
    """
    if str(path) == ":memory:":
        return
    p = Path(path)
    if p.is_dir():
        raise SchemaError(f"{path} is a folder, not a DuckDB database file")
    if not p.exists():
        return
    try:
        with p.open("rb") as fh:
            head = fh.read(_MAGIC_AT + len(_MAGIC))
    except OSError as exc:
        raise SchemaError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    if head and head[_MAGIC_AT:] != _MAGIC:
        kind = {b"PAR1": "a Parquet file", b"PK\x03\x04": "a zip archive", b"SQLi": "an SQLite database"}.get(
            head[:4], "a JSON file" if head.lstrip()[:1] in (b"{", b"[") else "not DuckDB's")
        raise SchemaError(f"{path} is not a DuckDB database file ({kind}; DuckDB would read it as a view in a "
                          "throw-away database and lose what is written): give a .duckdb file, or a new path")


def open_database(path=":memory:", *, read_only: bool = False, memory_limit=None,
                  wait: float = 0.0) -> duckdb.DuckDBPyConnection:
    """Open (or create) a DuckDB database with the mocapdb schema, without the SQL functions.

    Parameters
    ----------
    path : str or Path
        Database file; created with the schema if it does not exist.
        ``":memory:"`` gives a throw-away database (``":memory:<name>"`` one that other
        connections of this process can open by that name).
    read_only : bool, keyword-only
        Open the file read-only (it must exist; nothing is created).
    memory_limit : str, optional, keyword-only
        DuckDB's memory limit (``"512MB"``, ``"4GB"``); default
        ``$MOCAPDB_MEMORY_LIMIT`` or :data:`DEFAULT_MEMORY_LIMIT`. It applies to
        the whole database instance (every connection to the file in this process).
    wait : float, keyword-only, default 0
        Seconds to keep trying while another process holds the file (DuckDB
        lets one process write it and none open it meanwhile): the one
        lock-wait of mocapdb, for ``mocapdb.connect(lock_wait=…)`` and each
        request of ``mocapdb serve`` alike.

    Raises
    ------
    DatabaseLockedError
        Another process still holds the file after ``wait`` seconds (the message names it).
    SchemaError
        ``read_only`` and the file does not exist, or the path is no DuckDB
        database file (:func:`check_database_file`).
    """
    path = str(path)
    check_database_file(path)
    if read_only and not path.startswith(":memory:") and not Path(path).exists():
        raise SchemaError(f"{path}: no such database file (read_only=True cannot create it)")
    deadline = time.monotonic() + wait
    while True:
        try:
            con = connect_raw(path, read_only=read_only)
            break
        except duckdb.IOException as exc:
            m = _LOCK.search(str(exc))
            if m is None:
                raise SchemaError(f"{path}: cannot open the database: {str(exc).splitlines()[0]}") from None
            if time.monotonic() < deadline:
                time.sleep(LOCK_POLL)
                continue
            raise DatabaseLockedError(
                f"{path} is in use by another process (PID {m['pid']}, {m['program']}); DuckDB allows one "
                "writer at a time: wait for it to finish or stop it") from None
    try:
        limit = memory_limit or os.environ.get(MEMORY_LIMIT_ENV) or DEFAULT_MEMORY_LIMIT
        try:
            con.execute(statement("settings.sql", "memory_limit"), {"memory_limit": str(limit)})
        except duckdb.Error as exc:
            raise SchemaError(f"memory_limit: {limit!r} is not a memory size such as 512MB or 4GB "
                              f"({str(exc).splitlines()[0]})") from None
        if is_attached(con):
            # views over a ray-annotate archive (mocapdb.storage.attached): keep the Parquet footers read
            con.execute(statement("attached.sql", "settings"))
        if not read_only:
            create_schema(con)
    except BaseException:
        con.close()
        raise
    return con


#: the settings of every mocapdb open, not only the first: DuckDB refuses a second connection to a file
#: of this process with other settings. Archives are written in DuckDB 1.5's format (on a file of a
#: newer format the setting changes nothing); unsigned extensions are allowed because
#: mocapdb.connect LOADs its own native extension, which is unsigned (docs/EXTENSION.md).
OPEN_CONFIG = {"storage_compatibility_version": STORAGE_VERSION, "allow_unsigned_extensions": "true"}


def connect_raw(path, *, read_only: bool = False) -> duckdb.DuckDBPyConnection:
    """A plain DuckDB connection to ``path`` with mocapdb's settings (:data:`OPEN_CONFIG`): no
    schema, memory limit or lock wait. For another connection to a database this process has open
    (:func:`open_database` opened it first); DuckDB's errors are the caller's."""
    return duckdb.connect(str(path), read_only=read_only, config=OPEN_CONFIG)


def is_attached(con) -> bool:
    """Whether the database's motions, features and annotations are views over an archive
    (:mod:`mocapdb.storage.attached`)."""
    return con.execute(statement("attached.sql", "is_attached")).fetchall()[0][0]


def attached_archive(con):
    """The archive folder a database is attached to (:mod:`mocapdb.storage.attached`), or None."""
    if not is_attached(con):
        return None
    rows = con.execute(statement("attached.sql", "archive_root")).fetchall()
    return rows[0][0] if rows else None


def require_own_tables(con, what: str) -> None:
    """Raise a clear error when ``con`` is attached to an archive and ``what`` would write its tables.

    Raises
    ------
    SchemaError
    """
    root = attached_archive(con)
    if root is not None:
        raise SchemaError(f"{what}: this database is attached to the archive {root} (its motions, features, "
                          "annotations and keyframe index are read-only views of the archive's Parquet); use a "
                          "database of its own (import-features loads the archive into one)")


def _drop_stand_ins(con) -> None:
    """Drop the persisted stand-in macros an older mocapdb wrote (``sql/stand_ins.sql`` says why)."""
    for name, in con.execute(statement("stand_ins.sql", "present")).fetchall():
        con.execute(statement("stand_ins.sql", name))


def create_schema(con) -> None:
    """Create the mocapdb tables, views, keyframe index and shipped models where missing (idempotent).

    A new database gets the keyframe index built; an existing one keeps it or
    not, as its owner chose (:func:`mocapdb.storage.postings.drop_index`).
    Shipped models installed earlier are refreshed when the package's differ.
    """
    new = not con.execute(statement("motions.sql", "schema_exists")).fetchall()[0][0]
    if is_attached(con):  # its tables are views over an archive; the models are its own
        install_shipped_models(con)
        return
    with transaction(con):
        for name in SCHEMA_FILES:
            con.execute(sql_text(name))
        _drop_stand_ins(con)
        create_index_schema(con)
    if new:
        create_index(con)
    install_shipped_models(con)


__all__ = ["open_database", "connect_raw", "OPEN_CONFIG", "check_database_file", "create_schema", "is_attached", "attached_archive", "require_own_tables", "DatabaseLockedError", "SCHEMA_FILES", "DEFAULT_MEMORY_LIMIT",
           "MEMORY_LIMIT_ENV"]
