"""The SQL of mocapdb, read from the ``sql/*.sql`` files installed with the package.

A file is either one script (``schema.sql``, ``views.sql``, ``macros.sql``)
or a set of named statements, each introduced by a ``-- name: <name>`` line
(``index.sql``, ``ingest.sql``, …). Substitution is limited to a fixed set of
``%placeholder%`` names, each replaced by a quoted identifier (DuckDB's fts
does the same); values always travel as query parameters — except in DDL,
which DuckDB cannot prepare: a view over an archive's files names them in its
text. Those values fill the :data:`LITERALS` placeholders, written inside a
string literal in the SQL file (``'%archive%/motions/*.parquet'``), with
their quotes doubled (:func:`statement` with ``literals``).
"""
from __future__ import annotations

import functools
import re
from importlib import resources

from mocapdb.errors import ParameterError

#: schema of the keyframe index tables (plain tables, dropped with the schema, as DuckDB's fts)
INDEX_SCHEMA = "mocap_index"

#: the only placeholders the SQL files may use, and their values
PLACEHOLDERS = {"index_schema": INDEX_SCHEMA}
#: placeholders filled per statement with a value inside a string literal (DDL and LOAD only: they
#: take no parameters)
LITERALS = ("archive", "extension")

_NAME = re.compile(r"^--\s*name:\s*(\w+)\s*$", re.M)
_PLACEHOLDER = re.compile(r"%(\w+)%")


def quote_identifier(name: str) -> str:
    """``name`` as a double-quoted SQL identifier (embedded quotes doubled)."""
    return '"' + str(name).replace('"', '""') + '"'


def _substitute(text: str, where: str) -> str:
    def sub(m):
        key = m.group(1)
        if key in LITERALS:
            return m.group(0)  # filled in per statement
        if key not in PLACEHOLDERS:
            raise ParameterError(f"{where}: unknown placeholder %{key}%; allowed: "
                                 + ", ".join(f"%{k}%" for k in PLACEHOLDERS))
        return quote_identifier(PLACEHOLDERS[key])
    return _PLACEHOLDER.sub(sub, text)


@functools.cache
def sql_text(name: str) -> str:
    """The script ``sql/<name>`` with its placeholders filled in."""
    text = resources.files("mocapdb.sql").joinpath(name).read_text(encoding="utf-8")
    return _substitute(text, f"sql/{name}")


@functools.cache
def _statements(name: str) -> dict:
    text = sql_text(name)
    parts = _NAME.split(text)
    # parts = [preamble, name1, body1, name2, body2, ...]
    return {parts[i]: parts[i + 1].strip() for i in range(1, len(parts), 2)}


def statement(file: str, name: str, *, literals=None) -> str:
    """The statement ``-- name: <name>`` of ``sql/<file>``.

    Parameters
    ----------
    literals : dict, optional
        Values of the :data:`LITERALS` placeholders the statement uses, for
        DDL that cannot take parameters; each is inserted with its single
        quotes doubled, so it stays inside the string literal it is written in.

    Raises
    ------
    ParameterError
        If the file has no such statement or a literal is missing or unknown (programming errors).
    """
    stmts = _statements(file)
    if name not in stmts:
        raise ParameterError(f"sql/{file} has no statement {name!r}; it has {sorted(stmts)}")
    text = stmts[name]
    literals = literals or {}
    unknown = sorted(set(literals) - set(LITERALS))
    if unknown:
        raise ParameterError(f"unknown literal placeholders {unknown}; allowed: {', '.join(LITERALS)}")

    def fill(m):
        if m.group(1) not in literals:
            raise ParameterError(f"sql/{file} {name}: no value for %{m.group(1)}%")
        return str(literals[m.group(1)]).replace("'", "''")
    return re.sub(r"%(" + "|".join(LITERALS) + r")%", fill, text)


__all__ = ["INDEX_SCHEMA", "PLACEHOLDERS", "LITERALS", "quote_identifier", "sql_text", "statement"]
