"""The DuckDB side of mocapdb: what makes a DuckDB connection a mocap database.

:func:`register` is called by :func:`mocapdb.connect` on every connection. It
registers the Python UDFs (Arrow in, Arrow out; heavy work in nogil numba
kernels) and the temporary macros of ``sql/macros.sql`` that wrap them with
the user-facing names and defaults. Nothing here is persisted in the database
file: a persisted macro that calls a Python UDF would fail after reopening the
file without mocapdb, so every connection gets its own temporary copies.
"""
from mocapdb.extension.connection import Connection, connect
from mocapdb.extension.udfs import MAX_GAP, MAX_KEYFRAMES, register

__all__ = ["register", "connect", "Connection", "MAX_KEYFRAMES", "MAX_GAP"]
