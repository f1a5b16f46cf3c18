"""One transaction helper for every write of mocapdb.

DESIGN.md §6: a failed ingest (or model save, delete, import) leaves the
database exactly as it was. Every write runs inside :func:`transaction`, and
Arrow tables reach SQL through :func:`registered` (a view that is dropped
again whatever happens).
"""
from __future__ import annotations

from contextlib import contextmanager


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
    """Make Arrow tables visible to SQL under the given names for the ``with`` block."""
    for name, table in tables.items():
        con.register(name, table)
    try:
        yield con
    finally:
        for name in tables:
            con.unregister(name)


__all__ = ["transaction", "registered"]
