"""One transaction helper for every write of mocapdb.

DESIGN.md §6: a failed ingest (or model save, delete, import) leaves the
database exactly as it was. Every write runs inside :func:`transaction`, and
Arrow tables reach SQL through :func:`registered` (a view that is dropped
again whatever happens).
"""
from __future__ import annotations

from contextlib import contextmanager

import duckdb


@contextmanager
def transaction(con):
    """``with transaction(con): …`` — BEGIN, then COMMIT, or ROLLBACK on any exception."""
    con.begin()
    try:
        yield con
    except BaseException:
        con.rollback()
        raise
    con.commit()


@contextmanager
def registered(con, **tables):
    """Make Arrow tables visible to SQL under the given names for the ``with`` block.

    When the block fails inside a transaction, DuckDB has aborted that
    transaction and refuses every further statement, unregistering included
    ("Current transaction is aborted"): that refusal must not replace the
    block's own error, which names the cause (a truncated Parquet file, a
    constraint). The registrations belong to the aborted transaction and go
    with its rollback (:func:`transaction` rolls back on the way out).
    """
    for name, table in tables.items():
        con.register(name, table)
    try:
        yield con
    except BaseException:
        for name in tables:
            try:
                con.unregister(name)
            except duckdb.TransactionException:
                pass  # the aborted transaction's rollback drops the view
        raise
    for name in tables:
        con.unregister(name)


__all__ = ["transaction", "registered"]
