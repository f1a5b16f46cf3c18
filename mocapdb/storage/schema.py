"""Opening a mocap database: a DuckDB file with the mocapdb schema and the shipped models.

The schema lives in ``sql/schema.sql``, ``sql/views.sql`` and ``sql/index.sql``
(plain tables and views, persisted in the file). A read-write open creates
what is missing — a new database gets the tables, the keyframe index and
the shipped models (:data:`mocapdb.storage.models.SHIPPED_MODELS`) — so every
SQL function works on a fresh database. A read-only open changes nothing; the
shipped models then come from the package.

The SQL functions themselves are registered by :mod:`mocapdb.extension`
(``mocapdb.connect`` does both). In a DuckDB client without mocapdb, the
tables' comments and persisted stand-ins of the functions
(``sql/comments.sql``) say how to get them.
"""
from __future__ import annotations

import re
from pathlib import Path

import duckdb

from mocapdb.errors import SchemaError
from mocapdb.storage.models import install_shipped_models
from mocapdb.storage.postings import create_index, create_index_schema
from mocapdb.storage.sqltext import sql_text, statement
from mocapdb.storage.transaction import transaction

#: run in this order on every read-write open; comments.sql (the plain-DuckDB hints) after views.sql,
#: which recreates the views
SCHEMA_FILES = ("schema.sql", "views.sql", "comments.sql")

_LOCK = re.compile(r"Conflicting lock is held in (?P<program>.*?) \(PID (?P<pid>\d+)\)")


class DatabaseLockedError(SchemaError):
    """Another process has the database file open for writing."""


def open_database(path=":memory:", *, read_only: bool = False) -> duckdb.DuckDBPyConnection:
    """Open (or create) a DuckDB database with the mocapdb schema, without the SQL functions.

    Parameters
    ----------
    path : str or Path
        Database file; created with the schema if it does not exist.
        ``":memory:"`` gives a throw-away database.
    read_only : bool, keyword-only
        Open the file read-only (it must exist; nothing is created).

    Raises
    ------
    DatabaseLockedError
        Another process holds the file (the message names it).
    SchemaError
        ``read_only`` and the file does not exist.
    """
    path = str(path)
    if read_only and path != ":memory:" and not Path(path).exists():
        raise SchemaError(f"{path}: no such database file (read_only=True cannot create it)")
    try:
        con = duckdb.connect(path, read_only=read_only)
    except duckdb.IOException as exc:
        m = _LOCK.search(str(exc))
        if m is None:
            raise SchemaError(f"{path}: cannot open the database: {str(exc).splitlines()[0]}") from None
        raise DatabaseLockedError(
            f"{path} is in use by another process (PID {m['pid']}, {m['program']}); DuckDB allows one "
            "writer at a time: wait for it to finish or stop it") from None
    try:
        if not read_only:
            create_schema(con)
    except BaseException:
        con.close()
        raise
    return con


def create_schema(con) -> None:
    """Create the mocapdb tables, views, keyframe index and shipped models where missing (idempotent).

    A new database gets the keyframe index built; an existing one keeps it or
    not, as its owner chose (:func:`mocapdb.storage.postings.drop_index`).
    Shipped models installed earlier are refreshed when the package's differ.
    """
    new = not con.execute(statement("motions.sql", "schema_exists")).fetchall()[0][0]
    with transaction(con):
        for name in SCHEMA_FILES:
            con.execute(sql_text(name))
        create_index_schema(con)
    if new:
        create_index(con)
    install_shipped_models(con)


__all__ = ["open_database", "create_schema", "DatabaseLockedError", "SCHEMA_FILES"]
