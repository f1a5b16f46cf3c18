"""Opening a mocap database: a DuckDB file with the mocapdb schema and SQL functions.

The schema lives in ``sql/schema.sql`` and ``sql/views.sql`` (plain tables and
views, persisted in the file). The SQL functions are Python UDFs and
temporary macros, so they exist only on connections opened through
:func:`connect` (DuckDB cannot persist a Python function).
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

import duckdb

from .errors import SchemaError

SCHEMA_FILES = ("schema.sql", "views.sql")


def sql_text(name: str) -> str:
    """Return the text of ``sql/<name>`` as installed with the package."""
    return resources.files("mocapdb.sql").joinpath(name).read_text(encoding="utf-8")


def connect(path=":memory:", *, read_only: bool = False) -> duckdb.DuckDBPyConnection:
    """Open (or create) a mocap database and register the mocapdb SQL functions.

    Parameters
    ----------
    path : str or Path
        Database file; created with the schema if it does not exist.
        ``":memory:"`` gives a throw-away database (unit tests).
    read_only : bool, keyword-only
        Open the file read-only (the schema must already be there).

    Returns
    -------
    duckdb.DuckDBPyConnection
        A connection on which ``annotate``, ``mt_distance``,
        ``keyframe_search`` … are available. Close it when done.

    Examples
    --------
    >>> con = mocapdb.connect("archive.duckdb")
    >>> con.sql("SELECT name, n_frames FROM motions").fetchall()
    """
    path = str(path)
    if read_only and path != ":memory:" and not Path(path).exists():
        raise SchemaError(f"{path}: no such database file (read_only=True cannot create it)")
    con = duckdb.connect(path, read_only=read_only)
    try:
        if not read_only:
            create_schema(con)
        from .extension import register

        register(con)
    except BaseException:
        con.close()
        raise
    return con


def create_schema(con) -> None:
    """Create the mocapdb tables and views if they are missing (idempotent).

    A new database also gets the keyframe index (``mocap_index``); an existing
    one keeps it or not, as its owner chose (:func:`mocapdb.postings.drop_index`).
    """
    from .postings import create_index

    new = not con.execute("SELECT count(*) FROM duckdb_tables() WHERE schema_name = 'main' "
                          "AND table_name = 'motions'").fetchall()[0][0]
    for name in SCHEMA_FILES:
        con.execute(sql_text(name))
    if new:
        create_index(con)


def motion_ids(con, motions) -> list[int]:
    """Resolve motion ids or names to ids, raising SchemaError for unknown ones."""
    out = []
    for m in motions:
        if isinstance(m, int) or (isinstance(m, str) and m.isdigit()):
            row = con.execute("SELECT motion_id FROM motions WHERE motion_id = ?", [int(m)]).fetchall()
        else:
            row = con.execute("SELECT motion_id FROM motions WHERE name = ? ORDER BY motion_id", [m]).fetchall()
        if not row:
            raise SchemaError(f"no motion {m!r} in the database (see: SELECT motion_id, name FROM motions)")
        out.extend(r[0] for r in row)
    return out


__all__ = ["connect", "create_schema", "sql_text", "motion_ids"]
